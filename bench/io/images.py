"""Image file formats of the dataset: PNG (8/16-bit), OpenEXR (float32), Middlebury PFM.

Every writer is atomic (temporary file, then rename). Readers raise a one-line
``DatasetError`` naming the file and the problem.
"""
from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from pathlib import Path

import cv2
import numpy as np

from platebench.bench.io.atomic import temp_path, write_bytes
from platebench.errors import UserValueError

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_END = b"IEND\xaeB`\x82"


class DatasetError(UserValueError):
    """A dataset file is missing, unreadable or inconsistent."""


@contextlib.contextmanager
def _c_stderr(sink: list):
    """Hold what C libraries (libpng, OpenEXR) print on file descriptor 2 while reading a damaged file,
    so that the user sees one line naming the file; the captured text goes to ``sink``."""
    try:
        saved = os.dup(2)
    except OSError:
        yield
        return
    with tempfile.TemporaryFile() as buf:
        os.dup2(buf.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            buf.seek(0)
            sink.append(buf.read().decode(errors="replace"))


def _read_file(path: Path) -> bytes:
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: file is missing")
    return path.read_bytes()


def write_png(path: Path, image: np.ndarray) -> None:
    """Write a (H,W) uint8/uint16 image."""
    if image.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"PNG needs uint8 or uint16, got {image.dtype}")
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise OSError(f"could not encode {path}")
    write_bytes(Path(path), buf.tobytes())


def read_png(path: Path) -> np.ndarray:
    """A PNG image as (H,W) uint8/uint16 (colour is converted to grey); one-line DatasetError naming the
    file if it is missing, not a PNG, truncated or damaged."""
    path = Path(path)
    data = _read_file(path)
    if not data.startswith(_PNG_SIGNATURE):
        raise DatasetError(f"{path}: not a PNG file (bad signature)")
    if not data.rstrip(b"\0").endswith(_PNG_END):
        raise DatasetError(f"{path}: truncated PNG (no IEND chunk at the end)")
    said: list = []
    with _c_stderr(said):
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        why = next((ln.strip() for ln in "".join(said).splitlines() if ln.strip()), "cannot decode")
        raise DatasetError(f"{path}: damaged PNG ({why})")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    return img


def write_exr(path: Path, data: np.ndarray) -> None:
    """Write float32 (H,W) as channel Y, (H,W,2) as UV, (H,W,3) as XYZ/RGB-style 3-vector."""
    path = Path(path)
    data = np.ascontiguousarray(data, dtype=np.float32)
    name = {2: "Y", 3: None}.get(data.ndim)
    if data.ndim == 2:
        channels = {"Y": data}
    elif data.ndim == 3 and data.shape[2] == 2:
        channels = {"U": np.ascontiguousarray(data[..., 0]), "V": np.ascontiguousarray(data[..., 1])}
    elif data.ndim == 3 and data.shape[2] == 3:
        channels = {"RGB": data}
    else:
        raise ValueError(f"EXR writer takes (H,W), (H,W,2) or (H,W,3), got {data.shape} ({name})")
    import OpenEXR  # noqa: PLC0415  (only where EXR is written or read: the in-memory pipeline never needs it)

    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = str(temp_path(path))
    try:
        try:
            OpenEXR.File(header, channels).write(tmp)
        except RuntimeError as e:  # OpenEXR says the system's error in words: give it back as the OSError it is
            raise _exr_os_error(e, path) from None
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _exr_os_error(e: RuntimeError, path: Path) -> Exception:
    """An ``OSError`` (errno, ``path``) for OpenEXR's RuntimeError when its text names a system error (a full
    disk, a read-only file system, ...); else the RuntimeError itself."""
    text = str(e)
    for code in (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EIO, errno.ENOENT,
                 errno.EMFILE, errno.ENFILE, errno.EFBIG):
        if os.strerror(code) in text:
            return OSError(code, os.strerror(code), str(path))
    return e


