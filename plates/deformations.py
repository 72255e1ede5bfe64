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

__all__ = ["surface_point", "surface_derivatives", "surface_normal"]


def _as_uv(uv: np.ndarray) -> tuple[np.ndarray, bool]:
    uv = np.asarray(uv, dtype=np.float64)
    single = uv.ndim == 1
    uv = np.atleast_2d(uv)
    if uv.shape[-1] != 2 or uv.ndim != 2:
        raise ValueError(f"uv must have shape (N, 2) or (2,), got {uv.shape}")
    return uv, single


def _arc(x: np.ndarray, k: float) -> tuple[np.ndarray, np.ndarray]:
    """(sin(k x)/k, (1 - cos(k x))/k), accurate for small or zero k."""
    phi = k * x
    return x * np.sinc(phi / np.pi), x * np.sin(0.5 * phi) * np.sinc(phi / (2.0 * np.pi))


def _bend_profile(spec: PlateSpec, s: np.ndarray):
    """In-plane coordinate p(s), height z(s), and tangent angle phi(s) of the bent section."""
    d = spec.deformation
    sign = 1.0 if d.direction == "up" else -1.0
    if isinstance(d, CylindricalBend):
        k = sign * d.angle_rad / bending_extent_m(spec.length_m, spec.width_m, d.axis_rad)
        p, z = _arc(s, k)
        return p, z, k * s
    if isinstance(d, SCurve):
        k = sign * 2.0 * d.angle_rad / bending_extent_m(spec.length_m, spec.width_m, d.axis_rad)
        a, odd = np.abs(s), np.sign(s)
        p, z = _arc(a, k)
        return odd * p, odd * z, k * a
    k = sign * d.angle_rad / d.band_m
    s0 = d.position_m - 0.5 * d.band_m
    dist = s - s0
    inside = np.clip(dist, 0.0, d.band_m)
    phi = k * inside
    p_arc, z_arc = _arc(inside, k)
    rest = dist - inside
    return s0 + p_arc + rest * np.cos(phi), z_arc + rest * np.sin(phi), phi


def _bend(spec: PlateSpec, uv: np.ndarray):
    a = spec.deformation.axis_rad
    ca, sa = math.cos(a), math.sin(a)
    e = np.array([ca, sa, 0.0])
    g = np.array([-sa, ca, 0.0])
    zhat = np.array([0.0, 0.0, 1.0])
    s = uv[:, 0] * ca + uv[:, 1] * sa
    t = -uv[:, 0] * sa + uv[:, 1] * ca
    p, z, phi = _bend_profile(spec, s)
    r = p[:, None] * e + t[:, None] * g + z[:, None] * zhat
    r_s = np.cos(phi)[:, None] * e + np.sin(phi)[:, None] * zhat
    r_u = ca * r_s - sa * g
    r_v = sa * r_s + ca * g
    return r, r_u, r_v


def _twist(spec: PlateSpec, uv: np.ndarray):
    k = spec.deformation.angle_rad / spec.length_m
    u, v = uv[:, 0], uv[:, 1]
    c, s = np.cos(k * u), np.sin(k * u)
    r = np.stack([u, v * c, v * s], axis=1)
    r_u = np.stack([np.ones_like(u), -k * v * s, k * v * c], axis=1)
    r_v = np.stack([np.zeros_like(u), c, s], axis=1)
    return r, r_u, r_v


def _height_field(uv: np.ndarray, z: np.ndarray, z_u: np.ndarray, z_v: np.ndarray):
    ones, zeros = np.ones(len(uv)), np.zeros(len(uv))
    r = np.column_stack([uv, z])
    return r, np.stack([ones, zeros, z_u], axis=1), np.stack([zeros, ones, z_v], axis=1)


def dome_curvature_per_m(spec: PlateSpec) -> float:
    """Signed sphere curvature c (1/m) of a Dome: positive for a dome, negative for a bowl."""
    sag = spec.deformation.sag_m
    half_diag_sq = 0.25 * (spec.length_m**2 + spec.width_m**2)
    return 2.0 * sag / (half_diag_sq + sag**2)


def _dome(spec: PlateSpec, uv: np.ndarray):
    c = dome_curvature_per_m(spec)
    rho_sq = np.sum(uv**2, axis=1)
    w = np.sqrt(1.0 - c * c * rho_sq)
    z = -c * rho_sq / (1.0 + w)
    return _height_field(uv, z, -c * uv[:, 0] / w, -c * uv[:, 1] / w)


def _dent(spec: PlateSpec, uv: np.ndarray):
    d = spec.deformation
    du = uv[:, 0] - d.centre_u_m
    dv = uv[:, 1] - d.centre_v_m
    one_minus_q = np.maximum(1.0 - (du**2 + dv**2) / d.radius_m**2, 0.0)
    z = -d.depth_m * one_minus_q**3
    slope = 6.0 * d.depth_m * one_minus_q**2 / d.radius_m**2
    return _height_field(uv, z, slope * du, slope * dv)


def _flat(spec: PlateSpec, uv: np.ndarray):
    return _height_field(uv, np.zeros(len(uv)), np.zeros(len(uv)), np.zeros(len(uv)))


_FAMILY_MAPS = {Flat: _flat, CylindricalBend: _bend, Fold: _bend, Twist: _twist,
                Dome: _dome, Dent: _dent, SCurve: _bend}


def _surface_map(spec: PlateSpec):
    """The exact map of the spec's family (ValueError for a family without one: never a guess)."""
    try:
        return _FAMILY_MAPS[type(spec.deformation)]
    except KeyError:
        raise ValueError(f"deformation family {type(spec.deformation).__name__} has no exact surface: "
                         "allowed " + ", ".join(c.__name__ for c in _FAMILY_MAPS)) from None


def surface_derivatives(spec: PlateSpec, uv: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Top-surface point r and partial derivatives r_u, r_v at material coords uv.

    uv: (N, 2) metres. Returns three (N, 3) arrays in the world frame: r in metres,
    r_u and r_v dimensionless (metres per metre of u or v).
    """
    uv, _ = _as_uv(uv)
    return _surface_map(spec)(spec, uv)


def surface_point(spec: PlateSpec, uv: np.ndarray) -> np.ndarray:
    """Top-surface point (world frame, metres) at material coords uv ((N, 2) -> (N, 3), (2,) -> (3,))."""
    uv, single = _as_uv(uv)
    r = _surface_map(spec)(spec, uv)[0]
    return r[0] if single else r


def surface_normal(spec: PlateSpec, uv: np.ndarray) -> np.ndarray:
    """Unit top-surface normal (world frame) at material coords uv; +Z on a flat plate."""
    uv, single = _as_uv(uv)
    _, r_u, r_v = _surface_map(spec)(spec, uv)
    n = np.cross(r_u, r_v)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return n[0] if single else n
