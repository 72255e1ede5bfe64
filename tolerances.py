"""Numerical tolerances, defined once (cf. trimesh's ``constants.tol``).

Geometry is in metres, angles in radians. Each tolerance says what it guards; code imports
``tol`` and names the field instead of writing a bare literal. Relative tolerances are
multiplied by the scale of the quantity they compare (a length, a pixel count, ...).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["tol", "Tolerances", "is_rotation", "ceil_count", "floor_count"]


@dataclass(frozen=True)
class Tolerances:
    """Named tolerances; the module-level ``tol`` is the one instance."""

    rotation: float = 1e-9          # |R R^T - I| entries and det(R) = +1 of a proper rotation
    rotation_loose: float = 1e-6    # the same, for rotations read back from files (9 decimals)
    zero_length_m: float = 1e-12    # a vector or segment this short has no direction
    unit_norm: float = 1e-9         # |v| below this: "no direction" for a (near) unit vector
    parallel: float = 1e-12         # |d . n| below this: a ray parallel to a plane
    relative: float = 1e-12         # relative slack for comparing derived floats to their exact value
    step_count: float = 1e-9        # ceil(x - step_count): a count of steps not raised by rounding
    pixel: float = 1e-9             # pixel-coordinate equality (principal point, K entries)
    stereo_pose_m: float = 1e-12    # both cameras of a conventional rig share R, t differs by B only
    fit_converged: float = 1e-9     # fixed-point iterations (corner intersections) stop here (px)
    occlusion_slack_m: float = 1e-5  # a boundary point is occluded only by surface > 10 um before it
    flat_height_m: float = 1e-5     # a fitted height field this flat (over the plate) has no bend


tol = Tolerances()


def is_rotation(R, atol: float = tol.rotation) -> bool:
    """True if ``R`` is a proper 3x3 rotation: R R^T = I and det(R) = +1 within ``atol``."""
    R = np.asarray(R, dtype=float)
    return (R.shape == (3, 3) and bool(np.all(np.isfinite(R))) and np.allclose(R @ R.T, np.eye(3), atol=atol)
            and abs(np.linalg.det(R) - 1.0) <= 10 * atol + 1e-15)


def ceil_count(x: float) -> int:
    """ceil(x) for a count of steps, not raised by a rounding error of ``tol.step_count``."""
    return int(np.ceil(x - tol.step_count))


def floor_count(x: float) -> int:
    """floor(x) for a count of steps, not lowered by a rounding error of ``tol.step_count``."""
    return int(np.floor(x + tol.step_count))
