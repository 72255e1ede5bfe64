"""Files of a method's output, by kind: read what other programs write, write what plug-ins return.

=========  ==========================================  ======================================
kind       reads                                       meaning
=========  ==========================================  ======================================
disparity  ``.pfm`` (Middlebury, float32; +inf or   left view, px, d = u_left - u_right
           NaN = no estimate); ``.png`` 16-bit with
           a scale S: d = value / S, 0 = no estimate
           (KITTI: S = 256)
depth      ``.exr`` (one channel, or Z/Y/depth/R), left view z-depth, metres
           ``.pfm``, ``.npy``
points     ``.ply``, ``.csv`` (x, y, z columns, see    world frame, metres
           ``bench.io.points``), ``.npy`` (N, 3)
mesh       ``.ply`` (also ``.obj``, ``.stl``)          world frame, metres
=========  ==========================================  ======================================

Readers raise ``DatasetError`` with one line naming the file: missing, not a regular file (a FIFO,
a device), unknown format, larger than its header allows (sizes are read from PNG, EXR, PFM, NPY
and PLY headers before anything is allocated, ``bench.io.images``), unreadable, wrong shape.
Writers are atomic (``bench.io.atomic``).
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from platebench.bench.files import IMAGE_MAX_BYTES, regular_size
from platebench.bench.io.atomic import write_bytes
from platebench.bench.io.images import (
    DatasetError,
    check_ply,
    exr_size,
    load_npy,
    read_pfm,
    read_png,
    write_exr,
    write_pfm,
)
from platebench.bench.io.points import read_points_csv

if TYPE_CHECKING:
    import trimesh  # imported where a PLY is read or written: importing it takes a second

__all__ = ["READ_FORMATS", "OUTPUT_FILES", "read_disparity", "read_depth", "read_points", "read_mesh",
           "write_disparity", "write_depth", "write_points", "write_mesh"]

READ_FORMATS = {"disparity": (".pfm", ".png"), "depth": (".exr", ".pfm", ".npy"),
                "points": (".ply", ".csv", ".npy"), "mesh": (".ply", ".obj", ".stl")}
# What a plug-in's output is written as in its reconstruction directory.
OUTPUT_FILES = {"disparity": "disparity.pfm", "depth": "depth.exr", "points": "points.ply", "mesh": "mesh.ply"}


def _check(path: Path, kind: str) -> str:
    path = Path(path)
    size = regular_size(path, f"{kind} file", DatasetError, missing="file is missing")
    if size > IMAGE_MAX_BYTES:
        raise DatasetError(f"{path}: {size} bytes is too large for a {kind} file: allowed at most {IMAGE_MAX_BYTES}")
    ext = path.suffix.lower()
    if ext not in READ_FORMATS[kind]:
        raise DatasetError(f"{path}: unknown format {ext or '(no extension)'!r} for a {kind} file: allowed "
                           f"{', '.join(READ_FORMATS[kind])}")
    return ext


def _npy(path: Path) -> np.ndarray:
    a = load_npy(path)
    if not np.issubdtype(a.dtype, np.number):
        raise DatasetError(f"{path}: holds {a.dtype} values, not numbers")
    return a.astype(np.float64)


def read_disparity(path: Path, scale: float | None = None) -> np.ndarray:
    """(H, W) float64 disparity (px), +inf where the file has no estimate. A PFM's values are kept as
    they are, as the Middlebury SDK reads them (+inf: no estimate; 0, negative values and -inf are
    estimates, which its metrics clip to [0, ndisp]), except NaN, read as +inf (no estimate).
    ``scale``: required for a 16-bit PNG (disparity = value / scale, 0 = no estimate, as KITTI),
    refused otherwise."""
    path = Path(path)
    ext = _check(path, "disparity")
    if ext == ".pfm":
        if scale is not None:
            raise DatasetError(f"{path}: --disparity-scale applies to 16-bit PNG disparities only (PFM holds px)")
        d = read_pfm(path).astype(np.float64)
        if d.ndim != 2:
            raise DatasetError(f"{path}: a disparity PFM must have one channel ('Pf'), got 3 ('PF')")
        return np.where(np.isnan(d), np.inf, d)
    if scale is None:
        raise DatasetError(f"{path}: a PNG disparity needs --disparity-scale (PNG value / scale = px; KITTI: 256)")
    if not (np.isfinite(scale) and scale > 0):
        raise DatasetError(f"--disparity-scale = {scale}: allowed a number > 0")
    img = read_png(path, grey=False)  # its size from the header, before it is decoded
    if img.dtype != np.uint16 or img.ndim != 2:
        raise DatasetError(f"{path}: a disparity PNG must be single-channel 16-bit, got {img.dtype} with shape "
                           f"{img.shape}")
    return np.where(img > 0, img.astype(np.float64) / scale, np.inf)


EXR_DEPTH_CHANNELS = ("Z", "Y", "depth", "Depth", "D", "R")


def _read_exr_depth(path: Path) -> np.ndarray:
    """The depth channel of an EXR: its only channel, else the first of ``EXR_DEPTH_CHANNELS`` present."""
    import OpenEXR  # noqa: PLC0415  (EXR only where an EXR file is read)

    exr_size(path)  # a data window larger than an image of the bench: refused before OpenEXR allocates it
    try:
        ch = OpenEXR.File(str(path)).channels()
    except Exception as e:  # noqa: BLE001  (OpenEXR raises plain exceptions)
        raise DatasetError(f"{path}: not a readable OpenEXR file ({e})") from None
    names = list(ch)
    pick = names[0] if len(names) == 1 else next((n for n in EXR_DEPTH_CHANNELS if n in ch), None)
    if pick is None:
        raise DatasetError(f"{path}: which channel is the depth? found {', '.join(sorted(names))}: allowed one "
                           f"channel, or one named {', '.join(EXR_DEPTH_CHANNELS)}")
    return np.asarray(ch[pick].pixels, np.float64)


def read_depth(path: Path) -> np.ndarray:
    """(H, W) float64 z-depth (metres) from EXR (one channel, or Z/Y/depth/R), PFM or NPY; no estimate
    stays as written (NaN, inf or <= 0)."""
    path = Path(path)
    ext = _check(path, "depth")
    if ext == ".exr":
        z = _read_exr_depth(path)
    elif ext == ".pfm":
        z = read_pfm(path)
    else:
        z = _npy(path)
    if z.ndim == 3 and z.shape[2] == 1:
        z = z[..., 0]
    if z.ndim != 2:
        raise DatasetError(f"{path}: a depth map must have one channel, got shape {z.shape}")
    return np.asarray(z, np.float64)


def read_points(path: Path) -> np.ndarray:
    """(N, 3) float64 world points (metres) from PLY (vertices), CSV or NPY. Rows may hold NaN (scoring
    drops and counts them), except in CSV, whose reader refuses them."""
    path = Path(path)
    ext = _check(path, "points")
    if ext == ".csv":
        return read_points_csv(path)
    if ext == ".npy":
        P = _npy(path)
    else:
        import trimesh  # noqa: PLC0415

        check_ply(path)
        try:
            geom = trimesh.load(path, process=False)
        except Exception as e:  # noqa: BLE001  (trimesh raises many kinds on a bad file)
            raise DatasetError(f"{path}: not a readable PLY ({str(e).splitlines()[0] if str(e) else type(e).__name__})") \
                from None
        P = np.asarray(getattr(geom, "vertices", np.zeros((0, 3))), np.float64)
    if P.ndim != 2 or P.shape[1] != 3:
        raise DatasetError(f"{path}: expected (N, 3) points, got shape {P.shape}")
    return P


def read_mesh(path: Path) -> trimesh.Trimesh:
    """A triangle mesh (world frame, metres) from PLY/OBJ/STL; refused without faces."""
    import trimesh  # noqa: PLC0415

    path = Path(path)
    if _check(path, "mesh") == ".ply":
        check_ply(path)
    try:
        mesh = trimesh.load(path, process=False, force="mesh")
    except Exception as e:  # noqa: BLE001
        raise DatasetError(f"{path}: not a readable mesh ({str(e).splitlines()[0] if str(e) else type(e).__name__})") \
            from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise DatasetError(f"{path}: holds no triangle faces (a point cloud? use --points)")
    return mesh


# ----------------------------------------------------------------------------- writers
def write_disparity(path: Path, disparity: np.ndarray) -> None:
    """Middlebury PFM, +inf where there is no estimate."""
    d = np.asarray(disparity, np.float32)
    write_pfm(path, np.where(np.isfinite(d) & (d > 0), d, np.inf).astype(np.float32))


def write_depth(path: Path, depth: np.ndarray) -> None:
    """One-channel float32 EXR (metres), +inf where there is no estimate."""
    z = np.asarray(depth, np.float32)
    write_exr(path, np.where(np.isfinite(z) & (z > 0), z, np.inf).astype(np.float32))


def write_points(path: Path, points: np.ndarray) -> None:
    """Binary PLY of the finite points (world, metres)."""
    import trimesh  # noqa: PLC0415

    P = np.asarray(points, np.float64).reshape(-1, 3)
    P = P[np.all(np.isfinite(P), axis=1)]
    write_bytes(Path(path), trimesh.PointCloud(P).export(file_type="ply", encoding="binary") if len(P) else
                b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
                b"end_header\n")


def write_mesh(path: Path, mesh: trimesh.Trimesh) -> None:
    write_bytes(Path(path), mesh.export(file_type="ply", encoding="binary"))
