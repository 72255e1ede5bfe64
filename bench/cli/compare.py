"""``platebench compare``: score peer reconstruction methods side by side on one sample
(the work is ``bench.run.compare``; this module is argparse and printing).

Re-creates the sample's plate and scene from ``SAMPLE_DIR/sample.json`` (its calibration
must agree with ``calib.json``), renders the projector sequences the chosen methods need
with one renderer (``bench.run.pattern_sequences``), runs each method (``reconstruction.peers``:
pure functions of images and calibration) and scores it against the sample's ground truth:

* depth: |Z_est - Z_gt| (left camera z-depth, mm) over plate pixels with an estimate:
  mean, median, RMS, max, A50-A99, signed mean; coverage = those pixels / plate pixels (gt
  mask); estimates off the plate are counted separately (the disparity metrics ignore them);
* disparity: Middlebury v3 and ETH3D two-view metrics on all and on non-occluded pixels.

Plug-in methods (an installed entry point of ``platebench.methods``, or ``module:function``)
run on the sample's images and calibration and are scored by the kind they return
(``bench.run.plugins``): a disparity or depth map as above, points by their distance to the
true surface, a mesh by accuracy and completeness.

The "paper" row is read, not computed: ``--recon DIR`` (or the sample's parent
directory) holding ``points.csv`` (world x, y, z in metres) and optionally
``recon.json`` from ``platebench reconstruct``; its points are scored by depth error at
their left-image projection and by distance to the true plate surface. Without such
files the row is left out, with a note.

A reconstruction is scored only as ``platebench reconstruct`` wrote it and against the sample it was
made from (``bench.run.compare.paper_reconstruction``: the checks ``platebench evaluate`` makes): one
whose files differ from its stamp's checksums or made from other images is refused, as is a
``--recon`` that is not a reconstruction directory.

Outputs (``--out``, default ``SAMPLE_DIR/compare``): ``compare.json`` (every figure)
and ``compare.png`` (signed depth-error map per method).

What the flags name is checked before the output path: the methods (built in, installed or
``module:function``), ``--recon``, the SGBM search range; the paper row's reconstruction is checked by
``compare_sample`` before any render. Exit status
(``bench/cli/main.py``): 0 when every method gave its row; 1 when a method failed (recorded in
compare.json) or no method gave a row, with one summary line on stderr; 2 refused.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

from platebench.bench.files import require_dir
from platebench.bench.io.atomic import write_bytes, write_json
from platebench.bench.io.outputs import check_output, output_dir
from platebench.bench.report.text import num_text as _num
from platebench.errors import UserValueError

if TYPE_CHECKING:
    from platebench.bench.run.compare import Comparison

HELP = "score peer methods (Gray code, phase shifting, SGBM) and plug-ins side by side"
# bench.run.compare (the renderer, every peer method) and bench.report.plots (pandas, Matplotlib) are
# imported where they are used; these names of bench.run.compare stay reachable here (see __getattr__)
_RUN_COMPARE_NAMES = ("Comparison", "compare_sample", "comparison_json")


def __getattr__(name: str):
    """``compare_sample`` and the other names above, imported from ``bench.run.compare`` on first use."""
    if name in _RUN_COMPARE_NAMES:
        from platebench.bench.run import compare  # noqa: PLC0415
        return getattr(compare, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


# ----------------------------------------------------------------------------- reporting
def _cells(r) -> tuple[str, float | None, float | None, str, str]:
    """(measure, median mm, RMS mm, coverage, bad-1 %) of a row (``MethodFigures``): depth error for maps
    and the paper's points, distance to the surface for point clouds, accuracy for meshes."""
    f = r.figures
    cov = "-" if f.coverage_frac is None else f"{100 * f.coverage_frac:.1f} %"
    bad = "-" if f.mb_all_bad_1_0_pct is None else f"{f.mb_all_bad_1_0_pct:.1f}"
    return f.measure or "-", f.error_median_mm, f.error_rms_mm, cov, bad


