"""Results as text for the terminal: the tables and lines the commands print (``bench.cli``), read
from the typed results of ``bench.run``, ``bench.io`` and ``evaluation``. Lengths in millimetres,
angles in milliradians or degrees, as each line says; every function returns text and prints nothing."""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

from platebench.tolerances import tol

if TYPE_CHECKING:
    from platebench.bench.io.sensing_records import SensingResult

__all__ = ["format_score_table", "format_field_table", "format_calibration_table", "acquisition_lines",
           "step_lines", "summary_lines", "realism_lines", "grid_text", "legend_lines", "table_lines",
           "num_text"]


def format_score_table(score) -> str:
    """A reconstruction's ``evaluation.score.Score`` as its table (``evaluation.score.format_table``)."""
    from platebench.evaluation.score import format_table  # noqa: PLC0415

    return format_table(score)


# ----------------------------------------------------------------------------- a sample's acquisition
def acquisition_lines(cfg, report) -> list[str]:
    """What the realism's draw did to the acquisition (``bench.io.realism_records.DrawReport``), in
    mm, mrad and px."""
    rz = cfg.realism
    out = [f"realism     {rz.name} (draw {rz.seed}): " + (", ".join(rz.sources) or "no source on")]
    for cam, v in report.views.items():
        out.append(f"  {cam:5s} view  really posed {v.position_error_m * 1e3:.3f} mm, "
                   f"{v.rotation_error_rad * 1e3:.3f} mrad from the commanded pose")
    he = report.hand_eye
    if he:
        out.append(f"  hand/eye    mount {he.mount_position_error_m * 1e3:.3f} mm, "
                   f"{he.mount_rotation_error_rad * 1e3:.3f} mrad off; target {he.target_position_error_m * 1e3:.3f} "
                   f"mm, {he.target_rotation_error_rad * 1e3:.3f} mrad off ({he.views} views)")
    cal = report.calibration
    if cal:
        out.append(f"  intrinsics  fx {cal.fx_error_px:+.3f} px, fy {cal.fy_error_px:+.3f} px, principal point "
                   f"{cal.cx_error_px:+.3f}/{cal.cy_error_px:+.3f} px off (reprojection {cal.reprojection_rms_px:.3f} px)")
    return out





# ----------------------------------------------------------------------------- the sensing loop
def _visible_pct(gv: dict) -> str:
    if not gv:  # a pose not taken
        return "-"
    return f"{gv['left']['visible_fraction'] * 100:.0f}/{gv['right']['visible_fraction'] * 100:.0f} %"


def step_lines(s: SensingResult) -> list[str]:
    """One line per step of the loop, from the typed records."""
    from platebench.bench.io.sensing_records import ActiveRecord, StageRecord, ViewRecord  # noqa: PLC0415
    from platebench.reconstruction.strategy.planner import Decision  # noqa: PLC0415

    out = []
    for st in s.steps:
        if isinstance(st, StageRecord):
            out.append(f"stage {st.stage}: distance {st.pose.distance_m * 1e3:.0f} mm, {st.boundary_points} boundary "
                       f"points ({st.boundary_method}); GT boundary visible L/R {_visible_pct(st.gt_visibility)}")
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
            out.append(f"stage 3: {what}; GT boundary visible L/R {_visible_pct(st.gt_visibility)}")
        elif isinstance(st, ViewRecord):
            v = st.view
            what = f"{st.outline_points} outline points" if st.error is None else st.error
            out.append(f"{v.purpose} view {v.name} ({v.method}): distance {v.pose.distance_m * 1e3:.0f} mm, {what}; "
                       f"GT boundary visible L/R {_visible_pct(st.gt_visibility)}")
        elif isinstance(st, Decision):
            out.append(f"decision: {st.kind}: {st.reason}")
    return out


