"""Run a sweep's samples: embedded process pool (default) or a Dask distributed cluster.

``run_sweep(spec, out, executor)`` is the sweep: it checks the output directory, sweeps
leftovers of interrupted runs, writes the manifest (every sample "pending"), skips
samples already done (``--resume``), hands the rest to the executor, records each
result as it arrives (progress bar with counts, ETA and failures), and rewrites
``manifest.json`` and ``results.csv``/``results.parquet`` atomically (every few
seconds and at the end, also after Ctrl-C).

Executors yield ``(task, result, exception)`` as samples finish:

* ``LocalExecutor(workers)``: ``concurrent.futures.ProcessPoolExecutor`` with the
  spawn context; no server. Each worker process keeps one renderer (``bench.sweep.tasks``).
  Workers die with the sweep process (PR_SET_PDEATHSIG). If a worker dies (killed,
  out of memory) the pool is rebuilt and the samples it was running are retried
  (``retries`` times; the task is idempotent), the others resubmitted. ``workers=0``
  runs in this process (debugging).
* ``DaskExecutor(address)``: ``distributed.Client`` on a running scheduler
  (``tcp://HOST:PORT``); tasks are submitted with ``retries=2``; a worker lost
  mid-task has its task rescheduled by the scheduler. Workers must import this
  package (same code, same environment) and see DATASET at the same path (shared
  filesystem). Run workers with ``--nthreads 1`` (one renderer per process).
* ``PipelineExecutor(address)``: a sample in two Dask tasks placed by worker resources: the
  render stage on the worker that owns the renderer (``--resources GPU=1``), the writing, the
  methods and the scoring on CPU workers (``--resources CPU=1``), overlapped, with a bounded
  number of samples in flight.
* ``LoopbackCluster(n)``: starts a real ``dask scheduler`` and ``n`` ``dask worker``
  processes on 127.0.0.1 (free ports), for tests and benchmarks; always torn down
  (``render_workers=1``: the first declares GPU=1, the others CPU=1, for the pipeline).
"""
from __future__ import annotations

import contextlib
import multiprocessing
import os
import re
import secrets
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
from dataclasses import dataclass, field, replace
from pathlib import Path

from platebench.bench import interrupts
from platebench.bench.io.atomic import pid_alive, swap_in, sweep_stale
from platebench.bench.io.fs_errors import RunStopped, environmental
from platebench.bench.io.fs_errors import describe as describe_os_error
from platebench.bench.run.workers import stop_pool
from platebench.bench.sweep import dataset as ds
from platebench.bench.sweep.tasks import (
    SampleTask,
    failed_result,
    finish_stage,
    render_stage,
    run_sample,
    tasks_from_spec,
    worker_init,
)
from platebench.errors import PlateBenchError, UserValueError


class ExecutorError(PlateBenchError):
    """The executor cannot run (scheduler unreachable, no workers): one-line message."""


class ExecutorLost(ExecutorError):
    """The executor went away mid-sweep (the Dask scheduler, or every worker): an error of the sweep,
    not of its samples. The dataset keeps what was committed; ``--resume`` finishes it."""


