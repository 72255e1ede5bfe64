"""``platebench demo``: the main job, on the paper's reference experiment.

1. the reference experiment end to end at full size: render, reconstruct, evaluate;
2. the paper's three sensing stages on it (with the false-boundary test);
3. a bend sweep (examples/demo_sweep.toml: the paper's method, Gray code, SGBM) on 2 local workers,
   and a realism sweep (examples/realism_sweep.toml: rough aluminium x sensor noise);
4. a small false-boundary study (the sensing loop on cylinders of 170 and 200 degrees, convex and
   concave, about two axes; the L formula against ground truth);
5. the HTML report of all of it.
"""
from __future__ import annotations

import time
from pathlib import Path

from platebench.bench.config import SampleConfig
from platebench.bench.io.atomic import write_json
from platebench.bench.io.outputs import output_dir
from platebench.errors import PlateBenchError
from platebench.version import __version__
from platebench.bench.io.report_records import RunTimings

# the work's modules (renderer, pipeline, scores) are imported in _run(), once --out is checked
HELP = "the main job: the paper's reference experiment end to end, a bend sweep, a false-boundary study and the report"
# How long the whole demo takes (README says the same; tests/test_readme.py checks that they agree;
# the measurement: docs/findings/design-record.md).
DEMO_TIME = "about 4 minutes on 2 cores"
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"  # installed as platebench/examples (package data)
DEMO_SPEC = EXAMPLES / "demo_sweep.toml"
REALISM_SPEC = EXAMPLES / "realism_sweep.toml"


def add_parser(sub) -> None:
    p = sub.add_parser("demo", help=HELP,
                       description="Renders the reference experiment (116.5 x 73.5 mm plate bent 10 degrees, "
                                   "1280x960, f 2000 px, baseline 0.10 m, 0.40 m), reconstructs and scores it; "
                                   "runs the three sensing stages; a bend sweep; a small false-boundary study; "
                                   f"a realism sweep; and writes DIR/report/index.html. It takes {DEMO_TIME}.")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--overwrite", action="store_true", help="replace a demo output 'platebench demo' wrote "
                   "(nothing else is replaced)")
    p.add_argument("--quick", action="store_true", help="reference experiment only (no sensing, sweep, study)")
    p.set_defaults(run=run)


def run(args) -> int:
    # the output rule (bench.io.outputs) before any work; staged: DIR is replaced (with --overwrite, only a
    # demo output) only by a finished demo, which demo.json marks as one
    with output_dir(args.out, "demo output", overwrite=args.overwrite) as stage:
        rc = _run(args, stage, Path(args.out))
        if rc:
            raise DemoFailed(f"demo step failed (exit status {rc}): {args.out} is left as it was")
        write_json(stage / "demo.json", {"generator": "platebench demo", "quick": bool(args.quick),
                                         "version": __version__})
    print(f"output          {args.out}")
    return 0


class DemoFailed(PlateBenchError):
    """A step of the demo failed: its output is not swapped in."""


def _run(args, out: Path, final: Path) -> int:
    """The demo into the staging directory ``out`` (paths are shown as they will be: under ``final``)."""
    from platebench.bench.io.codecs import encode  # noqa: PLC0415
    from platebench.bench.io.recon_files import image_checksums, write_reconstruction  # noqa: PLC0415
    from platebench.bench.io.sample_files import write_sample  # noqa: PLC0415
    from platebench.bench.progress import bar, step_callback  # noqa: PLC0415
    from platebench.bench.report.text import format_score_table, step_lines, summary_lines, table_lines  # noqa: PLC0415
    from platebench.bench.run.paper_method import reconstruct_dir  # noqa: PLC0415
    from platebench.bench.run.render import render_sample  # noqa: PLC0415
    from platebench.bench.run.score import score_files  # noqa: PLC0415

    t0 = time.perf_counter()

    def shown(path) -> Path:
        return final / Path(path).relative_to(out)

    ref = out / "reference"
    print("== 1. reference experiment (paper V): render, reconstruct, evaluate")
    with bar(7, "render reference") as pbar:
        sample, _ = render_sample(SampleConfig(), progress=step_callback(pbar))
        write_sample(ref / "sample", sample)
    print(f"rendered        {shown(ref / 'sample')} in {RunTimings.from_dict(sample.timings_s).total_s:.1f} s ({sample.variant})")
    r, inputs = reconstruct_dir(ref / "sample")
    write_reconstruction(ref / "recon", r, ref / "sample", image_checksums(inputs.images))
    print(f"reconstructed   {shown(ref / 'recon')} in {RunTimings.from_dict(r.timings_s).total_s * 1e3:.0f} ms")
    score = score_files(ref / "sample", ref / "recon")
    write_json(ref / "recon" / "score.json", encode(score))
    print(format_score_table(score))
    if args.quick:
        return 0

    print("\n== 2. the sensing loop (paper IV-B, V-B; verification views) on the reference plate")
    from platebench.bench.run.sensing import SensingOptions, run_sensing  # noqa: PLC0415
    with bar(4 + SensingOptions().max_views, "sense") as pbar:
        s = run_sensing(SampleConfig(), out / "sensing", progress=step_callback(pbar))
    for line in step_lines(s) + summary_lines(s):
        print(line)

    print("\n== 3. bend sweep (examples/demo_sweep.toml), 2 local workers")
    from platebench.bench.sweep.executors import LocalExecutor, run_sweep  # noqa: PLC0415
    from platebench.bench.sweep.spec import load_spec  # noqa: PLC0415
    summary = run_sweep(load_spec(DEMO_SPEC), out / "bend_sweep", LocalExecutor(2))
    print(f"sweep           {summary.ok} ok, {summary.failed} failed, {summary.samples_per_min:.1f} samples/min")
    print("\n== 3b. realism sweep (examples/realism_sweep.toml): rough aluminium x sensor noise, paper and peers")
    summary = run_sweep(load_spec(REALISM_SPEC), out / "realism_sweep", LocalExecutor(2))
    print(f"sweep           {summary.ok} ok, {summary.failed} failed, {summary.samples_per_min:.1f} samples/min")

    print("\n== 4. false-boundary study (the sensing loop on a few bent plates; the L formula)")
    from platebench.bench.config import RenderSettings, SceneParams  # noqa: PLC0415
    from platebench.bench.run.sensing.study import REFERENCE_ASPECT, study_cases, write_study  # noqa: PLC0415
    cases = [c for c in study_cases((170.0, 200.0)) if c.family == "cylinder" and c.axis_deg in (0.0, 90.0)
             and c.aspect == REFERENCE_ASPECT and c.distance_m == 0.40]
    base = SampleConfig(scene=SceneParams(width=480, height=360),
                        render=RenderSettings(spp=4))
    with bar(len(cases), "study", unit="plate") as pbar:
        study = write_study(out / "study", cases, base, overwrite=True, progress=lambda row: pbar.update(1),
                            settings={"plates": len(cases), "width_px": 480, "spp": 4},
                            l_bends_deg=(150.0, 165.0, 172.0))
    for line in table_lines(study):
        print(line)

    print("\n== 5. report")
    from platebench.bench.report.html import write_report  # noqa: PLC0415
    index = write_report(out)
    print(f"report          {shown(index)}")
    print(f"demo finished in {time.perf_counter() - t0:.0f} s")
    return 0
