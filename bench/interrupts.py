"""Interrupts that are never lost: Ctrl-C (SIGINT) and SIGTERM end a command with status 130 / 143.

The command line calls ``install()`` before anything else. A signal is then recorded
(``received()``) and raised in the main thread: ``KeyboardInterrupt`` for SIGINT,
``Terminated`` (a ``KeyboardInterrupt``) for SIGTERM, so staged outputs are removed
(``bench.io.atomic``) and a sweep closes its manifest "interrupted".

Three things could lose it, or cut a step in half; all are closed here:

* A module being imported when the signal lands. Packages guard their optional imports with
  ``except BaseException`` (trimesh does, for shapely, networkx, scipy, ...): the exception
  would be swallowed and the package left half set up (later calls then fail in odd ways).
  While the main thread is inside an import, the signal is held and delivered again every
  ``REDELIVER_S`` (by SIGALRM) until the import has finished; a second signal while one is held
  is raised at once, so a module that never finishes importing can still be interrupted.
* Code whose exceptions Python ignores (``__del__``, a weak reference's callback run by the garbage
  collector) is held the same way, and so are the few steps that must not be cut in half
  (``CRITICAL``: taking an output's lock, swapping a finished output into place, committing a sample).
* Code that catches ``BaseException`` while it runs. The record stays: ``check()`` raises it
  again at the next stage boundary, and ``exit_status()`` turns a command that went on to the
  end into 130 / 143 all the same (its completed outputs are kept, as after any interrupt).

An interrupt can also cut a library object half-way through its constructor (pyparsing's ``Forward``,
built when matplotlib first lays out text, had no ``expr`` yet), and that object's ``__del__`` then
fails when the collector meets it: "Exception ignored in ... __del__" on the terminal of a command that
ended cleanly. Once a signal was raised, such finaliser errors are dropped (``_unraisable``); before
one, Python reports them as always.

Once the command has its exit status (``finish``), a signal is only recorded: it cannot break the
way out (threads joined, files closed), and the process still exits 130 / 143 (an ``atexit`` hook);
a second one ends the process at once, with the same status. So does a second signal while the
first one's exception unwinds (cleanup that hangs can be cut short; what it left, the next run
removes).
Nothing here runs unless ``install()`` was called (the library's own users keep Python's
default handling); a command run from Python (``main([...])``) gets the caller's handlers back
(``uninstall``).
"""
from __future__ import annotations

import atexit
import contextlib
import os
import signal
import sys
import threading

__all__ = ["Terminated", "install", "uninstall", "installed", "received", "check", "finish", "exit_status",
           "children_without_sigint",
           "REDELIVER_S",
           "EXIT_STATUS", "CRITICAL"]

REDELIVER_S = 0.02  # how often a signal held during an import is delivered again, seconds
EXIT_STATUS = {signal.SIGINT: 130, signal.SIGTERM: 143}  # 128 + the signal's number, as a shell reports it


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised as an exception so that cleanup runs as for Ctrl-C."""


_STATE = {"installed": False, "signum": None, "held": False, "redelivery": False, "finishing": False,
          "late": False, "atexit": False, "raised": False, "whole_process": False}


# Sections a signal must not cut, held until they end: taking and releasing an output's lock, writing a
# file under its temporary name and renaming it, setting a staged output up and swapping it into place
# (``staged_output``'s own code: the with-block it yields to runs outside it), committing a sweep's sample,
# starting a worker process (cut, it would die with a traceback on the terminal). Given as (module,
# qualified name); tests/test_interrupts.py checks that each still names a function.
CRITICAL = frozenset({
    ("platebench.bench.io.atomic", "OutputLock.acquire"), ("platebench.bench.io.atomic", "OutputLock.release"),
    ("platebench.bench.io.atomic", "staged_output"), ("platebench.bench.io.atomic", "swap_in"),
    ("platebench.bench.io.atomic", "write_bytes"), ("platebench.bench.io.images", "write_exr"),
    ("platebench.bench.sweep.dataset", "commit_sample"), ("platebench.bench.sweep.dataset", "make_attempt_dir"),
    ("multiprocessing.popen_spawn_posix", "Popen._launch"),  # a worker reads its start-up data from a pipe
})


def _must_hold(frame) -> bool:
    """Whether an exception raised at ``frame`` could be lost or leave a half-done step: inside an import
    (a module's body being executed), in code whose exceptions Python itself ignores (``__del__``, a weak
    reference's callback run by the garbage collector: "Exception ignored in ..."), or in a ``CRITICAL``
    section."""
    while frame is not None:
        code = frame.f_code
        if code.co_filename.startswith("<frozen importlib._bootstrap") or code.co_name == "__del__" \
                or code.co_filename.endswith(("/weakref.py", "/_weakrefset.py")) \
                or (frame.f_globals.get("__name__"), code.co_qualname) in CRITICAL:
            return True
        frame = frame.f_back
    return False


def _exception(signum: int) -> KeyboardInterrupt:
    if signum == signal.SIGTERM:
        return Terminated("terminated (SIGTERM)")
    return KeyboardInterrupt()


def _redeliver(signum: int) -> None:
    """Deliver the held signal again in ``REDELIVER_S`` (a one-shot ITIMER_REAL: no thread is started from
    the handler, which may have interrupted the main thread inside threading's own locks)."""
    signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, REDELIVER_S)


def _cancel_redelivery() -> None:
    """Cancel a pending re-delivery: once the signal is raised (or the command has its status), a timer left
    running would fire after Python's finalisation has put SIGALRM's default action back, and kill the
    process by SIGALRM instead of letting it exit 130 / 143."""
    if _STATE["held"] or _STATE["redelivery"]:
        _STATE["held"] = _STATE["redelivery"] = False
    if threading.current_thread() is threading.main_thread():
        with contextlib.suppress(OSError, ValueError):
            signal.setitimer(signal.ITIMER_REAL, 0)


def _alarm(_signum, frame):
    if _STATE["signum"] is not None and _STATE["held"]:
        _STATE["redelivery"] = True
        _handler(_STATE["signum"], frame)


def _handler(signum, frame):
    if _STATE["signum"] is None:
        _STATE["signum"] = signum
    if _STATE["finishing"]:  # the command is done: the exit status says it (``_exit_late``)
        if _STATE["late"]:  # a second one while the process winds down (a thread that will not end): now
            _exit_late(now=True)
        _STATE["late"] = True
        return
    redelivered, _STATE["redelivery"] = _STATE["redelivery"], False
    if _must_hold(frame) and (not _STATE["held"] or redelivered):
        _STATE["held"] = True  # raise it once the import (or the finaliser) has finished
        _redeliver(signum)
        return
    _STATE["held"] = False
    if _STATE["raised"] and _STATE["whole_process"]:  # a second one while the first unwinds: stop now
        with contextlib.suppress(Exception):
            print("platebench: interrupted again: stopped at once (the next run removes what was left)",
                  file=sys.stderr, flush=True)
        os._exit(exit_status() or 130)
    _STATE["raised"] = True
    _cancel_redelivery()
    raise _exception(signum)


def install(whole_process: bool = False) -> bool:
    """Handle SIGINT and SIGTERM as the module doc says (main thread only; False elsewhere). Forgets
    any signal recorded before. ``whole_process``: the command is the process (a second signal while the
    first unwinds ends it at once); else a second signal is raised again, as Python does."""
    _STATE.update(signum=None, held=False, redelivery=False, finishing=False, late=False, raised=False,
                  whole_process=whole_process)
    if threading.current_thread() is not threading.main_thread():
        return False
    with contextlib.suppress(ValueError, OSError):
        previous = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGALRM)}
        signal.signal(signal.SIGINT, _handler)
        signal.signal(signal.SIGTERM, _handler)
        _STATE["installed"] = True
        _STATE["previous"] = previous
    if _STATE["installed"] and not _STATE["atexit"]:
        atexit.register(_exit_late)
        _STATE["atexit"] = True
    if _STATE["installed"] and sys.unraisablehook is not _unraisable:
        _STATE["unraisablehook"] = sys.unraisablehook
        sys.unraisablehook = _unraisable
    return _STATE["installed"]


