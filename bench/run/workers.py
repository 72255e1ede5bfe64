"""Worker processes that share this machine's cores: the render threads each may use, and dying
with the parent. Used by the study's process pool (``bench.run.sensing.study``) and the sweep's
(``bench.sweep``)."""
from __future__ import annotations

import contextlib
import os
import sys

from platebench.bench.run.extensions import load_extensions
from platebench.scenes.render import runtime


def set_render_threads(n: int | None) -> bool:
    """Limit the renderer's CPU threads in this process (N workers on C cores: C // N each)."""
    if not n:
        return False
    runtime.set_thread_count(int(n))
    return True


def die_with_parent(parent_pid: int | None) -> None:
    """Be killed when the parent process dies (Linux PR_SET_PDEATHSIG), so that a run killed with -9
    leaves no worker writing behind it; exit at once if ``parent_pid`` is already gone."""
    if sys.platform.startswith("linux"):
        try:
            import ctypes  # noqa: PLC0415
            import signal  # noqa: PLC0415
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if parent_pid is not None and os.getppid() != parent_pid:
        os._exit(1)  # the parent is already gone


def pool_worker_init(parent_pid: int | None = None, render_threads: int | None = None) -> None:
    """Initializer of a process pool's workers: ``die_with_parent``, ``set_render_threads`` and the
    installed packages' families, metrics and cure rules (``bench.run.extensions.load_extensions``)."""
    set_render_threads(render_threads)
    die_with_parent(parent_pid)
    load_extensions()


def stop_pool(pool) -> None:
    """Stop a ``concurrent.futures.ProcessPoolExecutor`` now: terminate its workers, cancel what is
    queued, and wait (10 s at most each) until they are gone. ``shutdown(wait=False)`` alone is not
    enough: Python's exit joins the pool, so every task in flight would run to its end."""
    procs = list((getattr(pool, "_processes", None) or {}).values())
    for p in procs:
        with contextlib.suppress(Exception):
            p.terminate()
    pool.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(Exception):
            p.join(timeout=10)
