"""``platebench evaluate``: score a reconstruction directory against its sample's ground truth."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.atomic import write_json
from bench.image_io import DatasetError
from bench.recon_io import load_reconstruction
from bench.sample import load_calibration, load_ground_truth, load_pattern
from evaluation.score import ReconstructionData, SampleTruth, format_table, score_reconstruction


def add_parser(sub) -> None:
    p = sub.add_parser("evaluate", help="score a reconstruction against exact ground truth",
                       description="Score RECON_DIR (from 'platebench reconstruct') against SAMPLE_DIR's ground "
                                   "truth: point, boundary, surface and false-boundary metrics, the paper's bound "
                                   "and the bench's goals. Prints a table; writes JSON (units in every key).")
    p.add_argument("sample_dir", type=Path)
    p.add_argument("recon_dir", type=Path)
    p.add_argument("--out", type=Path, help="score JSON path (default RECON_DIR/score.json)")
    p.set_defaults(run=run)


def load_truth(sample_dir: Path):
    gt = load_ground_truth(sample_dir)
    calib = load_calibration(sample_dir)
    pattern = load_pattern(sample_dir)
    truth = SampleTruth(gt.mesh, gt.boundary, gt.mask, gt.feature, calib.rig, calib.projector_camera,
                        np.array([f.id for f in pattern.features]),
                        np.array([f.center for f in pattern.features], float).reshape(-1, 2), gt.visibility)
    return truth, gt.meta


def evaluate(sample_dir: Path, recon_dir: Path) -> dict:
    truth, meta = load_truth(sample_dir)
    rec = load_reconstruction(recon_dir)
    sums = rec.meta.get("input_checksums", {})
    want = meta.get("images", {})
    for name, digest in sums.items():
        if want.get(name) != digest:
            raise DatasetError(f"{recon_dir} was not made from {sample_dir}: image {name} differs "
                               "(reconstruct this sample first)")
    data = ReconstructionData(rec.points, rec.uv_left, rec.uv_right, rec.feature_id, rec.boundary,
                              None if rec.surface is None else np.asarray(rec.surface.vertices),
                              rec.meta.get("false_boundary", {}))
    return score_reconstruction(truth, data)


def run(args) -> int:
    score = evaluate(args.sample_dir, args.recon_dir)
    out = args.out or (args.recon_dir / "score.json")
    write_json(out, score)
    print(format_table(score))
    print(f"{'written':16s} {out}")
    return 0
