"""Atomic writes, staged outputs and output locks: an output appears complete or not at all.

* ``write_bytes``/``write_text``/``write_json``: a file is written to a temporary name in
  the same directory, fsync'ed and renamed over the target (``os.replace`` is atomic on POSIX).
* ``staged_output(target, overwrite=...)``: the one way a command makes an output directory.
  Before any work it refuses an existing target without ``overwrite``, takes the target's
  lock (``OutputLock``: a second writer is refused with the holder's PID and host), sweeps
  stale leftovers of earlier killed writers, and creates the staging directory next to the
  target (so an unwritable place fails at once, not after the work). It yields the staging
  directory; on success the finished output is swapped in (Linux ``renameat2``
  RENAME_EXCHANGE / RENAME_NOREPLACE where the file system has them, else two renames) and the
  old output removed; on any exception (Ctrl-C and SIGTERM included: ``bench.interrupts``
  turns SIGTERM into an exception) the staging directory is removed and the target is untouched.
* ``staged_directory``: the same without the lock (for sub-directories of an output that is
  already staged or locked).

Temporary names carry their owner: ``.tmp-NAME~HOST~PID~RANDOM`` (directories) and
``.NAME~HOST~PID~RANDOM.tmp`` (files). ``sweep_stale`` removes those whose owner process is gone
(same host, PID no longer running), so a kill -9 leaves nothing that the next writer does not
clean, and a live writer's staging is never touched.
"""
from __future__ import annotations

import contextlib
import ctypes
import datetime as _dt
import errno
import fcntl
import json
import os
import secrets
import shutil
import socket
import stat
import sys
from pathlib import Path

import numpy as np

from platebench.errors import PlateBenchError

__all__ = ["write_bytes", "write_text", "write_json", "staged_output", "staged_directory", "sweep_stale",
           "OutputLock", "OutputLockedError", "OutputExistsError",
           "owner_alive", "temp_owner", "is_temp_name", "check_target", "temp_path", "pid_alive", "swap_in",
           "rename_noreplace", "target_of_temp", "HOST"]

HOST = socket.gethostname()
_SEP = "~"


class OutputLockedError(PlateBenchError):
    """Another live process holds the output's lock (the message names its PID and host)."""


class OutputExistsError(PlateBenchError, FileExistsError):
    """The output exists and ``--overwrite`` was not given."""


# ----------------------------------------------------------------------------- owners of temporary names
def _tag() -> str:
    return f"{_SEP}{HOST}{_SEP}{os.getpid()}{_SEP}{secrets.token_hex(4)}"


def temp_owner(name: str) -> tuple[str, int] | None:
    """(host, pid) of a temporary name made here (``.tmp-NAME~HOST~PID~R`` or ``.NAME~HOST~PID~R.tmp``),
    None for any other name."""
    if not is_temp_name(name):
        return None
    base = name[:-4] if name.endswith(".tmp") else name
    parts = base.rsplit(_SEP, 3)
    if len(parts) != 4 or not parts[2].isdigit():
        return None
    return parts[1], int(parts[2])


def target_of_temp(path: Path) -> Path:
    """``path`` with every temporary name in it replaced by the output it stands for (``.tmp-NAME~...``
    and ``.NAME~....tmp`` -> ``NAME``): a file inside a staging directory is named where it will be.
    Messages name the target, never the temporary name."""
    def target(name: str) -> str:
        if name.startswith(".tmp-") and _SEP in name:
            return name[len(".tmp-"):].split(_SEP, 1)[0]
        if name.startswith(".") and name.endswith(".tmp") and _SEP in name:
            return name[1:].split(_SEP, 1)[0]
        return name
    path = Path(path)
    return Path(*(target(part) for part in path.parts)) if path.parts else path


def is_temp_name(name: str) -> bool:
    return name.startswith((".tmp-", ".old-")) or (name.startswith(".") and name.endswith(".tmp"))


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:  # a zombie (killed, not yet reaped) is gone for our purposes
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] not in ("Z", "X")
    except (OSError, IndexError):
        return True


def owner_alive(host: str, pid: int) -> bool:
    """Whether the process that made a temporary name may still be writing it (other hosts: assumed so)."""
    return host != HOST or pid_alive(pid)


# ----------------------------------------------------------------------------- files
def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temporary file in the same directory, then rename).
    An OSError (a full disk, no permission, ``path`` a directory) names ``path``, never the
    temporary file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.parent / f".{path.name}{_tag()}.tmp"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666 & ~_umask())
    except OSError as e:
        raise _naming(e, path) from None
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as e:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        if isinstance(e, OSError):
            raise _naming(e, path) from None
        raise


def _naming(e: OSError, path: Path) -> OSError:
    """``e`` as the same kind of OSError naming ``path`` (its errno and words kept)."""
    if e.errno is None:
        return e
    return type(e)(e.errno, e.strerror or os.strerror(e.errno), str(path))


def write_text(path: Path, text: str) -> None:
    write_bytes(path, text.encode())


