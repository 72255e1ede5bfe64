"""Accuracy and coverage of an estimated surface against the ground-truth plate mesh.

The estimate is a set of 3D points in world coordinates, metres: the vertices
of a reconstructed mesh, or a point cloud (e.g. one point per pixel of a dense
method). Conventions (docs/architecture.md): metres in, millimetres out.

Accuracy
    distance of every estimated point to the GT mesh surface (exact
    point-to-triangle distance, unsigned); mean / RMS / max / p95, in mm.

Surface coverage (how much of the true plate's area the estimate covers; ``surface_coverage_frac``,
not the bench's ``coverage_frac``, a share of the plate's pixels: ``evaluation.pixel_coverage``)
    1. The GT mesh surface (all faces, or only ``coverage_faces``) is sampled
       uniformly by area with ``trimesh.sample.sample_surface(mesh, n,
       face_weight=..., seed=seed)``, n = ceil(A / sample_spacing_m^2) where A
       is the sampled area (each sample stands for A / n square metres).
    2. Every estimated point whose distance to the GT surface is at most
       ``max_distance_m`` (no limit by default) is projected onto the GT surface
       (its closest point, "foot point").
    3. A GT sample is covered when some foot point lies within
       ``coverage_radius_m`` (default 2 x sample_spacing_m) of it. Measuring
       between foot points ON the surface makes the test lateral: a depth error
       alone does not uncover the plate (use ``max_distance_m`` to discard
       outliers).
    4. covered_area = (#covered samples) * A / n and
       surface_coverage_frac = covered_area / plate_area_m2 (default A).
    For a plate with thickness (a closed solid: top, bottom, side walls) pass
    the top faces as ``coverage_faces``: sampling the whole solid would count the
    unseen bottom as uncovered (coverage about 0.5 at best) or, when the plate
    is thinner than ``coverage_radius_m``, as covered by the top's foot points.
    surface_coverage_frac is not clipped to 1; a value above 1 signals such a mismatch
    (e.g. plate_area_m2 smaller than the sampled area).
    Expect surface_coverage_frac to exceed the true covered fraction by about
    coverage_radius_m x (length of the covered region's boundary) / plate area
    (the band around the covered region); sampling noise is about
    sqrt(f (1 - f) / n).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from platebench.tolerances import tol

from .point_metrics import closest_point_on_mesh
from .stats import ErrorStats, check_array

__all__ = ["SurfaceScore", "score_surface", "sample_mesh_surface"]

_MAX_SURFACE_SAMPLES = 5_000_000


@dataclass(frozen=True)
class SurfaceScore:
    """Surface accuracy (metres) and surface coverage (the share of the true plate's area within
    ``coverage_radius_m`` of the estimate); the JSON form (``bench.io.codecs.evaluation``) reports mm and mm^2."""

    dist: ErrorStats
    surface_coverage_frac: float
    covered_area_m2: float
    plate_area_m2: float
    gt_sample_count: int
    points_used_for_coverage: int
    sample_spacing_m: float
    coverage_radius_m: float
    max_distance_m: float | None


def _face_mask(mesh, faces) -> np.ndarray | None:
    if faces is None:
        return None
    f = np.asarray(faces)
    nf = len(mesh.faces)
    if f.dtype == np.bool_:
        if f.shape != (nf,):
            raise ValueError(f"coverage_faces: bool mask of shape {f.shape}, mesh has {nf} faces")
        mask = f
    else:
        if f.ndim != 1 or not np.issubdtype(f.dtype, np.integer) or (f.size and (f.min() < 0 or f.max() >= nf)):
            raise ValueError(f"coverage_faces: expected a bool mask or face indices in [0, {nf})")
        mask = np.zeros(nf, dtype=bool)
        mask[f] = True
    if not mask.any():
        raise ValueError("coverage_faces: selects no face")
    return mask


def sample_mesh_surface(mesh, sample_spacing_m: float, seed: int = 0, faces=None) -> tuple[np.ndarray, float]:
    """ceil(area / spacing^2) points uniform by area on ``mesh`` (seeded, reproducible).

    ``faces``: optional bool mask (F,) or face indices; only those faces are
    sampled (e.g. the top faces of a plate with thickness). Returns the points
    and the sampled area in m^2. (The ceiling ignores a relative excess of 1e-9,
    so float noise in the area does not add a sample.)
    """
    import trimesh

    mask = _face_mask(mesh, faces)
    face_area = np.asarray(mesh.area_faces, dtype=np.float64)
    weights = None if mask is None else np.where(mask, face_area, 0.0)
    area = float(face_area.sum() if weights is None else weights.sum())
    if not area > 0:
        raise ValueError("gt_mesh: the sampled faces have zero area")
    n = max(1, math.ceil(area / sample_spacing_m**2 * (1 - tol.step_count)))
    if n > _MAX_SURFACE_SAMPLES:
        raise ValueError(
            f"sample_spacing_m: {sample_spacing_m} m gives {n} samples on {area} m^2 "
            f"(limit {_MAX_SURFACE_SAMPLES}); use a larger spacing"
        )
    pts, _ = trimesh.sample.sample_surface(mesh, n, face_weight=weights, seed=seed)
    return np.asarray(pts, dtype=np.float64), area


def score_surface(
    vertices,
    gt_mesh,
    plate_area_m2: float | None = None,
    sample_spacing_m: float = 0.5e-3,
    *,
    coverage_radius_m: float | None = None,
    max_distance_m: float | None = None,
    coverage_faces=None,
    seed: int = 0,
) -> SurfaceScore:
    """Score an estimated surface (points (N, 3), world, metres) against ``gt_mesh`` (see module doc).

    Args:
        vertices: (N, 3) finite points (or a trimesh.Trimesh, whose vertices are used).
        gt_mesh: trimesh.Trimesh of the true plate, world frame, metres.
        plate_area_m2: area the coverage is a fraction of; default the area of
            the sampled faces (all of gt_mesh, or ``coverage_faces``).
        sample_spacing_m: spacing of the GT surface samples (default 0.5 mm).
        coverage_radius_m: lateral tolerance, default 2 x sample_spacing_m.
        max_distance_m: estimated points farther than this from the GT surface
            do not count for coverage (they still count for accuracy).
        coverage_faces: optional bool mask (F,) or indices of the GT faces the
            coverage is measured on (e.g. the top faces of a plate with
            thickness); accuracy always uses the whole mesh.
        seed: seed of the GT surface sampling.
    """
    if hasattr(vertices, "vertices") and hasattr(vertices, "faces"):
        vertices = vertices.vertices
    P = check_array(vertices, "vertices", shape=(None, 3))
    for nm, val in (("sample_spacing_m", sample_spacing_m), ("coverage_radius_m", coverage_radius_m),
                    ("max_distance_m", max_distance_m), ("plate_area_m2", plate_area_m2)):
        if val is not None and not (math.isfinite(val) and val > 0):
            raise ValueError(f"{nm}: must be a positive finite number, got {val!r}")
    radius = 2.0 * sample_spacing_m if coverage_radius_m is None else float(coverage_radius_m)

    foot, dist, _ = closest_point_on_mesh(P, gt_mesh)
    acc = ErrorStats.from_abs(dist, name="point-to-surface distance")

    samples, sampled_area = sample_mesh_surface(gt_mesh, sample_spacing_m, seed, coverage_faces)
    area = sampled_area if plate_area_m2 is None else float(plate_area_m2)
    use = np.ones(len(P), dtype=bool) if max_distance_m is None else dist <= max_distance_m
    n_use = int(np.count_nonzero(use))
    if n_use:
        from scipy.spatial import cKDTree  # noqa: PLC0415  (scipy.spatial takes a while to import)

        d_s, _ = cKDTree(foot[use]).query(samples, k=1, distance_upper_bound=radius * (1 + tol.relative), workers=-1)
        covered = int(np.count_nonzero(d_s <= radius))
    else:
        covered = 0
    covered_area = covered * sampled_area / len(samples)
    return SurfaceScore(
        dist=acc,
        surface_coverage_frac=covered_area / area,
        covered_area_m2=covered_area,
        plate_area_m2=area,
        gt_sample_count=int(len(samples)),
        points_used_for_coverage=n_use,
        sample_spacing_m=float(sample_spacing_m),
        coverage_radius_m=radius,
        max_distance_m=None if max_distance_m is None else float(max_distance_m),
    )
