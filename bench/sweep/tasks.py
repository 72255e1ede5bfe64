"""One sweep sample as a task: render, reconstruct with each method, evaluate, record.

``run_sample(task)`` is what every executor runs (local process pool, in-process, or a
Dask worker). It writes only into a private attempt directory
(``samples/.tmp-<id>~HOST~PID~R``, see ``dataset.make_attempt_dir``) and returns the sample's
``SampleResult`` (status, rows, checksums of every file it wrote, the attempt directory): one writer
per sample, since only the sweep process commits a result (``dataset.commit_sample``:
checksums verified, ``result.json`` written, the directory renamed to ``samples/<id>``).
A worker that outlives its scheduler, or a second attempt of the same sample, writes into
its own attempt directory that nobody commits. Any error of the sample (rendering, a
method, scoring) is caught and recorded in the result with status "failed": it never
stops the sweep; a sample is failed only by its own work. An error of the output itself (a full
disk, a read-only or vanished dataset: ``bench.io.fs_errors``) is no sample's failure: the attempt is
removed and the error raised, and the sweep stops.

Each worker process keeps one ``PlateRenderer`` (module global) and passes it back to
``render_sample`` for its next sample, so compiled kernels are reused. A lock makes
samples of one process run one at a time (run Dask workers with ``--nthreads 1``).

The methods a sample runs come from the registry ``reconstruction.methods`` (``bench.run.methods.get_method``).
Each task first loads the installed packages' families, metrics and cure rules in its process
(``bench.run.extensions.load_extensions``, once per process), so that a spawned or Dask worker knows them.
"""
from __future__ import annotations

import json
import os
import resource
import shutil
import socket
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

from platebench.bench.config import SampleConfig
from platebench.bench.io.codecs import decode, encode
from platebench.bench.io.fs_errors import environmental
from platebench.bench.io.layout import RECON, SAMPLE, method_folder
from platebench.bench.io.sample_files import write_sample
from platebench.bench.io.sweep_records import MethodRun, SampleResult, SampleTimings
from platebench.bench.run.extensions import load_extensions
from platebench.bench.run.methods import MethodContext, get_method
from platebench.bench.run.render import posed_scene, render_sample
from platebench.bench.run.workers import die_with_parent, set_render_threads
from platebench.bench.sweep.dataset import make_attempt_dir, now_utc, tree_checksums


# ----------------------------------------------------------------------------- tasks
@dataclass(frozen=True)
class SampleTask:
    """What a worker needs for one sample (plain data: picklable, no arrays)."""

    dataset: str  # absolute path of the dataset directory (shared with the workers)
    sample_id: str
    index: int
    config: dict  # a SampleConfig's form
    pose: dict | None
    methods: tuple
    config_sha256: str
    params: dict = field(default_factory=dict)
    redo_failed: bool = False  # a valid result.json with status "failed" does not count as done
    method_time_limit_s: float | None = None  # the longest a plug-in may run on the sample (None: the default)


def tasks_from_spec(spec, dataset: Path, redo_failed: bool = False,
                    method_time_limit_s: float | None = None) -> list[SampleTask]:
    """The spec's samples as tasks; ``method_time_limit_s`` (a flag) overrides the spec's own limit."""
    ds = str(Path(dataset).resolve())
    limit = method_time_limit_s if method_time_limit_s is not None else spec.method_time_limit_s
    return [SampleTask(ds, p.sample_id, p.index, encode(p.config), p.pose, tuple(spec.methods), p.config_sha256,
                       p.params, redo_failed, limit) for p in spec.samples]




# ----------------------------------------------------------------------------- worker state
_STATE = {"renderer": None, "samples": 0, "parent": None}
_LOCK = threading.Lock()


