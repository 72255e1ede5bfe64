"""Exact analytic surfaces of the deformation families: uv -> xyz, derivatives, normals.

Units: metres and radians. Input uv: (N, 2) or (2,) material coordinates in metres
(u along X, v along Y on the flat plate); output points in the world frame (+Z up),
metres. All derivatives are analytic (no finite differences). The unit normal is
(r_u x r_v) / |r_u x r_v|: the TOP surface normal, +Z for a flat plate.

The formulas (conventions in plates/spec.py):
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

import math

import numpy as np

from .spec import (
    CylindricalBend,
    Dent,
    Dome,
    Flat,
    Fold,
    PlateSpec,
    SCurve,
    Twist,
    bending_extent_m,
)

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


def _arc(x, k, xp):
    """(sin(k x)/k, (1 - cos(k x))/k), accurate for small or zero k."""
    phi = k * x
    return x * xp.sinc(phi / np.pi), x * xp.sin(0.5 * phi) * xp.sinc(phi / (2.0 * np.pi))


def _bend_profile(spec: PlateSpec, s, xp):
    """In-plane coordinate p(s), height z(s), and tangent angle phi(s) of the bent section."""
    d = spec.deformation
    sign = 1.0 if d.direction == "up" else -1.0
    if isinstance(d, CylindricalBend):
        k = xp.const(sign * d.angle_rad / bending_extent_m(spec.length_m, spec.width_m, d.axis_rad))
        p, z = _arc(s, k, xp)
        return p, z, k * s
    if isinstance(d, SCurve):
        k = xp.const(sign * 2.0 * d.angle_rad / bending_extent_m(spec.length_m, spec.width_m, d.axis_rad))
        a, odd = xp.abs(s), xp.sign(s)
        p, z = _arc(a, k, xp)
        return odd * p, odd * z, k * a
    k = xp.const(sign * d.angle_rad / d.band_m)
    s0 = xp.const(d.position_m - 0.5 * d.band_m)
    dist = s - s0
    inside = xp.clip(dist, 0.0, xp.const(d.band_m))
    phi = k * inside
    p_arc, z_arc = _arc(inside, k, xp)
    rest = dist - inside
    return s0 + p_arc + rest * xp.cos(phi), z_arc + rest * xp.sin(phi), phi


def _along(a, b, c, ea, eb, ec):
    """Components of a e_a + b e_b + c e_c for 3-vectors e_a, e_b, e_c (tuples), summed in that order."""
    return tuple(a * x + b * y + c * z for x, y, z in zip(ea, eb, ec))


def _bend(spec: PlateSpec, u, v, xp):
    a = spec.deformation.axis_rad
    ca, sa = xp.const(math.cos(a)), xp.const(math.sin(a))
    e, g, zhat = (ca, sa, 0.0), (-sa, ca, 0.0), (0.0, 0.0, 1.0)
    s = u * ca + v * sa
    t = -u * sa + v * ca
    p, z, phi = _bend_profile(spec, s, xp)
    r = _along(p, t, z, e, g, zhat)
    c, sn = xp.cos(phi), xp.sin(phi)
    r_s = tuple(c * x + sn * y for x, y in zip(e, zhat))
    r_u = tuple(ca * x - sa * y for x, y in zip(r_s, g))
    r_v = tuple(sa * x + ca * y for x, y in zip(r_s, g))
    return r, r_u, r_v


def _twist(spec: PlateSpec, u, v, xp):
    k = xp.const(spec.deformation.angle_rad / spec.length_m)
    c, s = xp.cos(k * u), xp.sin(k * u)
    return (u, v * c, v * s), (xp.ones_like(u), -k * v * s, k * v * c), (xp.zeros_like(u), c, s)


def _height_field(u, v, z, z_u, z_v, xp):
    ones, zeros = xp.ones_like(u), xp.zeros_like(u)
    return (u, v, z), (ones, zeros, z_u), (zeros, ones, z_v)


def dome_curvature_per_m(spec: PlateSpec) -> float:
    """Signed sphere curvature c (1/m) of a Dome: positive for a dome, negative for a bowl."""
    sag = spec.deformation.sag_m
    half_diag_sq = 0.25 * (spec.length_m**2 + spec.width_m**2)
    return 2.0 * sag / (half_diag_sq + sag**2)


def _dome(spec: PlateSpec, u, v, xp):
    c = xp.const(dome_curvature_per_m(spec))
    rho_sq = u * u + v * v
    w = xp.sqrt(1.0 - c * c * rho_sq)
    z = -c * rho_sq / (1.0 + w)
    return _height_field(u, v, z, -c * u / w, -c * v / w, xp)


def _dent(spec: PlateSpec, u, v, xp):
    d = spec.deformation
    du = u - xp.const(d.centre_u_m)
    dv = v - xp.const(d.centre_v_m)
    r2 = xp.const(d.radius_m**2)
    one_minus_q = xp.maximum(1.0 - (du * du + dv * dv) / r2, 0.0)
    depth = xp.const(d.depth_m)
    z = -depth * one_minus_q**3
    slope = 6.0 * depth * one_minus_q**2 / r2
    return _height_field(u, v, z, slope * du, slope * dv, xp)


def _flat(spec: PlateSpec, u, v, xp):
    return _height_field(u, v, xp.zeros_like(u), xp.zeros_like(u), xp.zeros_like(u), xp)


_FAMILY_MAPS = {Flat: _flat, CylindricalBend: _bend, Fold: _bend, Twist: _twist,
                Dome: _dome, Dent: _dent, SCurve: _bend}


def _surface_map(spec: PlateSpec):
    """The exact map of the spec's family (ValueError for a family without one: never a guess)."""
    try:
        return _FAMILY_MAPS[type(spec.deformation)]
    except KeyError:
        raise ValueError(f"deformation family {type(spec.deformation).__name__} has no exact surface: "
                         "allowed " + ", ".join(c.__name__ for c in _FAMILY_MAPS)) from None


def surface_frame(spec: PlateSpec, u, v, xp=NUMPY_OPS):
    """Top-surface point r and partial derivatives r_u, r_v at material coords (u, v) (arrays of
    one shape, metres), each a tuple of 3 world-frame components, computed with the array
    operations ``xp`` (``NumpyOps``: numpy; another array type: an object of the same methods)."""
    return _surface_map(spec)(spec, u, v, xp)


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
