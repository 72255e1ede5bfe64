"""``platebench reconstruct``: the paper's pipeline on a sample's images and calibration.

The files it reads (``bench.io.layout.METHOD_INPUTS``: the four PNG images, calib.json, pattern.json) are verified as every
reader verifies a sample (``bench.io.verify``): a symbolic link is refused before anything is opened;
once they are read (a damaged file is named by its reader), a file that differs from the checksum
recorded when the sample was written (the stamp of ``platebench render``, a sweep's manifest) is
refused before the pipeline runs: an image swapped in from another sample, an edited calibration.
A sample without recorded checksums is read as it is. Nothing is written when a file is refused.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from platebench.bench.io.layout import METHOD_INPUTS
from platebench.bench.io.outputs import output_dir
from platebench.errors import UserValueError
from platebench.bench.io.report_records import RunTimings

HELP = "run the paper's passive + active stereo pipeline on a sample"
_REFUSING = "refusing to reconstruct it"


def add_parser(sub) -> None:
    p = sub.add_parser("reconstruct", help=HELP,
                       description="Reads only SAMPLE_DIR/images, calib.json and pattern.json (never ground "
                                   "truth) and writes points.ply/csv, boundary.npy, surface.ply and recon.json "
                                   "to --out. Prints a summary.")
    p.add_argument("sample_dir", type=Path, help="sample directory written by 'platebench render'")
    p.add_argument("--out", type=Path, required=True, help="reconstruction directory to create")
    p.add_argument("--overwrite", action="store_true", help="replace a reconstruction directory 'platebench "
                   "reconstruct' wrote (nothing else is replaced)")
    p.add_argument("--grid-mm", type=float, default=2.0, help="surface grid spacing in MILLIMETRES (default 2)")
    p.add_argument("--calibration", type=Path,
                   help="calibration.json from 'platebench calibrate': run on the ESTIMATED stereo rig and "
                        "projector rays instead of the sample's true calib.json (to see how calibration error "
                        "propagates)")
    p.set_defaults(run=run)


def run(args) -> int:
    if not (0.1 <= args.grid_mm <= 20):
        raise UserValueError(f"--grid-mm = {args.grid_mm} is out of range: allowed 0.1 to 20 mm")
    from platebench.bench.io.verify import refuse_linked_inputs  # noqa: PLC0415

    refuse_linked_inputs(args.sample_dir, METHOD_INPUTS, then=_REFUSING)
    with output_dir(args.out, "reconstruction", overwrite=args.overwrite,
                    inputs=[args.sample_dir, args.calibration]) as stage:
        r = _reconstruct(args, stage)
    print_summary(r, args.out)
    return 0


def _reconstruct(args, stage: Path):
    # imported here, not at the top: a damaged sample is refused before the pipeline (SciPy,
    # Matplotlib) and trimesh are loaded, and --help answers at once
    from platebench.bench.io.sample_files import load_inputs  # noqa: PLC0415

    inputs = load_inputs(args.sample_dir)
    from platebench.bench.io.verify import verify_inputs  # noqa: PLC0415

    verify_inputs(args.sample_dir, METHOD_INPUTS, then=_REFUSING)  # the files read are the sample's, as written
    from platebench.bench.io.recon_files import image_checksums, write_reconstruction  # noqa: PLC0415
    from platebench.bench.run.paper_method import PipelineOptions, reconstruct_inputs  # noqa: PLC0415

    calibration = None
    if args.calibration is not None:
        from platebench.bench.run.calibration import load_estimated_calibration  # noqa: PLC0415
        calibration = load_estimated_calibration(args.calibration)
    r = reconstruct_inputs(inputs, args.sample_dir, PipelineOptions(grid_step_m=args.grid_mm * 1e-3), calibration)
    write_reconstruction(stage, r, args.sample_dir, image_checksums(inputs.images), into=True)
    return r


def print_summary(r, out) -> None:
    fb = r.false_boundary
    z = r.points[:, 2] * 1e3 if len(r.points) else np.array([np.nan])
    print(f"reconstruction  {out}")
    print(f"boundary        {len(r.boundary)} points; plane normal {np.round(r.boundary_plane.normal, 4).tolist()}, "
          f"L1 offset {r.boundary_plane.offset * 1e3:.3f} mm (least squares {r.least_squares_plane.offset * 1e3:.3f} mm)")
    print(f"squares         left {fb.detected['left_active']}, right {fb.detected['right_active']}, "
          f"expected inside boundary {fb.expected}, matched {len(r.points) + len(r.cut)}")
    if len(r.cut):
        print(f"cut squares     {len(r.cut)} matched centres set apart (left {fb.cut.get('left_active', 0)}, right "
              f"{fb.cut.get('right_active', 0)} squares cut by the plate's outline or the threshold): "
              f"cut_points.csv, not in the points or the surface")
    print(f"false boundary  {'DETECTED' if fb.false_boundary_detected else 'not detected'}")
    for name, chk in r.fig6.items():
        if chk.violations:
            for v in chk.violations:
                print(f"fig6            {v}")
    for note in r.unmatched:
        print(f"unmatched       {note}")
    print(f"points z        {np.nanmin(z):.3f} .. {np.nanmax(z):.3f} mm")
    print(f"surface         {len(r.surface_vertices)} vertices, {len(r.surface_faces)} faces")
    print(f"time            {RunTimings.from_dict(r.timings_s).total_s * 1e3:.0f} ms")
