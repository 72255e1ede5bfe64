"""Sensor poses of the exploring strategy (paper IV-B, V-B), and which poses can be reached.

A pose is the stereo sensor's centre line (mid-baseline point and the point it looks at) and its
baseline direction; the projector of stage 3 sits on its own centre line. Stage 1 covers the
workspace from far; stage 2 looks along the boundary plane's normal through the boundary centre
with the baseline across the most-bent direction; ``rotated_pose`` turns a pose about an axis
through its target (the verification views and the multi-view cures). ``Reach`` says what the
simulated robot can do: it stays above the plate and looks down at most ``max_tilt_rad`` from
vertical. World frame, +Z up, metres, radians. Nothing here renders or reads ground truth.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from platebench.errors import UserValueError
from platebench.reconstruction.paper.boundary_plane import BoundaryPlane, plane_frame
from platebench.scenes.camera import Camera
from platebench.tolerances import tol


class PoseError(UserValueError):
    """A sensing pose that cannot work (refused before rendering)."""


@dataclass(frozen=True)
class SensorPose:
    """Centre line of the stereo sensor (and projector): mid-baseline point looking at ``target``."""

    center: np.ndarray  # (3,) mid-baseline point, world
    target: np.ndarray  # (3,) point on the centre line the sensor looks at
    baseline_dir: np.ndarray  # (3,) unit, perpendicular to the centre line
    reason: str = ""

    @property
    def view_dir(self) -> np.ndarray:
        d = self.target - self.center
        return d / np.linalg.norm(d)

    @property
    def distance_m(self) -> float:
        return float(np.linalg.norm(self.target - self.center))

    def at_distance(self, distance_m: float, reason: str | None = None) -> "SensorPose":
        """The same line of sight with the sensor ``distance_m`` (m) from its target (and ``reason``, if
        given)."""
        return replace(self, center=self.target - self.view_dir * distance_m,
                       reason=self.reason if reason is None else reason)

    def camera_centers(self, baseline_m: float) -> np.ndarray:
        """(2,3) the two cameras' centres: the ends of the baseline, ``baseline_m`` apart along
        ``baseline_dir`` about the mid-baseline point (which end is the left one is the rig's
        business, ``scenes.scene_spec.scene_for_pose``)."""
        half = self.baseline_dir * baseline_m / 2
        return np.array([self.center - half, self.center + half])


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def unit(v) -> np.ndarray:
    """``v`` scaled to length 1."""
    return _unit(v)


def perpendicular(baseline, view) -> np.ndarray:
    """Unit part of ``baseline`` perpendicular to ``view`` (any perpendicular if they are parallel)."""
    return _perp(baseline, view)


def _perp(baseline, view) -> np.ndarray:
    b = np.asarray(baseline, float) - view * (np.asarray(baseline, float) @ view)
    if np.linalg.norm(b) < tol.unit_norm:  # baseline along the view: pick any perpendicular
        b = np.cross(view, [1.0, 0.0, 0.0]) if abs(view[0]) < 0.9 else np.cross(view, [0.0, 1.0, 0.0])
    return _unit(b)


def cover_distance(points: np.ndarray, view_dir, baseline_dir, target, half_fov_x: float, half_fov_y: float,
                   margin: float = 1.15, baseline_m: float = 0.0) -> float:
    """Distance from ``target`` along -view_dir at which every point fits both cameras' views."""
    view, bx = _unit(view_dir), _unit(baseline_dir)
    by = np.cross(view, bx)
    rel = np.asarray(points, float) - np.asarray(target, float)
    depth = rel @ view  # positive beyond the target
    x = np.abs(rel @ bx) + baseline_m / 2.0  # the farther camera sees the point further off-axis
    y = np.abs(rel @ by)
    # A point at lateral offset x and depth (D + depth) fits if x <= tan(half_fov) (D + depth).
    need = np.maximum(margin * x / np.tan(half_fov_x) - depth, margin * y / np.tan(half_fov_y) - depth)
    return float(need.max())


def half_fovs(camera: Camera) -> tuple[float, float]:
    """Half fields of view (rad) along image x and y."""
    K = camera.K
    return (float(np.arctan((camera.width / 2.0) / K[0, 0])), float(np.arctan((camera.height / 2.0) / K[1, 1])))


