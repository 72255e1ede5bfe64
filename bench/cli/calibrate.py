"""``platebench calibrate``: calibrate the stereo rig and the structured light from renders, score against truth."""
from __future__ import annotations

import math
from pathlib import Path

from platebench.bench.cli._args import add_sample_flags
from platebench.bench.config.sample_flags import config_from_args, refuse_robot_errors
from platebench.bench.io.config_files import load_config
from platebench.bench.io.atomic import write_json
from platebench.bench.io.outputs import check_output, output_dir
from platebench.errors import UserValueError

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
    cfg = config_from_args(args, load_config(args.config, args.width, args.height))
    refuse_robot_errors(cfg, "calibrate", allow_estimates=True)
    check_output(args.out, "calibration", overwrite=args.overwrite, inputs=[args.config])
    from platebench.bench.progress import bar, step_callback  # noqa: PLC0415
    from platebench.bench.report.text import format_calibration_table  # noqa: PLC0415
    from platebench.bench.run.calibration import (  # noqa: PLC0415
        DEFAULT_TARGET_Z_M,
        calibration_json,
        compare_reconstruction,
        progress_steps,
        run_calibration,
    )

    if args.target_z_mm is None:
        target_z = DEFAULT_TARGET_Z_M
    else:
        if len(args.target_z_mm) < 2 or len(set(args.target_z_mm)) != len(args.target_z_mm):
            raise UserValueError("--target-z-mm needs at least 2 distinct heights")
        if not all(math.isfinite(z) and -150.0 <= z <= 150.0 for z in args.target_z_mm):
            raise UserValueError("--target-z-mm values are out of range: allowed -150 to 150 mm")
        target_z = tuple(z * 1e-3 for z in args.target_z_mm)
    steps = progress_steps(cfg, target_z, not args.no_reconstruction)
    with output_dir(args.out, "calibration", overwrite=args.overwrite, inputs=[args.config]) as stage, \
            bar(steps, "calibrate") as pbar:
        step = step_callback(pbar)
        result, renderer = run_calibration(cfg, target_z_m=target_z, progress=step,
                                           distortion_model=args.distortion_model)
        comparison = None
        if not args.no_reconstruction:
            comparison = compare_reconstruction(cfg, result, renderer, progress=step)
        pbar.set_postfix_str("write")
        write_json(stage / "calibration.json", calibration_json(result, comparison))
        pbar.update(pbar.total - pbar.n)
    print(format_calibration_table(result.report, comparison))
    print(f"{'written':34s} {args.out / 'calibration.json'}")
    return 0
