"""``platebench sweep``: expand a sweep spec into samples; render, reconstruct and score each.

The spec format is documented in ``bench/sweep/spec.py``, the dataset layout in
``bench/sweep/dataset.py`` and ``bench/io/layout.py``, the executors in ``bench/sweep/executors.py``.

Exit status (``bench/cli/main.py``): 0 when every sample of the dataset is done and ok; 1 when a
sample failed (its failure is recorded in the dataset, the others are kept; a sample fails when one
of its methods does) or when the dataset holds no sample that is ok, with one summary line on
stderr; 2 for a spec or flag refused before any work.

The example specs ship with the package (``platebench.examples``, the files ``examples/*.toml``):
``--example NAME`` runs the one whose file is NAME.toml from anywhere, read with
``importlib.resources``; exactly one of SPEC.toml and ``--example`` is given.
"""
from __future__ import annotations

import contextlib
import math
import sys
from importlib import resources
from pathlib import Path

from platebench.errors import UserValueError

HELP = "run a sweep spec: many samples rendered, reconstructed and scored into a dataset"


EXAMPLES_PACKAGE = "platebench.examples"


def example_names() -> list[str]:
    """The example specs the package ships (the stems of its ``*.toml`` files), sorted."""
    try:
        root = resources.files(EXAMPLES_PACKAGE)
    except ModuleNotFoundError:
        return []
    return sorted(e.name[: -len(".toml")] for e in root.iterdir() if e.name.endswith(".toml") and e.is_file())


def example_spec(name: str, stack: contextlib.ExitStack) -> Path:
    """The file of the example spec ``name`` (a real path while ``stack`` is open); UserValueError
    (one line naming the allowed names) for any other name."""
    names = example_names()
    if name not in names:
        raise UserValueError(f"--example {name!r} is not an example spec: allowed {', '.join(names) or 'none'}")
    return stack.enter_context(resources.as_file(resources.files(EXAMPLES_PACKAGE) / f"{name}.toml"))


def add_parser(sub) -> None:
    p = sub.add_parser(
        "sweep", help=HELP,
        description="Expand SPEC.toml (grids or seeded random draws over plate family, bend, size, material, "
                    "distance and pose, pattern, noise, resolution, spp, seed; see bench/sweep/spec.py) into "
                    "samples, validate all of them, then render, reconstruct and score each one. DATASET gets "
                    "manifest.json, results.csv and results.parquet (one row per sample and method) and "
                    "samples/<id>/. Runs on a local process pool (--workers) or a Dask cluster (--scheduler). "
                    "A failing sample is recorded (status failed) and the sweep goes on; --resume continues an "
                    "interrupted sweep without redoing finished samples.")
    p.add_argument("spec", type=Path, nargs="?", metavar="SPEC.toml",
                   help="sweep spec (TOML); or --example NAME instead")
    p.add_argument("--example", metavar="NAME",
                   help="run an example spec shipped with the package instead of SPEC.toml: "
                        + (", ".join(example_names()) or "none installed"))
    p.add_argument("--out", type=Path, metavar="DATASET", help="dataset directory (required, except with --dry-run)")
    p.add_argument("--workers", type=int, default=None,
                   help="local worker processes (default 1; 0 runs in this process); not with --scheduler")
    p.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                   help="run on this Dask distributed scheduler instead (workers need this package and see "
                        "DATASET at the same path)")
    p.add_argument("--pipeline", action="store_true",
                   help="render and finish each sample in two stages that overlap: one worker owns the renderer "
                        "(the GPU where there is one) and renders, --workers CPU workers write, reconstruct and "
                        "score (a local Dask cluster); with --scheduler, the cluster's workers started with "
                        "--resources GPU=1 render and those with --resources CPU=1 finish")
    p.add_argument("--connect-timeout-s", type=float, default=10.0,
                   help="with --scheduler: seconds to reach the scheduler before giving up (default 10)")
    p.add_argument("--worker-timeout-s", type=float, default=60.0,
                   help="with --scheduler: seconds without any worker before the sweep stops with an error "
                        "(default 60; the dataset is kept for --resume)")
    p.add_argument("--methods", help="comma-separated reconstruction methods, overriding the spec's")
    p.add_argument("--method-time-limit-s", type=float, default=None, metavar="S",
                   help="the longest a plug-in method may run on one sample, seconds (default: the spec's "
                        "sweep.method_time_limit_s, else 600; 1 to 86400): one that takes longer is stopped and "
                        "recorded as that method's failure")
    p.add_argument("--resume", action="store_true", help="continue DATASET: skip samples whose result is done")
    p.add_argument("--retry-failed", action="store_true", help="with --resume, run failed samples again")
    p.add_argument("--overwrite", action="store_true", help="replace a sweep DATASET 'platebench sweep' wrote "
                   "(nothing else is replaced: a file no sample lists in it is refused)")
    p.add_argument("--dry-run", action="store_true", help="validate and list the samples; render nothing")
    p.add_argument("--progress", dest="progress", action="store_true", default=None,
                   help="show the progress bar even when stderr is not a terminal")
    p.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bar")
    p.set_defaults(run=run)


