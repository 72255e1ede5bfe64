"""The structured-light calibration's rays scored against the true ones: per feature, the angle
between an estimated and a true ray and the distance between their cuts with a plane z = const
(world frame, metres and radians), the RMS and largest value of such errors, and the angle
between an estimated and a true rotation."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.reconstruction.paper.false_boundary import FeatureRays

__all__ = ["RayErrors", "ray_errors", "rms_max", "rotation_angle_rad"]


@dataclass(frozen=True, eq=False)
class RayErrors:
    """Per feature (``ids``, (F,)): the angle between an estimated and a true ray (rad, (F,)) and
    the distance between their cuts with a plane z = const (metres, (F,))."""

    ids: np.ndarray
    angle_rad: np.ndarray
    distance_at_plane_m: np.ndarray


def ray_errors(est: FeatureRays, true: FeatureRays, plane_z_m: float) -> RayErrors:
    """Per feature (matched by id): angle between the rays (rad) and the distance between
    their cuts with the plane z = ``plane_z_m`` (metres)."""
    idx = {int(i): k for k, i in enumerate(true.ids)}
    k = np.array([idx[int(i)] for i in est.ids])
    de, dt = est.directions, true.directions[k]
    ang = np.arccos(np.clip(np.abs(np.einsum("ij,ij->i", de, dt)), -1.0, 1.0))

    def cut(o, d):
        s = (plane_z_m - o[:, 2]) / d[:, 2]
        return o + d * s[:, None]

    dist = np.linalg.norm(cut(est.origins, de) - cut(true.origins[k], dt), axis=1)
    return RayErrors(est.ids.astype(int), ang, dist)


def rms_max(v) -> tuple[float, float]:
    """(RMS, largest) of |v| over every element."""
    v = np.abs(np.asarray(v, float))
    return float(np.sqrt(np.mean(v ** 2))), float(v.max())


def rotation_angle_rad(Ra: np.ndarray, Rb: np.ndarray) -> float:
    """Angle (radians) of the rotation Ra Rb^T."""
    c = (np.trace(np.asarray(Ra) @ np.asarray(Rb).T) - 1.0) / 2.0
    return float(np.arccos(np.clip(c, -1.0, 1.0)))