def worker_init(parent_pid: int | None = None, render_threads: int | None = None) -> None:
    """Initializer of local pool workers: die with the parent (``workers.die_with_parent``), so a
    sweep killed with -9 leaves no worker writing behind it; share the CPU cores between workers. (They
    start with SIGINT blocked: ``interrupts.children_without_sigint``.)"""
    _STATE["parent"] = parent_pid
    _STATE["render_threads"] = render_threads if set_render_threads(render_threads) else None
    die_with_parent(parent_pid)


def worker_info() -> dict:
    r = _STATE["renderer"]
    return {"host": socket.gethostname(), "pid": os.getpid(),
            "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,  # Linux: KiB
            "samples_in_process": _STATE["samples"], "render_threads": _STATE.get("render_threads"),
            "scene_builds": getattr(r, "scene_builds", None)}


def _error_text(e: BaseException) -> str:
    msg = str(e).strip().splitlines()[0] if str(e).strip() else ""
    text = f"{type(e).__name__}: {msg}" if msg else type(e).__name__
    return text[:500]


def failed_result(task: SampleTask, error: str | None, phase: str | None = "executor") -> SampleResult:
    """A result for a sample whose task could not run at all (e.g. its worker kept dying)."""
    return SampleResult(task.sample_id, task.index, task.config_sha256, "failed", error, phase, task.params,
                        task.config, task.pose, tuple(task.methods),
                        rows=tuple(MethodRun.failed(m, error) for m in task.methods), finished_utc=now_utc())


def pose_supported() -> str | None:
    """Why pose axes cannot run in this build (None: they can)."""
    return None


def run_sample(task: SampleTask) -> SampleResult:
    """Make one sample into a private staging directory and return its result (see module doc)."""
    load_extensions()
    with _LOCK:
        return _run_sample(task)


def _run_sample(task: SampleTask) -> SampleResult:
    stage = make_attempt_dir(Path(task.dataset), task.sample_id)
    try:
        return _make_sample(task, stage)
    except BaseException:  # an error of the output (a full disk, ...) or an interrupt: this attempt is void
        shutil.rmtree(stage, ignore_errors=True)
        raise


def _render(task: SampleTask) -> tuple:
    """(the sample in memory or None, its error text or None, seconds) with this process's renderer."""
    t = time.perf_counter()
    try:
        cfg = decode(SampleConfig, task.config)
        kwargs = {}
        if task.pose:
            kwargs["scene"] = posed_scene(cfg.scene.build(), cfg.scene.distance_m, task.pose)
        renderer = _STATE["renderer"]
        if renderer is not None and cfg.variant and renderer.variant != cfg.variant:
            renderer = None
        try:
            sample, renderer = render_sample(cfg, renderer, **kwargs)
        except BaseException:
            _STATE["renderer"] = None  # its state is unknown now: start afresh next time
            raise
        _STATE["renderer"] = renderer
        return sample, None, time.perf_counter() - t
    except Exception as e:  # noqa: BLE001  (recorded, the sweep goes on)
        if environmental(e, Path(task.dataset)):
            raise  # the output's fault, not the sample's: the run stops (bench.io.fs_errors)
        return None, _error_text(e), time.perf_counter() - t


def _make_sample(task: SampleTask, stage: Path) -> SampleResult:
    t0 = time.perf_counter()
    sample, error, render_s = _render(task)
    return _complete(task, stage, sample, error, render_s, t0)


