"""``platebench report``: a self-contained HTML report of a sweep dataset, a false-boundary study
or compare.json files (see ``bench/report.py``)."""
from __future__ import annotations

from pathlib import Path


def add_parser(sub) -> None:
    p = sub.add_parser(
        "report", help="self-contained HTML report (tables + plots) of a sweep dataset or false-boundary study",
        description="Read DIR (a sweep dataset from 'platebench sweep', a study from 'platebench study "
                    "false-boundary', compare.json files from 'platebench compare', or a directory holding some of "
                    "them) and write one self-contained HTML page: counts, package versions, per-method tables "
                    "(mean / median of each metric), failures with their messages, detection precision / recall, "
                    "the L-formula table, and plots (error against bend, detection against bend, hidden boundary, "
                    "cures, L formula, per-sample error maps, method comparison) embedded as images. Errors in mm, "
                    "bends in degrees, distances in m. Prints the path of index.html.")
    p.add_argument("input", type=Path, metavar="DATASET_OR_STUDY", help="sweep dataset or study directory")
    p.add_argument("--out", type=Path, metavar="DIR",
                   help="output directory (default DATASET_OR_STUDY/report); must be new, empty or an earlier report")
    p.set_defaults(run=run)


def run(args) -> int:
    from platebench.bench.report.html import write_report  # noqa: PLC0415
    print(write_report(args.input, args.out))
    return 0
