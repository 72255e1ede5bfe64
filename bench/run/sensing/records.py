"""The sensing loop's options, its verification grid and the outcome class of a run. Its typed
records (sensing.json) and the outcome classes' texts are ``bench.io.sensing_records``.

Ground truth appears here only as the scores recorded beside the loop's own verdict
(``gt_visibility``: camera -> {"visible_fraction", "false_boundary"}).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from platebench.bench.config.sensing import VERIFY_GRID, WORKSPACE_MM
from platebench.reconstruction.strategy.planner import MAX_CURE_VIEWS, MAX_VIEWS
from platebench.reconstruction.strategy.poses import Reach

VERIFY_ROWS, VERIFY_COLS, VERIFY_SQUARE_PX, VERIFY_WIDTH_PX = 6, 12, 12, 640
# a grid of 6 rows with rows 4 squares apart (``parse_grid``) fits the 768-px projector up to this square size
VERIFY_MAX_SQUARE_PX = 29


def auto_verify_grid(width_px: int) -> str:
    """The verification grid for images ``width_px`` wide: 6x12@12 from 640 px up; on narrower
    images its squares grow as the pixels do (12 x 640 / width, at most ``VERIFY_MAX_SQUARE_PX``), so
    that a square keeps the 7 or so camera pixels it has at 640 x 480 and 0.4 m (at 320 x 240 12-px
    squares are 3-4 camera pixels: the stage-2 pose kept 8 centres of the 72)."""
    sq = min(VERIFY_MAX_SQUARE_PX, max(VERIFY_SQUARE_PX, int(np.ceil(VERIFY_SQUARE_PX * VERIFY_WIDTH_PX / width_px))))
    return f"{VERIFY_ROWS}x{VERIFY_COLS}@{sq}"


def outcome_class(hidden_first: bool, hidden_final: bool, verified: bool, cured_or_raised: bool) -> str:
    """The outcome class of a sensing run (``bench.io.sensing_records.OUTCOME_TEXT``) from ground truth's "hidden" at the stage-2
    pose and at the end, the loop's verdict, and whether it applied a cure or raised a flag."""
    if hidden_final:
        return "silent" if verified else "honest"
    if hidden_first:
        return "cured" if verified else "unconfirmed"
    return "false_alarm" if cured_or_raised else "clean"


def gt_visibility_dict(vis: dict) -> dict:
    """camera -> ``BoundaryVisibility`` as sensing.json records it (camera -> {"visible_fraction",
    "false_boundary"})."""
    return {c: {"visible_fraction": float(v.visible_fraction), "false_boundary": bool(v.false_boundary)}
            for c, v in vis.items()}


@dataclass(frozen=True)
class SensingOptions:
    # stage 1 covers a disc of this radius around the workspace centre (``platebench sense --workspace-mm``)
    workspace_radius_m: float = WORKSPACE_MM / 1e3
    working_distance_m: float = 0.40  # cameras focused here: stage 2 comes no closer
    # Stage 3 places the projector on its centre line at this distance from the boundary centre;
    # None: at the cameras' distance (a fixed far projector shrinks its squares when cameras move).
    projector_distance_m: float | None = None
    max_cures: int = MAX_CURE_VIEWS  # cure poses at most
    # Measuring poses at most (stage 2, verification, cures); None: derived from ``max_cures`` (stage 2,
    # every verification view and ``max_cures`` cures: ``MAX_VIEWS`` at the default budget).
    max_views: int | None = None
    verification: bool = True  # False: the paper's loop alone (stages 1-3, no verification views)
    # Every later measuring pose also projects the square grid (projector beside the rig,
    # ``active_views.projector_pose``) and measures its centres: the merged reconstruction's points
    # and surface (``active_views``).
    active_views: bool = True
    # The square grid the verification views and cures project ('ROWSxCOLS@SQUARE_PX', "auto":
    # ``auto_verify_grid`` of the image width); None: the sample's own pattern, as stage 3.
    verify_grid: str | None = VERIFY_GRID
    write_stages: bool = True
    reach: Reach = field(default_factory=Reach)
    # For scoring only: cast ground truth's boundary visibility from every pose the loop could reach
    # (its verification views and cure candidates) to say whether a reachable set sees the boundary.
    ground_truth_reach: bool = False
    # A real rig (``cfg.realism`` not ideal): the corner-localisation noise of its calibration views
    # (px; ``bench.run.realism.RealismSetup``); None: measured on renders at the start of the run.
    corner_noise_px: float | None = None

    def __post_init__(self):
        if self.max_views is None:
            object.__setattr__(self, "max_views", MAX_VIEWS - MAX_CURE_VIEWS + int(self.max_cures))
