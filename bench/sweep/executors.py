"""Run a sweep's samples: embedded process pool (default) or a Dask distributed cluster.

``run_sweep(spec, out, executor)`` is the sweep: it checks the output directory, sweeps
leftovers of interrupted runs, writes the manifest (every sample "pending"), skips
samples already done (``--resume``), hands the rest to the executor, records each
result as it arrives (progress bar with counts, ETA and failures), and rewrites
``manifest.json`` and ``results.csv``/``results.parquet`` atomically (every few
seconds and at the end, also after Ctrl-C).

Executors yield ``(task, result, exception)`` as samples finish:

* ``LocalExecutor(workers)``: ``concurrent.futures.ProcessPoolExecutor`` with the
  spawn context; no server. Each worker process keeps one renderer (``bench.jobs``).
  Workers die with the sweep process (PR_SET_PDEATHSIG). If a worker dies (killed,
  out of memory) the pool is rebuilt and the samples it was running are retried
  (``retries`` times; the task is idempotent), the others resubmitted. ``workers=0``
  runs in this process (debugging).
* ``DaskExecutor(address)``: ``distributed.Client`` on a running scheduler
  (``tcp://HOST:PORT``); tasks are submitted with ``retries=2``; a worker lost
  mid-task has its task rescheduled by the scheduler. Workers must import this
  package (same code, same environment) and see DATASET at the same path (shared
  filesystem). Run workers with ``--nthreads 1`` (one renderer per process).
* ``LoopbackCluster(n)``: starts a real ``dask scheduler`` and ``n`` ``dask worker``
  processes on 127.0.0.1 (free ports), for tests and benchmarks; always torn down.
"""
from __future__ import annotations

import contextlib
import multiprocessing
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path

from platebench.bench.sweep import dataset as ds
from platebench.bench.sweep.tasks import (
    SampleTask,
    failed_result,
    run_sample,
    tasks_from_spec,
    worker_init,
)
from platebench.errors import UserValueError


class ExecutorError(UserValueError):
    """The executor cannot run (scheduler unreachable, no workers): one-line message."""


class WorkerLost(RuntimeError):
    """A sample's worker process died more often than its retries allow."""


# ----------------------------------------------------------------------------- local pool
_START_QUEUE = None


def _pool_init(parent_pid: int, queue, render_threads: int | None) -> None:
    global _START_QUEUE
    _START_QUEUE = queue
    worker_init(parent_pid, render_threads)


def _pool_task(task: SampleTask) -> dict:
    if _START_QUEUE is not None:
        _START_QUEUE.put((os.getpid(), task.sample_id))
    return run_sample(task)


