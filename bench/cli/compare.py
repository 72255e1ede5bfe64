"""``platebench compare``: score peer reconstruction methods side by side on one sample
(the work is ``bench.run.compare``; this module is argparse and printing).

Re-creates the sample's plate and scene from ``SAMPLE_DIR/sample.json`` (its calibration
must agree with ``calib.json``), renders the projector sequences the chosen methods need
with one renderer (``bench.pattern_sequences``), runs each method (``reconstruction.peer_*``:
pure functions of images and calibration) and scores it against the sample's ground truth:

* depth: |Z_est - Z_gt| (left camera z-depth, mm) over plate pixels with an estimate:
  median, RMS, p95, max, signed mean; coverage = those pixels / plate pixels (gt mask);
  estimates off the plate are counted separately (the disparity metrics ignore them);
* disparity: Middlebury v3 and ETH3D two-view metrics against ``gt/disp0GT.pfm``.

The "paper" row is read, not computed: ``--recon DIR`` (or the sample's parent
directory) holding ``points.csv`` (world x, y, z in metres) and optionally
``recon.json`` from ``platebench reconstruct``; its points are scored by depth error at
their left-image projection and by distance to the true plate surface. Without such
files the row is left out, with a note.

Outputs (``--out``, default ``SAMPLE_DIR/compare``): ``compare.json`` (every figure)
and ``compare.png`` (signed depth-error map per method).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from platebench.bench.io.atomic import staged_output, write_bytes, write_json
from platebench.bench.report.plots import compare_error_figure
from platebench.bench.run.compare import (
    ALL_METHODS,
    METHODS,
    Comparison,
    compare_sample,
    comparison_json,
)
from platebench.errors import UserValueError


# ----------------------------------------------------------------------------- reporting
def format_table(cmp: Comparison) -> str:
    head = (f"{'method':16s} {'img/cam':>7s} {'depth med mm':>12s} {'depth RMS mm':>12s} {'coverage':>9s} "
            f"{'bad1 %':>7s} {'time s':>7s} {'render s':>8s}")
    lines = [head, "-" * len(head)]
    for r in cmp.rows:
        s = r.scores
        if r.name == "paper":
            cov = f"{s['points_on_plate']} pts"
            bad = "-"
        else:
            cov = f"{s['coverage_pct']:.1f} %"
            bad = f"{s['middlebury']['mb_all_bad_1_0_pct']:.1f}"
        lines.append(f"{r.name:16s} {r.n_images:7d} {s['depth_median_mm']:12.4f} {s['depth_rms_mm']:12.4f} "
                     f"{cov:>9s} {bad:>7s} {r.time_s:7.3f} {r.render_s:8.1f}")
    return "\n".join(lines)








# ----------------------------------------------------------------------------- CLI
def _method_list(text: str) -> tuple:
    names = tuple(m.strip() for m in text.split(",") if m.strip())
    bad = [m for m in names if m not in ALL_METHODS]
    if bad or not names:
        raise argparse.ArgumentTypeError(f"unknown method {bad[0] if bad else text!r}: choose from "
                                         f"{', '.join(ALL_METHODS)}")
    return names


def add_parser(sub) -> None:
    p = sub.add_parser("compare", help="score peer methods (Gray code, phase shifting, SGBM) side by side",
                       description="Re-render a sample's scene under each peer method's projector sequence, "
                                   "reconstruct, and score against the sample's exact ground truth (depth error "
                                   "in mm, coverage of the plate, Middlebury/ETH3D disparity metrics). "
                                   "Writes compare.json and compare.png.")
    p.add_argument("sample", type=Path, metavar="SAMPLE_DIR", help="sample directory from 'platebench render'")
    p.add_argument("--methods", type=_method_list, default=METHODS,
                   help=f"comma-separated list from {', '.join(ALL_METHODS)} (default: {','.join(METHODS)})")
    p.add_argument("--out", type=Path, help="output directory (default SAMPLE_DIR/compare)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output directory")
    p.add_argument("--recon", type=Path, help="directory with the paper pipeline's points.csv / recon.json "
                   "(default: the sample's parent directory)")
    p.add_argument("--spp", type=int, help="samples per pixel for the pattern sequences (default: the sample's)")
    p.add_argument("--min-depth-mm", type=float, help="SGBM search range: nearest depth in MILLIMETRES")
    p.add_argument("--max-depth-mm", type=float, help="SGBM search range: farthest depth in MILLIMETRES")
    p.set_defaults(run=run)


def run(args) -> int:
    if not Path(args.sample).is_dir():
        raise FileNotFoundError(f"{args.sample}: sample directory is missing")
    if (args.min_depth_mm is None) != (args.max_depth_mm is None):
        raise UserValueError("--min-depth-mm and --max-depth-mm go together")
    depth_range = None
    if args.min_depth_mm is not None:
        if not 0 < args.min_depth_mm < args.max_depth_mm:
            raise UserValueError(f"depth range {args.min_depth_mm}-{args.max_depth_mm} mm is out of range: "
                             "need 0 < min < max")
        depth_range = (args.min_depth_mm / 1e3, args.max_depth_mm / 1e3)
    if args.spp is not None and not 1 <= args.spp <= 65536:
        raise UserValueError(f"--spp = {args.spp} is out of range: allowed 1 to 65536")
    t0 = time.perf_counter()

    def say(msg):
        print(f"  {msg}", file=sys.stderr, flush=True)

    out = Path(args.out) if args.out is not None else Path(args.sample) / "compare"
    # staged (bench.io.atomic): --out checked before the renders, replaced only with --overwrite and complete
    with staged_output(out, overwrite=args.overwrite, what="comparison") as stage:
        cmp = compare_sample(args.sample, args.methods, args.recon, args.spp, depth_range, progress=say)
        doc = comparison_json(cmp)
        doc["total_s"] = time.perf_counter() - t0
        write_json(stage / "compare.json", doc)
        write_bytes(stage / "compare.png", compare_error_figure(cmp))
    print(f"sample      {args.sample}")
    print(format_table(cmp))
    for n in cmp.notes:
        print(f"note: {n}")
    print(f"wrote       {out / 'compare.json'}, {out / 'compare.png'}  ({doc['total_s']:.1f} s)")
    return 0
