"""Opening input files: regular files only, read with a size cap, checked before any byte is read.

Every file PlateBench reads (a ``--config``, a sweep spec, a dataset's JSON and images, another
program's output) is opened with ``O_NONBLOCK`` and checked on the open descriptor (``fstat``): a
FIFO, a socket or a device is refused at once (reading one would block forever or never end:
``/dev/zero``, ``/dev/urandom``), a directory is named as one, and a file larger than the cap of
its kind is refused from its size before it is read. Errors are one line naming the path.

Size caps (bytes) of the kinds read whole into memory: ``CONFIG_MAX_BYTES`` for TOML
configurations and sweep specs, ``JSON_MAX_BYTES`` for a dataset's JSON records,
``TABLE_MAX_BYTES`` for CSV tables, ``IMAGE_MAX_BYTES`` for an image or array file. Array sizes
are checked from the files' headers (``bench.io.images``, ``bench.io.method_outputs``).
"""
from __future__ import annotations

import contextlib
import hashlib
import os
import stat
from pathlib import Path

from platebench.errors import UserValueError

__all__ = ["CONFIG_MAX_BYTES", "file_sha256", "JSON_MAX_BYTES", "TABLE_MAX_BYTES", "IMAGE_MAX_BYTES", "InputFileError",
           "file_kind", "open_regular", "read_capped", "regular_size", "is_regular", "require_dir"]

MIB = 1 << 20
CONFIG_MAX_BYTES = 4 * MIB  # a sweep spec lists axes and values: kilobytes; 4 MiB is far beyond any real one
JSON_MAX_BYTES = 256 * MIB  # sample.json, manifest.json (a 10^5-sample manifest is about 100 MB), score.json
TABLE_MAX_BYTES = 4096 * MIB  # results.csv, points.csv: one row per (sample, method) or per point
IMAGE_MAX_BYTES = 4096 * MIB  # a float32 map of 8192 x 8192 x 3 is 805 MB; 16-bit PNGs are smaller


class InputFileError(UserValueError):
    """An input path that is not a regular file, or a file too large to be what it claims."""


_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISSOCK, "a socket"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))


def file_kind(mode: int) -> str:
    """'a regular file', 'a directory', 'a FIFO (named pipe)', ... for an ``st_mode``."""
    if stat.S_ISREG(mode):
        return "a regular file"
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def _refuse(path: Path, st: os.stat_result, what: str, error: type) -> Exception:
    kind = file_kind(st.st_mode)
    if stat.S_ISDIR(st.st_mode):
        return error(f"{path}: is a directory: allowed a {what}")
    return error(f"{path}: is {kind}, not a regular file: allowed a {what}")


def is_regular(path: Path) -> bool:
    """Whether ``path`` (followed if a link) is a regular file; False when it cannot be looked at."""
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except (OSError, ValueError):
        return False


def regular_size(path: Path, what: str = "file", error: type = InputFileError, missing: str | None = None) -> int:
    """The size in bytes of the regular file ``path``; a one-line ``error`` when it is missing
    (``missing``: the message's words, default '{what} is missing'), a directory, a FIFO or a device.
    Nothing is opened."""
    path = Path(path)
    try:
        st = os.stat(path)
    except FileNotFoundError:
        raise error(f"{path}: {missing or what + ' is missing'}") from None
    except NotADirectoryError:
        raise error(f"{path}: {missing or what + ' is missing'} (a part of the path is a file)") from None
    if not stat.S_ISREG(st.st_mode):
        raise _refuse(path, st, what, error)
    return st.st_size


@contextlib.contextmanager
def open_regular(path: Path, max_bytes: int, what: str = "file", error: type = InputFileError,
                 missing: str | None = None):
    """Yield a binary file object of the regular file ``path`` no larger than ``max_bytes``; refused
    (one-line ``error``) before reading when it is missing, not a regular file (checked on the opened
    descriptor, so a FIFO neither blocks nor is read) or larger than the cap. Permission errors stay
    the ``OSError`` they are (they name the path)."""
    path = Path(path)
    regular_size(path, what, error, missing)  # the common refusals, with their own words
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except FileNotFoundError:
        raise error(f"{path}: {missing or what + ' is missing'}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):  # swapped for something else since the look
            raise _refuse(path, st, what, error)
        if st.st_size > max_bytes:
            raise error(f"{path}: {st.st_size} bytes is too large for a {what}: allowed at most {max_bytes} bytes")
        f = os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
    with f:
        yield f


def read_capped(path: Path, max_bytes: int, what: str = "file", error: type = InputFileError,
                missing: str | None = None) -> bytes:
    """The bytes of the regular file ``path`` (see ``open_regular``); a file that grows past
    ``max_bytes`` while read is refused too."""
    with open_regular(path, max_bytes, what, error, missing) as f:
        data = f.read()  # one buffer of the size fstat gave (already checked against the cap by open_regular)
    if len(data) > max_bytes:
        raise error(f"{path}: more than {max_bytes} bytes: too large for a {what}")
    return data



def require_dir(path: Path, what: str = "directory", error: type = InputFileError) -> Path:
    """``path`` if it is a directory (followed if a link); else a one-line ``error``: '{what} is missing',
    or what it is instead ('is a regular file, not a {what}')."""
    path = Path(path)
    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        raise error(f"{path}: {what} is missing") from None
    if not stat.S_ISDIR(st.st_mode):
        raise error(f"{path}: is {file_kind(st.st_mode)}, not a {what}")
    return path


def file_sha256(path: Path) -> str:
    """The sha256 of a file's bytes (hex), read in 1 MiB pieces."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()
