"""Point tables on disk: one reader for every points.csv (ours and other programs').

``read_points_csv(path)`` reads a CSV of 3D points (world frame, metres): a header naming the
x, y, z columns (``x``/``x_m``/``x_world_m``/``world_x``/``x_world``), or three bare numeric
columns; lines starting with ``#`` are comments. ``read_points_table`` reads every column of a
headed CSV (e.g. a reconstruction's points.csv) as floats.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np

from platebench.bench.files import TABLE_MAX_BYTES, read_capped
from platebench.bench.io.images import DatasetError

__all__ = ["read_points_csv", "read_points_table"]

_AXIS_NAMES = {name: (name, f"{name}_m", f"{name}_world_m", f"world_{name}", f"{name}_world") for name in "xyz"}


def _rows(path: Path) -> list[list[str]]:
    path = Path(path)
    data = read_capped(path, TABLE_MAX_BYTES, "CSV table", DatasetError, missing="file is missing")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not a text CSV file") from None
    rows = list(csv.reader(text.splitlines()))
    return [r for r in rows if r and not r[0].lstrip().startswith("#")]


def read_points_table(path: Path) -> dict[str, np.ndarray]:
    """Every column of a headed CSV as a float64 array (name -> (N,)); NaN/inf refused."""
    path = Path(path)
    rows = _rows(path)
    if not rows:
        raise DatasetError(f"{path}: empty CSV (no header)")
    header = [h.strip() for h in rows[0]]
    try:
        table = np.array(rows[1:], dtype=float).reshape(-1, len(header))
    except ValueError:
        raise DatasetError(f"{path}: not a {len(header)}-column numeric table under its header") from None
    if not np.all(np.isfinite(table)):
        bad = int(np.argwhere(~np.isfinite(table))[0, 0]) + 2
        raise DatasetError(f"{path}: line {bad} holds NaN or inf")
    return {name: table[:, k] for k, name in enumerate(header)}


def read_points_csv(path: Path) -> np.ndarray:
    """(N, 3) world points (metres) from a CSV with x/y/z columns or three bare numeric columns."""
    path = Path(path)
    rows = _rows(path)
    if not rows:
        return np.zeros((0, 3))
    header = [h.strip().lower() for h in rows[0]]
    try:
        [float(x) for x in rows[0]]
        body, cols = rows, [0, 1, 2]
    except ValueError:
        body = rows[1:]
        cols = [next((header.index(c) for c in _AXIS_NAMES[a] if c in header), None) for a in "xyz"]
        if None in cols:
            raise DatasetError(f"{path}: cannot find x, y, z columns in header {rows[0]}")
    try:
        pts = np.array([[float(r[c]) for c in cols] for r in body], np.float64).reshape(-1, 3)
    except (ValueError, IndexError) as e:
        raise DatasetError(f"{path}: bad point row ({e})") from None
    if not np.all(np.isfinite(pts)):
        raise DatasetError(f"{path}: points hold NaN or inf")
    return pts