def format_table(cmp: Comparison) -> str:
    head = (f"{'method':24s} {'kind':9s} {'img/cam':>7s} {'median mm':>10s} {'RMS mm':>10s} {'coverage':>9s} "
            f"{'bad1 %':>7s} {'time s':>7s} {'render s':>8s}")
    lines = [head, "-" * len(head)]
    for r in cmp.rows:
        if r.status != "ok":
            lines.append(f"{r.name:24s} failed    {r.error}")
            continue
        kind, med, rms, cov, bad = _cells(r)
        lines.append(f"{r.name:24s} {kind:9s} {r.n_images:7d} {_num(med):>10s} {_num(rms):>10s} {cov:>9s} {bad:>7s} "
                     f"{r.time_s:7.3f} {r.render_s:8.1f}")
    lines.append("median/RMS: |depth error| over the plate's pixels (maps: disparity, depth), at the square centres "
                 "(kind centres: the paper's 16 points, sparse: not comparable with a map's), distance to the true "
                 "surface (clouds), accuracy (meshes); coverage = share of the plate's pixels with an estimate (paper: "
                 "those whose ray hits its surface.ply)")
    return "\n".join(lines)








# ----------------------------------------------------------------------------- CLI
def _recon_inputs(sample: Path, recon: Path | None) -> list[Path]:
    """What compare reads of the paper's reconstruction (``bench.run.compare.paper_reconstruction``):
    the --recon folder, else the points.csv and recon.json beside the sample or in its recon/."""
    if recon is not None:
        return [Path(recon)]
    return [d / n for d in (Path(sample).resolve().parent, Path(sample) / "recon") for n in ("points.csv", "recon.json")
            if (d / n).exists()]


def _check_methods(methods) -> None:
    """Refuse an unknown method (UserValueError naming it and what is allowed), before anything else."""
    from platebench.bench.run.compare import resolve_methods  # noqa: PLC0415  (the one check compare_sample makes)

    resolve_methods(methods)


def _check_recon_flag(recon: Path | None) -> None:
    """An explicit ``--recon`` must be a directory holding points.csv (a reconstruction directory)."""
    if recon is not None:
        recon = Path(recon)
        if not recon.exists():
            raise UserValueError(f"{recon}: --recon directory does not exist (give the directory 'platebench "
                                 "reconstruct' wrote for this sample)")
        if not recon.is_dir():
            raise UserValueError(f"{recon}: --recon is not a directory (give the directory 'platebench "
                                 "reconstruct' wrote for this sample)")
        if not (recon / "points.csv").is_file():
            raise UserValueError(f"{recon / 'points.csv'}: file is missing (--recon is the directory 'platebench "
                                 "reconstruct' wrote for this sample)")


def _check_sgbm_range(sample: Path, depth_range_m, method: str) -> None:
    """Refuse an SGBM disparity search that OpenCV cannot run on the sample's images
    (``bench.config.sgbm_range``); a damaged sample is left to its reader, after the output rule."""
    from platebench.bench.config.sgbm_range import check_sgbm_range  # noqa: PLC0415
    from platebench.bench.io.images import DatasetError  # noqa: PLC0415
    from platebench.bench.io.sample_files import load_calibration  # noqa: PLC0415

    try:
        rig = load_calibration(sample).rig
    except (DatasetError, OSError):
        return
    check_sgbm_range(rig, depth_range_m, method)


def _method_list(text: str) -> tuple:
    """Names as given; unknown ones are refused by ``compare_sample`` (plug-ins resolve there)."""
    from platebench.bench.config.methods import builtin_names  # noqa: PLC0415

    names = tuple(m.strip() for m in text.split(",") if m.strip())
    if not names:
        known = ", ".join(builtin_names())
        raise argparse.ArgumentTypeError(f"--methods {text!r} names no method: choose from {known}, "
                                         "an installed plug-in or module:function")
    return names


