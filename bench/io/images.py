"""Image file formats of the dataset: PNG (8/16-bit), OpenEXR (float32), Middlebury PFM.

Every writer is atomic (temporary file, then rename). Readers raise a one-line
``DatasetError`` naming the file and the problem.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

import cv2
import numpy as np
import OpenEXR

from platebench.bench.io.atomic import write_bytes
from platebench.errors import UserValueError


class DatasetError(UserValueError):
    """A dataset file is missing, unreadable or inconsistent."""


def write_png(path: Path, image: np.ndarray) -> None:
    """Write a (H,W) uint8/uint16 image."""
    if image.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"PNG needs uint8 or uint16, got {image.dtype}")
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise OSError(f"could not encode {path}")
    write_bytes(Path(path), buf.tobytes())


def read_png(path: Path) -> np.ndarray:
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: file is missing")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise DatasetError(f"{path}: not a readable PNG image")
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
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp.exr", dir=path.parent)
    os.close(fd)
    try:
        OpenEXR.File(header, channels).write(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def read_exr(path: Path) -> np.ndarray:
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: file is missing")
    try:
        ch = OpenEXR.File(str(path)).channels()
    except Exception as e:  # OpenEXR raises plain exceptions
        raise DatasetError(f"{path}: not a readable OpenEXR file ({e})") from None
    if "Y" in ch:
        return np.asarray(ch["Y"].pixels, np.float32)
    if "U" in ch and "V" in ch:
        return np.stack([ch["U"].pixels, ch["V"].pixels], axis=-1).astype(np.float32)
    if "RGB" in ch:
        return np.asarray(ch["RGB"].pixels, np.float32)
    raise DatasetError(f"{path}: unexpected EXR channels {sorted(ch)}")


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
            raise DatasetError(f"{path}: not a PFM file")
        w, h = map(int, f.readline().split())
        scale = float(f.readline())
        dtype = "<f4" if scale < 0 else ">f4"
        c = 3 if kind == b"PF" else 1
        data = np.frombuffer(f.read(), dtype=dtype)
    if data.size != w * h * c:
        raise DatasetError(f"{path}: truncated PFM ({data.size} of {w * h * c} values)")
    data = data.reshape(h, w, c) if c == 3 else data.reshape(h, w)
    return np.flipud(data).astype(np.float32)