def write_json(path: Path, obj) -> None:
    write_text(path, json.dumps(obj, indent=2, default=json_default) + "\n")


def json_default(o):
    """``json.dumps`` default: numpy arrays and scalars, paths."""
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def temp_path(path: Path, suffix: str = "") -> Path:
    """A temporary sibling name of ``path`` owned by this process (swept by ``sweep_stale`` once it dies)."""
    path = Path(path)
    return path.parent / f".{path.name}{_tag()}{suffix}.tmp"


# ----------------------------------------------------------------------------- renames
_RENAME_NOREPLACE, _RENAME_EXCHANGE, _AT_FDCWD = 1, 2, -100
try:
    _renameat2 = ctypes.CDLL(None, use_errno=True).renameat2
except (OSError, AttributeError):
    _renameat2 = None


def _rename2(src: Path, dst: Path, flags: int) -> bool:
    """renameat2(2); False where the C library or the file system does not have it."""
    if _renameat2 is None:
        return False
    if _renameat2(_AT_FDCWD, os.fsencode(str(src)), _AT_FDCWD, os.fsencode(str(dst)), flags) == 0:
        return True
    e = ctypes.get_errno()
    if e in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP):
        return False
    raise OSError(e, os.strerror(e), str(dst))


def rename_noreplace(src: Path, dst: Path) -> None:
    """Rename ``src`` to ``dst``; FileExistsError if ``dst`` exists (atomically where the FS allows)."""
    if _rename2(src, dst, _RENAME_NOREPLACE):
        return
    if os.path.lexists(dst):
        raise FileExistsError(errno.EEXIST, "exists", str(dst))
    os.rename(src, dst)


def swap_in(stage: Path, target: Path) -> None:
    """Put the finished ``stage`` at ``target``; an old ``target`` ends at ``stage``'s name (to be removed).

    With RENAME_EXCHANGE the swap is one atomic step; else the old target is renamed to the stage's
    name first (a kill between the two renames leaves the old output under the stage's name, which
    ``sweep_stale`` removes, and no output at ``target``)."""
    if not os.path.lexists(target):
        rename_noreplace(stage, target)
        return
    if _rename2(stage, target, _RENAME_EXCHANGE):
        return
    aside = stage.with_name(stage.name + ".old")
    os.rename(target, aside)
    os.rename(stage, target)
    os.rename(aside, stage)


# ----------------------------------------------------------------------------- locks
class OutputLock:
    """An exclusive lock on an output path: ``flock`` on the sibling file ``.NAME.lock``.

    The lock file holds the holder's PID, host, start time and command. ``acquire`` refuses a
    lock held by a live process (``OutputLockedError`` naming PID and host); a lock file left by a
    process that is gone (the kernel released its flock) is taken over, and ``stale`` then holds
    the previous holder's record (the caller says so). ``release`` removes the file. An OSError while
    the record is written (a full disk) names the lock file's path and leaves no lock file."""

    def __init__(self, target: Path, what: str = "output"):
        self.target = Path(target).absolute()
        self.path = self.target.parent / f".{self.target.name}.lock"
        self.what = what
        self.stale: dict | None = None
        self._fd: int | None = None

    @staticmethod
    def read(path: Path) -> dict | None:
        try:
            d = json.loads(Path(path).read_text() or "null")
        except (OSError, ValueError):
            return None
        return d if isinstance(d, dict) else None

    def holder(self) -> dict | None:
        """The live holder's record, or None if nobody holds the lock."""
        if not self.path.exists():
            return None
        try:
            fd = os.open(self.path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
        except OSError:
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return self.read(self.path) or {}
        finally:
            os.close(fd)
        return None

    def acquire(self) -> "OutputLock":
        self.target.parent.mkdir(parents=True, exist_ok=True)
        for _ in range(20):
            try:  # never through a link, never a file that is not a lock: it would be written over
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o666 & ~_umask())
            except OSError as e:
                if e.errno == errno.ELOOP or os.path.islink(self.path):
                    raise OutputLockedError(f"{self.path}: is a symbolic link where {self.target.name}'s lock file "
                                            "goes: refusing to write through it (remove it)") from None
                raise
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                os.close(fd)
                raise OutputLockedError(f"{self.path}: is not a regular file where {self.target.name}'s lock file "
                                        "goes: refusing to use it (remove it)")
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                h = self.read(self.path) or {}
                raise OutputLockedError(
                    f"{self.target} is being written by another platebench process (PID {h.get('pid', '?')} on "
                    f"host {h.get('host', '?')}, since {h.get('since', '?')}: {h.get('command', '?')}): wait for it "
                    f"to finish, or use another --out") from None
            try:  # the file may have been unlinked by its last holder between our open and flock
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if not same:
                os.close(fd)
                continue
            old = os.read(fd, 1 << 16)
            if old.strip():
                try:
                    prev = json.loads(old)
                except ValueError:
                    prev = None
                if not (isinstance(prev, dict) and "pid" in prev):
                    os.close(fd)
                    raise OutputLockedError(f"{self.path}: holds something that is not a platebench lock record, where "
                                            f"{self.target.name}'s lock file goes: refusing to write over it (move "
                                            "it away)")
                self.stale = prev
            rec = {"pid": os.getpid(), "host": HOST, "since": _dt.datetime.now().isoformat(timespec="seconds"),
                   "command": " ".join([Path(sys.argv[0]).name, *sys.argv[1:]])[:300] if sys.argv else "python"}
            try:
                os.lseek(fd, 0, os.SEEK_SET)
                os.ftruncate(fd, 0)
                os.write(fd, json.dumps(rec).encode())
                os.fsync(fd)
            except OSError as e:  # a full disk, a quota: the error names the lock file, which is not left behind
                with contextlib.suppress(OSError):
                    os.unlink(self.path)
                os.close(fd)
                raise _naming(e, self.path) from None
            self._fd = fd
            return self
        raise OutputLockedError(f"{self.target}: could not take the lock {self.path} (it keeps changing)")

    def stale_note(self) -> str | None:
        if self.stale is None:
            return None
        s = self.stale
        return (f"took over the stale lock of {self.target} (PID {s.get('pid', '?')} on host {s.get('host', '?')}, "
                f"since {s.get('since', '?')}: no longer running)")

    def release(self) -> None:
        fd, self._fd = self._fd, None
        if fd is None:
            return
        with contextlib.suppress(OSError):
            os.unlink(self.path)
        os.close(fd)

    @property
    def held(self) -> bool:
        return self._fd is not None

    def __enter__(self) -> "OutputLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def _note(msg: str) -> None:
    print(f"platebench: note: {msg}", file=sys.stderr)