class LocalExecutor:
    """Embedded executor: a spawn-context process pool of ``workers`` processes (0: this process)."""

    def __init__(self, workers: int = 1, retries: int = 2, render_threads: int | None = None):
        if not isinstance(workers, int) or not 0 <= workers <= 256:
            raise ExecutorError(f"--workers = {workers!r} is out of range: allowed 0 to 256")
        self.workers = workers
        self.retries = retries
        self.render_threads = render_threads  # None: cores // workers (if scenes.runtime can set it)
        self._pool = None

    def describe(self) -> dict:
        return {"kind": "local", "workers": self.workers, "start_method": "spawn" if self.workers else "in-process",
                "retries": self.retries}

    def run(self, tasks: list[SampleTask]):
        if self.workers == 0:
            for t in tasks:
                try:
                    yield t, run_sample(t), None
                except Exception as e:  # noqa: BLE001
                    yield t, None, e
            return
        ctx = multiprocessing.get_context("spawn")
        pending = {t.sample_id: t for t in tasks}
        attempts: Counter = Counter()
        while pending:
            queue = ctx.Queue()
            n = min(self.workers, len(pending))
            pool = ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_pool_init,
                                       initargs=(os.getpid(), queue, self.render_threads or
                                                 max(1, (os.cpu_count() or 1) // self.workers)))
            self._pool = pool
            futures = {pool.submit(_pool_task, t): t for t in pending.values()}
            started: dict = {}
            broken = aborted = False
            try:
                not_done = set(futures)
                while not_done and not broken:
                    done, not_done = wait(not_done, timeout=1.0, return_when=FIRST_COMPLETED)
                    _drain(queue, started)
                    for f in done:
                        t = futures[f]
                        exc = f.exception()
                        if isinstance(exc, BrokenProcessPool):
                            broken = True
                            continue
                        pending.pop(t.sample_id, None)
                        yield (t, f.result(), None) if exc is None else (t, None, exc)
                if broken:  # collect what finished before the break; the rest is retried
                    _drain(queue, started)
                    for f, t in futures.items():
                        if t.sample_id in pending and f.done() and not f.cancelled() and f.exception() is None:
                            pending.pop(t.sample_id)
                            yield t, f.result(), None
            except BaseException:  # Ctrl-C, or the consumer stopped: close(terminate=True) stops the workers
                aborted = True
                raise
            finally:
                if aborted:
                    _terminate(pool)
                else:
                    pool.shutdown(wait=not broken, cancel_futures=True)
                    self._pool = None
                    queue.close()
            if broken:
                suspects = {sid for sid in started.values() if sid in pending}
                for sid in suspects or set(pending):
                    attempts[sid] += 1
                for sid in list(pending):
                    if attempts[sid] > self.retries:
                        t = pending.pop(sid)
                        yield t, None, WorkerLost(f"worker process died {attempts[sid]} times while running it")

    def close(self, terminate: bool = False) -> None:
        """Shut the pool down; ``terminate``: also stop the samples in flight (after Ctrl-C)."""
        pool, self._pool = self._pool, None
        if pool is not None:
            if terminate:
                _terminate(pool)
            else:
                pool.shutdown(wait=False, cancel_futures=True)


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Stop a pool now: cancel what is queued, terminate the workers (their staged writes are left as
    ``.tmp-*`` leftovers, swept by the next run)."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(timeout=10)


def _drain(queue, started: dict) -> None:
    import queue as _q  # noqa: PLC0415
    while True:
        try:
            pid, sid = queue.get_nowait()
        except (_q.Empty, OSError, ValueError, EOFError):
            return
        started[pid] = sid  # a pid runs one sample at a time: the latest is the one in flight


# ----------------------------------------------------------------------------- Dask
class DaskExecutor:
    """Runs the samples on a Dask distributed cluster through ``distributed.Client``."""

    def __init__(self, address: str, retries: int = 2, connect_timeout_s: float = 10.0,
                 worker_timeout_s: float = 120.0):
        if not isinstance(address, str) or "://" not in address:
            raise ExecutorError(f"--scheduler = {address!r} is not an address: allowed tcp://HOST:PORT")
        self.address = address
        self.retries = retries
        self.connect_timeout_s = connect_timeout_s
        self.worker_timeout_s = worker_timeout_s
        self._client = None
        self._futures = []
        self._workers = None

    def describe(self) -> dict:
        return {"kind": "dask", "scheduler": self.address, "workers": self._workers, "retries": self.retries}

    def connect(self):
        if self._client is None:
            from distributed import Client  # noqa: PLC0415
            try:
                self._client = Client(self.address, timeout=f"{self.connect_timeout_s}s", set_as_default=False)
            except (OSError, TimeoutError) as e:
                raise ExecutorError(f"cannot reach the Dask scheduler at {self.address}: "
                                    f"{str(e).splitlines()[0] if str(e) else type(e).__name__}") from None
            try:
                self._client.wait_for_workers(1, timeout=self.worker_timeout_s)
            except (TimeoutError, OSError):
                self.close()
                raise ExecutorError(f"no Dask worker joined {self.address} within {self.worker_timeout_s:g} s") from None
            self._workers = len(self._client.scheduler_info().get("workers", {}))
        return self._client

    def run(self, tasks: list[SampleTask]):
        from distributed import as_completed  # noqa: PLC0415
        client = self.connect()
        by_key = {}
        tag = ds.text_sha256(tasks[0].dataset)[:10] if tasks else ""
        for t in tasks:
            key = f"platebench-sample-{tag}-{t.sample_id}-{t.config_sha256[:12]}"
            fut = client.submit(run_sample, t, key=key, pure=False, retries=self.retries)
            by_key[fut.key] = t
            self._futures.append(fut)
        for fut in as_completed(self._futures, loop=client.loop):
            t = by_key[fut.key]
            if fut.status == "finished":
                try:
                    yield t, fut.result(), None
                except Exception as e:  # noqa: BLE001
                    yield t, None, e
            else:
                try:
                    exc = fut.exception()
                except Exception as e:  # noqa: BLE001  (cancelled, lost)
                    exc = e
                yield t, None, exc
            fut.release()
        self._futures = []

    def close(self, terminate: bool = False) -> None:
        if self._client is not None:
            with contextlib.suppress(Exception):
                if self._futures:
                    self._client.cancel(self._futures)
            with contextlib.suppress(Exception):
                self._client.close(timeout=10)
            self._client = None
            self._futures = []


# ----------------------------------------------------------------------------- loopback cluster
def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def dask_cli() -> list[str]:
    """The ``dask`` command of this environment."""
    exe = Path(sys.executable).parent / "dask"
    if exe.exists():
        return [str(exe)]
    found = shutil.which("dask")
    if found:
        return [found]
    return [sys.executable, "-m", "dask"]


class LoopbackCluster:
    """A real ``dask scheduler`` + ``n_workers`` ``dask worker`` processes on 127.0.0.1.

    Every process runs in its own session (process group) so that ``kill_worker`` can
    kill -9 a worker with its nanny, and ``close`` tears everything down (SIGTERM, then
    SIGKILL after a bounded wait). Logs go to files in ``log_dir``.
    """

    def __init__(self, n_workers: int = 2, nthreads: int = 1, startup_timeout_s: float = 90.0,
                 log_dir: Path | None = None, env: dict | None = None):
        self.n_workers = n_workers
        self.nthreads = nthreads
        self.startup_timeout_s = startup_timeout_s
        self._tmp = tempfile.mkdtemp(prefix="platebench-dask-")
        self.log_dir = Path(log_dir) if log_dir else Path(self._tmp)
        self.env = dict(os.environ)  # workers import platebench from this same environment
        self.env.update(env or {})
        self.port = None
        self.scheduler = None
        self.workers: list[subprocess.Popen] = []
        self._logs = []

    @property
    def address(self) -> str:
        return f"tcp://127.0.0.1:{self.port}"

    def _spawn(self, args: list[str], name: str) -> subprocess.Popen:
        log = open(self.log_dir / f"{name}.log", "wb")  # noqa: SIM115
        self._logs.append(log)
        return subprocess.Popen(dask_cli() + args, stdout=log, stderr=subprocess.STDOUT, env=self.env,
                                cwd=self._tmp, start_new_session=True)

    def start(self) -> "LoopbackCluster":
        deadline = time.monotonic() + self.startup_timeout_s
        for attempt in range(3):
            self.port = free_port()
            self.scheduler = self._spawn(["scheduler", "--host", "127.0.0.1", "--port", str(self.port),
                                          "--no-dashboard"], f"scheduler-{attempt}")
            if self._wait_port(deadline):
                break
            self._stop(self.scheduler)
        else:
            raise ExecutorError(f"dask scheduler did not start: see {self.log_dir}")
        for i in range(self.n_workers):
            self.start_worker(i)
        self.wait_for_workers(self.n_workers, max(deadline - time.monotonic(), 1.0))
        return self

    def start_worker(self, i: int | None = None) -> subprocess.Popen:
        i = len(self.workers) if i is None else i
        wdir = Path(self._tmp) / f"worker-{i}-{len(self.workers)}"
        wdir.mkdir(parents=True, exist_ok=True)
        p = self._spawn(["worker", self.address, "--nthreads", str(self.nthreads), "--nworkers", "1",
                         "--no-dashboard", "--host", "127.0.0.1", "--name", f"w{i}-{len(self.workers)}",
                         "--local-directory", str(wdir)], f"worker-{len(self.workers)}")
        self.workers.append(p)
        return p

    def _wait_port(self, deadline: float) -> bool:
        while time.monotonic() < deadline:
            if self.scheduler.poll() is not None:
                return False
            with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
                s.settimeout(0.5)
                if s.connect_ex(("127.0.0.1", self.port)) == 0:
                    return True
            time.sleep(0.1)
        return False

    def wait_for_workers(self, n: int, timeout_s: float) -> None:
        from distributed import Client  # noqa: PLC0415
        with Client(self.address, timeout="30s", set_as_default=False) as c:
            try:
                c.wait_for_workers(n, timeout=timeout_s)
            except TimeoutError:
                raise ExecutorError(f"{n} dask workers did not join within {timeout_s:.0f} s: see {self.log_dir}") \
                    from None

    def worker_pids(self) -> dict:
        """Worker address -> pid of the worker process (inside its nanny)."""
        from distributed import Client  # noqa: PLC0415
        with Client(self.address, timeout="30s", set_as_default=False) as c:
            return c.run(os.getpid)

    def kill_worker(self, i: int) -> None:
        """kill -9 worker ``i`` (nanny and worker process: the whole process group)."""
        p = self.workers[i]
        with contextlib.suppress(ProcessLookupError):
            os.killpg(p.pid, signal.SIGKILL)
        with contextlib.suppress(subprocess.TimeoutExpired):
            p.wait(timeout=10)

    @staticmethod
    def _stop(p: subprocess.Popen | None, timeout_s: float = 10.0) -> None:
        if p is None:
            return
        for sig, wait_s in ((signal.SIGTERM, timeout_s), (signal.SIGKILL, 5.0)):
            if p.poll() is not None:
                break
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, sig)
            with contextlib.suppress(subprocess.TimeoutExpired):
                p.wait(timeout=wait_s)
        # the group may hold children whose leader is gone (nanny's worker)
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(p.pid, signal.SIGKILL)

    def close(self) -> None:
        for p in self.workers:
            self._stop(p, 5.0)
        self._stop(self.scheduler, 5.0)
        for log in self._logs:
            with contextlib.suppress(Exception):
                log.close()
        shutil.rmtree(self._tmp, ignore_errors=True)

    def __enter__(self) -> "LoopbackCluster":
        try:
            return self.start()
        except BaseException:
            self.close()
            raise

    def __exit__(self, *exc) -> None:
        self.close()


# ----------------------------------------------------------------------------- the sweep
@dataclass
class SweepSummary:
    dataset: Path
    total: int
    skipped: int
    run: int
    ok: int
    failed: int
    wall_s: float
    results: dict  # sample id -> result dict
    executor: dict
    interrupted: bool = False
    worker_stats: dict = field(default_factory=dict)  # "host:pid" -> {"samples", "maxrss_mb"}

    @property
    def samples_per_min(self) -> float:
        return 60.0 * self.run / self.wall_s if self.wall_s > 0 else float("nan")


def worker_stats(results) -> dict:
    out: dict = {}
    for res in results:
        w = res.get("worker") or {}
        if not w or res.get("cached"):
            continue
        k = f"{w.get('host')}:{w.get('pid')}"
        e = out.setdefault(k, {"samples": 0, "maxrss_mb": 0.0})
        e["samples"] += 1
        e["maxrss_mb"] = max(e["maxrss_mb"], float(w.get("maxrss_mb") or 0.0))
    return out


def run_sweep(spec, out: Path, executor=None, resume: bool = False, overwrite: bool = False,
              retry_failed: bool = False, progress: bool | None = None, flush_every_s: float = 5.0,
              log=None, on_result=None) -> SweepSummary:
    """Run ``spec`` into dataset directory ``out`` (see module doc); returns a summary.

    ``on_result(result_dict)`` is called as each sample finishes (in this process)."""
    from platebench.bench.progress import bar  # noqa: PLC0415
    out = Path(out).resolve()
    executor = executor if executor is not None else LocalExecutor(1)
    ds.prepare_dataset(out, spec, resume, overwrite)
    say = log or (lambda msg: None)
    old = ds.read_manifest(out) if resume else None
    started = (old or {}).get("created_utc") or ds.now_utc()
    packages = ds.package_versions()
    results: dict = {}
    todo = []
    for task in tasks_from_spec(spec, out, redo_failed=retry_failed):
        res = ds.validate_result(out, task.sample_id, task.config_sha256) if resume else None
        if res is not None and (res["status"] == "ok" or not retry_failed):
            res["_result_sha256"] = ds.file_sha256(ds.sample_dir(out, task.sample_id) / ds.RESULT)
            results[task.sample_id] = res
        else:
            todo.append(task)
    skipped = len(results)
    desc = executor.describe()

    def flush(state: str) -> None:
        ds.write_results(out, list(results.values()))
        ds.write_manifest(out, ds.manifest_dict(spec, results, executor.describe(), started, state, packages))

    flush("running")
    if skipped:
        say(f"resume: {skipped} of {len(spec.samples)} samples already done, {len(todo)} to run")
    t0 = time.perf_counter()
    counts = Counter(r["status"] for r in results.values())
    pbar = bar(len(spec.samples), f"sweep {spec.name}", unit="sample", enabled=progress)
    pbar.n = pbar.last_print_n = pbar.initial = skipped
    pbar.set_postfix_str(f"failed {counts['failed']}")
    ran: list = []
    interrupted = False
    last_flush = time.monotonic()
    flush_cost = 0.0
    try:
        if todo:
            for task, res, exc in executor.run(todo):
                if res is None:
                    res = failed_result(task, f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
                                        .rstrip(": ")[:500])
                    ds.write_json_result(out, task.sample_id, res)
                path = ds.sample_dir(out, task.sample_id) / ds.RESULT
                res["_result_sha256"] = ds.file_sha256(path) if path.is_file() else None
                results[task.sample_id] = res
                ran.append(res)
                counts[res["status"]] += 1
                if on_result is not None:
                    on_result(res)
                pbar.update(1)
                pbar.set_postfix_str(f"failed {counts['failed']}")
                if time.monotonic() - last_flush >= max(flush_every_s, 20.0 * flush_cost):
                    t = time.monotonic()
                    flush("running")
                    last_flush = time.monotonic()
                    flush_cost = last_flush - t
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        wall = time.perf_counter() - t0
        pbar.close()
        with contextlib.suppress(Exception):
            executor.close(terminate=interrupted)
        done = len(results) == len(spec.samples)
        flush("complete" if done and not interrupted else "interrupted" if interrupted else "incomplete")
    desc = executor.describe()
    return SweepSummary(out, len(spec.samples), skipped, len(ran), counts["ok"], counts["failed"], wall, results, desc,
                        interrupted, worker_stats(ran))