def summary_lines(s: SensingResult) -> list[str]:
    """The verdict, the detectors, the outcome, the counts and the time."""
    from platebench.bench.io.records import loop_verdict_text  # noqa: PLC0415
    from platebench.bench.io.sensing_records import OUTCOME_TEXT  # noqa: PLC0415

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
    lines.append(f"ground truth: boundary visible L/R at stage 2 {_visible_pct(f.gt_visibility_first)}, from the final poses "
                 f"{_visible_pct(f.gt_visibility)}; stage 3 depth RMS at the square centres "
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
    from platebench.bench.io.codecs import decode  # noqa: PLC0415
    from platebench.scenes.pattern import SquareGridLayout  # noqa: PLC0415

    if not desc or desc.get("kind") != "square_grid":
        return "-" if not desc else str(desc.get("kind"))
    g = decode(SquareGridLayout, desc)
    return f"{g.rows}x{g.cols}@{g.square_px} (row gap {g.gap_y_px} projector px)"


# ----------------------------------------------------------------------------- the false-boundary study
def num_text(x, spec: str = ".4f") -> str:
    """``x`` formatted by ``spec``; "-" for None and NaN (no value); an infinity as "inf" / "-inf"."""
    return "-" if x is None or math.isnan(x) else format(x, spec)


def _percent(frac):
    return num_text(None if frac is None else frac * 100, ".0f")


def _yn(v):
    return "-" if v is None else ("Y" if v else ".")


def legend_lines(short: dict, outcomes=()) -> list[str]:
    """The per-plate table's columns in words (``table_lines``); ``short``: detector name -> its column;
    ``outcomes``: the outcome classes the table shows, each explained (``OUTCOME_TEXT``)."""
    from platebench.bench.io.sensing_records import OUTCOME_TEXT  # noqa: PLC0415

    return ["columns: outcome: the plate's class (below); cur: cures the loop applied; vws: poses it measured "
            "from (stage 2, verification views, cures);",
            "  " + ", ".join(f"{col}: {name.replace('_', ' ')}" for name, col in short.items())
            + ": each detector at the stage-2 pose (Y fired, . quiet, - not evaluated);",
            "  GT vis 1st: the least share of the true boundary a camera sees from the stage-2 pose; final: from "
            "the final poses together; reach: the reachable poses see all of it (Y/.); pairs: pairs of reachable "
            "poses could confirm all of it (Y/.) (these four: ground truth, for scoring only; the loop's own verdict "
            "is in the outcome);",
            "  bnd mm: the merged boundary's mean distance to the true one; cover: share of the true surface the "
            "merged surface covers; time s: the plate's run"] + [
        f"  {c}: {OUTCOME_TEXT[c]}" for c in OUTCOME_TEXT if c in outcomes]


def table_lines(study) -> list[str]:
    """The per-plate table, outcome counts, detector scores and targets of a ``bench.run.sensing.study.StudyResult``
    as text lines."""
    from platebench.bench.io.codecs import decode  # noqa: PLC0415
    from platebench.bench.io.sensing_records import StudyRealism  # noqa: PLC0415
    from platebench.bench.run.sensing.study import detector_scores  # noqa: PLC0415
    from platebench.reconstruction.strategy.detectors import DETECTORS  # noqa: PLC0415

    short = {"counting_test": "cnt", "arrays_disagree": "arr", "viewpoint_consistency": "vpc",
             "occluding_contour": "occ", "end_tangents": "end"}
    out = [f"{'plate':38s} {'outcome':12s} {'cur':>3s} {'vws':>3s} " + " ".join(f"{short[d]:>3s}" for d in DETECTORS)
           + f" {'GT vis 1st':>10s} {'final':>6s} {'reach':>5s} {'pairs':>5s} {'bnd mm':>6s} {'cover':>5s} {'time s':>6s}"]
    rows = list(study.rows)
    for r in rows:
        if r.outcome == "error":
            out.append(f"{r.case:38s} {'error':12s} {r.error}")
            continue
        out.append(f"{r.case:38s} {r.outcome:12s} {r.cures:3d} {r.views:3d} "
                   + " ".join(f"{_yn(r.fired(d)):>3s}" for d in DETECTORS)
                   + f" {num_text(r.gt_visible_first_frac, '10.3f')} {num_text(r.gt_visible_final_frac, '6.3f')} "
                   f"{_yn(r.gt_reachable):>5s} {_yn(r.gt_verifiable):>5s} "
                   f"{num_text(r.merged_boundary_mean_mm, '6.2f')} "
                   f"{num_text(r.merged_surface_coverage_frac, '5.2f')} {r.time_s:6.1f}")
    out += legend_lines(short, {r.outcome for r in rows})
    alarms = [r for r in rows if r.outcome == "false_alarm"]
    if alarms:  # what the loop itself concluded where nothing was hidden (its verdict is no ground truth)
        out.append("false alarms, the loop's verdict on each:")
        out += [f"  {r.case}: {r.verdict_text()}" for r in alarms]
    out.append("outcomes: " + ", ".join(f"{k} {v}" for k, v in study.outcomes().items()))
    for fam, c in study.outcomes("family").items():
        out.append(f"  {fam:9s} " + ", ".join(f"{k} {v}" for k, v in c.items() if v))
    for b, c in study.outcomes("bend").items():
        out.append(f"  bend {b:>4s} " + ", ".join(f"{k} {v}" for k, v in c.items() if v))
    for d, s in detector_scores(rows)["all"].items():
        out.append(f"detector {d:22s} precision {num_text(s.precision, '.2f')}, recall {num_text(s.recall, '.2f')} "
                   f"(TP {s.true_positive}, FP {s.false_positive}, FN {s.false_negative}, TN {s.true_negative})")
    rz = decode(StudyRealism, study.settings)
    if rz.realism:
        out.append(f"realism {rz.realism}: " + ", ".join(rz.realism_sources) + "; each plate's draw: "
                   + (rz.realism_seeds or "") + f"; corner noise of the calibration views {rz.corner_noise_px or 0:.3f} px")
        if rz.realism_scales:
            out.append("scaled from the sourced magnitudes: " + ", ".join(f"{k} x{v:g}" for k, v in rz.realism_scales))
    t = study.targets
    out.append(f"targets: silent {t.silent}, errors {t.errors}, cured {t.seen_all_of_curable}/{t.curable} "
               f"({_percent(t.seen_all_frac)} %: the final poses see it all), verified {t.cured_of_verifiable} of the "
               f"{t.verifiable} verifiable ({_percent(t.cured_of_verifiable_frac)} %), false alarms "
               f"{t.false_alarms}/{t.nothing_hidden} ({_percent(t.false_alarm_frac)} %); "
               + ", ".join(f"{k}: {'n/a' if v is None else ('met' if v else 'NOT met')}" for k, v in t.met.items()))
    out.append(f"  the loop verified the boundary on {t.cured_of_curable} of the {t.curable} curable plates "
               f"({_percent(t.cured_frac)} %); the others it names as unverified (outcome unconfirmed or honest); "
               f"{t.verifiable} of the {t.curable} are verifiable by pairs of reachable poses (GT)")
    n = len(rows)
    ran = study.plates_run
    w = study.settings.get("workers", 1)
    each = sum(r.time_s or 0.0 for r in rows)
    out.append(f"time: {study.time_s:.0f} s for {ran} plates ({study.time_s / max(ran, 1):.1f} s per plate; {w} "
               f"worker{'s' if w != 1 else ''}, each plate's own run {each / max(n, 1):.1f} s on average)"
               + (f"; {n - ran} more from the journal of an interrupted run" if ran != n else ""))
    return out


# ----------------------------------------------------------------------------- scores
def format_field_table(score) -> str:
    """A readable summary of a field score (millimetres, pixels, percent)."""
    from platebench.evaluation.field_scores import (  # noqa: PLC0415
        DepthScore,
        DisparityScore,
        MeshScore,
        PointCloudScore,
    )

    lines = []
    if isinstance(score, DisparityScore):
        for reg in (score.middlebury.all, score.middlebury.nonocc):
            if reg is None:
                continue
            bad = ", ".join(f"bad{t:g} {num_text(v, '.2f')} %" for t, v in reg.bad_pct)
            q = ", ".join(f"A{k} {num_text(v, '.3f')}" for k, v in reg.quantiles)
            lines.append(f"{'middlebury ' + reg.region:16s} {reg.gt_count} px: {bad}; invalid {num_text(reg.invalid_pct, '.2f')} "
                         f"%; avgerr {num_text(reg.avgerr)} px, rms {num_text(reg.rms)} px; {q} px")
        for reg in (score.eth3d.all, score.eth3d.nonocc):
            if reg is None:
                continue
            bad = ", ".join(f"bad{t:g} {num_text(v, '.2f')} %" for t, v in reg.bad_pct)
            lines.append(f"{'eth3d ' + reg.region:16s} coverage {num_text(reg.coverage, '.4f')}; {bad}; avgerr "
                         f"{num_text(reg.avgerr)} px, rms {num_text(reg.rms)} px")
        depth = score.depth
    else:
        depth = score if isinstance(score, DepthScore) else None
    if depth is not None:
        e = depth.errors
        q = ", ".join(f"A{k} {num_text(v * 1e3)}" for k, v in e.quantiles_m)
        lines.append(f"{'depth':16s} {depth.estimated_px}/{depth.plate_px} plate px (coverage "
                     f"{num_text(depth.coverage_frac, '.4f')}), {depth.off_plate_px} off the plate; |error| mean "
                     f"{num_text(e.mean_m * 1e3)}, median {num_text(e.median_m * 1e3)}, RMS {num_text(e.rms_m * 1e3)}, max "
                     f"{num_text(e.max_m * 1e3)} mm; {q} mm; bias {num_text(e.signed_mean_m * 1e3)} mm")
    if isinstance(score, PointCloudScore):
        e, c = score.distance, score.surface
        lines.append(f"{'points':16s} {score.count} (+{score.dropped_count} non-finite dropped); distance to the "
                     f"surface mean {num_text(e.mean_m * 1e3)}, median {num_text(e.median_m * 1e3)}, RMS {num_text(e.rms_m * 1e3)}, max "
                     f"{num_text(e.max_m * 1e3)} mm")
        lines.append(f"{'outliers':16s} {score.outlier_count} beyond {score.outlier_threshold_m * 1e3:g} mm "
                     f"({num_text(100 * score.outlier_frac, '.2f')} %)")
        lines.append(f"{'coverage':16s} {num_text(score.coverage.coverage_frac, '.4f')} ({score.coverage.estimated_px}/"
                     f"{score.coverage.plate_px} plate px of the left view hold a point)")
        lines.append(f"{'surface cov.':16s} {num_text(c.surface_coverage_frac, '.4f')} of the plate's top within "
                     f"{c.coverage_radius_m * 1e3:g} mm")
    if isinstance(score, MeshScore):
        for name, e in (("accuracy", score.accuracy), ("completeness", score.completeness)):
            lines.append(f"{name:16s} mean {num_text(e.mean_m * 1e3)}, median {num_text(e.median_m * 1e3)}, RMS "
                         f"{num_text(e.rms_m * 1e3)}, max {num_text(e.max_m * 1e3)} mm ({e.count} samples)")
        lines.append(f"{'overall':16s} {num_text(score.overall_m * 1e3)} mm (DTU: mean of the two)")
        for t, p, r, f in score.thresholds:
            lines.append(f"{'at ' + format(t * 1e3, 'g') + ' mm':16s} precision {100 * p:.2f} %, recall "
                         f"{100 * r:.2f} %, F-score {100 * f:.2f} %")
    return "\n".join(lines)


def format_calibration_table(report, comparison: dict | None = None) -> str:
    """The calibration report (``bench.io.calibration_records.CalibrationReport``; and the reference
    reconstruction per calibration, ``Score``s) as text."""
    from platebench.bench.io.calibration_records import LENS_MODELS  # noqa: PLC0415
    from platebench.evaluation.metrics_row import MetricsRow  # noqa: PLC0415

    c = report.config
    est = report.estimate
    lines = [f"calibration at {c.width_px}x{c.height_px} px, f {c.f_px:.1f} px"
             + (f" (fy {c.fy_px:.1f})" if abs(c.fy_px - c.f_px) > tol.pixel else "")
             + f", spp {c.spp}, {len(c.board_poses)} board poses, "
             f"target z {[round(z * 1e3, 1) for z in c.target_z_m]} mm",
             f"estimate handed to the pipeline: {est.distortion_model.replace('_', ' ')} "
             f"({est.distortion_model_choice})",
             f"{'quantity':34s} {'fixed distortion':>22s} {'free distortion':>22s}"]

    def row(name, fmt, get):
        vals = [fmt.format(get(model)) for model in LENS_MODELS]
        lines.append(f"{name:34s} {vals[0]:>22s} {vals[1]:>22s}")

    for cam in ("left", "right"):
        def camera(model, cam=cam):
            return report.cameras[model][cam]
        row(f"{cam} fx error (px / %)", "{}",
            lambda k: f"{camera(k).fx_error_px:+.3f} / {camera(k).fx_error_pct:+.4f}")
        row(f"{cam} fy error (px / %)", "{}",
            lambda k: f"{camera(k).fy_error_px:+.3f} / {camera(k).fy_error_pct:+.4f}")
        row(f"{cam} principal point error (px)", "{}",
            lambda k: f"{camera(k).cx_error_px:+.3f}, {camera(k).cy_error_px:+.3f}")
        row(f"{cam} reprojection RMS (px)", "{:.4f}", lambda k: camera(k).reprojection_rms_px)
        row(f"{cam} max distortion shift (px)", "{:.3f}", lambda k: camera(k).max_distortion_displacement_px)
        row(f"{cam} lens model error max (px)", "{:.3f}", lambda k: camera(k).lens_model_error_max_px)
    st = report.stereo
    row("stereo f error (px / %)", "{}",
        lambda k: f"{st[k].K_left.fx_error_px:+.3f} / {st[k].K_left.fx_error_pct:+.4f}")
    row("stereo pp error L, R (px)", "{}", lambda k: f"{st[k].K_left.principal_point_error_px:.3f}, "
                                                     f"{st[k].K_right.principal_point_error_px:.3f}")
    row("baseline error (mm / %)", "{}",
        lambda k: f"{st[k].baseline_error_mm:+.4f} / {st[k].baseline_error_pct:+.4f}")
    row("rotation between cameras (deg)", "{:.4f}", lambda k: st[k].rotation_between_cameras_error_deg)
    row("f x baseline error (%)", "{:+.4f}", lambda k: st[k].f_times_baseline_error_pct)
    row("stereo reprojection RMS (px)", "{:.4f}", lambda k: st[k].stereo_reprojection_rms_px)
    row("left camera centre error (mm)", "{:.4f}", lambda k: st[k].left_center_error_norm_mm)
    row("left camera rotation error (deg)", "{:.4f}", lambda k: st[k].left_rotation_error_deg)
    true_shift = report.cameras["fixed_distortion"]["left"].true_max_distortion_displacement_px
    lines.append(f"{'true lens: max distortion shift (px)':34s} {true_shift:>22.3f}")
    lines.append("projector rays (estimated stereo | true stereo):")
    a, b = report.projector_rays, report.projector_rays_true_stereo
    for label, unit, rms_max in (("ray angle error", "mrad",
                                  lambda r: (r.angle_error_rms_mrad, r.angle_error_max_mrad)),
                                 ("ray distance at z = 0", "mm",
                                  lambda r: (r.distance_at_plate_plane_rms_mm, r.distance_at_plate_plane_max_mm))):
        (a_rms, a_max), (b_rms, b_max) = rms_max(a), rms_max(b)
        lines.append(f"  {label + ' RMS / max (' + unit + ')':32s} {a_rms:>10.4f} / {a_max:.4f} | "
                     f"{b_rms:.4f} / {b_max:.4f}")
    lines.append(f"  {'projector centre error (mm)':32s} {a.projector_center_error_norm_mm:>10.4f} | "
                 f"{b.projector_center_error_norm_mm:.4f}")
    lines.append(f"  {'target plane depth error (mm)':32s} "
                 + ", ".join(f"z {p.known_z_mm:+.0f}: {p.depth_error_mm:+.4f}" for p in a.target_planes))
    if comparison is not None:
        lines.append("reference reconstruction:")
        lines.append(f"  {'calibration':26s} {'points':>6s} {'depth RMS':>10s} {'depth max':>10s} {'x/y RMS':>15s} "
                     f"{'boundary':>9s} {'expected':>8s}  (mm; depth and x/y at the square centres)")
        for name in ("true", "estimated", "true_rig_estimated_rays"):
            s = comparison[name]
            if s.points is None:
                lines.append(f"  {name:26s} no points scored")
                continue
            p, m = s.points.stats, MetricsRow.from_score(s)
            lines.append(f"  {name:26s} {p.count:>6d} {m.centres_depth_rms_mm:>10.4f} "
                         f"{m.centres_depth_max_mm:>10.4f} {p.x.rms * 1e3:>7.4f}/{p.y.rms * 1e3:<7.4f} "
                         f"{m.boundary_mean_mm:>9.4f} "
                         f"{s.matching.expected_count_method:>8d}")
    t = report.timings_s
    lines.append(f"{'time (s)':34s} board {t.board_render_s:.1f}, target {t.target_render_s:.1f}, "
                 f"calibrate {t.calibrate_s:.1f}")
    return "\n".join(lines)