def stage1_pose(workspace_center, workspace_radius_m: float, camera: Camera, baseline_m: float) -> SensorPose:
    """Far pose looking straight down whose field of view covers the workspace disc."""
    c = np.asarray(workspace_center, float)
    hx, hy = half_fovs(camera)
    d = (workspace_radius_m + baseline_m / 2.0) / np.tan(min(hx, hy))
    return SensorPose(c + np.array([0.0, 0.0, d]), c, np.array([0.0, 1.0, 0.0]),
                      f"stage 1: far pose covering a {workspace_radius_m * 1e3:.0f} mm workspace radius")


def most_bent_direction(boundary: np.ndarray, plane: BoundaryPlane, extra_points: np.ndarray | None = None) -> np.ndarray:
    """In-plane unit direction of largest curvature of the boundary's height field (world).

    Fits h = c0 + c1 x + c2 y + a x^2 + b x y + c y^2 in the boundary-plane frame; the
    eigenvector of the Hessian with the largest |eigenvalue|. Measured surface points
    (``extra_points``, e.g. the squares) are used alone when there are at least 6 of them:
    the passive boundary cannot show a bend along the image rows (those edges get their depth
    by interpolation between corners). Flat plates fall back to the major axis of the boundary.
    """
    R, origin = plane_frame(plane)
    pts = boundary if extra_points is None or len(extra_points) < 6 else np.asarray(extra_points)
    loc = (pts - origin) @ R.T
    x, y, h = loc[:, 0], loc[:, 1], loc[:, 2]
    A = np.column_stack([np.ones_like(x), x, y, x * x, x * y, y * y])
    coef, *_ = np.linalg.lstsq(A, h, rcond=None)
    H = np.array([[2 * coef[3], coef[4]], [coef[4], 2 * coef[5]]])
    w, v = np.linalg.eigh(H)
    extent = np.ptp(loc[:, :2], axis=0).max()
    if np.abs(w).max() * extent ** 2 < tol.flat_height_m:  # flat over the plate: no bend
        outline = (boundary - origin) @ R.T
        _, _, vt = np.linalg.svd(outline[:, :2] - outline[:, :2].mean(axis=0))
        d2 = vt[0]
    else:
        d2 = v[:, int(np.argmax(np.abs(w)))]
    return _unit(d2[0] * R[0] + d2[1] * R[1])


def stage2_pose(boundary: np.ndarray, plane: BoundaryPlane, camera: Camera, baseline_m: float,
                working_distance_m: float, extra_points: np.ndarray | None = None) -> SensorPose:
    """Centre line through the boundary centre, perpendicular to the boundary plane; baseline
    perpendicular to the most-bent direction; distance covering the plate (>= working distance)."""
    R, _ = plane_frame(plane)
    n = _unit(plane.normal)
    centre = plane.point
    bent = most_bent_direction(boundary, plane, extra_points)
    baseline = _perp(np.cross(n, bent), n)  # in the plane, perpendicular to the bend
    hx, hy = half_fovs(camera)
    d = max(cover_distance(boundary, -n, baseline, centre, hx, hy, baseline_m=baseline_m), working_distance_m)
    return SensorPose(centre + n * d, centre.copy(), baseline,
                      f"stage 2: centre line through the boundary centre along the plane normal; baseline "
                      f"perpendicular to the most-bent direction {np.round(bent, 3).tolist()}; distance "
                      f"{d * 1e3:.0f} mm covers the plate")


def ensure_in_view(pose: SensorPose, boundary: np.ndarray, camera: Camera, baseline_m: float,
                   margin: float = 1.1) -> SensorPose:
    """``pose`` moved back along its centre line, if needed, until the boundary fits the view."""
    hx, hy = half_fovs(camera)
    need = cover_distance(boundary, pose.view_dir, pose.baseline_dir, pose.target, hx, hy, margin=margin,
                          baseline_m=baseline_m)
    if pose.distance_m >= need:
        return pose
    return SensorPose(pose.target - pose.view_dir * need, pose.target.copy(), pose.baseline_dir,
                      pose.reason + f"; moved back to {need * 1e3:.0f} mm to keep the plate in view")


