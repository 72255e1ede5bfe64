"""``platebench perf``: benchmarks with ratios against baselines measured in the same run."""
from __future__ import annotations

from pathlib import Path

from platebench.bench.config import SampleConfig, SceneParams
from platebench.bench.config.sample_config import RenderSettings
from platebench.bench.files import regular_size
from platebench.bench.io.atomic import write_json
from platebench.bench.io.outputs import check_output
from platebench.errors import UserValueError

HELP = "benchmarks: render and reconstruct timings against same-run baselines"
TARGETS = ("render", "reconstruct", "sweep", "score", "sequences")
EXTRA = ("variants", "gpu")  # run only when named


def add_parser(sub) -> None:
    p = sub.add_parser("perf", help=HELP,
                       description="render: a whole sample (4 images + ground truth) vs raw mitsuba.render of the "
                                   "same images, and kernel reuse on a second sample. reconstruct: the paper's "
                                   "pipeline vs OpenCV StereoSGBM on the same passive pair. sweep: samples per "
                                   "minute with 1 and 2 local workers and a 2-worker Dask cluster, peak memory per "
                                   "worker. score: exact point-to-mesh distance on a dent plate's mesh (triangles 0.15 to "
                                   "14 mm) by radius classes vs one class and vs trimesh. sequences: a Gray-code sample "
                                   "(the sample + its 22-frame sequence, decoded and scored) vs a paper sample, and "
                                   "the sequence three patterns to a launch vs one frame a launch. Reference experiment at "
                                   "1280x960, spp 16 unless told otherwise.")
    p.add_argument("targets", nargs="*", metavar="TARGET",
                   help=f"what to benchmark: {', '.join(TARGETS)} (default: all); also "
                        "variants (the same scene rendered by each of --variants, pixels compared with the first, "
                        "samples per second), and gpu (every throughput figure of a GPU machine beside its "
                        "baseline: host pixels and subnormal floats, whole sample vs raw renders, cuda vs llvm, "
                        "the sweep pipeline, with --full the 61-plate study; on a machine without a GPU the llvm "
                        "figures, saying so)")
    p.add_argument("--width", type=int, default=1280, help="image width in px of the rendered samples (default 1280; "
                   "f scales with it)")
    p.add_argument("--height", type=int, default=960, help="image height in px (default 960)")
    p.add_argument("--spp", type=int, default=16, help="samples per pixel of the renders (default 16)")
    p.add_argument("--repeat", type=int, default=2, help="timed repetitions (best is reported)")
    p.add_argument("--json", type=Path, help="also write the figures as JSON here (a new file, or with --overwrite "
                   "one 'platebench perf' wrote)")
    p.add_argument("--overwrite", action="store_true", help="replace the --json or --save file of an earlier run "
                   "(nothing else is replaced)")
    p.add_argument("--variants", default="cuda_ad_rgb,llvm_ad_rgb",
                   help="perf variants: comma-separated Mitsuba variants, the first is the baseline "
                        "(default cuda_ad_rgb,llvm_ad_rgb: a GPU machine)")
    p.add_argument("--full", action="store_true", help="perf gpu: also the 61-plate false-boundary study, and a "
                   "90-sample sweep (the run a GPU machine is measured with: bench/perf/gpu_check.sh)")
    p.add_argument("--workers", type=int, default=None, help="perf gpu: CPU workers of the sweep pipeline (the study "
                   "uses one more; default: the CPUs less one)")
    p.add_argument("--sweep-samples", type=int, default=None, help="perf gpu: samples of the pipeline sweep "
                   "(default 18; 90 with --full)")
    p.add_argument("--save", type=Path, help="perf variants: save the first variant's images (a new .npz file, or "
                   "with --overwrite one --save wrote)")
    p.add_argument("--against", type=Path, help="perf variants: compare the first variant's images with these "
                                                "(.npz from --save on another machine)")
    p.set_defaults(run=run)


def perf_document(target: str, figures) -> dict:
    """What ``--json`` holds: the figures, marked as perf's own (``bench.io.outputs``: what --overwrite may replace)."""
    return {"generator": "platebench perf", "target": target, "figures": figures}


