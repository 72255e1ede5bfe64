"""``platebench evaluate``: score a method's output against a sample's exact ground truth.

Either a PlateBench reconstruction directory (``platebench reconstruct``: the paper's metrics),
or exactly one file of another program's output, scored with the metrics of its kind
(``bench.run.field_score``; formats in ``bench.io.method_outputs``):

* ``--disparity F``: left-view disparity, PFM, or 16-bit PNG with ``--disparity-scale``;
* ``--depth F``: left-view z-depth in metres, EXR/PFM/NPY;
* ``--points F``: world points in metres, PLY/CSV/NPY;
* ``--mesh F``: surface mesh in metres, PLY.

A file whose errors lie orders of magnitude beyond the scene (a disparity given as ``--depth``,
millimetres for metres, points in the camera's frame) is scored all the same, with a hint
("is this file in millimetres?") printed and written to the score JSON's ``hints``
(``evaluation.plausibility``).
"""
from __future__ import annotations

import math
from pathlib import Path

from platebench.bench.io.atomic import write_json
from platebench.bench.io.outputs import KINDS, check_output
from platebench.errors import UserValueError

# the readers and scores (trimesh, SciPy, OpenCV, the pipeline's types) are imported where they are used
HELP = "score a reconstruction or another program's disparity/depth/points/mesh against exact truth"


def add_parser(sub) -> None:
    from platebench.bench.run.field_score import COVERAGE_RADIUS_M, OUTLIER_M  # noqa: PLC0415

    p = sub.add_parser(
        "evaluate", help=HELP,
        description="Score a method's output against SAMPLE_DIR's exact ground truth and write a score JSON (units in "
                    "every key). Give RECON_DIR (from 'platebench reconstruct': point, boundary, surface and "
                    "false-boundary metrics, the paper's bound), or exactly one file of another program: --disparity "
                    "(Middlebury and ETH3D metrics on all and non-occluded pixels, and the depth error they imply), "
                    "--depth (absolute errors, quantiles, coverage of the plate), --points (distance to the true "
                    "surface, outliers, coverage at a radius) or --mesh (accuracy and completeness both ways, "
                    "precision/recall/F-score at thresholds, as DTU and Tanks and Temples). Maps are the LEFT view "
                    "at the sample's resolution; points and meshes are in the world frame, metres.")
    p.add_argument("sample_dir", type=Path, metavar="SAMPLE_DIR",
                   help="sample directory with the exact ground truth (from 'platebench render' or a sweep)")
    p.add_argument("recon_dir", type=Path, nargs="?", metavar="RECON_DIR",
                   help="reconstruction directory from 'platebench reconstruct'")
    g = p.add_argument_group("another program's output (exactly one)")
    g.add_argument("--disparity", type=Path, metavar="F", help="left disparity in px: .pfm, or 16-bit .png with "
                   "--disparity-scale; +inf or NaN (PNG: 0) = no estimate; Middlebury's figures clip "
                   "other values to [0, ndisp] as its SDK does")
    g.add_argument("--disparity-scale", type=float, metavar="S", help="16-bit PNG disparity: px = value / S "
                   "(KITTI: 256)")
    g.add_argument("--depth", type=Path, metavar="F", help="left z-depth in METRES: .exr (one channel), .pfm, .npy")
    g.add_argument("--points", type=Path, metavar="F", help="world points in METRES: .ply, .csv (x,y,z), .npy (N,3)")
    g.add_argument("--mesh", type=Path, metavar="F", help="surface mesh in METRES, world frame: .ply")
    p.add_argument("--name", default=None, help="the method's name in the score JSON (default: the file's stem)")
    p.add_argument("--outlier-mm", type=float, default=None,
                   help=f"--points: a point farther than this from the true surface is an outlier, MILLIMETRES "
                        f"(default {OUTLIER_M * 1e3:g}, the paper's depth bound)")
    p.add_argument("--radius-mm", type=float, default=None,
                   help=f"--points: coverage radius on the plate, MILLIMETRES (default {COVERAGE_RADIUS_M * 1e3:g})")
    p.add_argument("--out", type=Path, help="score JSON path (default RECON_DIR/score.json, or F's name with "
                   ".score.json); never an input, nor inside SAMPLE_DIR or RECON_DIR elsewhere than there")
    p.add_argument("--overwrite", action="store_true", help="replace an existing score JSON 'platebench evaluate' "
                   "wrote (nothing else is replaced)")
    p.set_defaults(run=run)