def read_exr(path: Path) -> np.ndarray:
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: file is missing")
    with open(path, "rb"):  # permission errors as the OSError they are (one line naming the file)
        pass
    import OpenEXR  # noqa: PLC0415

    said: list = []
    try:
        with _c_stderr(said):
            ch = OpenEXR.File(str(path)).channels()
            if "Y" in ch:
                return np.asarray(ch["Y"].pixels, np.float32)
            if "U" in ch and "V" in ch:
                return np.stack([ch["U"].pixels, ch["V"].pixels], axis=-1).astype(np.float32)
            if "RGB" in ch:
                return np.asarray(ch["RGB"].pixels, np.float32)
    except Exception as e:  # noqa: BLE001  (OpenEXR raises plain exceptions)
        why = next((ln.split(" - ")[-1].strip() for ln in "".join(said).splitlines() if ln.strip()),
                   str(e).splitlines()[0] if str(e) else type(e).__name__)
        raise DatasetError(f"{path}: not a readable OpenEXR file, truncated or damaged ({why})") from None
    raise DatasetError(f"{path}: unexpected EXR channels {sorted(ch)}: allowed Y, U+V or RGB")


def write_pfm(path: Path, data: np.ndarray) -> None:
    """Middlebury PFM: greyscale 'Pf', little-endian (scale -1), rows stored bottom to top."""
    data = np.asarray(data, np.float32)
    if data.ndim != 2:
        raise ValueError(f"PFM writer takes (H,W), got {data.shape}")
    header = f"Pf\n{data.shape[1]} {data.shape[0]}\n-1\n".encode()
    write_bytes(Path(path), header + np.flipud(data).astype("<f4").tobytes())


def read_pfm(path: Path) -> np.ndarray:
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: file is missing")
    with open(path, "rb") as f:
        kind = f.readline().strip()
        if kind not in (b"Pf", b"PF"):
            raise DatasetError(f"{path}: not a PFM file (first line {kind[:20]!r}: allowed Pf or PF)")
        try:
            w, h = map(int, f.readline().split())
            scale = float(f.readline())
        except ValueError:
            raise DatasetError(f"{path}: bad PFM header: allowed 'WIDTH HEIGHT' then a scale") from None
        if not (0 < w <= 65536 and 0 < h <= 65536) or not np.isfinite(scale) or scale == 0:
            raise DatasetError(f"{path}: bad PFM header ({w} x {h}, scale {scale}): allowed 1 to 65536 pixels, "
                               "scale non-zero")
        dtype = "<f4" if scale < 0 else ">f4"
        c = 3 if kind == b"PF" else 1
        raw = f.read()
    if len(raw) != 4 * w * h * c:
        raise DatasetError(f"{path}: truncated PFM ({len(raw)} of {4 * w * h * c} bytes of data)")
    data = np.frombuffer(raw, dtype=dtype)
    data = data.reshape(h, w, c) if c == 3 else data.reshape(h, w)
    return np.flipud(data).astype(np.float32)


def read_npy(path: Path, shape: tuple | None = None) -> np.ndarray:
    """A float .npy array (no pickles), finite, of ``shape`` (None: any length on that axis); one-line
    DatasetError naming the file otherwise."""
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: file is missing")
    try:
        a = np.load(path, allow_pickle=False)
    except (ValueError, EOFError, OSError) as e:
        if isinstance(e, OSError) and e.errno is not None:
            raise
        why = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise DatasetError(f"{path}: not a readable .npy array, truncated or damaged ({why})") from None
    if not np.issubdtype(a.dtype, np.number):
        raise DatasetError(f"{path}: holds {a.dtype} values: allowed numbers")
    if shape is not None and (a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape))):
        want = "(" + ",".join("N" if s is None else str(s) for s in shape) + ")"
        raise DatasetError(f"{path}: must be a finite {want} array, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise DatasetError(f"{path}: must be a finite array, holds NaN or inf")
    return a
