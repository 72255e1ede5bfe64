"""Lens distortion: the Brown-Conrady model in OpenCV's form and coefficient order, written once.

Normalised image coordinates ``x = X/Z, y = Y/Z`` (camera frame, OpenCV axes) of the ideal
pinhole are distorted to ``(x_d, y_d)``::

    r2  = x^2 + y^2
    x_d = x (1 + k1 r2 + k2 r2^2 + k3 r2^3) + 2 p1 x y + p2 (r2 + 2 x^2)
    y_d = y (1 + k1 r2 + k2 r2^2 + k3 r2^3) + p1 (r2 + 2 y^2) + 2 p2 x y

and pixels follow as ``(u, v) = K (x_d, y_d, 1)`` (Brown 1966, "Decentering distortion of
lenses"; OpenCV's ``calib3d`` model with ``distCoeffs = (k1, k2, p1, p2, k3)``). ``undistort``
is the exact inverse: Newton's method on the 2 x 2 Jacobian, iterated to the rounding error
of float64 (not OpenCV's fixed five fixed-point steps). Pure numpy; the renderer evaluates the
same polynomial in ``scenes.render.lens_sensor``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["BrownConrady", "DistortionError"]

_NEWTON_MAX_ITER = 50
_NEWTON_STEP = 1e-15  # normalised units: a Newton step this small is the rounding error of float64


class DistortionError(ValueError):
    """The distortion model cannot be inverted where it was asked to (it folds over there)."""


@dataclass(frozen=True)
class BrownConrady:
    """Radial (k1, k2, k3) and tangential (p1, p2) distortion of normalised coordinates.

    Coefficients are dimensionless (normalised coordinates are tangents of the field angle);
    the default is the identity. ``as_opencv()`` gives OpenCV's ``(k1, k2, p1, p2, k3)``.
    """

    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    k3: float = 0.0

    def __post_init__(self):
        for name in ("k1", "k2", "p1", "p2", "k3"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not math.isfinite(v):
                raise ValueError(f"distortion {name} = {v!r} is not a finite number")
            if abs(v) > 100.0:
                raise ValueError(f"distortion {name} = {v} is out of range: allowed -100 to 100")
            object.__setattr__(self, name, float(v))

    # -- construction -------------------------------------------------------------
    @classmethod
    def from_opencv(cls, coeffs) -> "BrownConrady":
        """From OpenCV's coefficient vector (k1, k2, p1, p2[, k3]); longer vectors (rational,
        thin-prism terms) are refused unless those terms are zero."""
        c = np.asarray(coeffs, float).ravel()
        if c.size < 4:
            raise ValueError(f"OpenCV distortion needs >= 4 coefficients (k1, k2, p1, p2), got {c.size}")
        if c.size > 5 and np.any(c[5:] != 0):
            raise ValueError("only OpenCV's k1, k2, p1, p2, k3 terms are modelled; higher terms must be 0")
        k3 = float(c[4]) if c.size > 4 else 0.0
        return cls(float(c[0]), float(c[1]), float(c[2]), float(c[3]), k3)

    def as_opencv(self) -> np.ndarray:
        """OpenCV's distortion vector ``(k1, k2, p1, p2, k3)`` (float64, shape (5,))."""
        return np.array([self.k1, self.k2, self.p1, self.p2, self.k3])

    @property
    def is_identity(self) -> bool:
        return not any((self.k1, self.k2, self.p1, self.p2, self.k3))

    # -- the model ----------------------------------------------------------------------
    def distort(self, xy) -> np.ndarray:
        """(N,2) ideal normalised coordinates -> (N,2) distorted normalised coordinates."""
        p = np.atleast_2d(np.asarray(xy, float))
        x, y = p[:, 0], p[:, 1]
        r2 = x * x + y * y
        radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        xd = x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x)
        yd = y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y
        return np.column_stack([xd, yd])

    def jacobian(self, xy) -> np.ndarray:
        """(N,2,2) derivative d(x_d, y_d) / d(x, y) at ideal normalised coordinates."""
        p = np.atleast_2d(np.asarray(xy, float))
        x, y = p[:, 0], p[:, 1]
        r2 = x * x + y * y
        radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        dradial = self.k1 + r2 * (2.0 * self.k2 + 3.0 * self.k3 * r2)  # d radial / d r2
        J = np.empty((len(p), 2, 2))
        J[:, 0, 0] = radial + 2.0 * x * x * dradial + 2.0 * self.p1 * y + 6.0 * self.p2 * x
        J[:, 0, 1] = 2.0 * x * y * dradial + 2.0 * self.p1 * x + 2.0 * self.p2 * y
        J[:, 1, 0] = 2.0 * x * y * dradial + 2.0 * self.p1 * x + 2.0 * self.p2 * y
        J[:, 1, 1] = radial + 2.0 * y * y * dradial + 6.0 * self.p1 * y + 2.0 * self.p2 * x
        return J

    def undistort(self, xy_d) -> np.ndarray:
        """(N,2) distorted normalised coordinates -> (N,2) ideal ones: the exact inverse of
        ``distort`` (Newton's method to float64 rounding). Raises ``DistortionError`` where the
        model folds (Jacobian not positive) or Newton does not converge: the point lies outside
        the region where this lens maps one-to-one."""
        d = np.atleast_2d(np.asarray(xy_d, float))
        if self.is_identity:
            return d.copy()
        p = d.copy()
        for _ in range(_NEWTON_MAX_ITER):
            r = self.distort(p) - d
            J = self.jacobian(p)
            det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
            if np.any(~(det > 0)):
                raise DistortionError("distortion model folds over (Jacobian <= 0) at "
                                      f"{p[~(det > 0)][0].tolist()} (normalised): no unique inverse there")
            step = np.column_stack([(J[:, 1, 1] * r[:, 0] - J[:, 0, 1] * r[:, 1]) / det,
                                    (-J[:, 1, 0] * r[:, 0] + J[:, 0, 0] * r[:, 1]) / det])
            p -= step
            if np.max(np.abs(step), initial=0.0) <= _NEWTON_STEP * max(1.0, float(np.max(np.abs(p), initial=0.0))):
                return p
        raise DistortionError(f"undistort did not converge in {_NEWTON_MAX_ITER} Newton steps")

    def monotonic_to(self, r_max: float, samples: int = 2001) -> bool:
        """True if the radial map r -> r (1 + k1 r^2 + k2 r^4 + k3 r^6) increases on [0, r_max]
        (the lens maps one-to-one out to normalised radius ``r_max``)."""
        r = np.linspace(0.0, float(r_max), samples)
        r2 = r * r
        deriv = 1.0 + 3.0 * self.k1 * r2 + 5.0 * self.k2 * r2 ** 2 + 7.0 * self.k3 * r2 ** 3
        return bool(np.all(deriv > 0))
