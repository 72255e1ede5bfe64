"""Defaults of the sensing loop and of its study that the command line shows and checks (plain values,
so that ``platebench sense`` and ``platebench study`` parse and refuse flags without loading the loop):
``bench.run.sensing.records`` and ``bench.run.sensing.study`` take them from here."""
from __future__ import annotations

from dataclasses import dataclass

from platebench.errors import UserValueError
from platebench.plates.spec import reference_spec
from platebench.reconstruction.strategy.budget import MAX_CURE_VIEWS, MAX_CURES_ALLOWED

__all__ = ["VERIFY_GRID", "DEFAULT_BENDS_DEG", "STUDY_AXES_DEG", "REFERENCE_ASPECT", "MAX_CURE_VIEWS",
           "MAX_CURES_ALLOWED", "WORKSPACE_MM", "SenseSettings", "sense_settings", "parse_verify_grid"]

# The square grid the verification views and cures project (ROWSxCOLS@SQUARE_PX, ``bench.config.parse_grid``),
# "auto" by default (``bench.run.sensing.records.auto_verify_grid``): 6 arrays of 12 squares of 12 projector pixels (3 mm at 0.4 m;
# rows 48 px apart) at 640 px wide and more. Stage 3 keeps the sample's own pattern (the paper's 16
# squares by default) for the paper's pipeline and its counting test. The verdict's front check and its
# confirmations need square centres up to the plate's edges, which the paper's 16 squares do not give
# (docs/findings/design-record.md, "The verification grid").
VERIFY_GRID = "auto"

# The false-boundary study's cylinders (``bench.run.sensing.study.study_cases``)
DEFAULT_BENDS_DEG = (0.0, 60.0, 120.0, 180.0, 240.0, 300.0)  # bend angles, convex and concave
STUDY_AXES_DEG = (0.0, 30.0, 60.0, 90.0)  # bend axes from the plate's width direction
REFERENCE_ASPECT = reference_spec().length_m / reference_spec().width_m  # the paper's plate, length / width

# ``platebench sense --workspace-mm``: the radius stage 1 must cover (mm), its default and allowed range
WORKSPACE_MM = 150.0
WORKSPACE_MM_RANGE = (10.0, 2000.0)


@dataclass(frozen=True)
class SenseSettings:
    """What ``platebench sense`` asks of the loop, checked: the radius stage 1 covers (metres), the cure
    poses at most, and the verification views' grid (``parse_verify_grid``: a grid, "auto", or None for
    stage 3's). ``bench.run.sensing.SensingOptions`` takes these three."""

    workspace_radius_m: float
    max_cures: int
    verify_grid: str | None


def sense_settings(workspace_mm: float, max_cures: int, verify_grid: str) -> SenseSettings:
    """``sense``'s flags checked, in the order the command reports them; raises ``UserValueError`` naming
    the flag and what is allowed."""
    lo, hi = WORKSPACE_MM_RANGE
    if not (lo <= workspace_mm <= hi):
        raise UserValueError(f"--workspace-mm = {workspace_mm} is out of range: allowed {lo:g} to {hi:g} mm")
    if not (0 <= max_cures <= MAX_CURES_ALLOWED):
        raise UserValueError(f"--max-cures = {max_cures} is out of range: allowed 0 to {MAX_CURES_ALLOWED}")
    return SenseSettings(workspace_mm * 1e-3, max_cures, parse_verify_grid(verify_grid))


def parse_verify_grid(text: str) -> str | None:
    """``--verify-grid``'s value checked against the reference projector (``bench.config.parse_grid``,
    ``scenes.pattern.square_grid``): the grid text, "auto", or None for 'stage3'. Raises
    ``UserValueError`` for a grid that is not ROWSxCOLS@SQUARE_PX or does not fit the projector."""
    from platebench.bench.config.sample_config import parse_grid  # noqa: PLC0415
    from platebench.scenes.pattern import square_grid  # noqa: PLC0415
    from platebench.scenes.scene_spec import REFERENCE  # noqa: PLC0415

    if text.strip() == "stage3":
        return None
    if text.strip() == "auto":
        return "auto"
    try:
        square_grid(REFERENCE.projector_width, REFERENCE.projector_height, **parse_grid(text))
    except UserValueError as e:
        raise UserValueError(str(e).replace("--grid", "--verify-grid") + ", 'auto' or 'stage3'") from None
    except ValueError as e:  # the grid does not fit the projector's image
        raise UserValueError(f"--verify-grid = {text!r}: {e}") from None
    return text.strip()
