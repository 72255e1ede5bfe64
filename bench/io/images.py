"""Image and array file formats of the dataset: PNG (8/16-bit), OpenEXR (float32), Middlebury PFM,
NumPy .npy; and the size check of PLY files.

Every writer is atomic (temporary file, then rename). Readers raise a one-line
``DatasetError`` naming the file and the problem. Readers open regular files only
(``bench.files``) and check the size a file's header declares before anything is allocated:
an image holds at most ``MAX_IMAGE_SIDE_PX`` pixels a side and ``MAX_IMAGE_PIXELS`` in all, an
array at most ``MAX_ARRAY_VALUES`` values, a PLY element at most ``MAX_ARRAY_VALUES`` items, and
the file must be long enough to hold what its header declares (a 1.7 MB PNG declaring
30000 x 30000 pixels, a .npy declaring (100000, 100000), an ASCII PLY declaring 10^12 vertices
and holding one: refused from the header).
"""
from __future__ import annotations

import contextlib
import errno
import os
import tempfile
from pathlib import Path

import cv2
import numpy as np

from platebench.bench.files import IMAGE_MAX_BYTES, open_regular, read_capped
from platebench.bench.io.atomic import temp_path, write_bytes
from platebench.errors import UserValueError

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_END = b"IEND\xaeB`\x82"
# The largest image a sample can hold: scene width and height are at most 8192 px (bench.config);
# another program's map of a sample has the sample's size.
MAX_IMAGE_SIDE_PX = 65536
MAX_IMAGE_PIXELS = 8192 * 8192
MAX_ARRAY_VALUES = 3 * MAX_IMAGE_PIXELS  # a 3-channel map, or one 3D point per pixel


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


def _read_file(path: Path, what: str = "file") -> bytes:
    return read_capped(Path(path), IMAGE_MAX_BYTES, what, DatasetError, missing="file is missing")


def _check_pixels(path: Path, width: int, height: int, channels: int = 1, what: str = "image") -> None:
    """Refuse a header that declares more pixels than an image of the bench can hold."""
    if not (0 < width <= MAX_IMAGE_SIDE_PX and 0 < height <= MAX_IMAGE_SIDE_PX) or width * height > MAX_IMAGE_PIXELS \
            or width * height * channels > MAX_ARRAY_VALUES:
        raise DatasetError(f"{path}: its header declares a {width} x {height} {what}: allowed 1 to "
                           f"{MAX_IMAGE_SIDE_PX} px a side and at most {MAX_IMAGE_PIXELS} pixels")


def png_size(path: Path, head: bytes) -> tuple[int, int]:
    """(width, height) from a PNG's IHDR chunk (the first 24 bytes), checked (``_check_pixels``)."""
    if not head.startswith(_PNG_SIGNATURE):
        raise DatasetError(f"{path}: not a PNG file (bad signature)")
    if len(head) < 24 or head[12:16] != b"IHDR":
        raise DatasetError(f"{path}: truncated PNG (no IHDR chunk)")
    w, h = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    _check_pixels(path, w, h, what="PNG image")
    return w, h


def write_png(path: Path, image: np.ndarray) -> None:
    """Write a (H,W) uint8/uint16 image."""
    if image.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"PNG needs uint8 or uint16, got {image.dtype}")
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise OSError(f"could not encode {path}")
    write_bytes(Path(path), buf.tobytes())


def read_png(path: Path, grey: bool = True) -> np.ndarray:
    """A PNG image as (H,W) uint8/uint16 (colour is converted to grey; ``grey=False``: kept as decoded);
    one-line DatasetError naming the file if it is missing, not a regular file, not a PNG, larger than
    an image of the bench (from its header, before decoding), truncated or damaged."""
    path = Path(path)
    data = _read_file(path, "PNG image")
    png_size(path, data[:24])  # before anything is decoded
    if not data.rstrip(b"\0").endswith(_PNG_END):
        raise DatasetError(f"{path}: truncated PNG (no IEND chunk at the end)")
    said: list = []
    with _c_stderr(said):
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
    if img is None:
        why = next((ln.strip() for ln in "".join(said).splitlines() if ln.strip()), "cannot decode")
        raise DatasetError(f"{path}: damaged PNG ({why})")
    if img.ndim == 3 and grey:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY if img.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
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


