"""Plug-ins run in a process of their own: whatever a plug-in does (``sys.exit``, ``os._exit``, a
crash, an exception, a loop that never returns, at import or when called, an output that is not one),
it fails that method on that sample with one line, and the command that runs it goes on.

``PluginHost`` is that process (``python -m platebench.bench.run.plugin_process PARENT_PID``): one per
calling process and thread (a sweep's worker, ``compare``, a Dask worker's task thread), started on
first use and reused while its plug-ins succeed. A request names the plug-in (an installed entry point
or ``module:function``, imported in the host on its first call; or a function pickled by reference)
and a sample directory; the host imports the plug-in, loads the sample's inputs
(``plugins.method_inputs``), calls the plug-in and answers with its output as plain arrays (``.npy``
format, no pickles) and numbers (JSON). The caller waits at most the time limit, which covers all
three (``plugins.METHOD_TIME_LIMIT_S`` unless told; the host's own start-up, before any plug-in code,
has ``START_TIME_LIMIT_S``). The plug-in's own prints go to the command's stderr; its standard input
is empty.

Process groups: the host starts a session, and so a process group, of its own (a Ctrl-C at the
terminal reaches the command, which stops it), and everything the plug-in starts (``subprocess``,
``multiprocessing``) is in that group unless it leaves it with a session of its own. The group is
killed, never the host alone (``PluginHost.stop``: SIGTERM to the group, SIGKILL to it after
``STOP_GRACE_S`` or as soon as none of it is left):

* on a timeout, a crash, an exit, an interrupt of the request, or an answer saying the plug-in failed
  (the next request starts a fresh host);
* when the calling process exits (``stop_all``, an ``atexit`` hook; ``compare`` and sweeps end so);
* when the caller dies without running it (killed, or a pool worker terminated): the host dies with
  its calling thread (PR_SET_PDEATHSIG, as the sweep's workers do), and a guard process of the group,
  forked by the host before any plug-in code runs (``serve``), kills the group when the host dies.

Frames on the two pipes: 8 bytes of length (big-endian), then the bytes. A request is a pickled dict
(made by the bench itself); an answer is a JSON header, then one frame per array it lists.
"""
from __future__ import annotations

import atexit
import contextlib
import io
import json
import os
import pickle
import select
import signal
import struct
import subprocess
import sys
import threading
import time
import weakref

import numpy as np

__all__ = ["PluginHost", "HostFailure", "host", "serve", "stop_all", "group_members", "START_TIME_LIMIT_S",
           "STOP_GRACE_S"]

START_TIME_LIMIT_S = 120.0  # for the host process to start (Python, numpy, platebench's plug-in module)
STOP_GRACE_S = 1.0  # after SIGTERM to a host's process group, the longest it has before SIGKILL, seconds
_STOP_POLL_S = 0.02  # how often a stopping group is looked at, seconds
_REAP_TIME_LIMIT_S = 10.0  # the longest to wait for a killed host to be reaped, seconds
_GUARD_SIGNAL = signal.SIGUSR1  # what the group's guard receives when the host dies (PR_SET_PDEATHSIG)
_READY = b"platebench-plugin-host-ready"


class HostFailure(RuntimeError):
    """The plug-in's process did not answer: it died, exited, or ran past the time limit (one line)."""


class _Timeout(Exception):
    pass


# ----------------------------------------------------------------------------- frames
def _write_frame(fd: int, data: bytes) -> None:
    view = memoryview(struct.pack(">Q", len(data)) + data)
    while view:
        n = os.write(fd, view)
        view = view[n:]


def _read_exact(fd: int, n: int, deadline: float | None) -> bytes | None:
    chunks, got = [], 0
    while got < n:
        if deadline is not None:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([fd], [], [], left)[0]:
                raise _Timeout
        chunk = os.read(fd, min(n - got, 1 << 20))
        if not chunk:
            return None
        chunks.append(chunk)
        got += len(chunk)
    return b"".join(chunks)


