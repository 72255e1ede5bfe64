"""``platebench calibrate``: calibrate the stereo rig and the structured light from renders, score against truth."""
from __future__ import annotations

import math
from pathlib import Path

from platebench.bench.cli.render import add_sample_flags, config_from_args, refuse_robot_errors
from platebench.bench.io.atomic import write_json
from platebench.bench.io.calibration_records import LENS_MODELS
from platebench.bench.io.outputs import check_output, output_dir
from platebench.errors import UserValueError
from platebench.evaluation.metrics_row import MetricsRow
from platebench.tolerances import tol

# the calibration's modules (renderer, OpenCV, the pipeline) are imported in run(), once the flags are checked
HELP = "calibrate cameras (ChArUco) and projector rays (paper IV-A) from renders"


def add_parser(sub) -> None:
    p = sub.add_parser("calibrate",
                       help=HELP,
                       description="Render a ChArUco board in 20 poses for both cameras and a white target plane "
                                   "at known heights under the projector; calibrate the cameras (OpenCV, distortion "
                                   "fixed to zero and free), the stereo pair and each projected square's ray (the "
                                   "paper's structured-light calibration); compare with the true calibration; then "
                                   "reconstruct the reference sample with the estimated and the true calibration "
                                   "and score both. Writes DIR/calibration.json (units in the keys) and prints "
                                   "a table.")
    p.add_argument("--out", type=Path, required=True, help="output directory to create (holds calibration.json)")
    p.add_argument("--overwrite", action="store_true", help="replace a calibration directory 'platebench "
                   "calibrate' wrote (nothing else is replaced)")
    add_sample_flags(p)
    p.add_argument("--target-z-mm", type=float, nargs="+", metavar="Z",
                   help="heights of the white target plane in MILLIMETRES, world z (default -30 0 30; at least 2)")
    p.add_argument("--distortion-model", choices=("auto", "fixed", "free"), default="auto",
                   help="lens model of the estimate handed to the pipeline: auto (default: free k1, k2, p1, p2 "
                        "when they explain >= 0.05 px RMS of the board corners' displacement), fixed (no "
                        "distortion) or free")
    p.add_argument("--no-reconstruction", action="store_true",
                   help="skip the reference reconstruction with estimated vs true calibration")
    p.set_defaults(run=run)


def run(args) -> int:
    cfg = config_from_args(args)
    refuse_robot_errors(cfg, "calibrate", allow_estimates=True)
    check_output(args.out, "calibration", overwrite=args.overwrite, inputs=[args.config])
    from platebench.bench.progress import bar, step_callback  # noqa: PLC0415
    from platebench.bench.run.calibration import (  # noqa: PLC0415
        DEFAULT_TARGET_Z_M,
        compare_reconstruction,
        run_calibration,
    )
    from platebench.scenes.render.board_renderer import BoardSpec, calibration_poses  # noqa: PLC0415

    if args.target_z_mm is None:
        target_z = DEFAULT_TARGET_Z_M
    else:
        if len(args.target_z_mm) < 2 or len(set(args.target_z_mm)) != len(args.target_z_mm):
            raise UserValueError("--target-z-mm needs at least 2 distinct heights")
        if not all(math.isfinite(z) and -150.0 <= z <= 150.0 for z in args.target_z_mm):
            raise UserValueError("--target-z-mm values are out of range: allowed -150 to 150 mm")
        target_z = tuple(z * 1e-3 for z in args.target_z_mm)
    board = BoardSpec()
    n_poses = len(calibration_poses(cfg.scene.build().rig, board))
    steps = 2 * n_poses + 2 * len(target_z) + (0 if args.no_reconstruction else 6 + 3)
    with output_dir(args.out, "calibration", overwrite=args.overwrite, inputs=[args.config]) as stage, \
            bar(steps, "calibrate") as pbar:
        step = step_callback(pbar)
        result, renderer = run_calibration(cfg, board, target_z, progress=step,
                                           distortion_model=args.distortion_model)
        comparison = None
        if not args.no_reconstruction:
            comparison = compare_reconstruction(cfg, result, renderer, progress=step)
        pbar.set_postfix_str("write")
        out = result.report.to_dict()
        out["units"] = ("metres, radians, pixels unless a key names another unit; camera dicts (K, R, t) in the "
                        "OpenCV convention of calib.json (x_cam = R x_world + t, t in metres)")
        if comparison is not None:
            out["reconstruction"] = {name: {"metrics": MetricsRow.from_score(s).columns(), "score": s.to_dict()}
                                     for name, s in comparison.items()}
        write_json(stage / "calibration.json", out)
        pbar.update(pbar.total - pbar.n)
    print(format_table(result.report, comparison))
    print(f"{'written':34s} {args.out / 'calibration.json'}")
    return 0


def format_table(report, comparison: dict | None = None) -> str:
    """The calibration report (``bench.io.calibration_records.CalibrationReport``; and the reference
    reconstruction per calibration, ``Score``s) as text."""
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