def exr_size(path: Path) -> tuple[int, int] | None:
    """(width, height) of an OpenEXR file's data window, read from its header and checked
    (``_check_pixels``) before OpenEXR allocates anything; None when the header does not say (OpenEXR
    then refuses the file itself). Missing, not a regular file: one-line DatasetError."""
    with open_regular(Path(path), IMAGE_MAX_BYTES, "OpenEXR image", DatasetError, missing="file is missing") as f:
        head = f.read(1 << 16)
    if head[:4] != b"\x76\x2f\x31\x01":
        return None
    i = 8  # magic, version flags; then attributes: name\0 type\0 int32 size, value; an empty name ends them
    while i < len(head) and head[i] != 0:
        name_end = head.find(b"\0", i)
        type_end = head.find(b"\0", name_end + 1)
        if name_end < 0 or type_end < 0 or type_end + 5 > len(head):
            return None
        size = int.from_bytes(head[type_end + 1:type_end + 5], "little", signed=True)
        value = head[type_end + 5:type_end + 5 + size]
        if head[i:name_end] == b"dataWindow" and head[name_end + 1:type_end] == b"box2i" and len(value) == 16:
            x0, y0, x1, y1 = (int.from_bytes(value[k:k + 4], "little", signed=True) for k in range(0, 16, 4))
            w, h = x1 - x0 + 1, y1 - y0 + 1
            _check_pixels(path, w, h, what="OpenEXR image")
            return w, h
        if size < 0:
            return None
        i = type_end + 5 + size
    return None


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
    exr_size(path)  # missing, not a regular file, too large: refused before OpenEXR reads it
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
    """A Middlebury PFM as (H, W) or (H, W, 3) float32, top row first; its size checked from the header
    and against the file's length before the data is read: a file shorter than its header declares is
    refused as truncated, a longer one as longer than declared (``DatasetError``, one line)."""
    path = Path(path)
    with open_regular(path, IMAGE_MAX_BYTES, "PFM image", DatasetError, missing="file is missing") as f:
        size = os.fstat(f.fileno()).st_size
        kind = f.readline(16).strip()
        if kind not in (b"Pf", b"PF"):
            raise DatasetError(f"{path}: not a PFM file (first line {kind[:20]!r}: allowed Pf or PF)")
        try:
            w, h = map(int, f.readline(64).split())
            scale = float(f.readline(64))
        except ValueError:
            raise DatasetError(f"{path}: bad PFM header: allowed 'WIDTH HEIGHT' then a scale") from None
        if not (0 < w <= 65536 and 0 < h <= 65536) or not np.isfinite(scale) or scale == 0:
            raise DatasetError(f"{path}: bad PFM header ({w} x {h}, scale {scale}): allowed 1 to 65536 pixels, "
                               "scale non-zero")
        dtype = "<f4" if scale < 0 else ">f4"
        c = 3 if kind == b"PF" else 1
        _check_pixels(path, w, h, c, "PFM image")
        have, want = size - f.tell(), 4 * w * h * c
        if have < want:
            raise DatasetError(f"{path}: truncated PFM ({have} of {want} bytes of data)")
        if have > want:
            raise DatasetError(f"{path}: PFM longer than its header declares ({have} bytes of data, the header's "
                               f"{w} x {h}{' x 3' if c == 3 else ''} float32 pixels are {want} bytes)")
        raw = f.read(4 * w * h * c)
    if len(raw) != 4 * w * h * c:
        raise DatasetError(f"{path}: truncated PFM ({len(raw)} of {4 * w * h * c} bytes of data)")
    data = np.frombuffer(raw, dtype=dtype)
    data = data.reshape(h, w, c) if c == 3 else data.reshape(h, w)
    return np.flipud(data).astype(np.float32)


