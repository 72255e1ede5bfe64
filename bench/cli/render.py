"""``platebench render``: render one sample (4 images + exact ground truth) to a directory."""
from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

from platebench.bench.config import load_config, with_camera_preset, with_overrides
from platebench.bench.config.presets import with_realism
from platebench.bench.config.realism import REALISM_PRESETS
from platebench.bench.io.outputs import output_dir
from platebench.errors import UserValueError

HELP = "render one sample of a bent plate with exact ground truth"


def add_sample_flags(p: argparse.ArgumentParser) -> None:
    """Flags shared by commands that make a sample (render, demo, sense)."""
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


def config_from_args(args):
    cfg = load_config(args.config, args.width, args.height)  # the lens checked at the size asked for
    if getattr(args, "camera", None) and getattr(args, "realism", None):
        raise UserValueError("--camera and --realism both choose the camera: give one (a realism preset names its "
                             "camera)")
    if getattr(args, "camera", None):
        cfg = with_camera_preset(cfg, args.camera)
    if getattr(args, "realism", None):
        cfg = with_realism(cfg, args.realism)
    if getattr(args, "realism_seed", None) is not None:
        if not 0 <= args.realism_seed < 2 ** 31:
            raise UserValueError(f"--realism-seed = {args.realism_seed} is out of range: allowed 0 to 2^31-1")
        cfg = replace(cfg, realism=cfg.realism.with_seed(args.realism_seed))
    out = with_overrides(cfg, bend_deg=args.bend_deg, width=args.width, height=args.height, spp=args.spp,
                         seed=args.seed, variant=args.variant, distance_m=args.distance_m,
                         bend_direction=args.bend_direction, bend_axis_deg=args.bend_axis_deg, grid=args.grid)
    return realism_camera_at_width(cfg, out, args.width)


def realism_camera_at_width(cfg, out, width: int | None):
    """``out`` (``cfg`` with its flags applied) with a realism camera's pixel focal lengths scaled by
    ``width`` over its own width: the same field of view (and pixel aspect, lens) sampled by fewer or
    more pixels. Unchanged without a realism camera or a width."""
    if width is None or cfg.realism.camera == "ideal" or cfg.scene.f_px is None:
        return out
    k = out.scene.width / cfg.scene.width
    fy = None if cfg.scene.fy_px is None else cfg.scene.fy_px * k
    return replace(out, scene=replace(out.scene, f_px=cfg.scene.f_px * k, fy_px=fy))


def add_parser(sub) -> None:
    p = sub.add_parser("render", help=HELP,
                       description="Render the left/right images under passive and active (projected squares) "
                                   "lighting, cast ground truth at pixel centres, and write a dataset sample "
                                   "(layout v1, see README). Default: the paper's reference experiment "
                                   "(116.5 x 73.5 mm plate bent 10 degrees, cameras 0.40 m above).")
    p.add_argument("--out", type=Path, required=True, help="sample directory to create")
    p.add_argument("--overwrite", action="store_true", help="replace a sample directory 'platebench render' wrote "
                   "(nothing else is replaced)")
    add_sample_flags(p)
    p.set_defaults(run=run)


def run(args) -> int:
    cfg = config_from_args(args)
    # the output rule (bench.io.outputs) before the render: --out new, or with --overwrite a sample this
    # command wrote; staged, so it is replaced only once the new sample is complete
    with output_dir(args.out, "sample", overwrite=args.overwrite, inputs=[args.config]) as stage:
        # imported once the configuration and --out are checked: a bad one is refused at once
        from platebench.bench.io.sample_files import write_sample  # noqa: PLC0415
        from platebench.bench.progress import bar, step_callback  # noqa: PLC0415
        from platebench.bench.run.render import render_sample  # noqa: PLC0415

        with bar(8 if sample_moves(cfg) else 7, "render") as pbar:
            sample, _ = render_sample(cfg, progress=step_callback(pbar), on_pass=pass_postfix(pbar))
            pbar.set_postfix_str("write")
            write_sample(stage, sample, into=True)
            pbar.update(pbar.total - pbar.n)
    t = sample.timings_s
    vis = sample.visibility
    if sample.acquisition is not None:
        for line in acquisition_lines(cfg, sample.acquisition):
            print(line)
    print(f"sample      {args.out}")
    print(f"plate       {cfg.plate.deformation}  {cfg.plate.length_m * 1e3:.1f} x {cfg.plate.width_m * 1e3:.1f} mm, "
          f"mesh {len(sample.plate.mesh.vertices)} vertices")
    print(f"images      4 x {cfg.scene.width}x{cfg.scene.height} px, spp {cfg.render.spp}, seed {cfg.render.seed}, "
          f"variant {sample.variant}")
    for cam in ("left", "right"):
        g = sample.gt[cam]
        print(f"gt {cam:5s}    plate pixels {int(g.mask.sum())}, lit features {len(set(g.feature[g.feature >= 0].tolist()))}, "
              f"boundary visible {vis[cam].visible_fraction * 100:.1f} %, false boundary {vis[cam].false_boundary}")
    print(f"time        {t['total_s']:.1f} s (renders {sum(v for k, v in t.items() if k.startswith('render_')):.1f} s, "
          f"ground truth {t['ground_truth_s']:.1f} s)")
    return 0


def pass_postfix(pbar):
    """An ``on_pass(image_name, done_spp, spp)`` callback (``bench.run.render.render_sample``) that shows a
    render split into passes advancing on ``pbar``'s postfix."""
    def on_pass(name: str, done: int, spp: int) -> None:
        if done < spp:
            pbar.set_postfix_str(f"render {name} {done}/{spp} spp")
    return on_pass


def refuse_robot_errors(cfg, command: str, allow_estimates: bool = False) -> None:
    """One-line error when ``command`` would silently drop the realism's robot, hand/eye (or, unless
    ``allow_estimates``, estimated-intrinsics) errors: it places its cameras itself."""
    rz = cfg.realism
    dropped = [s for s in ("robot_repeatability", "robot_accuracy", "hand_eye") + (() if allow_estimates else
                                                                                   ("calibration",)) if rz.on(s)]
    if dropped:
        raise UserValueError(f"--realism {rz.name}: {command} does not model {', '.join(dropped)} (it places its "
                             f"cameras itself); the preset's camera alone: --camera {rz.camera}")


def sample_moves(cfg) -> bool:
    """True when the sample's realism adds an acquisition step (a robot, or estimates)."""
    return not cfg.realism.is_ideal


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
