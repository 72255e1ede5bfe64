"""The one conversion between OpenCV poses/intrinsics and Mitsuba's sensor/emitter frames.

Mitsuba's ``look_at`` frame has local axes (left, up, forward) and its image u grows
toward local -x, v toward local -y, with pixel centres at i + 0.5. The OpenCV camera
frame (x right, y down, z forward) is therefore Mitsuba's local frame turned 180
degrees about z: ``to_world = [-r_x, -r_y, r_z | C]`` where r_x, r_y, r_z are the
rows of R (camera axes in world) and C the centre. Mitsuba's projector emitter uses
the same mapping as the perspective camera. The textured ``spot`` emitter maps
u toward local +x and v toward local +y (rotated 180 degrees relative to the camera),
so its to_world takes the OpenCV axes unflipped.

A camera Mitsuba's ``perspective`` cannot model (lens distortion, non-square pixels, an
off-centre principal point or skew) is rendered by the bench's own sensor plugin
(``scenes.render.lens_sensor``), which works in OpenCV's frames directly: a film sample at
fractional film position (x, y) in [0, 1]^2 (pixel i covers [i, i + 1) / W) is the OpenCV
pixel ``u = x W - 0.5, v = y H - 0.5`` (pixel centres at integers); its ray leaves the
camera centre C along ``R^T (x_n, y_n, 1)``, ``(x_n, y_n)`` the ideal normalised coordinates
of that pixel (K^-1, then the lens's inverse distortion). ``lens_sensor_params`` is that
conversion.
"""
from __future__ import annotations

import numpy as np

from platebench.scenes.camera import Camera, centred_principal_point
from platebench.tolerances import tol


def _check_centred_square(cam: Camera, what: str, square: bool = True) -> None:
    K = cam.K
    cx, cy = centred_principal_point(cam.width, cam.height)
    if abs(K[0, 2] - cx) > tol.pixel or abs(K[1, 2] - cy) > tol.pixel or K[0, 1] != 0:
        raise ValueError(f"{what}: Mitsuba needs a centred principal point (cx={cx}, cy={cy}) and no skew, "
                         f"got cx={K[0, 2]}, cy={K[1, 2]}")
    if square and abs(K[0, 0] - K[1, 1]) > tol.pixel * K[0, 0]:
        raise ValueError(f"{what}: Mitsuba's perspective model needs square pixels, got fx={K[0, 0]}, fy={K[1, 1]}")


def perspective_to_world(cam: Camera) -> np.ndarray:
    """4x4 to_world of a Mitsuba ``perspective`` sensor / ``projector`` emitter for an OpenCV pose."""
    M = np.eye(4)
    M[:3, 0] = -cam.R[0]
    M[:3, 1] = -cam.R[1]
    M[:3, 2] = cam.R[2]
    M[:3, 3] = cam.center
    return M


def spot_to_world(cam: Camera) -> np.ndarray:
    """4x4 to_world of a textured Mitsuba ``spot`` emitter for an OpenCV pose."""
    M = np.eye(4)
    M[:3, :3] = cam.R.T
    M[:3, 3] = cam.center
    return M


def perspective_fov_deg(cam: Camera, what: str = "camera") -> float:
    """Horizontal field of view (degrees, Mitsuba ``fov_axis='x'``) of an OpenCV K."""
    _check_centred_square(cam, what)
    return float(np.degrees(2.0 * np.arctan(cam.width / 2.0 / cam.K[0, 0])))


def spot_cutoff_deg(cam: Camera, cutoff_rad: float) -> float:
    """Cutoff (degrees) of a textured spot whose texture spans +-cutoff; checks K agrees."""
    _check_centred_square(cam, "spot projector", square=False)
    tc = np.tan(cutoff_rad)
    if abs(cam.K[0, 0] - cam.width / (2 * tc)) > tol.pixel * cam.K[0, 0] or abs(cam.K[1, 1] - cam.height / (2 * tc)) > tol.pixel * cam.K[1, 1]:
        raise ValueError("spot projector K does not match its cutoff angle")
    return float(np.degrees(cutoff_rad))


def needs_lens_sensor(cam: Camera) -> bool:
    """True when Mitsuba's ``perspective`` sensor cannot render ``cam`` exactly: a distorted
    lens, non-square pixels, an off-centre principal point or skew."""
    K = cam.K
    cx, cy = centred_principal_point(cam.width, cam.height)
    return (cam.distortion is not None or abs(K[0, 0] - K[1, 1]) > tol.pixel * K[0, 0] or K[0, 1] != 0
            or abs(K[0, 2] - cx) > tol.pixel or abs(K[1, 2] - cy) > tol.pixel)


def lens_sensor_params(cam: Camera) -> dict:
    """What the bench's sensor plugin needs, in OpenCV frames (module doc): ``R_cw`` (3x3,
    camera-to-world rotation R^T), ``center`` (3,) metres, ``fx, fy, cx, cy, skew`` pixels,
    ``distortion`` OpenCV (k1, k2, p1, p2, k3)."""
    K = cam.K
    dist = np.zeros(5) if cam.distortion is None else cam.distortion.as_opencv()
    return {"R_cw": cam.R.T.copy(), "center": cam.center, "fx": float(K[0, 0]), "fy": float(K[1, 1]),
            "cx": float(K[0, 2]), "cy": float(K[1, 2]), "skew": float(K[0, 1]), "distortion": dist}