# ----------------------------------------------------------------------------- staged outputs
def _make_stage(target: Path) -> Path:
    stage = target.parent / f".tmp-{target.name}{_tag()}"
    try:
        os.mkdir(stage, 0o777 & ~_umask())
    except OSError as e:
        raise _naming(e, target) from None
    return stage


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def check_target(target: Path, overwrite: bool, what: str = "output") -> Path:
    """Refuse before any work: ``target`` exists without ``overwrite``, or is not a directory."""
    target = Path(target)
    if os.path.lexists(target):
        if not overwrite:
            raise OutputExistsError(errno.EEXIST, f"{what} already exists (use --overwrite to replace it)",
                                    str(target))
        if not target.is_dir():
            raise OutputExistsError(errno.EEXIST, f"exists and is not a directory: refusing to replace it with "
                                    f"a {what} directory", str(target))
    return target


@contextlib.contextmanager
def staged_output(target: Path, overwrite: bool = False, what: str = "output", note=_note, lock: bool = True,
                  check=None):
    """Yield a staging directory that replaces ``target`` once the block finishes (see module doc).

    Checked before any work: ``target`` does not exist (or ``overwrite``), nobody else writes it
    (its ``OutputLock``), and its parent is writable (the staging directory is created there).
    ``check(target)``: the caller's own rule (``bench.io.outputs``), run again under the lock and
    just before the swap. ``note(msg)`` is told when a stale lock of a killed writer is taken over."""
    target = check_target(Path(target).absolute(), overwrite, what)
    target.parent.mkdir(parents=True, exist_ok=True)
    guard = OutputLock(target, what) if lock else None
    if guard is not None:
        guard.acquire()
        if guard.stale_note() and note:
            note(guard.stale_note())
    stage = None
    try:
        check_target(target, overwrite, what)  # again, under the lock
        if check is not None:
            check(target)
        sweep_stale(target.parent, only=target.name)
        stage = _make_stage(target)
        yield stage
        check_target(target, overwrite, what)
        if check is not None:
            check(target)
        swap_in(stage, target)
        _remove(stage)  # the old output, if there was one
    except BaseException:
        if stage is not None and os.path.lexists(stage):
            _remove(stage)
        raise
    finally:
        if guard is not None:
            guard.release()


@contextlib.contextmanager
def staged_directory(target: Path, overwrite: bool = False):
    """``staged_output`` without the lock: for parts of an output that is itself staged or locked."""
    with staged_output(target, overwrite=overwrite, lock=False) as stage:
        yield stage


def sweep_stale(parent: Path, only: str | None = None, force: bool = False) -> int:
    """Remove leftovers of interrupted writes in ``parent``: temporary names (``.tmp-*`` dirs,
    ``.*.tmp`` files) whose owner process is gone (``force``: whoever owns them); ``only``: those of
    one target name. Returns how many were removed."""
    n = 0
    parent = Path(parent)
    if not parent.is_dir():
        return 0
    for p in parent.iterdir():
        name = p.name
        if not is_temp_name(name):
            continue
        if only is not None and not (name.startswith((f".tmp-{only}{_SEP}", f".{only}{_SEP}"))):
            continue
        owner = temp_owner(name)
        if not force and owner is not None and owner_alive(*owner):
            continue
        _remove(p)
        n += 1
    return n