def _kind(args) -> tuple[str | None, Path | None]:
    from platebench.bench.run.field_score import KINDS  # noqa: PLC0415

    given = [(k, getattr(args, k)) for k in KINDS if getattr(args, k) is not None]
    if args.recon_dir is not None:
        given.insert(0, ("recon", args.recon_dir))
    if len(given) != 1:
        what = ", ".join("RECON_DIR" if k == "recon" else f"--{k}" for k, _ in given) or "none"
        raise UserValueError(f"give exactly one of RECON_DIR, --disparity, --depth, --points, --mesh (got {what})")
    if args.disparity_scale is not None and given[0][0] != "disparity":
        raise UserValueError("--disparity-scale goes with --disparity")
    for flag in ("outlier_mm", "radius_mm"):
        v = getattr(args, flag)
        if v is None:
            continue
        if given[0][0] != "points":
            raise UserValueError(f"--{flag.replace('_', '-')} goes with --points")
        if not (math.isfinite(v) and 0 < v <= 1000):
            raise UserValueError(f"--{flag.replace('_', '-')} = {v} is out of range: allowed > 0 to 1000 mm")
    return given[0]


def _out(args, kind: str, path: Path) -> Path:
    """The score JSON's path after the output rule (``bench.io.outputs``), checked before any scoring;
    for a file, the error map beside it (``bench.io.error_map_files.error_map_beside``) too."""
    slot = path / "score.json" if kind == "recon" else path.with_name(f"{path.stem}.score.json")
    out = args.out or slot
    check_output(out, "score", overwrite=args.overwrite, inputs=[args.sample_dir, path], slots=[slot])
    if kind != "recon":
        from platebench.bench.io.error_map_files import error_map_beside  # noqa: PLC0415

        check_output(error_map_beside(out), "error map", overwrite=args.overwrite, inputs=[args.sample_dir, path],
                     slots=[error_map_beside(slot)])
    return out


def _check_roles(args, kind: str, path: Path) -> None:
    """Refuse a reconstruction given as SAMPLE_DIR and a sample given as RECON_DIR (the arguments in the
    wrong order, or the wrong directory), naming which is which."""
    sample_is_recon = KINDS["reconstruction"].recognised(args.sample_dir)
    recon_is_sample = kind == "recon" and KINDS["sample"].recognised(path)
    if sample_is_recon and recon_is_sample:
        raise UserValueError(f"SAMPLE_DIR {args.sample_dir} is a reconstruction and RECON_DIR {path} is a sample: "
                             f"the arguments are swapped (run 'platebench evaluate {path} {args.sample_dir}')")
    if sample_is_recon:
        raise UserValueError(f"SAMPLE_DIR {args.sample_dir} is a reconstruction (from 'platebench reconstruct'), not "
                             "a sample: give the sample directory first, then the reconstruction")
    if recon_is_sample:
        raise UserValueError(f"RECON_DIR {path} is a sample (from 'platebench render'), not a reconstruction: give "
                             "the sample directory first, then the directory 'platebench reconstruct' wrote")


def run(args) -> int:
    kind, path = _kind(args)
    _check_roles(args, kind, path)
    if kind == "recon":
        if path.is_file():
            raise UserValueError(f"{path}: is a file, not a reconstruction directory: score another program's output "
                                 "with --disparity, --depth, --points or --mesh F")
        if path.is_dir() and not (path / "recon.json").is_file():
            raise UserValueError(f"{path / 'recon.json'}: file is missing (RECON_DIR comes from 'platebench "
                                 "reconstruct'; score another program's output with --disparity, --depth, --points "
                                 "or --mesh F)")
        out = _out(args, kind, path)
        from platebench.bench.io.codecs import encode  # noqa: PLC0415
        from platebench.bench.report.text import format_score_table  # noqa: PLC0415
        from platebench.bench.run.score import score_files  # noqa: PLC0415

        score = score_files(args.sample_dir, args.recon_dir)
        write_json(out, encode(score))
        print(format_score_table(score))
        print(f"{'written':16s} {out}")
        return 0
    from platebench.bench.report.text import format_field_table  # noqa: PLC0415
    from platebench.bench.run.field_score import COVERAGE_RADIUS_M, OUTLIER_M, score_file  # noqa: PLC0415

    out = _out(args, kind, path)
    name = args.name or path.stem
    scored = score_file(kind, path, args.sample_dir, name, args.disparity_scale,
                        outlier_m=OUTLIER_M if args.outlier_mm is None else args.outlier_mm / 1e3,
                        coverage_radius_m=COVERAGE_RADIUS_M if args.radius_mm is None else args.radius_mm / 1e3)
    write_json(out, scored.document)
    from platebench.bench.io.error_map_files import error_map_beside, write_error_map  # noqa: PLC0415
    error_map = write_error_map(error_map_beside(out), scored.error_map)
    print(f"{'method':16s} {name} ({kind}: {path})")
    print(format_field_table(scored.score))
    for h in scored.hints:
        print(f"{'hint':16s} {h}")
    print(f"{'written':16s} {out}")
    print(f"{'written':16s} {error_map}")
    return 0
