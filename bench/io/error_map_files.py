"""A method's scored error map, written beside its output in its reconstruction directory
(``ERROR_MAP_FILE``, ``error_map.npz``) when the output is scored (``bench.run.outputs``), or beside
the score document ``F.score.json`` that ``platebench evaluate`` writes for a file (``F.error_map.npz``,
``error_map_beside``), and read
by the report's error map (``bench.report.plots.plot_output_error_map``): the report draws what was
scored and computes no error itself.

The file is a compressed NumPy ``.npz`` (``numpy.savez_compressed``, no pickles) holding these arrays:

=============  ==================  =============================================================
name           shape, dtype        meaning
=============  ==================  =============================================================
kind           (), str             the output's kind: disparity, depth, points or mesh
count          (), int64           errors the statistics are of (pixels with an estimate; points)
median_m       (), float64         median absolute error, metres (NaN for no error)
rms_m          (), float64         RMS of the absolute errors, metres (NaN for no error)
*disparity and depth*
error_m        (H, W), float32     signed depth error Z_est - Z_gt (metres) of each left-view
                                   pixel; NaN where there is no estimate or off the plate (a
                                   disparity's Z = f B / (d + doffs))
plate          (H, W), bool        the true plate's pixels
plate_px       (), int64           plate pixels (coverage = count / plate_px)
*points and mesh*
points_m       (K, 3), float64     the points shown (world frame, metres; a mesh's vertices): the
                                   finite ones, at most ``evaluation.error_maps.MAX_MAP_POINTS``
                                   of them drawn with seed 0
distance_m     (K,), float64       each point's exact distance to the true surface (metres)
finite_count   (), int64           the output's finite points (K of them are in the file)
=============  ==================  =============================================================

Its statistics are those of the values in the file (for points: of the K shown). The reader raises
``DatasetError`` (one line naming the file) for a missing, oversized, damaged or incomplete file.
Writes are atomic (``bench.io.atomic``).
"""
from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from platebench.bench.files import IMAGE_MAX_BYTES, regular_size
from platebench.bench.io.atomic import write_bytes
from platebench.bench.io.images import DatasetError

__all__ = ["ERROR_MAP_FILE", "StoredErrorMap", "write_error_map", "read_error_map", "error_map_beside"]

ERROR_MAP_FILE = "error_map.npz"
_DEPTH_KINDS = ("disparity", "depth")
_POINT_KINDS = ("points", "mesh")
_COMMON = ("kind", "count", "median_m", "rms_m")
_MEMBERS = {**dict.fromkeys(_DEPTH_KINDS, ("error_m", "plate", "plate_px")),
            **dict.fromkeys(_POINT_KINDS, ("points_m", "distance_m", "finite_count"))}


@dataclass(frozen=True, eq=False)
class StoredErrorMap:
    """An error map as the file holds it (module doc): a map's ``error_m`` (H, W) and ``plate`` (H, W),
    or ``points_m`` (K, 3) and ``distance_m`` (K,); None for the other kind's arrays."""

    kind: str
    count: int
    median_m: float
    rms_m: float
    error_m: np.ndarray | None = field(default=None, repr=False)
    plate: np.ndarray | None = field(default=None, repr=False)
    plate_px: int = 0
    points_m: np.ndarray | None = field(default=None, repr=False)
    distance_m: np.ndarray | None = field(default=None, repr=False)
    finite_count: int = 0

    @property
    def is_map(self) -> bool:
        """A disparity's or depth map's error map (else a point cloud's or mesh's)."""
        return self.kind in _DEPTH_KINDS

    @property
    def coverage_frac(self) -> float:
        """Plate pixels with an estimate / plate pixels (a map's; 0 for no plate pixel)."""
        return self.count / max(self.plate_px, 1)

    @classmethod
    def of(cls, kind: str, scored) -> "StoredErrorMap":
        """From an ``evaluation.error_maps`` result of an output of ``kind``: a ``DepthErrorMap`` for a
        disparity or depth map, a ``PointDistanceMap`` for points or a mesh (``finite_count`` its point
        count: the finite points it was drawn from when it is a sample)."""
        e = scored.errors
        common = dict(kind=kind, count=int(e.count), median_m=float(e.median_m), rms_m=float(e.rms_m))
        if kind in _DEPTH_KINDS:
            plate = np.isfinite(scored.error_m) if scored.plate is None else np.asarray(scored.plate, bool)
            return cls(**common, error_m=np.asarray(scored.error_m, np.float32), plate=plate,
                       plate_px=int(scored.plate_px))
        if kind in _POINT_KINDS:
            return cls(**common, points_m=np.asarray(scored.points, np.float64),
                       distance_m=np.asarray(scored.distance_m, np.float64),
                       finite_count=max(int(scored.finite_count), len(scored.points)))
        raise ValueError(f"kind {kind!r} has no error map: allowed {', '.join(_DEPTH_KINDS + _POINT_KINDS)}")