def _complete(task: SampleTask, stage: Path, sample, error: str | None, render_s: float, t0: float) -> SampleResult:
    """Write the rendered ``sample`` (or record ``error``) into ``stage``, run the methods on it, and
    return the sample's result."""
    status, phase, rows, write_s = "ok", None, [], None
    variant = false_boundary_gt = None
    images: dict = {}
    written = False
    try:
        if error is not None:
            raise _RenderFailed(error)
        t = time.perf_counter()
        write_sample(stage / SAMPLE, sample, overwrite=False)
        write_s = time.perf_counter() - t
        variant = sample.variant
        false_boundary_gt = bool(any(v.false_boundary for v in sample.visibility.values()))
        images = json.loads((stage / SAMPLE / "sample.json").read_text()).get("images", {})
        written = True
    except Exception as e:  # noqa: BLE001  (recorded, the sweep goes on)
        if environmental(e, Path(task.dataset)):
            raise  # the output's fault, not the sample's: the run stops (bench.io.fs_errors)
        error = str(e) if isinstance(e, _RenderFailed) else _error_text(e)
        status, phase = "failed", "render"
        rows = [MethodRun.failed(m, error) for m in task.methods]
    del sample
    if written:  # methods run only on a sample that was rendered AND written: one row per method, always
        for name in task.methods:
            ctx = MethodContext(stage / SAMPLE, stage / RECON / method_folder(name), _STATE["renderer"], task.pose,
                                task.method_time_limit_s)
            try:
                out = get_method(name).run(ctx)
                row = MethodRun(name, "ok", None, out.metrics.columns(), out.time_recon_s, out.time_eval_s,
                                out.time_render_extra_s)
            except Exception as e:  # noqa: BLE001
                if environmental(e, Path(task.dataset)):
                    raise
                row = MethodRun.failed(name, _error_text(e))
            rows.append(row)
        failed = [r for r in rows if r.status != "ok"]
        if failed:
            status, phase = "failed", "method"
            error = "; ".join(f"{r.method}: {r.error}" for r in failed)[:1000]
    files = tree_checksums(stage)  # every file of the sample; --resume checks them all
    _STATE["samples"] += 1
    timings = SampleTimings(render_s, write_s, time.perf_counter() - t0)
    # the sweep process verifies the files and commits the sample (dataset.commit_sample)
    return SampleResult(task.sample_id, task.index, task.config_sha256, status, error, phase, task.params,
                        task.config, task.pose, tuple(task.methods), variant, false_boundary_gt, tuple(rows), timings,
                        files, images, worker_info(), now_utc(), stage=str(stage))


class _RenderFailed(Exception):
    """A sample whose rendering failed (its error text, recorded as the sample's)."""


# ----------------------------------------------------------------------------- two stages
@dataclass(frozen=True)
class RenderedTask:
    """What the render stage hands the finish stage: the sample in memory (or the error that stopped
    its rendering), or, when one of the sample's methods renders too (its pattern sequences need
    the renderer), the whole sample's result, made where the renderer is."""

    sample: object  # bench.run.render.RenderedSample, or None
    error: str | None
    render_s: float
    result: SampleResult | None = None
    render_worker: dict | None = None


def needs_renderer(task: SampleTask) -> bool:
    """True when a method of ``task`` renders (the structured-light peers' sequences)."""
    return any(get_method(m).rerenders_from_config for m in task.methods)


def render_stage(task: SampleTask) -> RenderedTask:
    """The first of a sample's two stages, on the worker that owns the renderer (the GPU): the sample
    rendered in memory, nothing written. A sample with a method that renders is made whole here."""
    load_extensions()
    with _LOCK:
        if needs_renderer(task):
            return RenderedTask(None, None, 0.0, _run_sample(task), worker_info())
        sample, error, render_s = _render(task)
        return RenderedTask(sample, error, render_s, None, worker_info())


def finish_stage(task: SampleTask, rendered: RenderedTask) -> SampleResult:
    """The second stage, on any CPU worker: write the rendered sample into a private attempt directory,
    run the methods, return the sample's result (as ``run_sample`` does)."""
    if rendered.result is not None:
        return rendered.result
    load_extensions()
    with _LOCK:
        t0 = time.perf_counter() - rendered.render_s
        stage = make_attempt_dir(Path(task.dataset), task.sample_id)
        try:
            res = _complete(task, stage, rendered.sample, rendered.error, rendered.render_s, t0)
        except BaseException:
            shutil.rmtree(stage, ignore_errors=True)
            raise
        return replace(res, render_worker=rendered.render_worker)
