"""Pinhole camera model: OpenCV conventions, written once.

Frames and units (docs/architecture.md, "Frames and units"):

* World frame: right-handed, +Z up, metres.
* Camera frame: OpenCV (x right, y down, z forward). A pose is (R, t) with
  ``x_cam = R @ x_world + t``; the rows of R are the camera axes expressed in
  the world frame and the centre is ``C = -R.T @ t``.
* Pixels: OpenCV, pixel centres at integer coordinates, u to the right, v down.
  ``K = [[f, 0, cx], [0, f, cy], [0, 0, 1]]``; a centred principal point is
  ``cx = W/2 - 0.5``, ``cy = H/2 - 0.5``.
* Depth is z-depth along the optical axis, never distance along the ray.
* Lens distortion (optional, ``distortion``): Brown-Conrady on normalised coordinates
  (``scenes.lens``), applied between the pinhole projection and K, as OpenCV does:
  ``(u, v) = K distort(X/Z, Y/Z)``. ``rays`` inverts it exactly, so ``project``, ``rays`` and
  ``at_depth`` stay each other's inverses on a distorted camera.

This module knows no renderer; ``scenes.render.mitsuba_convert`` is the one place that
turns these poses into Mitsuba transforms.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.scenes.lens import BrownConrady, DistortionError
from platebench.tolerances import is_rotation, tol


def _as_matrix(a, shape, name):
    arr = np.asarray(a, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} has non-finite entries: {arr.tolist()}")
    return arr


def centred_principal_point(width: int, height: int) -> tuple[float, float]:
    """(cx, cy) of an image centre with pixel centres at integers: (W/2 - 0.5, H/2 - 0.5)."""
    return width / 2.0 - 0.5, height / 2.0 - 0.5


def intrinsics(f_px: float, width: int, height: int, fy_px: float | None = None) -> np.ndarray:
    """K for a centred principal point (OpenCV pixel centres); square pixels unless ``fy_px``."""
    fy = f_px if fy_px is None else fy_px
    if not (np.isfinite(f_px) and f_px > 0 and np.isfinite(fy) and fy > 0):
        raise ValueError(f"focal length f_px = {f_px} (fy {fy}) is out of range: allowed > 0")
    cx, cy = centred_principal_point(width, height)
    return np.array([[f_px, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def look_at_rotation(eye, target, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """World-to-camera rotation R of an OpenCV camera at ``eye`` looking at ``target``.

    ``up`` is the world direction that appears upward in the image (toward -v).
    """
    eye = np.asarray(eye, float)
    forward = np.asarray(target, float) - eye
    n = np.linalg.norm(forward)
    if n == 0:
        raise ValueError("look_at: eye and target coincide")
    z = forward / n
    x = np.cross(z, np.asarray(up, float))
    nx = np.linalg.norm(x)
    if nx < tol.unit_norm:
        raise ValueError(f"look_at: up {tuple(up)} is parallel to the viewing direction")
    x /= nx
    y = np.cross(z, x)
    return np.stack([x, y, z])


@dataclass(frozen=True)
class Camera:
    """A pinhole camera: OpenCV intrinsics K, pose (R, t), image size in pixels, and optionally
    the lens's distortion (None, or an identity ``BrownConrady``, is the ideal pinhole)."""

    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    width: int
    height: int
    distortion: BrownConrady | None = None

    def __post_init__(self):
        object.__setattr__(self, "K", _as_matrix(self.K, (3, 3), "K"))
        object.__setattr__(self, "R", _as_matrix(self.R, (3, 3), "R"))
        object.__setattr__(self, "t", _as_matrix(np.ravel(self.t), (3,), "t"))
        for name in ("width", "height"):
            v = getattr(self, name)
            if int(v) != v or not (1 <= v <= 16384):
                raise ValueError(f"camera {name} = {v} is out of range: allowed 1 to 16384 px")
            object.__setattr__(self, name, int(v))
        if not is_rotation(self.R):
            raise ValueError("R must be a proper rotation matrix (orthonormal, det +1)")
        d = self.distortion
        if d is not None and not isinstance(d, BrownConrady):
            raise ValueError(f"distortion must be a BrownConrady model or None, got {type(d).__name__}")
        if d is not None and d.is_identity:
            object.__setattr__(self, "distortion", None)  # one representation of "no distortion"
        elif d is not None:
            self._check_one_to_one()

    def _check_one_to_one(self) -> None:
        """Refuse a distortion that folds over inside the image (no unique ray per pixel)."""
        w, h = self.width, self.height
        edge = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [-0.5, h - 0.5], [w - 0.5, h - 0.5],
                         [(w - 1) / 2, -0.5], [(w - 1) / 2, h - 0.5], [-0.5, (h - 1) / 2], [w - 0.5, (h - 1) / 2]])
        try:
            ideal = self.distortion.undistort(self._normalised_distorted(edge))
        except DistortionError as e:
            raise ValueError(f"distortion {self.distortion.as_opencv().tolist()} does not map the "
                             f"{w}x{h} image one-to-one: {e}") from None
        r_max = float(np.max(np.linalg.norm(ideal, axis=1)))
        if not self.distortion.monotonic_to(r_max * 1.05):
            raise ValueError(f"distortion {self.distortion.as_opencv().tolist()} folds over inside the "
                             f"{w}x{h} image (radial map not increasing to r = {r_max:.3f})")

    # -- construction ---------------------------------------------------------
    @classmethod
    def look_at(cls, eye, target, f_px, width, height, up=(0.0, 1.0, 0.0)) -> "Camera":
        R = look_at_rotation(eye, target, up)
        return cls(intrinsics(f_px, width, height), R, -R @ np.asarray(eye, float), width, height)

    # -- geometry -------------------------------------------------------------
    @property
    def center(self) -> np.ndarray:
        """Optical centre in the world frame (metres)."""
        return -self.R.T @ self.t

    @property
    def f_px(self) -> float:
        return float(self.K[0, 0])

    def to_camera(self, points_world) -> np.ndarray:
        """(N,3) world points -> (N,3) camera-frame points (metres)."""
        p = np.atleast_2d(np.asarray(points_world, float))
        return p @ self.R.T + self.t

    def project(self, points_world) -> np.ndarray:
        """(N,3) world points -> (N,2) pixel coordinates (u, v), through the distortion if any;
        NaN behind the camera."""
        pc = self.to_camera(points_world)
        z = pc[:, 2:3]
        with np.errstate(divide="ignore", invalid="ignore"):
            if self.distortion is None:
                uvw = pc @ self.K.T
                uv = uvw[:, :2] / z
            else:
                uv = self.pixels(self.distortion.distort(pc[:, :2] / z))
        uv[(z[:, 0] <= 0)] = np.nan
        return uv

    def pixels(self, normalised) -> np.ndarray:
        """(N,2) normalised image coordinates (X/Z, Y/Z, distorted where the lens is) -> (N,2)
        pixel coordinates (u, v) through K: the inverse of ``_normalised_distorted``."""
        xy = np.atleast_2d(np.asarray(normalised, float))
        return xy @ self.K[:2, :2].T + self.K[:2, 2]

    def _normalised_distorted(self, pixels) -> np.ndarray:
        """(N,2) pixels -> (N,2) normalised coordinates K^-1 (u, v, 1) (distorted if the lens is)."""
        px = np.atleast_2d(np.asarray(pixels, float))
        K = self.K
        y = (px[:, 1] - K[1, 2]) / K[1, 1]
        x = (px[:, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
        return np.column_stack([x, y])

    def normalised(self, pixels) -> np.ndarray:
        """(N,2) pixels -> (N,2) ideal normalised coordinates (X/Z, Y/Z) of the rays through them:
        K^-1, then the exact inverse of the distortion."""
        xy = self._normalised_distorted(pixels)
        return xy if self.distortion is None else self.distortion.undistort(xy)

    def depth(self, points_world) -> np.ndarray:
        """z-depth (metres) of world points along the optical axis."""
        return self.to_camera(points_world)[:, 2]

    def rays(self, pixels) -> tuple[np.ndarray, np.ndarray]:
        """Unit world-frame ray directions through (N,2) pixels (through the distortion if any);
        origin is ``center``."""
        xy = self.normalised(pixels)
        d = np.outer(xy[:, 0], self.R[0]) + np.outer(xy[:, 1], self.R[1]) + self.R[2]
        d /= np.sqrt(np.einsum("ij,ij->i", d, d))[:, None]
        return self.center, d

    def at_depth(self, pixels, depth) -> np.ndarray:
        """(N,3) world points seen at (N,2) ``pixels`` at z-depth ``depth`` ((N,) or scalar, metres
        along the optical axis, as ``depth`` measures it): the inverse of ``project`` with ``depth``."""
        c, d = self.rays(pixels)
        return c + d * (np.asarray(depth, float) / (d @ self.R[2]))[..., None]

    def in_image(self, uv, margin: float = 0.0) -> np.ndarray:
        """True where pixel coordinates lie inside the image (pixel edges at -0.5, W-0.5)."""
        uv = np.atleast_2d(uv)
        with np.errstate(invalid="ignore"):
            return ((uv[:, 0] >= -0.5 + margin) & (uv[:, 0] <= self.width - 0.5 - margin)
                    & (uv[:, 1] >= -0.5 + margin) & (uv[:, 1] <= self.height - 0.5 - margin))

    @property
    def horizontal_fov_rad(self) -> float:
        return 2.0 * float(np.arctan(self.width / 2.0 / self.K[0, 0]))

    @property
    def pinhole(self) -> "Camera":
        """The same camera without its distortion (K, pose and size kept)."""
        return Camera(self.K, self.R, self.t, self.width, self.height)


def triangulate_rectified(u_left, v_left, u_right, left: Camera, baseline_m: float) -> np.ndarray:
    """Triangulate matches of a conventional (parallel) stereo pair into world points.

    Disparity d = u_left - u_right; Z = f B / d; X, Y from the left camera. Returns
    (N,3) world points in metres (NaN where d <= 0).
    """
    u_left, v_left, u_right = (np.asarray(a, float) for a in (u_left, v_left, u_right))
    d = u_left - u_right
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(d > 0, left.K[0, 0] * baseline_m / d, np.nan)
    x = (u_left - left.K[0, 2]) * z / left.K[0, 0]
    y = (v_left - left.K[1, 2]) * z / left.K[1, 1]
    pc = np.column_stack([x, y, z])
    return (pc - left.t) @ left.R