def _read_frame(fd: int, deadline: float | None) -> bytes | None:
    head = _read_exact(fd, 8, deadline)
    if head is None:
        return None
    return _read_exact(fd, struct.unpack(">Q", head)[0], deadline)


# ----------------------------------------------------------------------------- the caller's side
class PluginHost:
    """The host process of one calling thread (see module doc)."""

    def __init__(self):
        self.proc: subprocess.Popen | None = None
        with _ALL_LOCK:
            _ALL.add(self)

    def _start(self) -> None:
        self.proc = subprocess.Popen([sys.executable, "-m", "platebench.bench.run.plugin_process", str(os.getpid())],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, start_new_session=True)
        try:
            ready = _read_frame(self.proc.stdout.fileno(), time.monotonic() + START_TIME_LIMIT_S)
        except _Timeout:
            ready = None
        except BaseException:  # Ctrl-C while it starts: it goes with the command
            self.stop()
            raise
        if ready != _READY:
            self.stop()
            raise HostFailure(f"the plug-in process did not start within {START_TIME_LIMIT_S:g} s")

    def stop(self) -> None:
        """Kill the host and everything it started: its process group (module doc)."""
        proc, self.proc = self.proc, None
        if proc is None:
            return
        kill_group(proc)
        for f in (proc.stdin, proc.stdout):
            with contextlib.suppress(Exception):
                f.close()

    def _died(self, what: str) -> HostFailure:
        proc = self.proc
        rc = None
        if proc is not None:
            with contextlib.suppress(Exception):
                rc = proc.wait(timeout=5)
        self.stop()
        if rc is not None and rc < 0:
            try:
                how = f"was killed by {signal.Signals(-rc).name}"
            except ValueError:
                how = f"was killed by signal {-rc}"
        elif rc is not None:
            how = f"exited with status {rc} (os._exit?)"
        else:
            how = "stopped answering"
        return HostFailure(f"{what}: its process {how} before it answered")

    def request(self, req: dict, time_limit_s: float, what: str) -> tuple[dict, list]:
        """Send ``req``; (the answer's header, its arrays). ``HostFailure`` when the host dies, exits or
        takes longer than ``time_limit_s``; an answer saying the plug-in failed also retires the host."""
        data = pickle.dumps(req)
        for attempt in (0, 1):
            if self.proc is None or self.proc.poll() is not None:
                self.stop()
                self._start()
            try:
                _write_frame(self.proc.stdin.fileno(), data)
                break
            except BrokenPipeError:  # gone since its last answer (its parent thread ended): once more
                self.stop()
                if attempt:
                    raise HostFailure(f"{what}: its process could not take the request") from None
        deadline = time.monotonic() + time_limit_s
        fd = self.proc.stdout.fileno()
        try:
            head = _read_frame(fd, deadline)
            if head is None:
                raise self._died(what)
            doc = json.loads(head)
            arrays = []
            for _ in range(int(doc.get("arrays", 0))):
                blob = _read_frame(fd, deadline)
                if blob is None:
                    raise self._died(what)
                arrays.append(np.load(io.BytesIO(blob), allow_pickle=False))
        except _Timeout:
            self.stop()
            raise HostFailure(f"{what}: no answer within the time limit of {time_limit_s:g} s "
                              "(stopped; raise it with --method-time-limit-s or sweep.method_time_limit_s)") from None
        except BaseException:  # Ctrl-C, SIGTERM, a broken answer: the host goes with it
            self.stop()
            raise
        if not doc.get("ok"):
            self.stop()  # a plug-in that failed may have left its process in any state
        return doc, arrays


_HOSTS = threading.local()
_ALL: weakref.WeakSet = weakref.WeakSet()  # every host of this process, for stop_all
_ALL_LOCK = threading.Lock()


def host() -> PluginHost:
    """This thread's plug-in host."""
    h = getattr(_HOSTS, "host", None)
    if h is None:
        h = _HOSTS.host = PluginHost()
    return h


def stop_all() -> None:
    """Stop every plug-in host of this process with its process group (registered with ``atexit``)."""
    with _ALL_LOCK:
        hosts = list(_ALL)
    for h in hosts:
        with contextlib.suppress(Exception):
            h.stop()


