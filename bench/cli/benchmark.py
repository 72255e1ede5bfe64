"""``platebench benchmark``: build the frozen split, verify a copy, score methods on it, merge leaderboards.

The split, the protocol and the layouts are described in docs/benchmark.md; the code is in
``bench.benchmark``.
"""
from __future__ import annotations

import sys
from pathlib import Path

from platebench.errors import UserValueError

HELP = "the benchmark: build a versioned split, verify a copy, score a method or a folder of outputs, leaderboards"

_EPILOG = ("steps: 'benchmark build v1 --out B' renders the split (a sweep dataset; --resume after an interruption); "
           "'benchmark verify B' compares it with the ground-truth checksums shipped with the package; "
           "'benchmark score B --methods paper,sgbm --out R' or '--outputs NAME=DIR' scores methods by the protocol "
           "into R (results.parquet/.csv, leaderboard.html/.md); 'benchmark leaderboard R1 R2 --out L' merges "
           "results folders. Exit status: 0 all well; 1 some work failed or the copy is not the split (recorded); "
           "2 refused (one line); 130/143 interrupted. Definitions: docs/benchmark.md.")


def add_parser(sub) -> None:
    p = sub.add_parser("benchmark", help=HELP, description=HELP + ".", epilog=_EPILOG)
    steps = p.add_subparsers(dest="step", metavar="STEP", required=True,
                             help="list, build, verify, score or leaderboard (each has its own --help)")

    ls = steps.add_parser("list", help="the splits shipped with the package: version, samples, description")
    ls.set_defaults(run=run_list)

    b = steps.add_parser("build", help="render a split into a dataset (the sweep machinery: resume, checksums, Dask)",
                         description="Render every sample of SPLIT (a shipped version such as v1, or a split file "
                                     ".toml) with its ground truth into DATASET, as 'platebench sweep' does: every "
                                     "sample validated first, each committed with its checksums, --resume continues "
                                     "an interrupted build, --scheduler/--pipeline run it on a Dask cluster.")
    b.add_argument("split", metavar="SPLIT",
                   help="a shipped version (platebench benchmark list) or a split file (.toml)")
    b.add_argument("--out", type=Path, required=True, metavar="DATASET", help="the dataset folder to build")
    b.add_argument("--workers", type=int, default=None,
                   help="local worker processes (default 2; 0 runs in this process); not with --scheduler")
    b.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on this Dask distributed scheduler")
    b.add_argument("--pipeline", action="store_true",
                   help="one worker renders (the GPU), --workers CPU workers write and check (a local Dask cluster)")
    b.add_argument("--resume", action="store_true", help="continue DATASET: keep every sample already built")
    b.add_argument("--overwrite", action="store_true", help="replace a DATASET 'platebench benchmark build' wrote")
    b.add_argument("--record-checksums", type=Path, metavar="FILE",
                   help="also write the built copy's checksums to FILE (the document shipped as "
                        "splits/<version>.sha256.json beside the split's definition)")
    _progress_flags(b)
    b.set_defaults(run=run_build)

    v = steps.add_parser("verify", help="is a built copy the split? ground truth byte for byte, images by variant",
                         description="Check that DATASET is a whole, intact build of its split, then compare its "
                                     "ground truth (byte for byte) and images (byte for byte on the renderer variant "
                                     "the checksums were recorded with; else block means within the render-noise "
                                     "limit, the largest difference printed) with the checksums shipped with the "
                                     "package. Exit 0: the copy is the split; 1: it differs (listed); 2: not whole.")
    v.add_argument("dataset", type=Path, metavar="DATASET", help="a built benchmark (platebench benchmark build)")
    v.add_argument("--split", metavar="SPLIT", help="the split it should be (default: the one it was built from)")
    v.set_defaults(run=run_verify)

    s = steps.add_parser("score", help="score methods or folders of outputs on a built benchmark, by the protocol",
                         description="Check that DATASET is a whole, intact build of its split, then score every "
                                     "sample: each of --methods run by the bench (built-in, module:function plug-in "
                                     "or installed entry point), each --outputs folder read (one folder per sample "
                                     "id holding disparity.pfm|png, depth.exr|pfm|npy, mesh.ply|obj|stl or "
                                     "points.ply|csv|npy). A sample without an output counts as a failure (no "
                                     "estimate anywhere). Writes OUT/results.parquet, results.csv, sparse.csv, "
                                     "leaderboard.html, a Markdown leaderboard and the ranking tables.")
    s.add_argument("dataset", type=Path, metavar="DATASET", help="a built benchmark (platebench benchmark build)")
    s.add_argument("--out", type=Path, required=True, metavar="RESULTS", help="the results folder to write")
    s.add_argument("--methods", help="comma-separated methods run by the bench, e.g. paper,graycode,graycode-subpx,"
                                     "phase,sgbm or mypkg.mod:func")
    s.add_argument("--outputs", action="append", default=[], metavar="NAME=DIR",
                   help="a folder of another program's outputs, scored under NAME (repeatable)")
    s.add_argument("--split", metavar="SPLIT", help="the split DATASET must be (default: the one it was built from)")
    s.add_argument("--workers", type=int, default=2, help="worker processes (default 2; 0 runs in this process)")
    s.add_argument("--method-time-limit-s", type=float, default=None, metavar="S",
                   help="the longest a plug-in method may run on one sample, seconds (1 to 86400; default 600)")
    s.add_argument("--overwrite", action="store_true", help="replace a RESULTS folder 'benchmark score' wrote")
    _progress_flags(s)
    s.set_defaults(run=run_score)

    lb = steps.add_parser("leaderboard", help="merge results folders (from any machines) into one leaderboard",
                          description="Read RESULTS folders of one split (each verified by the checksums of its "
                                      "tables), merge them and write OUT/leaderboard.html, a Markdown leaderboard, the "
                                      "ranking and breakdown tables and the merged results.")
    lb.add_argument("results", type=Path, nargs="+", metavar="RESULTS", help="results folders (benchmark score)")
    lb.add_argument("--out", type=Path, required=True, metavar="DIR", help="the leaderboard folder to write")
    lb.add_argument("--overwrite", action="store_true", help="replace a folder 'benchmark leaderboard' wrote")
    lb.set_defaults(run=run_leaderboard)


