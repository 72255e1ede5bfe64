"""Sub-pixel position of a bright region's edge along image rows or columns (area method).

A camera pixel integrates radiance over its area, so across a straight edge the
normalised intensity c = (I - background) / (plate - background) is the fraction of
the pixel covered by the plate. Summing c over a window that starts fully outside
and ends fully inside gives the covered length, hence the edge position at the
row's (column's) centre line, exactly for any straight edge crossing the window,
whatever its slant. Pixel centres are at integers; pixel x covers [x-0.5, x+0.5].

Vectorised over lines: each line is scanned from ``start`` toward ``stop`` (either
direction) for the first pixel above the threshold.
"""
from __future__ import annotations

import numpy as np

HALF_WINDOW = 4


def profile_edges(profiles: np.ndarray, threshold: float, start, stop, background: float,
                  half_window: int = HALF_WINDOW) -> np.ndarray:
    """Sub-pixel edge positions in each row of ``profiles`` (L, N), NaN where none is found.

    The scan on line k runs from ``start[k]`` toward ``stop[k]`` (exclusive); the plate is
    on the far side of the edge.
    """
    P = np.asarray(profiles, np.float64)
    L, N = P.shape
    start = np.broadcast_to(np.asarray(start, int), (L,))
    stop = np.broadcast_to(np.asarray(stop, int), (L,))
    step = np.where(stop >= start, 1, -1)
    span = int(np.max(np.abs(stop - start))) if L else 0
    out = np.full(L, np.nan)
    if L == 0 or span == 0:
        return out
    k = np.arange(span)
    idx = start[:, None] + step[:, None] * k[None, :]
    valid = (k[None, :] < np.abs(stop - start)[:, None]) & (idx >= 0) & (idx < N)
    vals = np.where(valid, P[np.arange(L)[:, None], np.clip(idx, 0, N - 1)], -np.inf)
    above = vals > threshold
    found = above.any(axis=1)
    x = idx[np.arange(L), np.argmax(above, axis=1)]  # first inside pixel
    w = half_window
    lo = x - step * w
    hi = x + step * w
    inner_end = x + step * (2 * w)
    ok = found & (np.minimum(lo, inner_end) >= 0) & (np.maximum(lo, inner_end) < N)
    rows = np.nonzero(ok)[0]
    if rows.size == 0:
        return out
    s = step[rows][:, None]
    win = lo[rows][:, None] + s * np.arange(2 * w + 1)[None, :]  # outside -> inside
    inner = x[rows][:, None] + s * (w + 1 + np.arange(w))[None, :]
    plate = np.median(P[rows[:, None], inner], axis=1)
    good = plate - background > 0
    cov = np.clip((P[rows[:, None], win] - background) / np.where(good, plate - background, 1.0)[:, None], 0, 1)
    covered = cov.sum(axis=1)
    h = hi[rows]
    edge = np.where(step[rows] > 0, h + 0.5 - covered, h - 0.5 + covered)
    out[rows[good]] = edge[good]
    return out


def row_edges(image: np.ndarray, rows, threshold: float, background: float, start_x, stop_x) -> np.ndarray:
    """Sub-pixel u of the first rising edge in each row, scanning from start_x toward stop_x."""
    rows = np.asarray(rows, int)
    return profile_edges(np.asarray(image)[rows], threshold, start_x, stop_x, background)


def column_edges(image: np.ndarray, cols, threshold: float, background: float, start_y, stop_y) -> np.ndarray:
    """Sub-pixel v of the first rising edge in each column, scanning from start_y toward stop_y."""
    cols = np.asarray(cols, int)
    return profile_edges(np.asarray(image)[:, cols].T, threshold, start_y, stop_y, background)
