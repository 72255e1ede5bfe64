"""The studies' flags (``platebench study false-boundary | accuracy | cut-squares``) checked and turned
into frozen settings before any study module is loaded: every refusal is one ``UserValueError`` naming
the flag and what is allowed. The studies themselves are ``bench.run.sensing.study``, ``bench.run.accuracy``
and ``bench.run.cut_study``; the settings each writes into its JSON are their forms
(``bench.io.codecs.bench_records``)."""
from __future__ import annotations

from dataclasses import dataclass, replace

from platebench.bench.config.ranges import parse_range_text
from platebench.bench.config.sample_config import SampleConfig, SceneParams, parse_grid
from platebench.errors import UserValueError
from platebench.scenes.scene_spec import RenderSettings

__all__ = ["MAX_BENDS", "MAX_PERTURB_AXIS_DEG", "MAX_PERTURB_MM", "DEFAULT_WORKERS", "MAX_WORKERS", "DEFAULT_WIDTH",
           "DEFAULT_SPP", "MAX_DRAWS", "ACCURACY_SPP", "parse_perturb", "with_scales", "FalseBoundaryFlags",
           "false_boundary_flags", "StudySettings", "study_sample_config", "CutSquaresSettings",
           "cut_squares_settings", "AccuracyFlags", "accuracy_flags"]

MAX_BENDS = 400  # bend values a study accepts (each gives 8 cylinders)
MAX_PERTURB_AXIS_DEG = 10.0  # --perturb: small shifts only (the study's plates, moved a little)
MAX_PERTURB_MM = 50.0
DEFAULT_WORKERS = 2  # plates at once (study --workers)
MAX_WORKERS = 64
DEFAULT_WIDTH = 640  # false-boundary and cut-squares: the ideal camera's image width (px)
DEFAULT_SPP = 2  # false-boundary and cut-squares: samples per pixel
MAX_DRAWS = 1000  # accuracy: Monte Carlo draws per budget row at most
# accuracy: samples per pixel; the block's corners are fitted to edges, and the renderer's Monte Carlo
# noise at the edge pixels adds to the camera's, so the no-source floor needs more than the other studies
ACCURACY_SPP = 16
WIDTH_RANGE = (160, 4096)  # --width (px)
SPP_RANGE = (1, 1024)  # --spp
ASPECT_RANGE = (0.25, 8.0)  # false-boundary --aspect (length / width)
BEND_RANGE_DEG = (0.0, 350.0)
L_BEND_RANGE_DEG = (1.0, 179.0)
AXIS_RANGE_DEG = (0.0, 179.9)
DISTANCE_RANGE_M = (0.2, 2.0)


def _width(width: int | None) -> None:
    if width is not None and not (WIDTH_RANGE[0] <= width <= WIDTH_RANGE[1]):
        raise UserValueError(f"--width = {width} is out of range: allowed {WIDTH_RANGE[0]} to {WIDTH_RANGE[1]}")


def _spp(spp: int) -> None:
    if not (SPP_RANGE[0] <= spp <= SPP_RANGE[1]):
        raise UserValueError(f"--spp = {spp} is out of range: allowed {SPP_RANGE[0]} to {SPP_RANGE[1]}")


def _render(spp: int | None, seed: int) -> RenderSettings:
    """``RenderSettings``' own checks, as 'render --seed' has them, as a one-line flag error."""
    try:
        return RenderSettings(spp=spp, seed=seed)
    except ValueError as e:
        raise UserValueError(f"--{e}") from None


def _values(text: str | None, key: str, default, lo: float, hi: float) -> list[float]:
    return parse_range_text(text or ",".join(f"{v:g}" for v in default), key, lo, hi, max_count=MAX_BENDS)


