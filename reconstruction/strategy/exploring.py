"""The paper's exploring strategy (sections II, IV-B, V-B): where to put the sensor, as pure decisions.

A pose is the stereo sensor's centre line (mid-baseline point and viewing direction),
its baseline direction and its distance to the target; the projector sits on the
centre line between the cameras, its centre ray along it (stage 3).

* Stage 1: a far pose whose field of view covers the whole workspace; the baseline
  is arbitrary.
* Stage 2: centre line through the geometric centre of the (rough) boundary,
  perpendicular to the boundary plane; baseline perpendicular to the most-bent
  direction; distance long enough for the field of view to cover the plate (and no
  shorter than the working distance at which the cameras are focused).
* Stage 3: the projector's centre ray through the boundary centre, perpendicular to
  the boundary plane (the stage-2 centre line).
* Cure 1: orient the centre line to bisect, and be perpendicular to, the chord AB of
  the most bending curve.
* Cure 2: move the cameras back: beyond the point C where the end tangents at A and B
  meet, ``L = AB tan a tan b / (tan a + tan b)`` from AB (a, b: angles between AB and
  the end tangents); and the empirical rule: the more squares are missing, the further.

World frame, metres, radians. Nothing here renders or reads ground truth.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.errors import UserValueError
from platebench.reconstruction.paper.boundary_plane import BoundaryPlane, plane_frame
from platebench.scenes.camera import Camera


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

    def to_dict(self) -> dict:
        return {"center_m": self.center.tolist(), "target_m": self.target.tolist(),
                "view_dir": self.view_dir.tolist(), "baseline_dir": self.baseline_dir.tolist(),
                "distance_m": self.distance_m, "reason": self.reason}


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _perp(baseline, view) -> np.ndarray:
    b = np.asarray(baseline, float) - view * (np.asarray(baseline, float) @ view)
    if np.linalg.norm(b) < 1e-9:  # baseline along the view: pick any perpendicular
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
    if np.abs(w).max() * extent ** 2 < 1e-5:  # flat within ~10 um over the plate: no bend
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


@dataclass(frozen=True)
class BendingCurve:
    """The most bending curve's end points A, B and the angles a, b between AB and the end tangents."""

    A: np.ndarray
    B: np.ndarray
    tangent_A: np.ndarray  # unit, pointing from A into the plate
    tangent_B: np.ndarray
    a_rad: float
    b_rad: float
    normal: np.ndarray  # unit normal of the bending plane's "up" side (toward the sensor)

    @property
    def chord_m(self) -> float:
        return float(np.linalg.norm(self.B - self.A))

    def to_dict(self) -> dict:
        return {"A_m": self.A.tolist(), "B_m": self.B.tolist(), "chord_m": self.chord_m,
                "a_deg": float(np.degrees(self.a_rad)), "b_deg": float(np.degrees(self.b_rad))}


def bending_curve(profile: np.ndarray, up: np.ndarray, end_fraction: float = 0.12) -> BendingCurve:
    """End points and end-tangent angles of a bending curve given as an ordered (N,3) polyline.

    Tangents: derivative at the end of a quadratic fit (coordinates vs arc length) to the
    first/last ``end_fraction`` of the curve's arc.
    The angle at A is between AB and the tangent at A pointing into the plate, signed positive
    when it rises from the chord toward the sensor (``up``): positive for a convex bend whose ends
    fall away from the sensor, negative for a concave one.
    """
    P = np.asarray(profile, float)
    A, B = P[0], P[-1]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    k = max(3, int(np.searchsorted(s, end_fraction * s[-1])))

    def tangent(pts):
        # Quadratic fit of each coordinate against arc length; its derivative at the end point.
        sl = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
        t = np.array([np.polyfit(sl, pts[:, k], 2)[1] for k in range(3)])
        return _unit(t)

    tA = tangent(P[:k])  # from A into the plate
    tB = tangent(P[::-1][:k])  # from B into the plate
    ab = _unit(B - A)
    up = _unit(up - ab * (up @ ab))

    def angle(t, chord):  # signed angle of tangent t above the chord direction (toward up)
        return float(np.arctan2(t @ up, t @ chord))

    return BendingCurve(A, B, tA, tB, angle(tA, ab), angle(tB, -ab), up)


