"""Argument groups that several commands share (not a command: ``bench.cli.main`` lists the commands).
Each builder only declares flags; what they mean is read by ``bench.config`` (``sample_flags``,
``sensing``)."""
from __future__ import annotations

import argparse
from pathlib import Path

from platebench.bench.config.realism import REALISM_PRESETS


def add_sample_flags(p: argparse.ArgumentParser) -> None:
    """Flags shared by commands that make a sample (render, calibrate, sense), read by
    ``bench.config.sample_flags.config_from_args``."""
    p.add_argument("--config", type=Path, help="TOML file with [plate], [scene], [render], [sensor] tables "
                   "(SI units); flags below override it")
    p.add_argument("--bend-deg", type=float, help="cylindrical bend angle in DEGREES, 0 to 350 (default 10)")
    p.add_argument("--bend-direction", choices=("down", "up"),
                   help="down: convex (the ends fall away from the cameras); up: concave (default up, the paper's plate)")
    p.add_argument("--bend-axis-deg", type=float,
                   help="bend axis in DEGREES from the plate's width direction: 0 bends it along its length, "
                        "90 across its width; 0 to 180 (default 0)")
    p.add_argument("--grid", metavar="ROWSxCOLS@PX",
                   help="projected square grid: ROWS arrays of COLS squares of PX projector pixels "
                        "(default 4x4@40, the paper's 16 squares; 6x12@12 is fine enough for the "
                        "false-boundary counting test, see README)")
    p.add_argument("--distance-m", type=float, help="rig height above the plate in metres (default 0.40)")
    p.add_argument("--width", type=int, help="image width in pixels (default 1280; under --realism the camera's own, "
                   "its field of view kept at another width)")
    p.add_argument("--height", type=int, help="image height in pixels (default 960)")
    p.add_argument("--spp", type=int, help="Monte Carlo samples per pixel (default 16)")
    p.add_argument("--seed", type=int, help="random seed; same seed, same bytes (default 0)")
    p.add_argument("--variant", help="Mitsuba variant (default: cuda_ad_rgb with a GPU, else llvm_ad_rgb)")
    p.add_argument("--camera", choices=("ideal", "1995", "modern"),
                   help="camera preset: resolution + sensor noise/bit depth (1995: 512x480 8-bit noisy CCD; "
                        "modern: 2048x1536 16-bit); default ideal (noise-free 8-bit)")
    p.add_argument("--realism", choices=tuple(REALISM_PRESETS),
                   help="error model of a real rig (README: what each source costs): its camera (as --camera), "
                        "the robot that moves the camera between the views and the estimated hand/eye and "
                        "intrinsics; images and ground truth come from the cameras really posed, calib.json is "
                        "what the method is told. ideal (default): none. 1995: the paper's PULNiX camera moved "
                        "by a PUMA 560. modern: a rigid two-camera head on a current arm")
    p.add_argument("--realism-seed", type=int, help="the draw of the realism's error sources (default 0)")


def add_verify_grid_flag(p: argparse.ArgumentParser) -> None:
    """``--verify-grid``: the square grid the verification views and cures project (sense, study), read by
    ``bench.config.sensing.parse_verify_grid``."""
    from platebench.bench.config.sensing import VERIFY_GRID  # noqa: PLC0415

    p.add_argument("--verify-grid", metavar="ROWSxCOLS@PX", default=VERIFY_GRID,
                   help="square grid projected by the verification views and cures (default auto: 6x12@12 at 640 "
                        "px wide and more, larger squares on narrower images; fine enough to orient the plate's "
                        "front up to its edges, see README); 'stage3' projects stage 3's grid (--grid) there too")