def _progress_flags(p) -> None:
    p.add_argument("--progress", dest="progress", action="store_true", default=None,
                   help="show the progress bar even when stderr is not a terminal")
    p.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")


def _split_of(dataset: Path, given: str | None):
    """The split ``dataset`` should be: ``given``, else the shipped version named in its manifest."""
    from platebench.bench.benchmark.split import load_split, split_names  # noqa: PLC0415
    from platebench.bench.io.verify import dataset_manifest  # noqa: PLC0415
    if given:
        return load_split(given)
    m = dataset_manifest(dataset) if Path(dataset).is_dir() else None
    name = str(((m or {}).get("spec") or {}).get("name", ""))
    version = name.removeprefix("platebench-")
    if not name.startswith("platebench-") or version not in split_names():
        raise UserValueError(f"{dataset}: not a build of a shipped split (give --split FILE.toml for a split of "
                             "your own)")
    return load_split(version)


def run_list(args) -> int:
    from platebench.bench.benchmark.split import load_split, split_names  # noqa: PLC0415
    for name in split_names():
        s = load_split(name)
        print(f"{name:<6} {len(s.samples):>4} samples  sha256 {s.sha256[:12]}  {s.description}")
    return 0


def run_build(args) -> int:
    import contextlib  # noqa: PLC0415

    from platebench.bench.benchmark.split import load_split  # noqa: PLC0415
    from platebench.bench.io.outputs import guard_output  # noqa: PLC0415

    split = load_split(args.split)
    if args.scheduler and args.workers is not None:
        raise UserValueError("--workers applies to this machine; with --scheduler the cluster's workers build")
    if args.resume and args.overwrite:
        raise UserValueError("--resume and --overwrite exclude each other")
    if args.workers is None and not args.scheduler:
        args.workers = 2
    if args.workers is not None and not 0 <= args.workers <= 256:
        raise UserValueError(f"--workers = {args.workers} is out of range: allowed 0 to 256")
    if not args.resume:
        guard_output(args.out)
    if args.record_checksums is not None:
        guard_output(args.record_checksums, inputs=[args.out])
    from platebench.bench.sweep.executors import executor_for, run_sweep  # noqa: PLC0415
    with contextlib.ExitStack() as stack:
        executor = executor_for(stack, workers=args.workers, scheduler=args.scheduler, pipeline=args.pipeline)
        summary = run_sweep(split.spec, args.out, executor, resume=args.resume, overwrite=args.overwrite,
                            progress=args.progress, log=lambda m: print(m, file=sys.stderr))
    print(f"split       {split.name}: {summary.total} samples (sha256 {split.sha256[:12]})")
    print(f"built       {summary.ok + summary.failed} of {summary.total}"
          + (f" ({summary.skipped} before)" if summary.skipped else "")
          + (f", {summary.wall_s:.0f} s" if summary.run else ""))
    if summary.failed:
        print(f"note        the build's own method check failed on {summary.failed} sample(s) (results.csv); "
              "the benchmark's samples are its renders and ground truth")
    if summary.ok + summary.failed != summary.total:
        print(f"platebench: error: {args.out}: {summary.total - summary.ok - summary.failed} samples not built: "
              "run again with --resume", file=sys.stderr)
        return 1
    if args.record_checksums is not None:
        import json  # noqa: PLC0415

        from platebench.bench.benchmark.verify import checksums_of  # noqa: PLC0415
        from platebench.bench.io.atomic import write_text  # noqa: PLC0415
        doc = checksums_of(args.out, split)
        write_text(args.record_checksums, json.dumps(doc, sort_keys=True, separators=(",", ":")) + "\n")
        print(f"checksums   {args.record_checksums}")
    print(f"next        platebench benchmark verify {args.out}")
    return 0


