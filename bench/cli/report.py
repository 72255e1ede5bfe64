"""``platebench report``: the HTML report of a sweep dataset, a false-boundary study, a sensing run,
a reconstruction, a sample, compare.json files, or a folder holding some of them (see
``bench/report/html.py``)."""
from __future__ import annotations

import sys
from pathlib import Path

HELP = "HTML report (headline, tables, plots, thumbnails) of a dataset, study, sensing run, reconstruction or sample"


def add_parser(sub) -> None:
    p = sub.add_parser(
        "report", help=HELP,
        description="Read PATH (a sweep dataset from 'platebench sweep', a study from 'platebench study "
                    "false-boundary', a sensing run from 'platebench sense', a reconstruction from 'platebench "
                    "reconstruct' with the score.json of 'platebench evaluate', a sample from 'platebench render', "
                    "compare.json files from 'platebench compare', or a folder holding some of them, such as the "
                    "demo's) and write one HTML page. It starts with a headline (the experiment's key figures and "
                    "whether the paper's bound is met, each dataset's and study's summary, a sensing run's "
                    "outcome), then per input: per-method tables, failures counted by kind (crashes, bound "
                    "violations, mismatched points), plots against every swept axis, error maps, and samples "
                    "linked to their folders with thumbnails of their images. Plots are embedded; thumbnails sit "
                    "in OUT/thumbs. Errors in mm, bends in degrees, distances in m. A damaged input (a truncated "
                    "JSON file, a results table that is not one, a sample_id leading out of its dataset) is refused "
                    "with one line and exit status 2. Prints the path of index.html.")
    p.add_argument("input", type=Path, metavar="PATH", help="dataset, study, sensing run, reconstruction or sample "
                                                           "directory, or a folder holding some of them")
    p.add_argument("--out", type=Path, metavar="DIR",
                   help="output directory (default PATH/report); new, or with --overwrite an earlier report; never "
                        "PATH itself or another folder inside it")
    p.add_argument("--overwrite", action="store_true", help="replace a report 'platebench report' wrote (nothing "
                   "else is replaced)")
    p.set_defaults(run=run)


def run(args) -> int:
    from platebench.bench.report.html import write_report  # noqa: PLC0415

    def warn(message: str) -> None:  # a part left out of the page, and why
        print(f"platebench: warning: {message}", file=sys.stderr)
    print(write_report(args.input, args.out, overwrite=args.overwrite, warn=warn))
    return 0