def _methods(text: str | None):
    if text is None:
        return None
    return tuple(m.strip() for m in text.split(",") if m.strip())


def run(args) -> int:
    with contextlib.ExitStack() as examples:
        if (args.spec is None) == (args.example is None):
            raise UserValueError("give exactly one of SPEC.toml and --example NAME (allowed: "
                                 f"{', '.join(example_names())})")
        if args.example is not None:
            args.spec = example_spec(args.example, examples)
        return _run(args)


def _run(args) -> int:
    from platebench.bench.io.outputs import guard_output  # noqa: PLC0415
    from platebench.bench.sweep.spec import load_spec  # noqa: PLC0415

    if args.scheduler and args.workers is not None:
        raise UserValueError("--workers applies to this machine; with --scheduler the cluster's workers run the sweep")
    if args.retry_failed and not args.resume:
        raise UserValueError("--retry-failed goes with --resume")
    if args.resume and args.overwrite:
        raise UserValueError("--resume and --overwrite exclude each other")
    if args.method_time_limit_s is not None:
        from platebench.bench.run.plugins import check_time_limit  # noqa: PLC0415
        check_time_limit(args.method_time_limit_s)
    spec = load_spec(args.spec, _methods(args.methods))  # every sample validated before anything is written
    if args.dry_run:
        print(f"spec        {args.example or args.spec} ({spec.mode}, {len(spec.samples)} samples, methods {', '.join(spec.methods)})")
        for s in spec.samples:
            print(f"  {s.sample_id}  {s.params}")
        if spec.duplicates:
            print(f"note: {spec.duplicates} duplicate samples dropped")
        for k, n in spec.ignored.items():
            print(f"note: axis {k} does not apply to {n} samples (ignored there)")
        return 0
    if args.out is None:
        raise UserValueError("--out DATASET is required (only --dry-run runs without it)")
    if not args.resume:  # the output rule (bench.io.outputs): a new or replaced dataset never holds its spec
        guard_output(args.out, inputs=[args.spec])
    for flag, v in (("--connect-timeout-s", args.connect_timeout_s), ("--worker-timeout-s", args.worker_timeout_s)):
        if not math.isfinite(v) or not 1.0 <= v <= 86400.0:
            raise UserValueError(f"{flag} = {v} is out of range: allowed 1 to 86400 s")
    from platebench.bench.sweep.executors import run_sweep  # noqa: PLC0415  (after the spec and flags are checked)

    with contextlib.ExitStack() as stack:
        from platebench.bench.sweep.executors import executor_for  # noqa: PLC0415
        executor = executor_for(stack, workers=args.workers, scheduler=args.scheduler, pipeline=args.pipeline,
                                connect_timeout_s=args.connect_timeout_s, worker_timeout_s=args.worker_timeout_s)
        summary = run_sweep(spec, args.out, executor, resume=args.resume, overwrite=args.overwrite,
                            retry_failed=args.retry_failed, progress=args.progress,
                            log=lambda m: print(m, file=sys.stderr), method_time_limit_s=args.method_time_limit_s)
    ex = summary.executor
    where = f"dask {ex.get('scheduler')} ({ex.get('workers')} workers)" if ex.get("kind") == "dask" else \
        (f"local, {ex.get('workers')} worker(s)" if ex.get("workers") else "in-process")
    if ex.get("kind") == "dask-pipeline":
        where = (f"pipeline on dask {ex.get('scheduler')}: {ex.get('render_workers')} render worker(s), "
                 f"{ex.get('finish_workers')} CPU worker(s), at most {ex.get('max_in_flight')} samples in flight")
    print(f"sweep       {spec.name}: {summary.total} samples x {len(spec.methods)} method(s), {where}")
    print(f"done        {summary.ok} ok, {summary.failed} failed"
          + (f" ({summary.skipped} already done before)" if summary.skipped else ""))
    if summary.run:
        print(f"time        {summary.wall_s:.1f} s for {summary.run} samples ({summary.samples_per_min:.1f} samples/min)")
    failed = [r for r in summary.results.values() if r.status == "failed"]
    for r in sorted(failed, key=lambda r: r.index or 0)[:5]:
        print(f"failed      {r.sample_id}: {r.error}")
    if len(failed) > 5:
        print(f"failed      ... and {len(failed) - 5} more (see results.csv)")
    out = summary.dataset
    print(f"written     {out / 'manifest.json'}, {out / 'results.csv'}, {out / 'results.parquet'}")
    return _status(summary)


def _status(summary) -> int:
    """The exit status of a finished sweep (module doc), its summary line printed on stderr when not 0."""
    if summary.failed or summary.ok == 0:
        what = "every sample failed" if summary.failed and summary.failed == summary.total else \
            "some samples failed" if summary.failed else "no sample gave a result"
        print(f"platebench: sweep {summary.dataset}: {what}: {summary.ok} ok, {summary.failed} failed of "
              f"{summary.total} (recorded in results.csv)", file=sys.stderr)
        return 1
    return 0