def parse_perturb(text: str) -> tuple[float, float]:
    """'AXIS_DEG,DISTANCE_MM' -> (degrees, millimetres), each within the allowed small shift."""
    parts = [p.strip() for p in str(text).split(",")]
    try:
        if len(parts) != 2:
            raise ValueError
        axis_deg, distance_mm = float(parts[0]), float(parts[1])
    except ValueError:
        raise UserValueError(f"--perturb = {text!r} is not AXIS_DEG,DISTANCE_MM: allowed two numbers, e.g. 1,5") from None
    if not (abs(axis_deg) <= MAX_PERTURB_AXIS_DEG):
        raise UserValueError(f"--perturb axis = {axis_deg:g} deg is out of range: allowed -{MAX_PERTURB_AXIS_DEG:g} "
                             f"to {MAX_PERTURB_AXIS_DEG:g}")
    if not (abs(distance_mm) <= MAX_PERTURB_MM):
        raise UserValueError(f"--perturb distance = {distance_mm:g} mm is out of range: allowed -{MAX_PERTURB_MM:g} "
                             f"to {MAX_PERTURB_MM:g}")
    return axis_deg, distance_mm


def with_scales(realism, text: str):
    """``realism`` (a ``bench.config.realism`` preset) with the scales of ``--realism-scale``
    ('SOURCE=F,SOURCE=F'); one-line errors name the value and what is allowed."""
    from platebench.bench.config.realism import SOURCES  # noqa: PLC0415

    scales = {}
    for item in (t.strip() for t in text.split(",")):
        name, eq, value = item.partition("=")
        if not eq:
            raise UserValueError(f"--realism-scale item {item!r} is not SOURCE=F (e.g. robot_accuracy=4)")
        try:
            f = float(value)
        except ValueError:
            raise UserValueError(f"--realism-scale {name.strip()} = {value!r} is not a number") from None
        name = name.strip()
        if name in scales:
            raise UserValueError(f"--realism-scale source {name!r} is given twice: allowed once")
        if name not in realism.sources:
            raise UserValueError(f"--realism-scale source {name!r} is not on in realism {realism.name}: allowed "
                                 + ", ".join(s for s in SOURCES if s in realism.sources))
        scales[name] = f
    return replace(realism, scales={**realism.scales, **scales})


# ----------------------------------------------------------------------------- false-boundary
@dataclass(frozen=True)
class FalseBoundaryFlags:
    """``study false-boundary``'s flags, checked: angles in degrees, the perturbation in degrees and
    millimetres, ``families`` ("all",) or family names of ``plates.spec.FAMILIES``, ``verify_grid``
    as ``bench.config.sensing.parse_verify_grid`` gives it."""

    bends_deg: tuple[float, ...]
    l_bends_deg: tuple[float, ...]
    axes_deg: tuple[float, ...]
    extra_axes_deg: tuple[float, ...] | None
    aspect: float
    families: tuple[str, ...]
    limit: int | None
    grid: str | None
    verify_grid: str | None
    width: int | None
    render: RenderSettings
    workers: int
    perturb_axis_deg: float
    perturb_distance_mm: float

    @property
    def family_filter(self) -> list[str] | None:
        """The families to run for ``bench.run.sensing.study.study_cases``: None for all."""
        return None if self.families == ("all",) else list(self.families)