def validate_pose(pose: SensorPose, boundary: np.ndarray, plane: BoundaryPlane, camera: Camera,
                  baseline_m: float) -> None:
    """Refuse poses that cannot work: plate outside the view, cameras inside the plate's extent,
    projector behind the plate. Raises PoseError with the reason."""
    n = plane.normal
    dist = plane.signed_distance(pose.center[None])[0]
    if dist <= 0:
        raise PoseError(f"projector and cameras at {np.round(pose.center, 3).tolist()} are behind the plate "
                        f"(signed distance {dist * 1e3:.0f} mm from the boundary plane)")
    heights = plane.signed_distance(boundary)
    if dist <= heights.max() + 0.01:
        raise PoseError(f"sensor at {dist * 1e3:.0f} mm from the boundary plane is inside the plate's extent "
                        f"(plate reaches {heights.max() * 1e3:.0f} mm; keep 10 mm clear)")
    hx, hy = half_fovs(camera)
    need = cover_distance(boundary, pose.view_dir, pose.baseline_dir, pose.target, hx, hy, margin=1.0,
                          baseline_m=baseline_m)
    if pose.distance_m < need:
        raise PoseError(f"plate outside the field of view at distance {pose.distance_m * 1e3:.0f} mm "
                        f"(needs at least {need * 1e3:.0f} mm)")
    if abs(pose.view_dir @ n) < 0.2:
        raise PoseError("centre line nearly parallel to the boundary plane: the plate would be seen edge-on")




@dataclass(frozen=True)
class Reach:
    """What the simulated robot can reach: a view at most ``max_tilt_rad`` from straight down, with
    both cameras at least ``clearance_m`` above the highest measured point of the plate's lower
    half-space near them (the table is below the plate)."""

    max_tilt_rad: float = float(np.radians(75.0))
    clearance_m: float = 0.02

    @staticmethod
    def tilt_rad(pose: SensorPose) -> float:
        """The angle (rad) of ``pose``'s view from straight down."""
        return float(np.arccos(np.clip(-pose.view_dir[2], -1.0, 1.0)))

    def tilts_past(self, pose: SensorPose) -> bool:
        """Whether ``pose``'s view tilts past ``max_tilt_rad`` from straight down."""
        return self.tilt_rad(pose) > self.max_tilt_rad + tol.angle_rad

    def why_not(self, pose: SensorPose, measured: np.ndarray, baseline_m: float) -> str | None:
        """None if ``pose`` is reachable above the ``measured`` points (N,3), else the reason."""
        if self.tilts_past(pose):
            return (f"view {np.degrees(self.tilt_rad(pose)):.0f} deg from vertical (the robot reaches "
                    f"{np.degrees(self.max_tilt_rad):.0f} deg)")
        low = float(np.min(np.asarray(measured)[:, 2])) if len(measured) else pose.target[2]
        for c in pose.camera_centers(baseline_m):
            if c[2] < low + self.clearance_m:
                return f"a camera at z = {c[2] * 1e3:.0f} mm is below the plate's lowest measured point + clearance"
        return None


def rotation_matrix(axis, angle_rad: float) -> np.ndarray:
    """Rotation by ``angle_rad`` about the unit ``axis`` (right hand), (3,3)."""
    a = _unit(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle_rad) * K + (1 - np.cos(angle_rad)) * K @ K


def rotated_pose(pose: SensorPose, axis, angle_rad: float, baseline_dir=None, reason: str = "") -> SensorPose:
    """``pose`` turned by ``angle_rad`` about ``axis`` through its target (distance kept); the new
    baseline is ``baseline_dir`` made perpendicular to the view, or the old one turned along."""
    Rm = rotation_matrix(axis, angle_rad)
    center = pose.target + Rm @ (pose.center - pose.target)
    view = _unit(pose.target - center)
    b = Rm @ pose.baseline_dir if baseline_dir is None else np.asarray(baseline_dir, float)
    return SensorPose(center, pose.target.copy(), _perp(b, view), reason)


def diagonal_baseline(view_dir, a, b) -> np.ndarray:
    """Unit baseline at 45 degrees between directions ``a`` and ``b`` (made perpendicular to the
    view): edges along ``a`` and along ``b`` both cross the image rows at about 45 degrees, so
    both are matched along rows rather than interpolated."""
    v = _unit(view_dir)
    a2, b2 = _perp(a, v), _perp(b, v)
    if a2 @ b2 < 0:
        b2 = -b2
    return _perp(a2 + b2, v) if np.linalg.norm(a2 + b2) > tol.unit_norm else a2
