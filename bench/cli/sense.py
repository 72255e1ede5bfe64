"""``platebench sense``: the sensing loop (stages 1-3, verification views, cures) on one plate."""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from platebench.bench.cli.render import acquisition_lines, add_sample_flags, config_from_args
from platebench.bench.io.outputs import output_dir
from platebench.errors import UserValueError

if TYPE_CHECKING:
    from platebench.bench.run.sensing import SensingResult

# bench.run.sensing (renderer, pipeline, trimesh, SciPy) is imported where it is used, once the flags are
# checked; the parser's defaults are plain values (bench.config.sensing, reconstruction.strategy.budget)
HELP = "run the sensing loop (three stages, verification views, cures) with a simulated robot"


def add_parser(sub) -> None:
    from platebench.reconstruction.strategy.budget import MAX_CURE_VIEWS, MAX_CURES_ALLOWED  # noqa: PLC0415

    p = sub.add_parser("sense", help=HELP,
                       description="Stage 1: far pose, rough boundary. Stage 2: centre line through the boundary "
                                   "centre perpendicular to the boundary plane, precise boundary. Stage 3: projector "
                                   "on the centre line, active stereo, the paper's false-boundary test. Then "
                                   "verification views (every plate) and cures chosen from the measured geometry "
                                   "until the boundary is verified without ground truth, or a stop with the reason. "
                                   "Writes sensing.json, multiview.npz and stage 3's sample and reconstruction.")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--overwrite", action="store_true", help="replace a sensing run 'platebench sense' wrote "
                   "(nothing else is replaced)")
    p.add_argument("--max-cures", type=int, default=MAX_CURE_VIEWS,
                   help=f"cure poses at most (default {MAX_CURE_VIEWS}; allowed 0 to {MAX_CURES_ALLOWED})")
    p.add_argument("--workspace-mm", type=float, default=150.0,
                   help="radius of the workspace stage 1 must cover, in MILLIMETRES (default 150)")
    add_verify_grid_flag(p)
    add_sample_flags(p)
    p.set_defaults(run=run)


def add_verify_grid_flag(p) -> None:
    """``--verify-grid``: the square grid the verification views and cures project (sense, study)."""
    from platebench.bench.config.sensing import VERIFY_GRID  # noqa: PLC0415

    p.add_argument("--verify-grid", metavar="ROWSxCOLS@PX", default=VERIFY_GRID,
                   help="square grid projected by the verification views and cures (default auto: 6x12@12 at 640 "
                        "px wide and more, larger squares on narrower images; fine enough to orient the plate's "
                        "front up to its edges, see README); 'stage3' projects stage 3's grid (--grid) there too")


def verify_grid_arg(text: str) -> str | None:
    """``--verify-grid``'s value checked (``parse_grid``): the grid, or None for 'stage3'."""
    from platebench.bench.config import parse_grid  # noqa: PLC0415
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


def _pct(gv: dict) -> str:
    if not gv:  # a pose not taken
        return "-"
    return f"{gv['left']['visible_fraction'] * 100:.0f}/{gv['right']['visible_fraction'] * 100:.0f} %"


def step_lines(s: SensingResult) -> list[str]:
    """One line per step of the loop, from the typed records."""
    from platebench.bench.run.sensing import ActiveRecord, StageRecord, ViewRecord  # noqa: PLC0415
    from platebench.reconstruction.strategy.planner import Decision  # noqa: PLC0415

    out = []
    for st in s.steps:
        if isinstance(st, StageRecord):
            out.append(f"stage {st.stage}: distance {st.pose.distance_m * 1e3:.0f} mm, {st.boundary_points} boundary "
                       f"points ({st.boundary_method}); GT boundary visible L/R {_pct(st.gt_visibility)}")
        elif isinstance(st, ActiveRecord):
            fb = st.false_boundary
            if fb is None:
                what = f"active stage failed: {st.error}"
            else:
                why = [n for flag, n in ((fb.counting_test, "counting test"), (fb.arrays_disagree, "arrays disagree"))
                       if flag]
                cut = f" (and {st.cut} of cut squares, set apart)" if st.cut else ""
                what = (f"{st.matched} points{cut}; squares L/R {fb.detected.get('left_active')}/"
                        f"{fb.detected.get('right_active')} of {fb.expected} expected; paper's test: false boundary "
                        + ("DETECTED (" + ", ".join(why) + ")" if why else "not detected"))
            out.append(f"stage 3: {what}; GT boundary visible L/R {_pct(st.gt_visibility)}")
        elif isinstance(st, ViewRecord):
            v = st.view
            what = f"{st.outline_points} outline points" if st.error is None else st.error
            out.append(f"{v.purpose} view {v.name} ({v.method}): distance {v.pose.distance_m * 1e3:.0f} mm, {what}; "
                       f"GT boundary visible L/R {_pct(st.gt_visibility)}")
        elif isinstance(st, Decision):
            out.append(f"decision: {st.kind}: {st.reason}")
    return out