def false_boundary_flags(args) -> FalseBoundaryFlags:
    """``study false-boundary``'s flags (an argparse namespace) checked, in the order the command reports
    them; ``args.spp`` None is ``DEFAULT_SPP``."""
    from platebench.bench.config.sensing import DEFAULT_BENDS_DEG, STUDY_AXES_DEG, parse_verify_grid  # noqa: PLC0415

    spp = DEFAULT_SPP if args.spp is None else args.spp
    bends = _values(args.bend, "--bend", DEFAULT_BENDS_DEG, *BEND_RANGE_DEG)
    l_bends = parse_range_text(args.l_bends, "--l-bends", *L_BEND_RANGE_DEG, max_count=MAX_BENDS) \
        if args.l_bends.strip() else []
    _width(args.width)
    _spp(spp)
    render = _render(spp, args.seed)
    if not (1 <= args.workers <= MAX_WORKERS):
        raise UserValueError(f"--workers = {args.workers} is out of range: allowed 1 to {MAX_WORKERS}")
    axis_deg, distance_mm = parse_perturb(args.perturb)
    fams = [f.strip() for f in args.families.split(",") if f.strip()]
    if fams != ["all"]:
        from platebench.plates.spec import FAMILIES  # noqa: PLC0415
        bad = [f for f in fams if f not in FAMILIES]
        if bad:
            raise UserValueError(f"--families value {bad[0]!r} is unknown: allowed all or " + ", ".join(FAMILIES))
    axes = _values(args.axes, "--axes", STUDY_AXES_DEG, *AXIS_RANGE_DEG)
    if not (ASPECT_RANGE[0] <= args.aspect <= ASPECT_RANGE[1]):
        raise UserValueError(f"--aspect = {args.aspect} is out of range: allowed {ASPECT_RANGE[0]:g} to "
                             f"{ASPECT_RANGE[1]:g}")
    if args.limit is not None and args.limit < 1:
        raise UserValueError(f"--limit = {args.limit} is out of range: allowed >= 1")
    if args.grid:
        parse_grid(args.grid)  # its one-line error with the other flags (study_sample_config reads it again)
    verify_grid = parse_verify_grid(args.verify_grid)
    extra = None
    if args.extra_axes is not None:
        extra = parse_range_text(args.extra_axes, "--extra-axes", *AXIS_RANGE_DEG, max_count=2)
        if len(extra) != 2:
            raise UserValueError(f"--extra-axes = {args.extra_axes!r}: give two axes, FIRST,LAST (degrees)")
    return FalseBoundaryFlags(tuple(bends), tuple(l_bends), tuple(axes), None if extra is None else tuple(extra),
                              args.aspect, tuple(fams), args.limit, args.grid, verify_grid, args.width, render,
                              args.workers, axis_deg, distance_mm)