class WorkerLost(RuntimeError):
    """A sample's worker process died more often than its retries allow (while running it alone)."""


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
    """Embedded executor: a spawn-context process pool of ``workers`` processes (0: this process).

    When a worker process dies, the pool is rebuilt. The samples that were in flight are suspects:
    a lone suspect is charged an attempt; several are then run one at a time, each alone in a
    fresh one-process pool, so that a sample that kills its worker ("poisoned") is charged alone
    and its healthy neighbours finish. A sample whose worker died more than ``retries`` times while
    running it alone fails with ``WorkerLost``."""

    def __init__(self, workers: int = 1, retries: int = 2, render_threads: int | None = None):
        if isinstance(workers, bool) or not isinstance(workers, int) or not 0 <= workers <= 256:
            raise ExecutorError(f"--workers = {workers!r} is out of range: allowed 0 to 256")
        self.workers = workers
        self.retries = retries
        self.render_threads = render_threads  # None: cores // workers (if scenes.render.runtime can set it)
        self._pool = None
        self.isolated: list[str] = []  # sample ids run alone after a worker death (for reports and tests)

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
        pending = {t.sample_id: t for t in tasks}
        attempts: Counter = Counter()
        suspects: list[str] = []
        blind = 0  # breaks that named no sample in flight
        while pending:
            if suspects:
                sid = suspects.pop(0)
                if sid not in pending:
                    continue
                self.isolated.append(sid)
                broken, _ = yield from self._round([pending[sid]], 1, pending)
                culprits = {sid} if broken else set()
            else:
                broken, in_flight = yield from self._round(list(pending.values()), self.workers, pending)
                in_flight &= set(pending)
                culprits = set()
                if broken:
                    if len(in_flight) == 1:
                        culprits = in_flight
                    elif in_flight:
                        suspects.extend(sorted(in_flight))
                    else:
                        blind += 1
                        if blind > self.retries:  # nothing tells who died: isolate every one left
                            suspects.extend(sorted(pending))
            for sid in sorted(culprits):
                attempts[sid] += 1
                if attempts[sid] > self.retries:
                    t = pending.pop(sid)
                    yield t, None, WorkerLost(f"its worker process died {attempts[sid]} times while running it "
                                              "alone")
                else:
                    suspects.insert(0, sid)  # a sample charged once runs alone until it succeeds or fails

    def _round(self, tasks: list[SampleTask], workers: int, pending: dict):
        """Run ``tasks`` on a fresh pool until all finish or a worker dies; yields results (and pops
        them from ``pending``); returns (broken, sample ids in flight when it broke)."""
        ctx = multiprocessing.get_context("spawn")
        queue = ctx.Queue()
        n = max(1, min(workers, len(tasks)))
        pool = ProcessPoolExecutor(max_workers=n, mp_context=ctx, initializer=_pool_init,
                                   initargs=(os.getpid(), queue, self.render_threads or
                                             max(1, (os.cpu_count() or 1) // self.workers)))
        self._pool = pool
        with interrupts.children_without_sigint():  # the workers start here; Ctrl-C is the sweep's to handle
            futures = {pool.submit(_pool_task, t): t for t in tasks}
        started: dict = {}
        broken = aborted = False
        dataset = tasks[0].dataset if tasks else None
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
        except BaseException:  # Ctrl-C, or the consumer stopped: stop the workers
            aborted = True
            raise
        finally:
            if aborted:
                stop_pool(pool)  # their attempt directories are left, swept by the next run
            else:
                pool.shutdown(wait=not broken, cancel_futures=True)
                queue.close()
            self._pool = None
        in_flight = set()
        if broken:
            in_flight = {sid for sid in started.values() if sid in pending}
            # a worker killed before its start message got through: its attempt directory names it
            pids = set(started) | {p.pid for p in (getattr(pool, "_processes", None) or {}).values()}
            for sid, host, pid, _path in ds.attempt_dirs(dataset):
                if host == ds.HOST and not pid_alive(pid) and sid in pending and (pid in pids or not started):
                    in_flight.add(sid)
            ds.sweep_attempts(dataset)  # the dead workers' attempts
        return broken, in_flight

    def close(self, terminate: bool = False) -> None:
        """Shut the pool down; ``terminate``: also stop the samples in flight (after Ctrl-C)."""
        pool, self._pool = self._pool, None
        if pool is not None:
            if terminate:
                stop_pool(pool)  # their attempt directories are left, swept by the next run
            else:
                pool.shutdown(wait=False, cancel_futures=True)


def _drain(queue, started: dict) -> None:
    import queue as _q  # noqa: PLC0415
    while True:
        try:
            pid, sid = queue.get_nowait()
        except (_q.Empty, OSError, ValueError, EOFError):
            return
        started[pid] = sid  # a pid runs one sample at a time: the latest is the one in flight


# ----------------------------------------------------------------------------- Dask
MAX_REFETCH = 2  # a sample whose result died with its worker before it was fetched is run again at most this often
_ADDRESS = re.compile(r"^(tcp|tls)://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})$")


def check_scheduler_address(address) -> str:
    """``tcp://HOST:PORT`` (or tls://), checked before any connection; one-line error otherwise."""
    m = _ADDRESS.match(address) if isinstance(address, str) else None
    if m is None or not 1 <= int(m.group(3)) <= 65535:
        raise ExecutorError(f"--scheduler = {address!r} is not a scheduler address: allowed tcp://HOST:PORT "
                            "(PORT 1 to 65535, e.g. tcp://127.0.0.1:8786)")
    return address


def probe_scheduler(address: str, timeout_s: float) -> dict:
    """Ask ``address`` for its identity within ``timeout_s`` (connect, handshake and reply): a port that
    is closed, or open but not a Dask scheduler, fails with one line instead of hanging."""
    import asyncio  # noqa: PLC0415

    from distributed.comm import connect  # noqa: PLC0415

    async def ask():
        comm = await asyncio.wait_for(connect(address, timeout=timeout_s), timeout_s)
        try:
            await asyncio.wait_for(comm.write({"op": "identity", "reply": True}), timeout_s)
            return await asyncio.wait_for(comm.read(), timeout_s)
        finally:
            comm.abort()

    try:
        reply = asyncio.run(asyncio.wait_for(ask(), timeout_s + 1.0))
    except (OSError, asyncio.TimeoutError, TimeoutError) as e:
        why = "no answer" if isinstance(e, (asyncio.TimeoutError, TimeoutError)) else \
            (str(e).splitlines()[0] if str(e) else type(e).__name__)
        raise ExecutorError(f"cannot reach a Dask scheduler at {address} within {timeout_s:g} s ({why})") from None
    except Exception as e:  # noqa: BLE001  (a peer that speaks something else: decode errors of any kind)
        raise ExecutorError(f"{address} does not answer as a Dask scheduler ({type(e).__name__})") from None
    if not isinstance(reply, dict) or reply.get("type") != "Scheduler":
        raise ExecutorError(f"{address} is not a Dask scheduler (it answered {str(reply)[:60]!r})")
    return reply


def _quiet_dask_logs() -> None:
    """The client logs every reconnection attempt with a traceback on stderr; the sweep reports a lost
    scheduler itself, in one line (PLATEBENCH_DEBUG=1 keeps Dask's logs)."""
    import logging  # noqa: PLC0415
    if os.environ.get("PLATEBENCH_DEBUG"):
        return
    import distributed  # noqa: F401,PLC0415  (configures its loggers on import; set the levels after)
    for name in ["distributed", "tornado", "asyncio",
                 *(n for n in logging.root.manager.loggerDict if n.startswith("distributed."))]:
        logging.getLogger(name).setLevel(logging.CRITICAL)


class DaskExecutor:
    """Runs the samples on a Dask distributed cluster through ``distributed.Client``.

    Connections are bounded: the address is checked, then probed (``probe_scheduler``) within
    ``connect_timeout_s`` before a client is made. While the sweep runs, the client's connection and
    the number of workers are watched: a lost scheduler (the client's futures cancelled, or the
    client no longer connected) or no worker for ``worker_timeout_s`` raises ``ExecutorLost``, an
    error of the sweep; a task error (``KilledWorker``: its worker died repeatedly while running it)
    fails that sample only."""

    def __init__(self, address: str, retries: int = 2, connect_timeout_s: float = 10.0,
                 worker_timeout_s: float = 60.0, poll_s: float = 0.2, max_in_flight: int | None = None):
        self.max_in_flight = max_in_flight  # samples submitted at a time (None: all)
        self.address = check_scheduler_address(address)
        self.retries = retries
        self.connect_timeout_s = connect_timeout_s
        self.worker_timeout_s = worker_timeout_s
        self.poll_s = poll_s
        self._client = None
        self._futures = []
        self._workers = None

    def describe(self) -> dict:
        return {"kind": "dask", "scheduler": self.address, "workers": self._workers, "retries": self.retries}

    def connect(self):
        if self._client is None:
            _quiet_dask_logs()
            probe_scheduler(self.address, self.connect_timeout_s)
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
            self._workers = self._n_workers()
        return self._client

    def _submit(self, client, task: SampleTask, key: str):
        """The future of one sample's result (one task: ``run_sample``)."""
        return client.submit(run_sample, task, key=key, pure=False, retries=self.retries)

    def _n_workers(self) -> int:
        c = self._client
        return len(c.sync(c.scheduler.ncores, callback_timeout=max(self.connect_timeout_s, 5.0)))

    def _lost(self, done: int, total: int, why: str) -> ExecutorLost:
        return ExecutorLost(f"lost the Dask scheduler at {self.address} ({why}) with {total - done} of {total} "
                            "samples not finished: the dataset keeps the finished ones (state interrupted); "
                            "run the same command with --resume to finish it")

    def run(self, tasks: list[SampleTask]):
        client = self.connect()
        tag = ds.text_sha256(tasks[0].dataset)[:10] if tasks else ""
        run_id = secrets.token_hex(3)
        pending, refetched = {}, Counter()

        def submit(t: SampleTask, attempt: int = 0) -> None:
            key = f"platebench-sample-{tag}-{t.sample_id}-{t.config_sha256[:12]}-{run_id}" + (
                f"-r{attempt}" if attempt else "")
            fut = self._submit(client, t, key)
            pending[fut.key] = (fut, t)
            self._futures.append(fut)

        waiting = list(tasks)
        limit = self.max_in_flight or len(tasks)

        def top_up() -> None:  # at most ``limit`` samples in the cluster at a time (memory stays flat)
            while waiting and len(pending) < limit:
                submit(waiting.pop(0))

        def run_again(key, fut, t: SampleTask) -> bool:
            """Submit ``t`` again (its result was lost with a worker), at most ``MAX_REFETCH`` times."""
            refetched[t.sample_id] += 1
            if refetched[t.sample_id] > MAX_REFETCH:
                return False
            del pending[key]
            with contextlib.suppress(Exception):
                fut.release()
            submit(t, refetched[t.sample_id])
            return True

        top_up()
        total, done = len(tasks), 0
        next_check = time.monotonic() + 2.0
        no_workers_since = None
        while pending:
            progressed = False
            for key, (fut, t) in list(pending.items()):
                status = fut.status
                if status in ("pending",):
                    continue
                if status == "cancelled" or client.status != "running":
                    raise self._lost(done, total, "its futures were cancelled" if status == "cancelled"
                                     else f"client {client.status}")
                if status == "lost" and run_again(key, fut, t):  # its result died with the worker holding it
                    progressed = True
                    continue
                try:
                    if status == "finished":
                        res, exc = fut.result(timeout=self.connect_timeout_s), None
                    else:  # "error": the task raised, or its workers kept dying (KilledWorker)
                        res, exc = None, fut.exception(timeout=self.connect_timeout_s)
                except Exception as e:  # noqa: BLE001  (the result could not be fetched)
                    if client.status != "running":
                        raise self._lost(done, total, f"client {client.status}") from None
                    # The worker holding the result died before it was fetched: the sample did not fail,
                    # its result was lost. Run it again (the sweep process commits only verified
                    # attempts); if no worker is left, the no-worker timeout below stops the sweep with
                    # the sample still pending, never recorded as failed.
                    if run_again(key, fut, t):
                        progressed = True
                        continue
                    res, exc = None, e
                del pending[key]
                done += 1
                progressed = True
                with contextlib.suppress(Exception):
                    fut.release()
                top_up()
                yield t, res, exc
            if not pending:
                break
            now = time.monotonic()
            if now >= next_check:
                next_check = now + 2.0
                try:
                    n = self._n_workers()
                except Exception as e:  # noqa: BLE001
                    raise self._lost(done, total, f"it does not answer: {type(e).__name__}") from None
                self._workers = max(self._workers or 0, n)
                if n == 0:
                    no_workers_since = no_workers_since or now
                    if now - no_workers_since >= self.worker_timeout_s:
                        raise ExecutorLost(
                            f"every Dask worker of {self.address} is gone (none for {self.worker_timeout_s:g} s) with "
                            f"{total - done} of {total} samples not finished: the dataset keeps the finished ones "
                            "(state interrupted); start workers and run the same command with --resume")
                else:
                    no_workers_since = None
            if not progressed:
                time.sleep(self.poll_s)
        self._futures = []

    def close(self, terminate: bool = False) -> None:
        if self._client is not None:
            client, self._client = self._client, None
            with contextlib.suppress(Exception):
                if self._futures and client.status == "running":
                    client.cancel(self._futures)
            self._futures = []
            with contextlib.suppress(Exception):
                client.close(timeout=5)


# ----------------------------------------------------------------------------- two-stage pipeline on Dask
RENDER_RESOURCE = "GPU"  # the worker that owns the renderer: dask worker --resources GPU=1 (the GPU where one is)
FINISH_RESOURCE = "CPU"  # a worker that writes, reconstructs and scores: dask worker --resources CPU=1


class PipelineExecutor(DaskExecutor):
    """A sample in two Dask tasks, placed by worker resources (``resources={"GPU": 1}``): the render
    stage (``tasks.render_stage``: the sample rendered in memory) on a worker that declares GPU=1
    and owns the renderer, then the finish stage (``tasks.finish_stage``: written into its attempt
    directory, every method run and scored) on a worker that declares CPU=1, which fetches the
    rendered sample from the render worker. The render worker renders the next samples while the
    CPU workers finish earlier ones; at most ``max_in_flight`` samples are in the cluster at a time
    (default two per CPU worker, plus two), so the rendered samples waiting for a CPU worker (about
    150 MB each at 1280 x 960) are bounded and memory stays flat.

    The same spec runs on one machine (``LoopbackCluster(render_workers=1)``, ``platebench sweep
    --pipeline``) and on a cluster of GPU and CPU workers (``--pipeline --scheduler``). Everything
    else is the sweep's: one writer (this process commits), checksums, ``--resume``, a failure
    recorded for its sample only. A sample with a method that renders (the peers' pattern
    sequences) is made whole on the render worker."""

    def describe(self) -> dict:
        return {**super().describe(), "kind": "dask-pipeline", "render_workers": self._counts[0],
                "finish_workers": self._counts[1], "max_in_flight": self.max_in_flight}

    _counts = (None, None)

    def connect(self):
        fresh = self._client is None
        client = super().connect()
        if fresh:
            workers = client.scheduler_info()["workers"].values()
            n_render = sum(1 for w in workers if (w.get("resources") or {}).get(RENDER_RESOURCE, 0) >= 1)
            n_finish = sum(1 for w in workers if (w.get("resources") or {}).get(FINISH_RESOURCE, 0) >= 1)
            if not n_render or not n_finish:
                self.close()
                raise ExecutorError(f"the pipeline needs workers started with --resources {RENDER_RESOURCE}=1 (the "
                                    f"renderer) and with --resources {FINISH_RESOURCE}=1 (writing, methods, scoring): "
                                    f"{self.address} has {n_render} and {n_finish}")
            self._counts = (n_render, n_finish)
            if self.max_in_flight is None:
                self.max_in_flight = 2 * n_finish + 2
        return client

    def _submit(self, client, task: SampleTask, key: str):
        rendered = client.submit(render_stage, task, key=f"{key}-render", pure=False, retries=self.retries,
                                 resources={RENDER_RESOURCE: 1})
        return client.submit(finish_stage, task, rendered, key=key, pure=False, retries=self.retries,
                             resources={FINISH_RESOURCE: 1})


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

    Everything listens on 127.0.0.1 only (scheduler, workers, nannies and their HTTP servers), with
    no dashboard unless ``dashboard=True``.

    Every process runs in its own session (process group) so that ``kill_worker`` can
    kill -9 a worker with its nanny, and ``close`` tears everything down (SIGTERM, then
    SIGKILL after a bounded wait). Logs go to files in ``log_dir``.
    """

    def __init__(self, n_workers: int = 2, nthreads: int = 1, startup_timeout_s: float = 90.0,
                 log_dir: Path | None = None, env: dict | None = None, dashboard: bool = False,
                 render_workers: int = 0):
        self.n_workers = n_workers
        self.render_workers = render_workers  # > 0: the first ones declare GPU=1, the others CPU=1 (PipelineExecutor)
        self.dashboard = dashboard
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

    def _http_flags(self) -> list[str]:
        """Dask serves HTTP (health, metrics; the dashboard when asked) even with --no-dashboard, on
        every interface by default: bind it to 127.0.0.1 (a free port) as well."""
        return (["--dashboard"] if self.dashboard else ["--no-dashboard"]) + ["--dashboard-address", "127.0.0.1:0"]

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
                                          *self._http_flags()], f"scheduler-{attempt}")
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
        resources = []
        if self.render_workers:
            resources = ["--resources", f"{RENDER_RESOURCE if i < self.render_workers else FINISH_RESOURCE}=1"]
        p = self._spawn(["worker", self.address, "--nthreads", str(self.nthreads), "--nworkers", "1",
                         *self._http_flags(), "--host", "127.0.0.1", "--name", f"w{i}-{len(self.workers)}",
                         "--local-directory", str(wdir), *resources], f"worker-{len(self.workers)}")
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
    results: dict  # sample id -> SampleResult (bench.io.sweep_records)
    executor: dict
    interrupted: bool = False
    worker_stats: dict = field(default_factory=dict)  # "host:pid" -> {"samples", "maxrss_mb"}

    @property
    def samples_per_min(self) -> float:
        return 60.0 * self.run / self.wall_s if self.wall_s > 0 else float("nan")


def worker_stats(results) -> dict:
    out: dict = {}
    for res in results:
        w = res.worker or {}
        if not w:
            continue
        k = f"{w.get('host')}:{w.get('pid')}"
        e = out.setdefault(k, {"samples": 0, "maxrss_mb": 0.0})
        e["samples"] += 1
        e["maxrss_mb"] = max(e["maxrss_mb"], float(w.get("maxrss_mb") or 0.0))
    return out


def executor_for(stack, *, workers: int | None = None, scheduler: str | None = None, pipeline: bool = False,
                 connect_timeout_s: float = 10.0, worker_timeout_s: float = 60.0):
    """The executor a sweep's flags ask for, connected: a local pool of ``workers`` processes (default 1;
    0 runs in this process); a Dask cluster at ``scheduler``; ``pipeline``: render and finish in two
    stages (on ``scheduler``, or a loopback cluster of one render worker and ``workers`` CPU workers,
    closed by ``stack``, a ``contextlib.ExitStack``, as is the executor)."""
    if not scheduler and not pipeline:
        return LocalExecutor(1 if workers is None else workers)
    address = scheduler
    if address is None:  # --pipeline on this machine: one render worker and --workers CPU workers
        n = 1 if workers is None else workers
        if not 1 <= n <= 256:
            raise UserValueError(f"--workers = {n} is out of range with --pipeline: allowed 1 to 256 CPU workers")
        cluster = stack.enter_context(LoopbackCluster(n_workers=n + 1, render_workers=1))
        address = cluster.address
    kind = PipelineExecutor if pipeline else DaskExecutor
    executor = kind(address, connect_timeout_s=connect_timeout_s, worker_timeout_s=worker_timeout_s)
    executor.connect()  # fail fast, before the dataset is created
    stack.callback(executor.close)
    return executor


def run_sweep(spec, out: Path, executor=None, resume: bool = False, overwrite: bool = False,
              retry_failed: bool = False, progress: bool | None = None, flush_every_s: float = 5.0,
              log=None, on_result=None, method_time_limit_s: float | None = None) -> SweepSummary:
    """Run ``spec`` into dataset directory ``out``; returns a summary.

    Holds the dataset lock (``dataset.dataset_lock``) for the whole run: a second writer is refused
    with the holder's PID and host, a stale lock of a killed sweep is taken over (and said so).
    ``overwrite``: the new dataset is made in a staging directory beside ``out`` and replaces it only
    once complete (an interrupted ``--overwrite`` leaves the old dataset as it was). ``resume``:
    samples whose committed files still match their checksums are kept, every other one is (re)done.
    Each result is committed by this process (``dataset.commit_sample``) and the manifest and tables
    are rewritten after it (at most every ``flush_every_s`` when that gets slow). The manifest ends
    "complete" (every sample committed), "interrupted" (Ctrl-C, SIGTERM, or the executor lost:
    ``ExecutorLost`` is raised after the manifest is written) or "incomplete".

    ``on_result(result)`` is called with each sample's ``SampleResult`` as it is committed (in this process).
    ``method_time_limit_s``: the longest a plug-in may run on one sample (default: the spec's
    ``sweep.method_time_limit_s``, else ``plugins.METHOD_TIME_LIMIT_S``)."""
    from platebench.bench.progress import bar  # noqa: PLC0415
    out = Path(out).absolute()
    executor = executor if executor is not None else LocalExecutor(1)
    say = log or (lambda msg: None)
    lock = ds.dataset_lock(out)
    lock.acquire()
    stage = None
    try:
        if lock.stale_note():
            say(f"note: {lock.stale_note()}")
        sweep_stale(out.parent, only=out.name)  # staging of a killed --overwrite sweep into the same place
        old = ds.check_dataset(out, spec, resume, overwrite)
        if overwrite and old is not None:
            stage = ds.make_stage_dataset(out)
            work = stage
        else:
            work = out
        if old is not None and not overwrite and old.get("state") == "interrupted" and old.get("state_note"):
            say(f"note: the previous sweep into {out} did not finish (killed); its committed samples are kept")
        if old is not None and old.get("recovered"):
            bad = old.get("unreadable_samples") or []
            say(f"note: {out / ds.MANIFEST} is missing or damaged: "
                + ("replacing the dataset, recognised by" if overwrite else "rebuilding it from")
                + f" its {old['recovered_samples']} samples' own {ds.RESULT} files"
                + ("" if overwrite else " (each verified by its checksums; what cannot be verified is made again)")
                + (f"; {len(bad)} sample folder(s) without a readable {ds.RESULT} ({bad[0]}, ...)" if bad else ""))
        ds.prepare_dataset(work, spec)
        summary = _run(spec, work, executor, old if resume else None, retry_failed, progress, flush_every_s, say,
                       on_result, bar, method_time_limit_s)
        if stage is not None:
            if summary.interrupted or summary.total != summary.ok + summary.failed:
                raise ExecutorLost(f"--overwrite sweep into {out} did not finish: {out} is left as it was")
            swap_in(stage, out)
            shutil.rmtree(stage, ignore_errors=True)  # the old dataset
            stage = None
            summary.dataset = out
        return summary
    finally:
        if stage is not None:
            shutil.rmtree(stage, ignore_errors=True)
        lock.release()


def _run(spec, out: Path, executor, old_manifest, retry_failed, progress, flush_every_s, say, on_result,
         bar, method_time_limit_s=None) -> SweepSummary:
    started = (old_manifest or {}).get("created_utc") or ds.now_utc()
    packages = ds.package_versions()
    listed = {e.get("id"): e.get("files_sha256") or {} for e in (old_manifest or {}).get("samples", [])}
    results: dict = {}
    todo = []
    redo = 0
    for task in tasks_from_spec(spec, out, redo_failed=retry_failed, method_time_limit_s=method_time_limit_s):
        res = None
        if old_manifest is not None or ds.sample_dir(out, task.sample_id).is_dir():
            res = ds.validate_result(out, task.sample_id, task.config_sha256, listed.get(task.sample_id))
            if res is None and (ds.sample_dir(out, task.sample_id) / ds.RESULT).exists():
                redo += 1  # committed once, but its files no longer match: made again
        if res is not None and (res.ok or not retry_failed):
            results[task.sample_id] = replace(
                res, result_sha256=ds.file_sha256(ds.sample_dir(out, task.sample_id) / ds.RESULT))
        else:
            todo.append(task)
    skipped = len(results)

    def flush(state: str) -> None:  # the manifest first: a dataset with a manifest can always be resumed
        ds.write_manifest(out, ds.manifest_dict(spec, results, executor.describe(), started, state, packages))
        ds.write_results(out, list(results.values()))

    def stopped(e: OSError, what: str) -> RunStopped:
        left = len(spec.samples) - len(results)
        return RunStopped(f"{out}: {describe_os_error(e)} ({what}): the sweep stopped with {left} of "
                          f"{len(spec.samples)} samples not finished, none of them counted as failed; the dataset "
                          "keeps the finished ones (state interrupted): free space or make it writable, then run "
                          "the same command with --resume")

    @contextlib.contextmanager
    def output_errors_stop(what: str):
        """An error of the output (``bench.io.fs_errors``) in the block stops the sweep (``RunStopped``)."""
        try:
            yield
        except OSError as e:
            if environmental(e, out):
                raise stopped(e, what) from None
            raise

    with output_errors_stop("writing its manifest"):
        flush("running")
    if skipped or redo:
        say(f"resume: {skipped} of {len(spec.samples)} samples already done, {len(todo)} to run"
            + (f" ({redo} whose files no longer match their checksums)" if redo else ""))
    t0 = time.perf_counter()
    counts = Counter(r.status for r in results.values())
    pbar = bar(len(spec.samples), f"sweep {spec.name}", unit="sample", enabled=progress)
    pbar.n = pbar.last_print_n = pbar.initial = skipped
    pbar.set_postfix_str(f"failed {counts['failed']}")
    ran: list = []
    interrupted = False
    lost = None
    last_flush = time.monotonic()
    flush_cost = 0.0
    try:
        if todo:
            for task, res, exc in executor.run(todo):
                if res is None and environmental(exc, out):  # the output's fault: no sample failed
                    raise stopped(exc, f"sample {task.sample_id}") from None
                if res is None:
                    res = failed_result(task, f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
                                        .rstrip(": ")[:500])
                with output_errors_stop(f"committing sample {task.sample_id}"):
                    try:
                        res = ds.commit_sample(out, res)
                    except ds.CommitError as e:  # the attempt's files are not what its worker listed
                        res = ds.commit_sample(out, failed_result(task, f"CommitError: {e}"))
                results[task.sample_id] = res
                ran.append(res)
                counts[res.status] += 1
                pbar.update(1)
                pbar.set_postfix_str(f"failed {counts['failed']}")
                if time.monotonic() - last_flush >= min(flush_every_s, 20.0 * flush_cost):
                    t = time.monotonic()
                    with output_errors_stop("writing its manifest"):
                        flush("running")
                    last_flush = time.monotonic()
                    flush_cost = last_flush - t
                if on_result is not None:
                    on_result(res)
                interrupts.check()  # an interrupt that a library swallowed stops the sweep here
    except KeyboardInterrupt:
        interrupted = True
        raise
    except (ExecutorLost, RunStopped) as e:
        interrupted = True
        lost = e if isinstance(e, ExecutorLost) else None
        raise
    finally:
        wall = time.perf_counter() - t0
        pbar.close()
        with contextlib.suppress(Exception):
            executor.close(terminate=interrupted)
        if isinstance(executor, LocalExecutor) or lost is None:
            with contextlib.suppress(OSError):
                ds.sweep_attempts(out)  # attempts of workers that are gone
        done = len(results) == len(spec.samples)
        state = "complete" if done and not interrupted else "interrupted" if interrupted else "incomplete"
        try:
            flush(state)
        except OSError as e:
            if not environmental(e, out):
                raise
            if not interrupted:  # the last write failed: say so (an error raised already takes precedence)
                raise stopped(e, "writing its manifest") from None
    return SweepSummary(out, len(spec.samples), skipped, len(ran), counts["ok"], counts["failed"], wall, results,
                        executor.describe(), interrupted, worker_stats(ran))
