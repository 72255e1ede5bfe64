"""False-boundary test (paper section IV-B, stage 3): count squares against the projector rays.

"The false boundary problem can be detected by comparing the number of squares
extracted in the image pair to the actual number of squares within the surface
boundary. [...] The actual number of squares can be known by checking how many
structured light rays are projected within the surface boundary since the position
and orientation of the structured light are available from structured light
calibration."

Each feature's ray (origin + direction in the world frame, from calibration: the
projector's K, R, t, or rays fitted by the structured-light calibration) counts when it
passes inside the reconstructed boundary *as seen from the projector*: the boundary and
the rays are put in a gnomonic (pinhole) projection about the rays' common point, and
the ray's image must fall inside the boundary's image. This is exact for any surface
shape. ``expected_features_inside_plane`` cuts the rays with the boundary plane instead,
for comparison: it undercounts on strongly bent plates. Units: metres.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from platebench.reconstruction.paper.boundary_plane import BoundaryPlane, plane_frame
from platebench.reconstruction.paper.surface_interpolation import points_in_polygon
from platebench.tolerances import tol


@dataclass(frozen=True)
class FeatureRays:
    """One ray per projected feature (world frame): origins (N,3), unit directions (N,3), ids (N,)."""

    origins: np.ndarray
    directions: np.ndarray
    ids: np.ndarray


@dataclass(frozen=True)
class FalseBoundaryTest:
    """The counting test's inputs and verdict, plus the Fig. 2 symptom (arrays that disagree)."""

    detected: dict  # image name -> whole squares detected inside the passive boundary
    expected: int
    expected_ids: tuple[int, ...]
    counting_test: bool  # paper IV-B: fewer squares in an image than rays inside the boundary
    arrays_disagree: bool = False  # paper II, Fig. 2: a horizontal array holds different counts L/R
    # image name -> detected squares that are cut (by the plate's outline or the threshold,
    # ``squares.Square.cut``): counted as the test counts them, their centres set apart by the pipeline
    cut: dict = field(default_factory=dict)

    @property
    def false_boundary_detected(self) -> bool:
        return self.counting_test or self.arrays_disagree


def rays_on_plane(rays: FeatureRays, plane: BoundaryPlane) -> np.ndarray:
    """Intersections (N,3) of the feature rays with the plane (NaN where parallel or behind)."""
    denom = rays.directions @ plane.normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (plane.offset - rays.origins @ plane.normal) / denom
    hit = rays.origins + rays.directions * t[:, None]
    hit[~(np.abs(denom) > tol.parallel) | ~(t > 0)] = np.nan
    return hit


def rays_common_point(rays: FeatureRays) -> np.ndarray:
    """Least-squares point closest to all rays (the projector's centre for a pinhole)."""
    d = rays.directions / np.linalg.norm(rays.directions, axis=1, keepdims=True)
    P = np.eye(3)[None] - d[:, :, None] * d[:, None, :]
    A = P.sum(axis=0)
    b = np.einsum("kij,kj->i", P, rays.origins)
    if np.linalg.cond(A) > 1e12:  # parallel rays: no common point
        return rays.origins.mean(axis=0)
    return np.linalg.solve(A, b)


def expected_features_inside(rays: FeatureRays, plane: BoundaryPlane, boundary: np.ndarray) -> np.ndarray:
    """Ids of the features whose rays pass inside the boundary as seen from the projector."""
    O = rays_common_point(rays)
    d = rays.directions / np.linalg.norm(rays.directions, axis=1, keepdims=True)
    axis = d.mean(axis=0)
    axis /= np.linalg.norm(axis)
    e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(axis, e1)

    def gnomonic(v):
        z = v @ axis
        return np.column_stack([(v @ e1) / z, (v @ e2) / z]), z > 0

    poly, front = gnomonic(np.asarray(boundary, float) - O)
    pts, ok = gnomonic(d)
    if not front.all():
        return expected_features_inside_plane(rays, plane, boundary)  # boundary wraps behind the projector
    inside = np.zeros(len(d), bool)
    inside[ok] = points_in_polygon(pts[ok], poly)
    return rays.ids[inside]


def expected_features_inside_plane(rays: FeatureRays, plane: BoundaryPlane, boundary: np.ndarray) -> np.ndarray:
    """Ids of the features whose rays cut the boundary plane inside the boundary (first version)."""
    R, origin = plane_frame(plane)
    hits = rays_on_plane(rays, plane)
    ok = np.all(np.isfinite(hits), axis=1)
    poly = (np.asarray(boundary) - origin) @ R.T
    inside = np.zeros(len(hits), bool)
    if ok.any():
        inside[ok] = points_in_polygon(((hits[ok] - origin) @ R.T)[:, :2], poly[:, :2])
    return rays.ids[inside]


def false_boundary_test(detected: dict, rays: FeatureRays, plane: BoundaryPlane, boundary: np.ndarray,
                        arrays_disagree: bool = False, cut: dict | None = None) -> FalseBoundaryTest:
    """The paper's counting test: a false boundary exists if either image shows fewer squares than
    expected. ``arrays_disagree`` carries the matching's Fig. 2 symptom, reported separately, as
    ``cut`` does the cut squares of each image."""
    ids = expected_features_inside(rays, plane, boundary)
    expected = int(len(ids))
    flag = any(n < expected for n in detected.values())
    return FalseBoundaryTest(dict(detected), expected, tuple(int(i) for i in ids), bool(flag), bool(arrays_disagree),
                             dict(cut or {}))