def error_map_beside(score_path: Path) -> Path:
    """The error map's path beside a score document: ``F.score.json`` (or ``F.json``) -> ``F.error_map.npz``."""
    score_path = Path(score_path)
    stem = score_path.name.removesuffix(".json").removesuffix(".score")
    return score_path.with_name(f"{stem}.error_map.npz")


def write_error_map(path: Path, m: StoredErrorMap) -> Path:
    """Write ``m`` to ``path`` (module doc) atomically; returns ``path``."""
    arrays = {"kind": np.array(m.kind), "count": np.int64(m.count), "median_m": np.float64(m.median_m),
              "rms_m": np.float64(m.rms_m)}
    if m.is_map:
        arrays.update(error_m=np.asarray(m.error_m, np.float32), plate=np.asarray(m.plate, bool),
                      plate_px=np.int64(m.plate_px))
    else:
        arrays.update(points_m=np.asarray(m.points_m, np.float64).reshape(-1, 3),
                      distance_m=np.asarray(m.distance_m, np.float64).ravel(), finite_count=np.int64(m.finite_count))
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    write_bytes(Path(path), buf.getvalue())
    return Path(path)


def read_error_map(path: Path) -> StoredErrorMap:
    """The error map in ``path`` (module doc), checked: its members, their shapes and dtypes, and at most
    ``IMAGE_MAX_BYTES`` unpacked. ``DatasetError`` naming the file otherwise."""
    path = Path(path)
    size = regular_size(path, "error map file", DatasetError, missing="file is missing")
    if size > IMAGE_MAX_BYTES:
        raise DatasetError(f"{path}: {size} bytes is too large for an error map: allowed at most {IMAGE_MAX_BYTES}")
    try:
        with zipfile.ZipFile(path) as z:
            unpacked = sum(i.file_size for i in z.infolist())
        if unpacked > IMAGE_MAX_BYTES:
            raise DatasetError(f"{path}: unpacks to {unpacked} bytes: allowed at most {IMAGE_MAX_BYTES}")
        with np.load(path, allow_pickle=False) as z:
            kind = str(z["kind"]) if "kind" in z.files else ""
            if kind not in _MEMBERS:
                raise DatasetError(f"{path}: not an error map (kind {kind!r})")
            missing = [n for n in (*_COMMON, *_MEMBERS[kind]) if n not in z.files]
            if missing:
                raise DatasetError(f"{path}: not a complete error map ({', '.join(missing)} missing)")
            a = {n: z[n] for n in (*_COMMON, *_MEMBERS[kind])}
    except (zipfile.BadZipFile, ValueError, EOFError, KeyError) as e:
        if isinstance(e, DatasetError):
            raise
        why = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise DatasetError(f"{path}: not a readable error map, truncated or damaged ({why})") from None
    common = dict(kind=kind, count=int(a["count"]), median_m=float(a["median_m"]), rms_m=float(a["rms_m"]))
    if kind in _DEPTH_KINDS:
        err, plate = a["error_m"], a["plate"]
        if err.ndim != 2 or plate.shape != err.shape or plate.dtype != bool or not np.issubdtype(err.dtype, np.floating):
            raise DatasetError(f"{path}: error_m {err.shape} {err.dtype} and plate {plate.shape} {plate.dtype}: "
                               "expected (H, W) floats and (H, W) bools")
        return StoredErrorMap(**common, error_m=err, plate=plate, plate_px=int(a["plate_px"]))
    P, dist = a["points_m"], a["distance_m"]
    if P.ndim != 2 or P.shape[1:] != (3,) or dist.shape != (len(P),) or not (
            np.issubdtype(P.dtype, np.floating) and np.issubdtype(dist.dtype, np.floating)):
        raise DatasetError(f"{path}: points_m {P.shape} {P.dtype} and distance_m {dist.shape} {dist.dtype}: "
                           "expected (K, 3) and (K,) floats")
    return StoredErrorMap(**common, points_m=P, distance_m=dist, finite_count=int(a["finite_count"]))