def add_parser(sub) -> None:
    from platebench.bench.config.methods import builtin_names, default_names  # noqa: PLC0415

    known, defaults = builtin_names(), default_names()  # the registry's, in its order

    p = sub.add_parser("compare", help=HELP,
                       description="Re-render a sample's scene under each peer method's projector sequence, "
                                   "reconstruct, and score against the sample's exact ground truth (depth error "
                                   "in mm, coverage of the plate, Middlebury/ETH3D disparity metrics). "
                                   "Writes compare.json and compare.png.")
    p.add_argument("sample", type=Path, metavar="SAMPLE_DIR", help="sample directory from 'platebench render'")
    p.add_argument("--methods", type=_method_list, default=defaults,
                   help=f"comma-separated list from {', '.join(known)}, installed plug-ins (entry points "
                        f"of platebench.methods) and module:function plug-ins (default: {','.join(defaults)})")
    p.add_argument("--out", type=Path, help="output directory (default SAMPLE_DIR/compare)")
    p.add_argument("--overwrite", action="store_true", help="replace a comparison directory 'platebench compare' "
                   "wrote (nothing else is replaced)")
    p.add_argument("--recon", type=Path, help="directory with the paper pipeline's points.csv / recon.json "
                   "(default: the sample's parent directory)")
    p.add_argument("--spp", type=int, help="samples per pixel for the pattern sequences (default: the sample's)")
    p.add_argument("--min-depth-mm", type=float, help="SGBM search range: nearest depth in MILLIMETRES")
    p.add_argument("--max-depth-mm", type=float, help="SGBM search range: farthest depth in MILLIMETRES")
    p.add_argument("--method-time-limit-s", type=float, default=None, metavar="S",
                   help="the longest a plug-in may run on the sample, seconds (default 600; 1 to 86400): one "
                        "that takes longer is stopped and recorded as failed")
    p.set_defaults(run=run)


def run(args) -> int:
    from platebench.bench.progress import bar  # noqa: PLC0415
    from platebench.bench.report.plots import compare_error_figure  # noqa: PLC0415
    from platebench.bench.run.compare import compare_sample, comparison_json  # noqa: PLC0415

    require_dir(Path(args.sample), "sample directory", UserValueError)
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
    if args.method_time_limit_s is not None:
        from platebench.bench.run.plugins import check_time_limit  # noqa: PLC0415
        check_time_limit(args.method_time_limit_s)
    # what the flags name, before the output rule and before any render (module doc)
    _check_methods(args.methods)
    _check_recon_flag(args.recon)
    sgbm_method = next((m for m in ("sgbm", "sgbm-passive") if m in args.methods), None)
    if sgbm_method is not None:  # both search the same disparity range
        _check_sgbm_range(Path(args.sample), depth_range, sgbm_method)
    t0 = time.perf_counter()
    out = Path(args.out) if args.out is not None else Path(args.sample) / "compare"
    # the output rule (bench.io.outputs): never into the sample or the reconstruction it reads, except the
    # sample's own compare/; checked before the renders, staged, replaced only with --overwrite and complete
    rule = {"overwrite": args.overwrite, "inputs": [args.sample, *_recon_inputs(args.sample, args.recon)],
            "slots": [Path(args.sample) / "compare"]}
    check_output(out, "comparison", **rule)
    with output_dir(out, "comparison", **rule) as stage, bar(len(args.methods) + 1, "compare", unit="method") as pbar:
        def say(msg):  # progress on a terminal only: a failure's one line stands alone on stderr
            if pbar.n < pbar.total - 1:
                pbar.update(1)
            pbar.set_postfix_str(str(msg)[:60])
        cmp = compare_sample(args.sample, args.methods, args.recon, args.spp, depth_range, progress=say,
                             method_time_limit_s=args.method_time_limit_s)
        total_s = time.perf_counter() - t0
        write_json(stage / "compare.json", {**comparison_json(cmp), "total_s": total_s})
        write_bytes(stage / "compare.png", compare_error_figure(cmp))
    print(f"sample      {args.sample}")
    print(format_table(cmp))
    for n in cmp.notes:
        print(f"note: {n}")
    failed = [r.name for r in cmp.rows if r.status != "ok"]
    if failed:
        print(f"failed      {len(failed)} of {len(cmp.rows)} method(s): {', '.join(failed)} (recorded in compare.json)")
    print(f"wrote       {out / 'compare.json'}, {out / 'compare.png'}  ({total_s:.1f} s)")
    return _status(cmp, args.sample, failed)


def _status(cmp: Comparison, sample, failed: list) -> int:
    """The exit status (module doc); its summary line on stderr when not 0."""
    if not cmp.rows:
        print(f"platebench: compare {sample}: no method gave a result (see the notes above)", file=sys.stderr)
        return 1
    if failed:
        what = "every method failed" if len(failed) == len(cmp.rows) else "some methods failed"
        print(f"platebench: compare {sample}: {what}: {len(failed)} of {len(cmp.rows)} ({', '.join(failed)}; "
              "recorded in compare.json)", file=sys.stderr)
        return 1
    return 0
