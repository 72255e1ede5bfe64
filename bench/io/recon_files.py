"""Reconstruction directory: write (atomically) and read back.

    RECON/points.ply    triangulated square centres (world, metres)
    RECON/points.csv    pattern_row, pattern_col, feature_id, u_left, v_left, u_right, v_right, x_m, y_m, z_m
    RECON/cut_points.csv  the same columns for the centres of squares cut in either image (by the
                        plate's outline or the threshold), set apart from points and surface
    RECON/boundary.npy  (N,3) reconstructed closed boundary (world, metres)
    RECON/surface.ply   interpolated surface mesh (world, metres)
    RECON/recon.json    counts, expected count, false-boundary flags, planes, Fig. 6 checks,
                        timings per step, thresholds, and the sample's image checksums
"""
from __future__ import annotations

import contextlib
import hashlib
import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from platebench.bench.files import TABLE_MAX_BYTES, read_capped, require_dir
from platebench.bench.io.atomic import (
    staged_directory,
    write_bytes,
    write_json,
    write_text,
)
from platebench.bench.io.codecs import decode, encode
from platebench.bench.io.images import DatasetError, check_ply, read_npy
from platebench.bench.io.outputs import write_stamp
from platebench.bench.io.sample_files import read_json
from platebench.reconstruction.paper.false_boundary import FalseBoundaryTest

if TYPE_CHECKING:  # trimesh is imported where a mesh is written or read; the pipeline is not needed here
    import trimesh

    from platebench.reconstruction.paper.pipeline import Reconstruction

CSV_COLUMNS = ("pattern_row", "pattern_col", "feature_id", "u_left", "v_left", "u_right", "v_right",
               "x_m", "y_m", "z_m")


def image_checksums(images: dict) -> dict:
    return {n: hashlib.sha256(np.ascontiguousarray(img).tobytes()).hexdigest() for n, img in images.items()}


def _plane_dict(p) -> dict:
    return {"point_m": p.point.tolist(), "normal": p.normal.tolist(), "offset_m": float(p.offset),
            "objective": float(p.objective_m2), "iterations": int(p.iterations), "method": p.method}


def recon_summary(r: Reconstruction, sample_dir: Path, checksums: dict, method: str = "paper") -> dict:
    return {
        "method": method,
        "sample_dir": str(Path(sample_dir).resolve()),
        "input_checksums": checksums,
        "n_points": int(len(r.points)),
        "cut_squares": encode(r.cut),
        "false_boundary": encode(r.false_boundary),
        "boundary_plane": _plane_dict(r.boundary_plane),
        "least_squares_plane": _plane_dict(r.least_squares_plane),
        "fig6": {k: encode(v) for k, v in r.fig6.items()},
        "unmatched": list(r.unmatched),
        "corner_row_mismatch_px": r.corner_row_mismatch_px.tolist(),
        "thresholds": r.thresholds,
        "timings_s": r.timings_s,
        "n_boundary_points": int(len(r.boundary)),
    }


def points_csv(r: Reconstruction) -> str:
    return _csv(r.pattern_row, r.pattern_col, r.feature_id, r.uv_left, r.uv_right, r.points)


def cut_points_csv(r: Reconstruction) -> str:
    """The centres of cut squares (``Reconstruction.cut``), in points.csv's columns (row and column
    -1: the pipeline labels only the points it keeps)."""
    c = r.cut
    none = np.full(len(c), -1)
    return _csv(none, none, c.feature_id, c.uv_left, c.uv_right, c.points)


def _csv(rows, cols, ids, uv_left, uv_right, points) -> str:
    buf = io.StringIO()
    buf.write(",".join(CSV_COLUMNS) + "\n")
    for k in range(len(points)):
        vals = [rows[k], cols[k], ids[k], *uv_left[k], *uv_right[k], *points[k]]
        buf.write(",".join(str(int(v)) if i < 3 else f"{v:.9g}" for i, v in enumerate(vals)) + "\n")
    return buf.getvalue()


