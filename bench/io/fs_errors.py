"""Errors of the place a run writes to, not of its work: a full disk, a read-only or vanished output.

A sample does not fail because the disk is full: such an error stops the whole run, with the
run's state "interrupted" and nothing recorded as a sample's or a method's failure, and
``--resume`` finishes the run once the cause is gone (``bench.sweep.executors``). ``environmental``
tells these errors apart from the work's own.
"""
from __future__ import annotations

import errno
import os
from pathlib import Path

from platebench.errors import PlateBenchError

__all__ = ["environmental", "RunStopped", "ALWAYS", "UNDER_OUTPUT"]

# errors of the file system whatever the path: no space or quota left, read-only, I/O error, no file handles
ALWAYS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EIO, errno.EFBIG, errno.EMFILE, errno.ENFILE})
# errors of the output when they concern a path inside it: made unwritable, removed under the run
UNDER_OUTPUT = frozenset({errno.EACCES, errno.EPERM, errno.ENOENT, errno.ENOTDIR, errno.ESTALE})


class RunStopped(PlateBenchError):
    """The run stopped for an error of its output (one line naming the output, the cause and what to do)."""


def _inside(path, root: Path) -> bool:
    try:
        p = Path(os.path.abspath(os.fsdecode(path)))
    except (TypeError, ValueError):
        return False
    root = Path(os.path.abspath(root))
    return p == root or root in p.parents


def environmental(exc: BaseException | None, output: Path | None = None) -> bool:
    """Whether ``exc`` is an error of the file system rather than of the work (module doc): an ``OSError``
    whose errno is in ``ALWAYS``, or in ``UNDER_OUTPUT`` for a path inside ``output``."""
    if not isinstance(exc, OSError) or exc.errno is None:
        return False
    if exc.errno in ALWAYS:
        return True
    if exc.errno in UNDER_OUTPUT and output is not None:
        return any(f is not None and _inside(f, Path(output)) for f in (exc.filename, exc.filename2))
    return False


def describe(exc: OSError) -> str:
    """The error's cause in words, lower case ("no space left on device")."""
    text = exc.strerror or os.strerror(exc.errno or 0)
    return text[:1].lower() + text[1:]