def study_sample_config(realism_name: str | None, realism_scale: str | None, grid: str | None, width: int | None,
                        render: RenderSettings) -> SampleConfig:
    """The false-boundary study's sample configuration before each plate's: ideal, ``width`` (default
    ``DEFAULT_WIDTH``) by 3/4 of it; under a realism preset, its camera at its own size, or at ``width``
    with its field of view and aspect kept, its sources scaled by ``realism_scale`` (``with_scales``).
    Raises ``UserValueError`` for a scale without an error source."""
    pattern = parse_grid(grid) if grid else {}
    if realism_name in (None, "ideal"):
        if realism_scale:
            raise UserValueError(f"--realism-scale {realism_scale} without an error source: allowed only with "
                                 "--realism 1995 or modern (ideal has none to scale)")
        w = width or DEFAULT_WIDTH
        return SampleConfig(scene=SceneParams(width=w, height=w * 3 // 4, pattern=pattern), render=render)
    from platebench.bench.config.presets import with_realism  # noqa: PLC0415
    from platebench.bench.config.realism import realism_preset  # noqa: PLC0415
    from platebench.bench.config.sample_flags import realism_camera_at_width  # noqa: PLC0415

    realism = realism_preset(realism_name)
    if realism_scale:
        realism = with_scales(realism, realism_scale)
    cfg = with_realism(SampleConfig(scene=SceneParams(pattern=pattern), render=render), realism)
    if width is not None:
        at = replace(cfg, scene=replace(cfg.scene, width=width,
                                        height=max(16, round(width * cfg.scene.height / cfg.scene.width))))
        cfg = realism_camera_at_width(cfg, at, width)
    return cfg


@dataclass(frozen=True)
class StudySettings:
    """What a false-boundary study ran with, as study.json's settings record it (the realism's part,
    ``bench.io.sensing_records.StudyRealism``, is added beside it): angles in degrees, the image in pixels."""

    bends_deg: tuple[float, ...]
    axes_deg: tuple[float, ...]
    aspect: float
    families: tuple[str, ...]
    grid: str | None
    verify_grid: str | None
    width_px: int
    height_px: int
    spp: int
    seed: int
    perturb_axis_deg: float
    perturb_distance_mm: float
    plates: int
    workers: int

    @classmethod
    def of(cls, flags: FalseBoundaryFlags, base: SampleConfig, verify_grid: str | None, plates: int) -> StudySettings:
        """The settings of a study of ``plates`` plates run with ``flags`` on ``base``, the verification
        grid resolved (``verify_grid``: a grid, or None for stage 3's)."""
        return cls(flags.bends_deg, flags.axes_deg, flags.aspect, flags.families, flags.grid, verify_grid,
                   base.scene.width, base.scene.height, flags.render.spp, flags.render.seed, flags.perturb_axis_deg,
                   flags.perturb_distance_mm, plates, flags.workers)


# ----------------------------------------------------------------------------- cut-squares
@dataclass(frozen=True)
class CutSquaresSettings:
    """``study cut-squares``' flags, checked: bends and axes in degrees, distances in metres, the image
    width in pixels; ``base`` the sample configuration before each plate's."""

    bends_deg: tuple[float, ...]
    axes_deg: tuple[float, ...]
    distances_m: tuple[float, ...]
    width_px: int
    spp: int
    seed: int
    grid: str | None
    base: SampleConfig

    @property
    def plates(self) -> int:
        """Plates the study runs: every bend convex and concave about every axis at every distance."""
        return len(self.bends_deg) * 2 * len(self.axes_deg) * len(self.distances_m)


def refuse_realism_for_cut_squares(realism: str | None, realism_scale: str | None) -> None:
    """The cut-squares study places its cameras itself and has no error source: ``--realism`` other than
    ideal and ``--realism-scale`` are refused with that reason."""
    if realism not in (None, "ideal"):
        raise UserValueError(f"--realism = {realism} for the cut-squares study: it places its cameras itself; "
                             "allowed: ideal")
    if realism_scale:
        raise UserValueError(f"--realism-scale {realism_scale} for the cut-squares study: it has no error "
                             "source to scale (allowed with accuracy and false-boundary)")


def cut_squares_settings(args, bends_deg, axes_deg, distances_m) -> CutSquaresSettings:
    """``study cut-squares``' flags (an argparse namespace) checked; ``bends_deg``, ``axes_deg`` and
    ``distances_m`` are the defaults of the flags not given (``bench.run.cut_study``)."""
    refuse_realism_for_cut_squares(args.realism, args.realism_scale)
    spp = DEFAULT_SPP if args.spp is None else args.spp
    bends = _values(args.bend, "--bend", bends_deg, *BEND_RANGE_DEG)
    axes = _values(args.axes, "--axes", axes_deg, *AXIS_RANGE_DEG)
    distances = _values(args.distances, "--distances", distances_m, *DISTANCE_RANGE_M)
    width = DEFAULT_WIDTH if args.width is None else args.width
    _width(width)
    render = _render(spp, args.seed)
    base = SampleConfig(scene=SceneParams(width=width, height=width * 3 // 4,
                                          pattern=parse_grid(args.grid) if args.grid else {}), render=render)
    return CutSquaresSettings(tuple(bends), tuple(axes), tuple(distances), width, spp, args.seed, args.grid, base)


# ----------------------------------------------------------------------------- accuracy
@dataclass(frozen=True)
class AccuracyFlags:
    """``study accuracy``'s flags, checked: the realism preset (scaled), draws per budget row, the
    targets, whether the budget runs, samples per pixel, the base seed and how corners are located."""

    realism: object  # bench.config.realism's preset
    draws: int
    targets: tuple[str, ...]
    budget: bool
    spp: int
    seed: int
    corners: str


def accuracy_flags(args, allowed_targets) -> AccuracyFlags:
    """``study accuracy``'s flags (an argparse namespace) checked, in the order the command reports them;
    ``allowed_targets``: the targets the study knows (``bench.run.accuracy.TARGETS``)."""
    from platebench.bench.config.realism import realism_preset  # noqa: PLC0415

    realism = realism_preset(args.realism or "1995")
    if args.realism_scale:
        realism = with_scales(realism, args.realism_scale)
    if not (1 <= args.draws <= MAX_DRAWS):
        raise UserValueError(f"--draws = {args.draws} is out of range: allowed 1 to {MAX_DRAWS}")
    targets = tuple(t.strip() for t in args.targets.split(",") if t.strip())
    bad = [t for t in targets if t not in allowed_targets]
    if bad or not targets:
        raise UserValueError(f"--targets value {(bad or [args.targets])[0]!r} is not allowed: allowed "
                             + ", ".join(allowed_targets) + " (comma-separated)")
    spp = ACCURACY_SPP if args.spp is None else args.spp
    _spp(spp)
    _render(spp, args.seed)
    return AccuracyFlags(realism, args.draws, targets, not args.no_budget, spp, args.seed, args.corners)
