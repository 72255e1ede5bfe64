"""Exact analytic surfaces of the deformation families: uv -> xyz, derivatives, normals.

Units: metres and radians. Input uv: (N, 2) or (2,) material coordinates in metres
(u along X, v along Y on the flat plate); output points in the world frame (+Z up),
metres. All derivatives are analytic (no finite differences). The unit normal is
(r_u x r_v) / |r_u x r_v|: the TOP surface normal, +Z for a flat plate.

Each family computes its own surface (``DeformationFamily.surface``, plates/spec.py, from the
building blocks of plates/surfaces.py); the formulas (conventions in plates/spec.py):
- CylindricalBend: with bending coordinate s, ruling coordinate t = -u sin a + v cos a,
  signed curvature k = +-angle/S, phi = k s:
  r = (sin(phi)/k) e + t g + ((1 - cos phi)/k) Z, e = (cos a, sin a, 0), g = (-sin a, cos a, 0).
- Fold: same profile with phi = k * clip(s - s0, 0, band), s0 = position - band/2, the
  part s < s0 left in place and straight continuations beyond the band.
- SCurve: the cylinder's profile of |s| with k = +-2 angle/S, odd in s: r = sign(s) (sin(k|s|)/k e
  + ((1 - cos k|s|)/k) Z) + t g, tangent angle phi = k|s|.
- Twist: r = (u, v cos(ku), v sin(ku)), k = angle/L.
- Dome: height field z = -c rho^2 / (1 + sqrt(1 - c^2 rho^2)), c = 2 sag / (D^2 + sag^2).
- Dent: height field z = -depth (1 - q)^3 for q = |uv - centre|^2 / R^2 < 1, else 0.
"""

from __future__ import annotations

import numpy as np

from .spec import PlateSpec

__all__ = ["surface_point", "surface_derivatives", "surface_normal", "surface_frame", "NumpyOps", "NUMPY_OPS"]


def _as_uv(uv: np.ndarray) -> tuple[np.ndarray, bool]:
    uv = np.asarray(uv, dtype=np.float64)
    single = uv.ndim == 1
    uv = np.atleast_2d(uv)
    if uv.shape[-1] != 2 or uv.ndim != 2:
        raise ValueError(f"uv must have shape (N, 2) or (2,), got {uv.shape}")
    return uv, single


class NumpyOps:
    """The array operations the surface formulas use, for numpy arrays. The same formulas run on
    other array types (drjit's, for the renderer's ground truth on its device) with an object of
    the same methods (``scenes.render.ground_truth_device``); ``const`` makes a plate's parameter an
    array operand (there: an opaque kernel input, so another plate reuses the compiled kernel)."""

    sin, cos, sqrt, maximum, clip, sinc, abs, sign = (staticmethod(f) for f in (
        np.sin, np.cos, np.sqrt, np.maximum, np.clip, np.sinc, np.abs, np.sign))
    zeros_like, ones_like = staticmethod(np.zeros_like), staticmethod(np.ones_like)

    @staticmethod
    def const(value: float) -> float:
        return float(value)


NUMPY_OPS = NumpyOps()


def surface_frame(spec: PlateSpec, u, v, xp=NUMPY_OPS):
    """Top-surface point r and partial derivatives r_u, r_v at material coords (u, v) (arrays of
    one shape, metres), each a tuple of 3 world-frame components, computed with the array
    operations ``xp`` (``NumpyOps``: numpy; another array type: an object of the same methods): the
    family's own ``DeformationFamily.surface``."""
    return spec.deformation.surface(spec.length_m, spec.width_m, u, v, xp)


def _stacked(spec: PlateSpec, uv: np.ndarray):
    return tuple(np.stack(c, axis=1) for c in surface_frame(spec, uv[:, 0], uv[:, 1]))


def surface_derivatives(spec: PlateSpec, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Top-surface point r and partial derivatives r_u, r_v at material coords uv.

    uv: (N, 2) metres. Returns three (N, 3) arrays in the world frame: r in metres,
    r_u and r_v dimensionless (metres per metre of u or v).
    """
    uv, _ = _as_uv(uv)
    return _stacked(spec, uv)


def surface_point(spec: PlateSpec, uv: np.ndarray) -> np.ndarray:
    """Top-surface point (world frame, metres) at material coords uv ((N, 2) -> (N, 3), (2,) -> (3,))."""
    uv, single = _as_uv(uv)
    r = _stacked(spec, uv)[0]
    return r[0] if single else r


def surface_normal(spec: PlateSpec, uv: np.ndarray) -> np.ndarray:
    """Unit top-surface normal (world frame) at material coords uv; +Z on a flat plate."""
    uv, single = _as_uv(uv)
    _, r_u, r_v = _stacked(spec, uv)
    n = np.cross(r_u, r_v)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return n[0] if single else n