def load_npy(path: Path) -> np.ndarray:
    """A numeric .npy array (no pickles). Its header (shape, dtype) is read and checked first: at most
    ``MAX_ARRAY_VALUES`` values, numbers only, and the file long enough to hold them; one-line
    DatasetError naming the file otherwise."""
    path = Path(path)
    with open_regular(path, IMAGE_MAX_BYTES, ".npy array", DatasetError, missing="file is missing") as f:
        try:
            version = np.lib.format.read_magic(f)
            header = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
            shape, _fortran, dtype = header(f)
        except (ValueError, EOFError, OSError) as e:
            if isinstance(e, OSError) and e.errno is not None:
                raise
            why = str(e).splitlines()[0] if str(e) else type(e).__name__
            raise DatasetError(f"{path}: not a readable .npy array, truncated or damaged ({why})") from None
        if dtype.hasobject or not (np.issubdtype(dtype, np.number) or np.issubdtype(dtype, np.bool_)):
            raise DatasetError(f"{path}: holds {dtype} values: allowed numbers")
        n = int(np.prod(shape, dtype=object))
        if n > MAX_ARRAY_VALUES:
            raise DatasetError(f"{path}: its header declares shape {tuple(shape)} ({n} values): allowed at most "
                               f"{MAX_ARRAY_VALUES} values")
        left = os.fstat(f.fileno()).st_size - f.tell()
        if left < n * dtype.itemsize:
            raise DatasetError(f"{path}: truncated .npy array ({left} of {n * dtype.itemsize} bytes of data)")
        f.seek(0)
        try:
            return np.load(f, allow_pickle=False)
        except (ValueError, EOFError) as e:
            why = str(e).splitlines()[0] if str(e) else type(e).__name__
            raise DatasetError(f"{path}: not a readable .npy array, truncated or damaged ({why})") from None


def read_npy(path: Path, shape: tuple | None = None) -> np.ndarray:
    """A float .npy array (no pickles), finite, of ``shape`` (None: any length on that axis); one-line
    DatasetError naming the file otherwise (``load_npy``)."""
    path = Path(path)
    a = load_npy(path)
    if not np.issubdtype(a.dtype, np.number):
        raise DatasetError(f"{path}: holds {a.dtype} values: allowed numbers")
    if shape is not None and (a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape))):
        want = "(" + ",".join("N" if s is None else str(s) for s in shape) + ")"
        raise DatasetError(f"{path}: must be a finite {want} array, got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise DatasetError(f"{path}: must be a finite array, holds NaN or inf")
    return a


_PLY_BYTES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2,
              "int": 4, "uint": 4, "int32": 4, "uint32": 4, "float": 4, "float32": 4, "double": 8, "float64": 8}


def check_ply(path: Path) -> None:
    """Refuse a PLY file whose header declares more items than a file of its length can hold (every
    ASCII value takes at least 2 bytes, every binary one its type's size) or more than
    ``MAX_ARRAY_VALUES`` items of an element, before a reader allocates them; also a file that is
    missing or not a regular file. A file that is not PLY is left to its reader."""
    path = Path(path)
    with open_regular(path, IMAGE_MAX_BYTES, "PLY file", DatasetError, missing="file is missing") as f:
        size = os.fstat(f.fileno()).st_size
        head = f.read(1 << 16)
    if not head.startswith(b"ply"):
        return
    end = head.find(b"end_header")
    if end < 0:
        raise DatasetError(f"{path}: PLY header without 'end_header' in its first {len(head)} bytes")
    newline = head.find(b"\n", end)
    body = size - (newline + 1 if newline >= 0 else len(head))
    binary, elements = False, []  # [name, count, bytes per item at least]
    for line in head[:end].decode("ascii", "replace").splitlines():
        t = line.split()
        if len(t) >= 2 and t[0] == "format":
            binary = t[1].startswith("binary")
        elif len(t) >= 3 and t[0] == "element":
            try:
                count = int(t[2])
            except ValueError:
                raise DatasetError(f"{path}: PLY element {t[1]!r} has count {t[2]!r}: allowed a whole number") from None
            if not 0 <= count <= MAX_ARRAY_VALUES:
                raise DatasetError(f"{path}: its PLY header declares {count} {t[1]} items: allowed 0 to "
                                   f"{MAX_ARRAY_VALUES}")
            elements.append([t[1], count, 0])
        elif len(t) >= 3 and t[0] == "property" and elements:
            elements[-1][2] += _PLY_BYTES.get(t[2] if t[1] == "list" else t[1], 1) if binary else 2
    need = sum(count * max(per_item, 1) for _name, count, per_item in elements)
    if need > body:
        declared = ", ".join(f"{count} {name}" for name, count, _ in elements)
        raise DatasetError(f"{path}: its PLY header declares {declared}, which need at least {need} bytes, but "
                           f"{body} follow it: truncated or damaged")
