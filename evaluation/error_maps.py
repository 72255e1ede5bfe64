"""What an error map of a method's output draws, scored against the sample's exact ground truth:
the signed depth error of each plate pixel of a depth map (``depth_error_map``), or each point's
exact distance to the true surface (``point_distance_map``, ``evaluation.point_metrics``), with
their statistics (``field_scores.AbsErrors``). Metres in, metres out; world frame for points, the
left view's pixels for depth maps.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from platebench.evaluation.field_scores import AbsErrors, implied_depth
from platebench.evaluation.point_metrics import point_to_surface_distance

if TYPE_CHECKING:
    import trimesh  # annotations only: importing trimesh takes a second

__all__ = ["DepthErrorMap", "depth_error_map", "PointDistanceMap", "point_distance_map", "MAX_MAP_POINTS",
           "implied_depth", "output_error_map"]

MAX_MAP_POINTS = 20_000  # a point cloud's or mesh's error map holds at most this many points (seeded sample)


@dataclass(frozen=True, eq=False)
class DepthErrorMap:
    """A depth map against the true depth of the left view: ``error_m`` (H, W) the signed error
    Z_est - Z_gt on the plate's pixels with an estimate (finite and > 0), NaN elsewhere; ``errors``
    the statistics of its absolute values; ``plate_px`` the plate's pixels; ``plate`` (H, W) bool the
    plate's pixels (None: not kept)."""

    error_m: np.ndarray = field(repr=False)
    errors: AbsErrors
    plate_px: int
    plate: np.ndarray | None = field(default=None, repr=False)

    @property
    def coverage_frac(self) -> float:
        """Plate pixels with an estimate / plate pixels (0 for no plate pixel)."""
        return self.errors.count / max(self.plate_px, 1)


def depth_error_map(depth_m, true_depth_m, mask) -> DepthErrorMap:
    """``DepthErrorMap`` of a z-depth map ``depth_m`` (H, W, metres; non-finite or <= 0: no estimate)
    against ``true_depth_m`` (H, W) on the plate's pixels ``mask`` (H, W bool)."""
    z = np.asarray(depth_m, np.float64)
    mask = np.asarray(mask, bool)
    with np.errstate(invalid="ignore"):  # inf - inf off the plate, masked out
        err = np.where(mask & np.isfinite(z) & (z > 0), z - true_depth_m, np.nan)
    return DepthErrorMap(err, AbsErrors.of(err[np.isfinite(err)], signed=False), int(mask.sum()), mask)


@dataclass(frozen=True, eq=False)
class PointDistanceMap:
    """Points (K, 3, world, metres) and each one's exact distance to the true surface ``distance_m``
    (K,), with their statistics; ``finite_count`` the finite points they were drawn from (K or more)."""

    points: np.ndarray = field(repr=False)
    distance_m: np.ndarray = field(repr=False)
    errors: AbsErrors
    finite_count: int = 0


def point_distance_map(points_m, mesh: trimesh.Trimesh, max_points: int | None = None,
                       seed: int = 0) -> PointDistanceMap:
    """``PointDistanceMap`` of the finite rows of ``points_m`` (N, 3) against ``mesh``; more than
    ``max_points`` of them: a sample of that many drawn without replacement with ``seed``."""
    P = np.asarray(points_m, np.float64)
    P = P[np.all(np.isfinite(P), axis=1)]
    finite = len(P)
    if max_points is not None and len(P) > max_points:
        P = P[np.random.default_rng(seed).choice(len(P), max_points, replace=False)]
    dist = point_to_surface_distance(P, mesh)
    return PointDistanceMap(P, dist, AbsErrors.of(dist, signed=False), finite)


def output_error_map(kind: str, values, truth, max_points: int | None = MAX_MAP_POINTS,
                     seed: int = 0) -> DepthErrorMap | PointDistanceMap:
    """The error map of a method's output of ``kind`` against ``truth`` (an
    ``evaluation.field_scores.FieldTruth``): a ``DepthErrorMap`` of a disparity (``values`` (H, W) px,
    through ``field_scores.implied_depth``, the depth its score is made of) or a depth map ((H, W)
    metres) on the true plate's pixels; a
    ``PointDistanceMap`` of points ((N, 3) world, metres) or a mesh's vertices (``values`` a
    trimesh.Trimesh), at most ``max_points`` of them (``point_distance_map``). ``ValueError`` for a map
    of another shape than the truth's or an unknown kind."""
    if kind in ("disparity", "depth"):
        z = (implied_depth(values, truth.pair.fb, truth.pair.doffs_px) if kind == "disparity"
             else np.asarray(values, np.float64))
        if z.shape != truth.depth.shape:
            raise ValueError(f"{kind} map of shape {z.shape}: the sample's maps are {truth.depth.shape}")
        return depth_error_map(z, truth.depth, truth.mask)
    if kind in ("points", "mesh"):
        return point_distance_map(values if kind == "points" else values.vertices, truth.mesh, max_points, seed)
    raise ValueError(f"kind {kind!r} has no error map: allowed disparity, depth, points, mesh")
