"""``platebench demo``: the main job: the paper's reference experiment, end to end."""
from __future__ import annotations

import shutil
from pathlib import Path

from bench.cmd_evaluate import evaluate
from bench.config import SampleConfig
from bench.progress import bar, step_callback
from bench.recon_io import image_checksums, write_reconstruction
from bench.sample import load_inputs, render_sample, write_sample
from evaluation.score import format_table
from bench.atomic import write_json
from reconstruction.pipeline import projector_feature_rays, reconstruct


def add_parser(sub) -> None:
    p = sub.add_parser("demo", help="the main job: the paper's reference experiment end to end",
                       description="Render the reference experiment (116.5 x 73.5 mm plate bent 10 degrees, "
                                   "1280x960, f 2000 px, baseline 0.10 m, 0.40 m), reconstruct it with the "
                                   "paper's pipeline, and score it against ground truth. Writes DIR/sample, "
                                   "DIR/recon (with score.json).")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output directory")
    p.set_defaults(run=run)


def run(args) -> int:
    out: Path = args.out
    if out.exists():
        if not args.overwrite:
            raise FileExistsError(f"{out} already exists (use --overwrite to replace it)")
        shutil.rmtree(out)
    out.mkdir(parents=True)
    with bar(7, "render reference") as pbar:
        sample, _ = render_sample(SampleConfig(), progress=step_callback(pbar))
        write_sample(out / "sample", sample)
    print(f"rendered        {out / 'sample'} in {sample.timings_s['total_s']:.1f} s ({sample.variant})")
    inputs = load_inputs(out / "sample")
    rays = projector_feature_rays(inputs.calibration.projector_camera, inputs.pattern)
    r = reconstruct(inputs.images, inputs.calibration.rig, rays, inputs.pattern)
    write_reconstruction(out / "recon", r, out / "sample", image_checksums(inputs.images))
    print(f"reconstructed   {out / 'recon'} in {r.timings_s['total_s'] * 1e3:.0f} ms")
    score = evaluate(out / "sample", out / "recon")
    write_json(out / "recon" / "score.json", score)
    print(format_table(score))
    return 0