def tangent_intersection_distance(curve: BendingCurve) -> float:
    """Paper's L = AB tan a tan b / (tan a + tan b): distance from chord AB to the point C where the
    end tangent lines meet. Positive: C lies on the sensor's side and the cameras must be beyond it
    (a convex bend, whose ends fall away from the sensor). Negative or zero: C lies behind AB and
    distance is no constraint (a concave bend under 180 degrees). Infinite: an end tangent turns past
    90 degrees (the plate curls over itself), which no distance along this centre line cures.
    """
    a, b = curve.a_rad, curve.b_rad
    if abs(a) >= np.pi / 2 or abs(b) >= np.pi / 2:
        return float("inf")
    ta, tb = np.tan(a), np.tan(b)
    if abs(ta + tb) < 1e-12:
        return float("inf") if ta * tb > 0 else 0.0
    return float(curve.chord_m * ta * tb / (ta + tb))


def cure_orient(curve: BendingCurve, current: SensorPose) -> SensorPose:
    """Cure 1: centre line perpendicular to AB through its midpoint, in the bending plane, on the
    sensor's side; the baseline perpendicular to the bending plane (both cameras then share the
    cross-section, as stage 2 asks); distance kept."""
    mid = 0.5 * (curve.A + curve.B)
    ab = _unit(curve.B - curve.A)
    up = _unit(curve.normal - ab * (curve.normal @ ab))
    d = current.distance_m
    view = -up
    return SensorPose(mid + up * d, mid, _perp(np.cross(ab, up), view),
                      "cure 1: centre line bisects and is perpendicular to the chord AB of the most bending "
                      "curve; baseline perpendicular to its plane")


def cure_move_back(curve: BendingCurve, current: SensorPose, missing: int, expected: int,
                   safety: float = 1.1, step: float = 0.5) -> SensorPose:
    """Cure 2: move back along the centre line beyond C (distance from AB > L, times ``safety``);
    at least by the empirical rule: distance x (1 + step x missing/expected)."""
    L = tangent_intersection_distance(curve)
    mid = 0.5 * (curve.A + curve.B)
    view = current.view_dir
    height_above_ab = float((current.center - mid) @ -view)
    empirical = current.distance_m * (1.0 + step * max(missing, 1) / max(expected, 1))
    want = current.distance_m
    reason = []
    if np.isfinite(L) and L > 0 and height_above_ab < safety * L:
        want = current.distance_m + (safety * L - height_above_ab)
        reason.append(f"beyond C: L = {L * 1e3:.0f} mm from AB")
    if want < empirical:
        want = empirical
        reason.append(f"empirical rule: {missing} of {expected} squares missing")
    return SensorPose(current.target - view * want, current.target.copy(), current.baseline_dir,
                      "cure 2: move back (" + "; ".join(reason) + f"), distance {want * 1e3:.0f} mm")


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


def boundary_edges(boundary: np.ndarray, source: np.ndarray) -> list[np.ndarray]:
    """Split a matched boundary polygon at its four corners into four ordered edges (corner to corner)."""
    idx = np.nonzero(np.asarray(source) == "corner")[0]
    if len(idx) != 4:
        raise ValueError(f"boundary has {len(idx)} corners, expected 4")
    n = len(boundary)
    edges = []
    for k in range(4):
        i, j = idx[k], idx[(k + 1) % 4]
        sel = np.arange(i, j + 1) if j > i else np.concatenate([np.arange(i, n), np.arange(0, j + 1)])
        edges.append(boundary[sel])
    return edges


def most_bending_curves(boundary: np.ndarray, source: np.ndarray, plane: BoundaryPlane,
                        bent_dir: np.ndarray) -> list[BendingCurve]:
    """The two boundary edges running along the most-bent direction, as bending curves (A -> B)."""
    edges = boundary_edges(boundary, source)
    align = [abs(_unit(e[-1] - e[0]) @ bent_dir) for e in edges]
    order = np.argsort(align)[::-1][:2]
    curves = []
    for k in order:
        e = edges[k]
        if (e[-1] - e[0]) @ bent_dir < 0:
            e = e[::-1]
        curves.append(bending_curve(e, plane.normal))
    return curves