def summary_lines(s: SensingResult) -> list[str]:
    """The verdict, the detectors, the outcome, the counts and the time."""
    from platebench.bench.io.records import loop_verdict_text  # noqa: PLC0415
    from platebench.bench.run.sensing import OUTCOME_TEXT  # noqa: PLC0415

    f = s.final
    lines = [loop_verdict_text(f.outcome, f.boundary_verified, s.cures, f.verdict_reason)]
    for u in f.unverified_parts[:6]:
        lines.append(f"  unverified: {u.get('what', u)}")
    if len(f.unverified_parts) > 6:
        lines.append(f"  ... {len(f.unverified_parts) - 6} more unverified parts (sensing.json)")
    if s.verdict.verified and not f.boundary_verified:  # the loop closed, the front check overturned it
        lines.append("  hint: the verification views' grid is too sparse to tell the plate's front from its back "
                     "near the boundary; the default --verify-grid auto (6x12@12) measures enough square centres "
                     "(README: false-boundary study)")
    lines.append("patterns: stage 3 " + grid_text(s.patterns.get("stage3")) + ", verification views and cures "
                 + grid_text(s.patterns.get("verification")))
    lines.append("detectors at stage 2: " + ", ".join(
        f"{d.name} {'-' if d.fired is None else ('FIRED' if d.fired else 'quiet')}" for d in s.detectors))
    m = f.merged
    merged = ", ".join(f"{k} {v:.3f}" for k, v in (
        ("boundary_mean_mm", m.boundary_mean_mm), ("boundary_covered_frac", m.boundary_covered_frac),
        ("points_rms_mm", m.points_rms_mm), ("surface_rms_mm", m.surface_rms_mm), ("surface_coverage_frac", m.surface_coverage_frac))
        if v is not None)
    merged += f", {m.points} square centres"
    lines.append(f"poses: {len(f.poses)} (stage 2, {len(s.verification_views)} verification views, {s.cures} cures); "
                 f"merged: {merged}")
    a = f.accuracy

    def mm(v):
        return "-" if v is None else f"{v:.3f} mm"
    lines.append(f"ground truth: boundary visible L/R at stage 2 {_pct(f.gt_visibility_first)}, from the final poses "
                 f"{_pct(f.gt_visibility)}; stage 3 depth RMS at the square centres "
                 f"{mm(None if a is None else a.centres_depth_rms_mm)}")
    lines += realism_lines(s)
    lines.append(f"outcome: {f.outcome} ({OUTCOME_TEXT[f.outcome]})")
    lines.append(f"time: {s.time_s:.1f} s")
    return lines


def realism_lines(s: SensingResult) -> list[str]:
    """Under a real rig: the draw, its estimates' errors, and how far the moves really landed."""
    acq = s.acquisition
    if acq is None:
        return []
    import numpy as np  # noqa: PLC0415

    from platebench.reconstruction.strategy.multiview import SPREAD_REPORT_DISTANCE_M  # noqa: PLC0415

    out = acquisition_lines(s.config, acq["estimates"])
    moves = acq["moves"]
    if moves:
        pos = np.array([[m.views[c].position_error_m for c in ("left", "right")] for m in moves]) * 1e3
        rot = np.array([[m.views[c].rotation_error_rad for c in ("left", "right")] for m in moves]) * 1e3
        turned = sum(m.cell_turn_deg != 0 for m in moves)
        out.append(f"  moves       {len(moves)}: cameras really posed {np.median(pos):.3f} mm (max {pos.max():.3f}), "
                   f"{np.median(rot):.3f} mrad (max {rot.max():.3f}) from the commanded poses (median); the loop "
                   f"measured at the commanded poses; cell turned for {turned} of them")
    sp = acq.get("pose_spread")
    if sp is not None:
        out.append(f"  pose spread {sp.translation_m * 1e3:.2f} mm, {sp.rotation_rad * 1e3:.2f} mrad RMS (the hand/eye "
                   f"calibration's residuals): the poses were registered on edges they put within "
                   f"{float(sp.match_tol_m(SPREAD_REPORT_DISTANCE_M)) * 1e3:.2f} mm of each other at "
                   f"{SPREAD_REPORT_DISTANCE_M:.2f} m")
    reg = acq.get("registration")
    if reg is not None and reg.shifts_m:
        n = reg.norms_mm()
        out.append(f"  registered  {len(n)} poses moved {float(np.median(n)):.2f} mm (median, max {n.max():.2f}) "
                   "onto their common edges (sensing.json: acquisition.registration, mm)")
    return out


def grid_text(desc: dict | None) -> str:
    """A square grid's description (``Pattern.description``) as 'ROWSxCOLS@PX (row gap GAP px)'."""
    from platebench.scenes.pattern import SquareGridLayout  # noqa: PLC0415

    if not desc or desc.get("kind") != "square_grid":
        return "-" if not desc else str(desc.get("kind"))
    g = SquareGridLayout.from_dict(desc)
    return f"{g.rows}x{g.cols}@{g.square_px} (row gap {g.gap_y_px} projector px)"


def run(args) -> int:
    from platebench.reconstruction.strategy.budget import MAX_CURES_ALLOWED  # noqa: PLC0415

    cfg = config_from_args(args)
    if not (10 <= args.workspace_mm <= 2000):
        raise UserValueError(f"--workspace-mm = {args.workspace_mm} is out of range: allowed 10 to 2000 mm")
    if not (0 <= args.max_cures <= MAX_CURES_ALLOWED):
        raise UserValueError(f"--max-cures = {args.max_cures} is out of range: allowed 0 to {MAX_CURES_ALLOWED}")
    verify_grid = verify_grid_arg(args.verify_grid)
    from platebench.bench.progress import bar, step_callback  # noqa: PLC0415  (the flags are good: the loop)
    from platebench.bench.run.sensing import SensingOptions, run_sensing  # noqa: PLC0415

    opts = SensingOptions(workspace_radius_m=args.workspace_mm * 1e-3, max_cures=args.max_cures,
                          verify_grid=verify_grid)
    # the output rule (bench.io.outputs) before the first render; staged, replaced only once complete
    with output_dir(args.out, "sensing run", overwrite=args.overwrite, inputs=[args.config]) as stage:
        with bar(4 + opts.max_views, "sense") as pbar:
            s = run_sensing(cfg, stage, opts, progress=step_callback(pbar))
    for line in step_lines(s) + summary_lines(s):
        print(line)
    print(f"written: {args.out / 'sensing.json'}")
    return 0
