"""Scoring of a merged multi-view reconstruction (every pose's boundary, square centres and visible
surface in one, world frame, metres) against the plate's ground truth (``score_merged``).

* Boundary: the mean symmetric distance to the true boundary, the one-way (estimate to truth) mean
  distance, and the fraction of the true boundary's length within ``BOUNDARY_COVERED_M`` of the
  estimate. The true side is sampled uniformly by arc length every ``TRUE_BOUNDARY_STEP_M``: a
  plate's boundary vertices are dense on bends and sparse on flat stretches, so a mean over vertices
  would weigh the bends only.
* Square centres: RMS and maximum exact distance to the true surface
  (``point_metrics.closest_point_on_mesh``).
* Surface: points sampled on the merged surface every ``SURFACE_SAMPLE_M`` (the caller samples
  them), scored by ``surface_metrics.score_surface``: RMS distance to the true surface and the share
  of the true surface's area within ``SURFACE_COVERAGE_RADIUS_M`` of them.

Every figure is in metres (fractions 0..1); a part the reconstruction lacks is None.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from platebench.evaluation.boundary_metrics import points_to_polyline_distance
from platebench.evaluation.point_metrics import closest_point_on_mesh
from platebench.evaluation.stats import ErrorStats
from platebench.evaluation.surface_metrics import score_surface

if TYPE_CHECKING:
    import trimesh  # annotations only: importing trimesh takes a second

__all__ = ["TRUE_BOUNDARY_STEP_M", "SURFACE_SAMPLE_M", "BOUNDARY_COVERED_M", "SURFACE_COVERAGE_RADIUS_M",
           "SURFACE_MAX_DISTANCE_M", "MergedBoundaryScore", "MergedPointsScore", "MergedSurfaceScore",
           "MergedScore", "score_merged"]

TRUE_BOUNDARY_STEP_M = 0.5e-3  # the true boundary is sampled this finely (by arc length)
SURFACE_SAMPLE_M = 2e-3  # the merged surface is sampled this finely (under the coverage radius)
BOUNDARY_COVERED_M = 2e-3  # a true boundary point within this of the estimate is covered
SURFACE_COVERAGE_RADIUS_M = 2e-3  # the true surface within this of the estimate is covered
SURFACE_MAX_DISTANCE_M = 1e-3  # ``score_surface``'s distance bound for its coverage search


@dataclass(frozen=True)
class MergedBoundaryScore:
    """The merged boundary against the true one (metres): the symmetric mean, the estimate-to-truth
    mean and the covered fraction of the true boundary's length."""

    mean_sym_m: float
    est_to_gt_mean_m: float
    covered_frac: float


@dataclass(frozen=True)
class MergedPointsScore:
    """The merged square centres' exact distances to the true surface (metres): RMS and maximum."""

    rms_m: float
    max_m: float


@dataclass(frozen=True)
class MergedSurfaceScore:
    """The merged surface's samples against the true surface: RMS distance (metres), the share of
    the true surface's area within the coverage radius, and the samples scored."""

    rms_m: float
    coverage_frac: float
    samples: int


@dataclass(frozen=True)
class MergedScore:
    """A merged reconstruction's figures: boundary, square centres and surface (None: the
    reconstruction has no such part)."""

    boundary: MergedBoundaryScore | None
    points: MergedPointsScore | None
    surface: MergedSurfaceScore | None


def _true_boundary_samples(true_boundary: np.ndarray) -> np.ndarray:
    """The closed true boundary (N, 3) sampled every ``TRUE_BOUNDARY_STEP_M`` by arc length."""
    from trimesh.path.traversal import resample_path  # noqa: PLC0415  (importing trimesh takes a second)

    B = np.asarray(true_boundary, float)
    return resample_path(np.vstack([B, B[:1]]), step=TRUE_BOUNDARY_STEP_M)[:-1]  # closed: drop the repeat


def score_merged(true_mesh: trimesh.Trimesh, true_boundary, boundary, points, surface_samples) -> MergedScore:
    """Score a merged reconstruction: ``true_mesh`` the plate's mesh and ``true_boundary`` (N, 3) its
    closed boundary; ``boundary`` (B, 3) the merged boundary, ``points`` (P, 3) the merged square
    centres, ``surface_samples`` (S, 3) points sampled on the merged surface every
    ``SURFACE_SAMPLE_M``; world frame, metres."""
    from scipy.spatial import cKDTree  # noqa: PLC0415  (scipy.spatial takes a while to import)

    boundary = np.asarray(boundary, float)
    points = np.asarray(points, float)
    surface_samples = np.asarray(surface_samples, float)
    bscore = pscore = sscore = None
    if len(boundary):
        est_gt = points_to_polyline_distance(boundary, np.asarray(true_boundary, float))
        gt_est = cKDTree(boundary).query(_true_boundary_samples(true_boundary))[0]
        bscore = MergedBoundaryScore(mean_sym_m=float(0.5 * (est_gt.mean() + gt_est.mean())),
                                     est_to_gt_mean_m=float(est_gt.mean()),
                                     covered_frac=float(np.mean(gt_est <= BOUNDARY_COVERED_M)))
    if len(points):
        d = ErrorStats.from_abs(closest_point_on_mesh(points, true_mesh)[1], name="centre distance")
        pscore = MergedPointsScore(rms_m=d.rms, max_m=d.max)
    if len(surface_samples):
        s = score_surface(surface_samples, true_mesh, sample_spacing_m=SURFACE_SAMPLE_M,
                          coverage_radius_m=SURFACE_COVERAGE_RADIUS_M, max_distance_m=SURFACE_MAX_DISTANCE_M)
        sscore = MergedSurfaceScore(rms_m=float(s.dist.rms), coverage_frac=float(s.surface_coverage_frac),
                                    samples=int(len(surface_samples)))
    return MergedScore(bscore, pscore, sscore)