def run_verify(args) -> int:
    from platebench.bench.benchmark.verify import verify_benchmark  # noqa: PLC0415
    from platebench.bench.progress import bar  # noqa: PLC0415
    split = _split_of(args.dataset, args.split)
    with bar(len(split.samples), "verify", "sample") as pbar:
        r = verify_benchmark(args.dataset, split, progress=lambda: pbar.update(1))
    print(f"split       {r.split}: {r.samples} samples, whole and intact")
    for n in r.notes:
        print(f"note        {n}")
    if not r.checked_truth:
        return 0
    print(f"truth       {'byte for byte' if not r.truth_differ else f'{len(r.truth_differ)} files differ'}")
    for f in r.truth_differ[:5]:
        print(f"  differs   {f}")
    same = r.variant == r.recorded_variant
    print(f"images      {r.images_bytes_equal} byte for byte" + ("" if same else
          f", {r.images_within_noise} within the render-noise limit (variant {r.variant}; checksums recorded on "
          f"{r.recorded_variant}; largest block-mean difference {r.max_block_frac:.2e} of full scale)")
          + (f", {len(r.images_differ)} differ" if r.images_differ else ""))
    for f in r.images_differ[:5]:
        print(f"  differs   {f}")
    print(f"verdict     {'this copy is ' + r.split if r.is_split else 'this copy is NOT ' + r.split}")
    return 0 if r.is_split else 1


def _outputs(items) -> list:
    from platebench.bench.benchmark.score import OutputsFolder  # noqa: PLC0415
    out = []
    for it in items:
        name, sep, folder = it.partition("=")
        if not sep or not name.strip() or not folder:
            raise UserValueError(f"--outputs {it!r}: write NAME=DIR (the name the folder is scored under)")
        p = Path(folder)
        if not p.is_dir():
            raise UserValueError(f"--outputs {it!r}: {folder} is not a folder")
        out.append(OutputsFolder(name.strip(), p))
    return out