def _unraisable(u) -> None:
    """``sys.unraisablehook`` while installed: after a signal was raised, an exception in a ``__del__``
    is dropped (an object the interrupt cut in its constructor, module doc); anything else goes to the
    hook that was there before."""
    if _STATE["raised"] and getattr(u.object, "__name__", None) == "__del__":
        return
    _STATE.get("unraisablehook", sys.__unraisablehook__)(u)


def uninstall() -> None:
    """Put back the handlers ``install()`` replaced (SIGINT, SIGTERM, and SIGALRM, which re-delivers a held
    signal), for a command run from Python rather than as the process."""
    previous = _STATE.pop("previous", None)
    if previous and threading.current_thread() is threading.main_thread():
        with contextlib.suppress(OSError):
            signal.setitimer(signal.ITIMER_REAL, 0)  # a re-delivery still pending
        for s, h in previous.items():
            with contextlib.suppress(ValueError, OSError, TypeError):
                signal.signal(s, h if h is not None else signal.SIG_DFL)
    if sys.unraisablehook is _unraisable:
        sys.unraisablehook = _STATE.pop("unraisablehook", sys.__unraisablehook__)
    _STATE["installed"] = False


def finish(status: int) -> int:
    """The command ends with ``status``: from now on a signal is recorded, not raised, and the process
    exits 130 / 143 if one comes (see module doc). Returns ``status``."""
    _STATE["finishing"] = True
    _STATE["status"] = status
    _cancel_redelivery()
    return status


def _exit_late(now: bool = False) -> None:
    """At exit: a signal that came after ``finish`` still makes the exit status 130 / 143 (``now``: a second
    one, which ends the process at once)."""
    _cancel_redelivery()
    interrupted = _STATE.get("status") in EXIT_STATUS.values()
    if not now and (not _STATE["late"] or interrupted):
        return
    with contextlib.suppress(Exception):
        sys.stdout.flush()
        if not interrupted:
            what = "terminated (SIGTERM)" if _STATE["signum"] == signal.SIGTERM else "interrupted"
            print(f"platebench: {what} while finishing; its outputs are complete", file=sys.stderr, flush=True)
    os._exit(_STATE["status"] if interrupted else exit_status() or 130)


@contextlib.contextmanager
def children_without_sigint():
    """Start child processes in this block with SIGINT blocked, which they inherit (across exec too): a
    Ctrl-C at the terminal reaches every process of the group, and it is the command's to handle (it
    stops its children), not a worker's half-way through its start-up. A SIGINT that comes meanwhile
    reaches this process when the block ends."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def installed() -> bool:
    return bool(_STATE["installed"])


def received() -> int | None:
    """The first signal received since ``install()`` (its number), or None."""
    return _STATE["signum"]


def check() -> None:
    """Raise the recorded signal's exception (call it where a stage ends: if the first one was
    swallowed, the command stops here)."""
    if _STATE["signum"] is not None:
        _cancel_redelivery()
        raise _exception(_STATE["signum"])


def exit_status() -> int | None:
    """130 (SIGINT) or 143 (SIGTERM) once a signal was received, else None."""
    s = _STATE["signum"]
    return None if s is None else EXIT_STATUS.get(s, 128 + int(s))