def write_reconstruction(out: Path, r: Reconstruction, sample_dir: Path, checksums: dict,
                         overwrite: bool = False, into: bool = False) -> Path:
    """Write a reconstruction directory atomically. ``into``: ``out`` is an empty directory of an output
    that is already staged (``bench.io.atomic.staged_output``): the files are written straight into it."""
    import trimesh  # noqa: PLC0415

    with (contextlib.nullcontext(Path(out)) if into else staged_directory(Path(out), overwrite=overwrite)) as d:
        cloud = trimesh.PointCloud(r.points) if len(r.points) else None
        if cloud is not None:
            write_bytes(d / "points.ply", cloud.export(file_type="ply"))
        write_text(d / "points.csv", points_csv(r))
        if len(r.cut):
            write_text(d / "cut_points.csv", cut_points_csv(r))
        np.save(d / "boundary.npy", r.boundary)
        surf = trimesh.Trimesh(r.surface_vertices, r.surface_faces, process=False)
        write_bytes(d / "surface.ply", surf.export(file_type="ply", encoding="binary"))
        write_json(d / "recon.json", recon_summary(r, sample_dir, checksums))
        if not into:  # a command's staged output gets its stamp when the whole output is complete
            write_stamp(d, "reconstruction")
    return Path(out)


@dataclass(frozen=True)
class ReconFiles:
    """A reconstruction directory read back (world frame, metres)."""

    points: np.ndarray
    feature_id: np.ndarray
    uv_left: np.ndarray
    uv_right: np.ndarray
    boundary: np.ndarray
    surface: trimesh.Trimesh | None
    meta: dict
    # the centres of cut squares (cut_points.csv; empty when there is none): (K,3), (K,2), (K,2)
    cut_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    cut_uv_left: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    cut_uv_right: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def false_boundary(self) -> FalseBoundaryTest:
        """recon.json's ``false_boundary`` section as the counting test it records."""
        return decode(FalseBoundaryTest, self.meta.get("false_boundary") or {})


def load_reconstruction(recon_dir: Path) -> ReconFiles:
    d = require_dir(Path(recon_dir), "reconstruction directory", DatasetError)
    meta = read_json(d / "recon.json")
    csv = d / "points.csv"
    table = _read_points_csv(csv)
    cut = _read_points_csv(d / "cut_points.csv") if (d / "cut_points.csv").is_file() \
        else np.zeros((0, len(CSV_COLUMNS)))
    boundary = read_npy(d / "boundary.npy", (None, 3))
    spath = d / "surface.ply"
    surface = None
    if spath.exists():
        import trimesh  # noqa: PLC0415

        check_ply(spath)
        try:
            surface = trimesh.load(spath, process=False, force="mesh")
        except Exception as e:  # noqa: BLE001  (trimesh raises many kinds on a damaged file)
            raise DatasetError(f"{spath}: not a readable PLY mesh ({str(e).splitlines()[0] if str(e) else type(e).__name__})") from None
        if not isinstance(surface, trimesh.Trimesh):
            raise DatasetError(f"{spath}: not a PLY triangle mesh")
    if surface is not None and not np.all(np.isfinite(surface.vertices)):
        raise DatasetError(f"{spath}: surface vertices hold NaN or inf")
    return ReconFiles(table[:, 7:10], table[:, 2].astype(int), table[:, 3:5], table[:, 5:7], boundary, surface, meta,
                      cut[:, 7:10], cut[:, 3:5], cut[:, 5:7])


def _read_points_csv(csv: Path) -> np.ndarray:
    """points.csv (or cut_points.csv) as an (N, 10) table; one-line DatasetError naming the file."""
    data = read_capped(csv, TABLE_MAX_BYTES, "CSV table", DatasetError, missing="file is missing")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise DatasetError(f"{csv}: not a UTF-8 text CSV file") from None
    rows = [line.split(",") for line in text.splitlines()[1:] if line.strip()]
    try:
        table = np.array(rows, dtype=float).reshape(-1, len(CSV_COLUMNS))
    except ValueError:
        raise DatasetError(f"{csv}: not a {len(CSV_COLUMNS)}-column numeric table") from None
    if not np.all(np.isfinite(table)):
        bad = int(np.argwhere(~np.isfinite(table))[0, 0]) + 2
        raise DatasetError(f"{csv}: line {bad} holds NaN or inf: a reconstruction must not contain them")
    return table
