"""Sub-pixel position of a bright region's edge along an image row or column (area method).

A camera pixel integrates radiance over its area, so across a straight edge the
normalised intensity c = (I - background) / (plate - background) is the fraction of
the pixel covered by the plate. Summing c over a window that starts fully outside
and ends fully inside gives the covered length, hence the edge position at the
row's (column's) centre line, exactly for any straight edge crossing the window,
whatever its slant. Pixel centres are at integers; pixel x covers [x-0.5, x+0.5].
"""
from __future__ import annotations

import numpy as np

HALF_WINDOW = 4


def edge_in_profile(profile: np.ndarray, threshold: float, start: int, stop: int, background: float,
                    half_window: int = HALF_WINDOW) -> float:
    """Sub-pixel edge where ``profile`` first rises above ``threshold`` scanning start -> stop.

    ``start`` may be greater than ``stop`` (scan backwards). Returns NaN when the window
    does not fit or the level is not reached.
    """
    step = 1 if stop >= start else -1
    idx = np.arange(start, stop, step)
    idx = idx[(idx >= 0) & (idx < len(profile))]
    above = np.nonzero(profile[idx] > threshold)[0]
    if above.size == 0:
        return np.nan
    x = int(idx[above[0]])  # first pixel above threshold (inside)
    w = half_window
    # Window from fully outside (x - step*w) to fully inside (x + step*w).
    lo, hi = x - step * w, x + step * w
    inner = x + step * (w + 1 + np.arange(w))
    if min(lo, hi, inner.min()) < 0 or max(lo, hi, inner.max()) >= len(profile):
        return np.nan
    plate = float(np.median(profile[inner]))
    if plate - background <= 0:
        return np.nan
    seg = profile[min(lo, hi):max(lo, hi) + 1]
    covered = float(np.clip((seg - background) / (plate - background), 0.0, 1.0).sum())
    if step > 0:  # plate after the edge: edge = end of window - covered length
        return hi + 0.5 - covered
    return hi - 0.5 + covered  # plate before the edge (scanning backwards)


def row_edges(image: np.ndarray, rows, threshold: float, background: float, start_x, stop_x) -> np.ndarray:
    """Sub-pixel u of the first rising edge in each row, scanning from start_x toward stop_x."""
    rows = np.asarray(rows, int)
    start_x = np.broadcast_to(np.asarray(start_x, int), rows.shape)
    stop_x = np.broadcast_to(np.asarray(stop_x, int), rows.shape)
    return np.array([edge_in_profile(image[v], threshold, int(a), int(b), background)
                     for v, a, b in zip(rows, start_x, stop_x)])


def column_edges(image: np.ndarray, cols, threshold: float, background: float, start_y, stop_y) -> np.ndarray:
    """Sub-pixel v of the first rising edge in each column, scanning from start_y toward stop_y."""
    cols = np.asarray(cols, int)
    start_y = np.broadcast_to(np.asarray(start_y, int), cols.shape)
    stop_y = np.broadcast_to(np.asarray(stop_y, int), cols.shape)
    return np.array([edge_in_profile(image[:, u], threshold, int(a), int(b), background)
                     for u, a, b in zip(cols, start_y, stop_y)])