def run_score(args) -> int:
    from platebench.bench.benchmark.leaderboard import ranking, write_results  # noqa: PLC0415
    from platebench.bench.benchmark.score import score_benchmark  # noqa: PLC0415
    from platebench.bench.benchmark.verify import NotTheSplitError, verify_benchmark  # noqa: PLC0415
    from platebench.bench.io.outputs import check_output  # noqa: PLC0415
    from platebench.bench.run.methods import get_method  # noqa: PLC0415

    methods = tuple(m.strip() for m in (args.methods or "").split(",") if m.strip())
    for m in methods:
        get_method(m)  # an unknown name is refused before any work
    outputs = _outputs(args.outputs)
    if not methods and not outputs:
        raise UserValueError("nothing to score: give --methods and/or --outputs NAME=DIR")
    if not 0 <= args.workers <= 64:
        raise UserValueError(f"--workers = {args.workers} is out of range: allowed 0 to 64")
    if args.method_time_limit_s is not None:
        from platebench.bench.run.plugins import check_time_limit  # noqa: PLC0415
        check_time_limit(args.method_time_limit_s)
    split = _split_of(args.dataset, args.split)
    check_output(args.out, "benchmark results", overwrite=args.overwrite,
                 inputs=[args.dataset, *[o.path for o in outputs]])  # before any work; again when written
    copy = verify_benchmark(args.dataset, split)  # whole and intact, else refused (NotTheSplitError)
    if copy.truth_differ or copy.images_differ:
        raise NotTheSplitError(f"{args.dataset} is not {split.name}: {len(copy.truth_differ)} ground-truth files and "
                               f"{len(copy.images_differ)} images differ from the published checksums (platebench "
                               "benchmark verify lists them)")
    summary = score_benchmark(args.dataset, split, methods=methods, outputs=outputs, workers=args.workers,
                              time_limit_s=args.method_time_limit_s, progress=args.progress,
                              say=lambda m: print(m, file=sys.stderr))
    sources = {m: "run by the bench" for m in methods} | {o.name: f"outputs folder {o.path.name}" for o in outputs}
    table = write_results(args.out, summary.rows, summary.sparse, split.name, split.sha256, methods=list(sources),
                          overwrite=args.overwrite, sources=sources, leaderboard=True,
                          inputs=[args.dataset, *[o.path for o in outputs]],
                          extra={"copy": {"compared_with_published_checksums": copy.checked_truth,
                                          "renderer_variant": copy.variant,
                                          "images_byte_for_byte": copy.images_bytes_equal,
                                          "images_within_render_noise": copy.images_within_noise}})
    ranks = ranking(table)
    print(f"split       {split.name}: {len(split.samples)} samples x {len(sources)} method(s), "
          f"{summary.wall_s:.0f} s")
    print("copy        " + ("the published split (ground truth byte for byte" + (
        ")" if not copy.images_within_noise else f"; {copy.images_within_noise} images within render noise)")
        if copy.checked_truth else "whole and intact; no published checksums to compare with"))
    print(f"{'rank':<5} {'method':<24} {'bad 2 mm %':>10} {'coverage':>9} {'ok':>5} {'failed':>7} {'missing':>8}")
    for r in ranks:
        print(f"{r.rank:<5} {r.method:<24} {r.primary:>10.2f} {r.coverage_frac:>9.3f} {r.n_ok:>5} {r.n_failed:>7} "
              f"{r.n_missing:>8}")
    print(f"written     {args.out}: results.parquet, results.csv, leaderboard.html and the Markdown leaderboard")
    if all(r.n_ok == 0 for r in ranks):
        print("platebench: error: no method produced an output on any sample (see results.csv)", file=sys.stderr)
        return 1
    return 1 if any(r.n_ok == 0 for r in ranks) else 0


def run_leaderboard(args) -> int:
    from platebench.bench.benchmark.leaderboard import merge, read_results, write_leaderboard  # noqa: PLC0415
    from platebench.bench.io.outputs import check_output  # noqa: PLC0415
    check_output(args.out, "leaderboard", overwrite=args.overwrite, inputs=list(args.results))
    table = merge([read_results(r) for r in args.results])
    ranks = write_leaderboard(table, args.out, overwrite=args.overwrite)
    for r in ranks:
        print(f"{r.rank:<5} {r.method:<24} {r.primary:>10.2f} {r.coverage_frac:>9.3f}")
    print(f"written     {args.out}: leaderboard.html and the Markdown leaderboard")
    return 0
