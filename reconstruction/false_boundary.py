"""False-boundary test (paper section IV-B, stage 3): count squares against the projector rays.

"The false boundary problem can be detected by comparing the number of squares
extracted in the image pair to the actual number of squares within the surface
boundary. [...] The actual number of squares can be known by checking how many
structured light rays are projected within the surface boundary since the position
and orientation of the structured light are available from structured light
calibration."

Each feature's ray (origin + direction in the world frame, from calibration: the
projector's K, R, t, or rays fitted by the structured-light calibration) is cut with
the boundary plane and counted when the cut lies inside the reconstructed boundary
(both expressed in the plane's own 2D frame). Units: metres.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from reconstruction.boundary_plane import BoundaryPlane, plane_frame
from reconstruction.surface_interpolation import points_in_polygon


@dataclass(frozen=True)
class FeatureRays:
    """One ray per projected feature (world frame): origins (N,3), unit directions (N,3), ids (N,)."""

    origins: np.ndarray
    directions: np.ndarray
    ids: np.ndarray


@dataclass(frozen=True)
class FalseBoundaryTest:
    detected: dict  # image name -> squares detected inside the passive boundary
    expected: int
    expected_ids: tuple[int, ...]
    false_boundary_detected: bool

    def to_dict(self) -> dict:
        return {"detected": self.detected, "expected": self.expected, "expected_ids": list(self.expected_ids),
                "false_boundary_detected": self.false_boundary_detected}


def rays_on_plane(rays: FeatureRays, plane: BoundaryPlane) -> np.ndarray:
    """Intersections (N,3) of the feature rays with the plane (NaN where parallel or behind)."""
    denom = rays.directions @ plane.normal
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (plane.offset - rays.origins @ plane.normal) / denom
    hit = rays.origins + rays.directions * t[:, None]
    hit[~(np.abs(denom) > 1e-12) | ~(t > 0)] = np.nan
    return hit


def expected_features_inside(rays: FeatureRays, plane: BoundaryPlane, boundary: np.ndarray) -> np.ndarray:
    """Ids of the features whose rays land inside the boundary (on the boundary plane)."""
    R, origin = plane_frame(plane)
    hits = rays_on_plane(rays, plane)
    ok = np.all(np.isfinite(hits), axis=1)
    poly = (np.asarray(boundary) - origin) @ R.T
    inside = np.zeros(len(hits), bool)
    if ok.any():
        inside[ok] = points_in_polygon(((hits[ok] - origin) @ R.T)[:, :2], poly[:, :2])
    return rays.ids[inside]


def false_boundary_test(detected: dict, rays: FeatureRays, plane: BoundaryPlane, boundary: np.ndarray) -> FalseBoundaryTest:
    """The paper's counting test: a false boundary exists if either image shows fewer squares than expected."""
    ids = expected_features_inside(rays, plane, boundary)
    expected = int(len(ids))
    flag = any(n < expected for n in detected.values())
    return FalseBoundaryTest(dict(detected), expected, tuple(int(i) for i in ids), bool(flag))