atexit.register(stop_all)


def group_members(pgid: int) -> list[int]:
    """The live processes (not zombies) of process group ``pgid``, read from /proc; [] where there is none."""
    out = []
    try:
        names = os.listdir("/proc")
    except OSError:
        return out
    for name in names:
        if not name.isdigit():
            continue
        try:
            with open(f"/proc/{name}/stat", "rb") as f:
                fields = f.read().rpartition(b")")[2].split()
        except OSError:
            continue
        if len(fields) > 2 and fields[0] not in (b"Z", b"X") and int(fields[2]) == pgid:
            out.append(int(name))
    return out


def kill_group(proc: subprocess.Popen) -> None:
    """Kill the process group ``proc`` leads (its session's): SIGTERM, then SIGKILL once none of it is left
    alive or after ``STOP_GRACE_S``; then reap ``proc``. The leader stays unreaped until the SIGKILL, so
    its group id names no other group meanwhile."""
    pgid = proc.pid
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, signal.SIGTERM)
    deadline = time.monotonic() + STOP_GRACE_S
    while time.monotonic() < deadline and group_members(pgid):
        time.sleep(_STOP_POLL_S)
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, signal.SIGKILL)
    with contextlib.suppress(Exception):
        proc.wait(timeout=_REAP_TIME_LIMIT_S)


# ----------------------------------------------------------------------------- the host's side
def serve(handle, parent_pid: int) -> None:
    """The host's loop (``bench.run.plugin_process``): answer each request with ``handle(request) ->
    (header, arrays)`` until the caller closes the pipe."""
    from platebench.bench.run.workers import die_with_parent  # noqa: PLC0415

    die_with_parent(parent_pid)
    _guard_group(os.getpid())
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the command decides; it kills this process to stop it
    proto_in, proto_out = os.dup(0), os.dup(1)
    os.dup2(os.open(os.devnull, os.O_RDONLY), 0)  # the plug-in reads nothing of the protocol
    os.dup2(2, 1)  # and its prints go to stderr
    _write_frame(proto_out, _READY)
    while True:
        data = _read_frame(proto_in, None)
        if data is None:
            return
        req = pickle.loads(data)
        head, arrays = handle(req)
        try:
            body = [_npy(a) for a in arrays]
        except ValueError as e:  # an array numpy cannot write without pickles (dtype object)
            head, body = {"ok": False, "error": f"method {req.get('name')!r} returned an array numpy cannot "
                                                f"store ({str(e).splitlines()[0]}): give numbers"}, []
        head["arrays"] = len(body)
        _write_frame(proto_out, json.dumps(head).encode())
        for b in body:
            _write_frame(proto_out, b)


def _guard_group(host_pid: int) -> None:
    """Fork the guard of the host's process group (Linux): a process that holds no pipe of the protocol and
    waits; when the host dies (its PR_SET_PDEATHSIG, ``_GUARD_SIGNAL``) it kills the whole group with
    SIGKILL, itself included. SIGTERM to the group stops it as it stops the rest."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes  # noqa: PLC0415  (loaded before the fork: the guard only calls it)
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return
    if os.fork():
        return
    try:
        null = os.open(os.devnull, os.O_RDWR)
        os.dup2(null, 0)
        os.dup2(null, 1)
        os.closerange(3, os.sysconf("SC_OPEN_MAX"))
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(_GUARD_SIGNAL, lambda *_: os.killpg(0, signal.SIGKILL))
        prctl(1, int(_GUARD_SIGNAL), 0, 0, 0)  # PR_SET_PDEATHSIG
        if os.getppid() != host_pid:  # the host died before the line above
            os.killpg(0, signal.SIGKILL)
        while True:
            signal.pause()
    finally:
        os._exit(0)


def _npy(a: np.ndarray) -> bytes:
    buf = io.BytesIO()
    np.save(buf, a, allow_pickle=False)
    return buf.getvalue()
