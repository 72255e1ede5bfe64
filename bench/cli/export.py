"""``platebench export``: write a dataset in the layouts stereo code reads (Middlebury, KITTI 2015).

The work is ``bench.io.export`` (layouts) and ``bench.io.dataset_reader`` (samples as stereo pairs
with exact disparities, non-occlusion masks and an optional shift); this module is argparse and
printing.
"""
from __future__ import annotations

from pathlib import Path

from platebench.errors import UserValueError

# bench.io.export and bench.io.dataset_reader (trimesh, OpenCV, SciPy) are imported where they are used:
# by add_parser (the formats, the defaults) only when 'export' is the command (see main.build_parser)
HELP = "export a dataset to the Middlebury or KITTI layout (images, true disparities, masks, calib)"


def _shift(text: str):
    if text == "auto":
        return "auto"
    try:
        v = int(text)
    except ValueError:
        v = -1
    if v < 0:
        raise UserValueError(f"--shift = {text!r} is not allowed: a whole number of px >= 0, or 'auto'")
    return v


def add_parser(sub) -> None:
    from platebench.bench.io.dataset_reader import MIN_DISPARITY_PX  # noqa: PLC0415
    from platebench.bench.io.export import FORMATS, IMAGES, MIDDLEBURY_TREE  # noqa: PLC0415

    p = sub.add_parser(
        "export", help=HELP,
        description="Write every sample under DATASET (a sample directory, a sweep dataset or a folder of samples) "
                    "in a layout stereo code reads unchanged. middlebury: the Middlebury 2014 SDK tree, "
                    f"OUT/{MIDDLEBURY_TREE}/<scene>/im0.png, im1.png, calib.txt (tight vmin/vmax, dyavg/dymax, "
                    "doffs; Z = baseline f / (d + doffs), baseline in mm), disp0GT.pfm, mask0nocc.png (255 seen by "
                    "both cameras, 128 occluded, 0 unknown) and disp1GT.pfm; <scene> is the sample id (a sweep's "
                    "0003), characters other than letters, digits and . _ - replaced by _; full resolution only. "
                    "kitti: OUT/training/image_2, image_3, disp_occ_0, disp_noc_0 (uint16 = 256 d), "
                    "calib_cam_to_cam (P_rect_02/03, one K: Z = f B / d as KITTI loaders read it; images reduced "
                    "by a whole factor where the true disparities exceed 256 px, said in export.json). "
                    "OUT/export.json lists the samples and their folders. Disparities and masks are computed from "
                    "the samples' exact ground truth. A sweep dataset that holds fewer rendered samples than its "
                    "manifest lists (interrupted, still running) is refused unless --allow-incomplete.")
    p.add_argument("dataset", type=Path, metavar="DATASET",
                   help="a sample directory, a sweep dataset or a folder of samples")
    p.add_argument("--format", required=True, choices=FORMATS, dest="fmt",
                   help=f"middlebury (2014 SDK tree OUT/{MIDDLEBURY_TREE}/<scene>/, calib.txt with doffs) or kitti "
                        "(2015 layout, calib_cam_to_cam with P_rect_02/03)")
    p.add_argument("--out", type=Path, required=True, metavar="DIR", help="output directory (created; must not exist "
                   "unless --overwrite)")
    p.add_argument("--images", choices=("active", "passive"), default=IMAGES,
                   help="active: the projected square grid (default: what a matcher can match on a plain plate); "
                        "passive: the plate under the overhead light")
    p.add_argument("--shift", type=str, default="0", metavar="PX|auto",
                   help="middlebury: lower every disparity by PX by cropping the left image's first PX columns and "
                        "the right image's last PX (doffs grows by PX, so Z = baseline f / (d + doffs) still holds); "
                        "allowed 0 to floor(smallest true disparity of the dataset's plates) - 1, so every exported "
                        "disparity stays >= 1 px. 'auto': per sample, so the smallest true disparity is "
                        f"{MIN_DISPARITY_PX} to {MIN_DISPARITY_PX + 1} px (default 0; not with kitti, whose loaders "
                        "assume equal principal points)")
    p.add_argument("--allow-incomplete", action="store_true",
                   help="export the samples an incomplete sweep dataset holds (interrupted or still running), with "
                        "a note saying how many of how many; without it such a dataset is refused")
    p.add_argument("--include-unrectified", action="store_true",
                   help="also export samples whose image pair is no rectified pair (taken by a robot, or through a "
                        "distorting lens: the realism presets), marked 'unrectified' in export.json: for them "
                        "Z = f B / (d + doffs) holds only approximately; without it they are left out, with a note")
    p.add_argument("--overwrite", action="store_true", help="replace a DIR 'platebench export' wrote (nothing else "
                   "is replaced)")
    p.set_defaults(run=run)


def run(args) -> int:
    from platebench.bench.io.export import export_dataset  # noqa: PLC0415
    from platebench.bench.progress import bar  # noqa: PLC0415

    shift = _shift(args.shift)
    with bar(None, "export", unit="sample") as pbar:  # on a terminal only: a failure's one line stands alone
        def step(msg: str) -> None:
            pbar.update(1)
            pbar.set_postfix_str(msg)
        summary = export_dataset(args.dataset, args.out, args.fmt, images=args.images, shift=shift,
                                 allow_incomplete=args.allow_incomplete, include_unrectified=args.include_unrectified,
                                 overwrite=args.overwrite, progress=step)
    for s in summary.samples:
        print(f"{s.id:24s} {s.width}x{s.height}  shift {s.shift_px} px, disparity {s.vmin} to "
              f"{s.vmax} px, doffs {s.doffs_px:g} px" + (f"; resampled: {s.resampled}" if s.resampled else ""))
    if summary.note:
        print(f"note: {summary.note}")
    print(f"exported    {len(summary.samples)} sample(s), {args.fmt} layout, {args.images} images -> {summary.out}"
          + (f" (largest --shift this dataset allows: {summary.max_shift_px} px)" if summary.max_shift_px is not None
             else ""))
    return 0
