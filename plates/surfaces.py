"""Building blocks of the families' exact surface maps (``DeformationFamily.surface``).

Units: metres and radians. Each function works on the array operations ``xp`` it is given
(``plates.deformations.NumpyOps`` for numpy; an object of the same methods for another array
type), so one formula serves the mesh, the ground truth and the renderer's device. A frame is
(r, r_u, r_v): the top-surface point and its partial derivatives along the material coordinates
u and v, each a tuple of 3 world-frame components (arrays of the shape of u).
"""

from __future__ import annotations

import math

__all__ = ["arc", "along", "height_field", "ruled_frame"]


def arc(x, k, xp):
    """(sin(k x)/k, (1 - cos(k x))/k): the in-plane position and the height after arc length x
    (metres) on a circle of signed curvature k (1/m), accurate for small or zero k."""
    phi = k * x
    return x * xp.sinc(phi / math.pi), x * xp.sin(0.5 * phi) * xp.sinc(phi / (2.0 * math.pi))


def along(a, b, c, ea, eb, ec):
    """Components of a e_a + b e_b + c e_c for 3-vectors e_a, e_b, e_c (tuples), summed in that order."""
    return tuple(a * x + b * y + c * z for x, y, z in zip(ea, eb, ec))


def height_field(u, v, z, z_u, z_v, xp):
    """The frame of the height field (u, v, z(u, v)) from z and its partial derivatives z_u, z_v."""
    ones, zeros = xp.ones_like(u), xp.zeros_like(u)
    return (u, v, z), (ones, zeros, z_u), (zeros, ones, z_v)


def ruled_frame(axis_rad: float, profile, u, v, xp):
    """The frame of a surface ruled along the bend axis ``axis_rad`` (``CylindricalBend.axis_rad``):
    bending coordinate s = u cos a + v sin a, ruling coordinate t = -u sin a + v cos a, and
    ``profile(s)`` -> (p, z, phi), the bent section's in-plane coordinate p (m), height z (m) and
    tangent angle phi (rad): r = p e + t g + z Z, e = (cos a, sin a, 0), g = (-sin a, cos a, 0)."""
    ca, sa = xp.const(math.cos(axis_rad)), xp.const(math.sin(axis_rad))
    e, g, zhat = (ca, sa, 0.0), (-sa, ca, 0.0), (0.0, 0.0, 1.0)
    s = u * ca + v * sa
    t = -u * sa + v * ca
    p, z, phi = profile(s)
    r = along(p, t, z, e, g, zhat)
    c, sn = xp.cos(phi), xp.sin(phi)
    r_s = tuple(c * x + sn * y for x, y in zip(e, zhat))
    r_u = tuple(ca * x - sa * y for x, y in zip(r_s, g))
    r_v = tuple(sa * x + ca * y for x, y in zip(r_s, g))
    return r, r_u, r_v