def _check_outputs(args) -> None:
    """The output rule (``bench.io.outputs``) for --json and --save, before any benchmark runs."""
    if args.json is not None:
        check_output(args.json, "perf figures", overwrite=args.overwrite, inputs=[args.against])
    if args.save is not None:
        if args.save.suffix != ".npz":
            raise UserValueError(f"--save = {args.save}: allowed a file name ending in .npz")
        check_output(args.save, "perf images", overwrite=args.overwrite, inputs=[args.against, args.json])


def run(args) -> int:
    from platebench.bench.perf.benchmarks import perf_reconstruct, perf_render  # noqa: PLC0415
    _check_outputs(args)
    if args.targets and args.targets[0] in EXTRA:
        if len(args.targets) != 1:
            raise UserValueError(f"perf {args.targets[0]} runs alone: got {' '.join(args.targets)}")
        if args.targets[0] == "variants":
            return _variants(args)
        return _gpu(args)
    bad = [t for t in args.targets if t not in TARGETS]
    if bad:
        raise UserValueError(f"perf target {bad[0]!r} is not known: choose from {', '.join(TARGETS + EXTRA)}")
    if args.repeat < 1:
        raise UserValueError(f"--repeat = {args.repeat} is out of range: allowed >= 1")
    cfg = SampleConfig(scene=SceneParams(width=args.width, height=args.height), render=RenderSettings(spp=args.spp))
    out = {}
    for target in args.targets or TARGETS:
        print(f"== perf {target}" + ("" if target == "score" else f" ({args.width}x{args.height}, spp {args.spp})"))
        if target == "sweep":
            from platebench.bench.perf.sweep import perf_sweep  # noqa: PLC0415
            out[target] = perf_sweep()
        elif target == "sequences":
            from platebench.bench.perf.sequences import perf_sequences  # noqa: PLC0415
            out[target] = perf_sequences(cfg, repeat=args.repeat)
        elif target == "score":
            from platebench.bench.perf.benchmarks import perf_score  # noqa: PLC0415
            out[target] = perf_score(repeat=args.repeat)
        else:
            out[target] = (perf_render if target == "render" else perf_reconstruct)(cfg, repeat=args.repeat)
    if args.json:
        write_json(args.json, perf_document(",".join(args.targets or TARGETS), out))
    return 0


def _gpu(args) -> int:
    from platebench.bench.perf.gpu import perf_gpu  # noqa: PLC0415
    if args.repeat < 1:
        raise UserValueError(f"--repeat = {args.repeat} is out of range: allowed >= 1")
    for flag, v in (("--workers", args.workers), ("--sweep-samples", args.sweep_samples)):
        if v is not None and not 1 <= v <= 10000:
            raise UserValueError(f"{flag} = {v} is out of range: allowed 1 to 10000")
    print(f"== perf gpu ({args.width}x{args.height}, spp {args.spp})" + (", full" if args.full else ""))
    def save(figures):
        if args.json:
            write_json(args.json, perf_document("gpu", figures))
    perf_gpu(args.width, args.height, args.spp, args.repeat, args.full, args.workers, args.sweep_samples,
             on_section=save)
    return 0


def _variants(args) -> int:
    from platebench.bench.perf.variants import perf_variants  # noqa: PLC0415
    variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    if not variants:
        raise UserValueError(f"--variants = {args.variants!r}: give at least one Mitsuba variant")
    if args.against is not None:  # a regular file (a FIFO would block the reader)
        regular_size(args.against, "an .npz written by --save", UserValueError,
                     missing="no such file (an .npz written by --save)")
    if args.repeat < 1:
        raise UserValueError(f"--repeat = {args.repeat} is out of range: allowed >= 1")
    print(f"== perf variants ({args.width}x{args.height}, spp {args.spp}): {', '.join(variants)}")
    out = perf_variants(variants, args.width, args.height, args.spp, args.repeat, args.save, args.against)
    if args.json:
        write_json(args.json, perf_document("variants", out))
    return 0
