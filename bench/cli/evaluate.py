"""``platebench evaluate``: score a reconstruction directory against its sample's ground truth."""
from __future__ import annotations

from pathlib import Path

from platebench.bench.io.atomic import write_json
from platebench.bench.run.score import score_files
from platebench.evaluation.score import format_table


def add_parser(sub) -> None:
    p = sub.add_parser("evaluate", help="score a reconstruction against exact ground truth",
                       description="Score RECON_DIR (from 'platebench reconstruct') against SAMPLE_DIR's ground "
                                   "truth: point, boundary, surface and false-boundary metrics, the paper's bound "
                                   "and the bench's goals. Prints a table; writes JSON (units in every key).")
    p.add_argument("sample_dir", type=Path)
    p.add_argument("recon_dir", type=Path)
    p.add_argument("--out", type=Path, help="score JSON path (default RECON_DIR/score.json)")
    p.set_defaults(run=run)


def run(args) -> int:
    score = score_files(args.sample_dir, args.recon_dir)
    out = args.out or (args.recon_dir / "score.json")
    write_json(out, score.to_dict())
    print(format_table(score))
    print(f"{'written':16s} {out}")
    return 0
