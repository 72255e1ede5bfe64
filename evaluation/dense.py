"""Sparse world points scored by depth at their left-image projection (``compare``'s paper row).

* ``score_points_depth``: sparse world points (the paper's square centres) by their depth error at
  their left-image projection (keys ``centres_depth_*_mm``: sparse, never to be compared with a dense
  map's ``depth_*_mm`` over the plate's pixels), and by their distance to the true surface; the
  caller may add the method's ``coverage`` (``evaluation.pixel_coverage``: for the paper, the plate
  pixels whose true ray hits its surface mesh).

Dense maps, point clouds and meshes of any method are scored by ``evaluation.field_scores``.
Inputs: metres, pixels (OpenCV, centres at integers); outputs: keys carry their unit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from platebench.evaluation.pixel_coverage import PixelCoverage
from platebench.evaluation.point_metrics import point_to_surface_distance

__all__ = ["SparseDepthScore", "score_points_depth", "bilinear"]


@dataclass(frozen=True)
class SparseDepthScore:
    """Sparse world points against the truth (millimetres): their count, those whose left-image
    projection lands on the plate, the |depth error| there (median, RMS, max; NaN when none lands),
    and their distance to the true surface (RMS, max; None without a mesh); ``coverage``: the
    method's pixel coverage (``coverage_frac``; None: not measured)."""

    points: int
    points_on_plate: int
    centres_depth_median_mm: float
    centres_depth_rms_mm: float
    centres_depth_max_mm: float
    surface_rms_mm: float | None = None
    surface_max_mm: float | None = None
    coverage: PixelCoverage | None = None

    @property
    def coverage_frac(self) -> float | None:
        """The share of the plate's pixels with an estimate (None: not measured)."""
        return None if self.coverage is None else self.coverage.coverage_frac


def bilinear(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup at (N,2) pixel coordinates; NaN unless all four neighbours are finite."""
    H, W = img.shape
    u, v = uv[:, 0], uv[:, 1]
    ok = np.isfinite(u) & np.isfinite(v) & (u >= 0) & (v >= 0) & (u <= W - 1) & (v <= H - 1)
    out = np.full(len(uv), np.nan)
    u0 = np.clip(np.floor(u[ok]).astype(int), 0, W - 2)
    v0 = np.clip(np.floor(v[ok]).astype(int), 0, H - 2)
    fu, fv = u[ok] - u0, v[ok] - v0
    g = img.astype(np.float64)
    val = (g[v0, u0] * (1 - fu) * (1 - fv) + g[v0, u0 + 1] * fu * (1 - fv)
           + g[v0 + 1, u0] * (1 - fu) * fv + g[v0 + 1, u0 + 1] * fu * fv)
    out[ok] = val
    return out


def score_points_depth(points, left_camera, gt_depth, mesh=None) -> SparseDepthScore:
    """Depth error of sparse world points at their left-image projection, and distance to the true surface."""
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    uv = left_camera.project(pts)
    z_gt = bilinear(np.where(np.isfinite(gt_depth), gt_depth, np.nan), uv)
    z = left_camera.depth(pts)
    ok = np.isfinite(z_gt)
    a = np.abs(z[ok] - z_gt[ok]) * 1e3
    nan = math.nan
    surface = (None, None)
    if mesh is not None and len(pts):
        d = point_to_surface_distance(pts, mesh) * 1e3
        surface = (float(np.sqrt(np.mean(d * d))), float(d.max()))
    return SparseDepthScore(int(len(pts)), int(ok.sum()), float(np.median(a)) if a.size else nan,
                            float(np.sqrt(np.mean(a * a))) if a.size else nan, float(a.max()) if a.size else nan,
                            *surface)

