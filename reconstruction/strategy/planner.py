"""Where to look next: the verification views every plate gets, and the cure chosen from measured
geometry when the boundary is not verified (``decide``, a pure function).

Verification views (not cures: every plate gets them). The stage-2 pose turned about the boundary
centre by +-30 and +-60 degrees about the ruling direction ``g`` (the boundary plane's direction
across the most-bent direction ``e``: a bend's occluding contours run along ``g`` and slide under
these turns), by +-30 and +-60 degrees about ``e`` (for edges running along ``e``; a bend
about an oblique axis needs the 60-degree turns to confirm them) and by +-45 degrees about the
diagonals ``g+e`` and ``g-e`` (they turn about both at once, and confirm the corners and the
oblique edges the others leave as loose ends: without them, 6 of 31 study plates with nothing
hidden got a cure, a false alarm; with them, none). Their baselines lie
at 45 degrees between ``g`` and ``e``, so that edges along either cross the image rows and are
matched on the rows, not interpolated.

Cures. Candidates are the paper's cure 1 and cure 2 (from the stage-3 reconstruction's most bending
curve, when it has one) and further turns of the stage-2 pose (about ``g``, ``e`` and the two
diagonals, up to the reach), each checked against the reconstructed surface model: for every gap
of the verdict, is the stretch just beyond it (3 and 8 mm along the gap's direction) seen by both
cameras of the candidate from the outer side of the surface measured there (at least
``FRONT_MARGIN_RAD``), not blocked by the measured plate (ray casting), and from a direction turned
far enough from the pose that saw the gap's end to confirm or refute it? The candidate that sees
past most gaps wins (the paper's cures first on a tie); its baseline is set across the gaps'
direction. No candidate seeing past any gap: stop, naming the gaps.

World frame, metres, radians. Nothing here renders or reads ground truth.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from platebench.reconstruction.strategy.bending import measured_bending_curves, tangent_intersection_distance
from platebench.reconstruction.strategy.cures import cure_move_back, cure_orient
from platebench.reconstruction.strategy.multiview import CONFIRM_ANGLE_RAD, BoundaryVerdict, Gap, ViewOutline
from platebench.reconstruction.strategy.poses import (
    Reach,
    SensorPose,
    diagonal_baseline,
    ensure_in_view,
    most_bent_direction,
    perpendicular,
    rotated_pose,
    unit,
)
from platebench.reconstruction.strategy.surface_model import SurfaceModel
from platebench.scenes.camera import Camera

VERIFY_TURNS_DEG = (("g", -30.0), ("g", 30.0), ("g", -60.0), ("g", 60.0), ("e", -30.0), ("e", 30.0), ("e", -60.0),
                    ("e", 60.0), ("g+e", -45.0), ("g+e", 45.0), ("g-e", -45.0), ("g-e", 45.0))
CANDIDATE_TURNS_DEG = tuple([("g", a) for a in (-15, 15, -45, 45, -75, 75)] +
                            [("e", a) for a in (-45, 45, -60, 60, -75, 75)] +
                            [(d, a) for a in (-45, 45, -60, 60, -75, 75) for d in ("g+e", "g-e")])
FRONT_MARGIN_RAD = float(np.radians(15.0))
LOOK_AHEAD_M = (3e-3, 8e-3)
SAME_VIEW_RAD = float(np.radians(8.0))  # a candidate this close in direction to a done pose adds nothing
MAX_CURE_VIEWS = 5  # cure poses the view budget leaves room for
MAX_VIEWS = 1 + len(VERIFY_TURNS_DEG) + MAX_CURE_VIEWS  # measuring poses at most: stage 2, verification, cures


@dataclass(frozen=True)
class PlannedView:
    """A pose to measure from, and why: ``purpose`` "verification" or "cure"; ``method``
    "verification", "cure 1", "cure 2" (the paper's) or "multi-view"."""

    name: str
    pose: SensorPose
    purpose: str
    method: str
    reason: str

    def to_dict(self) -> dict:
        return {"name": self.name, "purpose": self.purpose, "method": self.method, "reason": self.reason,
                "pose": self.pose.to_dict()}


@dataclass(frozen=True)
class Decision:
    """What the loop does next: ``kind`` "done" (verified), "view" (measure ``view``) or "stop"."""

    kind: str
    view: PlannedView | None
    reason: str
    gaps_targeted: int = 0
    gaps_predicted_seen: int = 0

    def to_dict(self) -> dict:
        return {"decision": self.kind, "reason": self.reason, "gaps_targeted": self.gaps_targeted,
                "gaps_predicted_seen": self.gaps_predicted_seen,
                **({"view": self.view.to_dict()} if self.view is not None else {})}


def sensing_axes(bent_dir, plane_normal) -> tuple[np.ndarray, np.ndarray]:
    """(g, e): the ruling direction (across the bend, in the boundary plane) and the most-bent one."""
    n = unit(plane_normal)
    e = perpendicular(bent_dir, n)
    return unit(np.cross(n, e)), e


def _axis(name: str, g: np.ndarray, e: np.ndarray) -> np.ndarray:
    return {"g": g, "e": e, "g+e": unit(g + e), "g-e": unit(g - e)}[name]


def turned_views(first: SensorPose, g, e, turns, purpose: str, reach: Reach, measured: np.ndarray,
                 camera: Camera, baseline_m: float) -> tuple[list[PlannedView], list[str]]:
    """The stage-2 pose turned as listed ((axis name, degrees)), kept in view, with a diagonal
    baseline; unreachable ones are left out and named in the second list."""
    views, skipped = [], []
    for ax, deg in turns:
        name = f"turn {ax} {deg:+.0f}"
        p = rotated_pose(first, _axis(ax, g, e), np.radians(deg))
        p = replace(p, baseline_dir=diagonal_baseline(p.view_dir, g, e),
                    reason=f"stage-2 pose turned {deg:+.0f} deg about {ax} through the boundary centre")
        p = ensure_in_view(p, measured, camera, baseline_m)
        why = reach.why_not(p, measured, baseline_m)
        if why:
            skipped.append(f"{name}: {why}")
            continue
        views.append(PlannedView(name, p, purpose, "verification" if purpose == "verification" else "multi-view",
                                 p.reason))
    return views, skipped


def verification_views(first: SensorPose, g, e, reach: Reach, measured: np.ndarray, camera: Camera,
                       baseline_m: float) -> tuple[list[PlannedView], list[str]]:
    """The views every plate gets (module doc)."""
    return turned_views(first, g, e, VERIFY_TURNS_DEG, "verification", reach, measured, camera, baseline_m)


def _close(a: SensorPose, b: SensorPose) -> bool:
    return float(np.arccos(np.clip(a.view_dir @ b.view_dir, -1, 1))) < SAME_VIEW_RAD and \
        abs(a.distance_m - b.distance_m) < 0.05 * max(a.distance_m, b.distance_m)


def _sees_past(view: PlannedView, gap, seen_from: np.ndarray, normal: np.ndarray, model: SurfaceModel,
               baseline_m: float) -> bool:
    pose = view.pose
    a = gap.position_m
    cams = np.array([pose.center - pose.baseline_dir * baseline_m / 2, pose.center + pose.baseline_dir * baseline_m / 2])
    ra, rb = a - seen_from, a - pose.center
    if np.arccos(np.clip(ra @ rb / (np.linalg.norm(ra) * np.linalg.norm(rb)), -1, 1)) < CONFIRM_ANGLE_RAD:
        return False
    targets = np.array([a + gap.direction * d for d in LOOK_AHEAD_M])
    for c in cams:
        to_c = c - targets
        front = to_c @ normal / np.linalg.norm(to_c, axis=1)
        if np.any(front < np.sin(FRONT_MARGIN_RAD)):
            return False
        if model.blocked(np.repeat(c[None], len(targets), 0), targets).any():
            return False
    return True


def decide(verdict: BoundaryVerdict, done: list[ViewOutline], done_poses: list[SensorPose],
           candidates: list[PlannedView], model: SurfaceModel, baseline_m: float,
           max_views: int = MAX_VIEWS) -> Decision:
    """The next step of the loop (module doc). ``done``/``done_poses``: the poses measured so far."""
    if verdict.verified:
        return Decision("done", None, "boundary verified: " + verdict.reason)
    gaps = list(verdict.gaps)
    if not gaps:  # separate groups with no loose end: look past the ends of the unconfirmed outline runs
        for u in verdict.unconfirmed:
            if not u.covered:
                d = u.end_m - u.start_m
                n = float(np.linalg.norm(d))
                if n > 0:
                    gaps += [Gap(u.start_m, d / n, u.view), Gap(u.end_m, -d / n, u.view)]
    if not gaps:
        return Decision("stop", None, f"not verified ({verdict.reason}) but no piece end to look past")
    if len(done) >= max_views:
        return Decision("stop", None, f"view budget spent ({len(done)} poses); {len(gaps)} gap(s) remain: "
                        + "; ".join(g.to_dict()["what"] for g in gaps[:3]), len(gaps))
    centers = {v.name: v.camera_center for v in done}
    normals = []
    for g in gaps:
        c = centers.get(g.view, done[0].camera_center)
        n = model.normals_near(g.position_m[None], c)[0]
        normals.append(n if np.all(np.isfinite(n)) else unit(c - g.position_m))
    best, best_seen = None, []
    for cand in candidates:
        if any(_close(cand.pose, p) for p in done_poses):
            continue
        seen = [i for i, g in enumerate(gaps)
                if _sees_past(cand, g, centers.get(g.view, done[0].camera_center), normals[i], model, baseline_m)]
        if len(seen) > len(best_seen):
            best, best_seen = cand, seen
    if best is None:
        return Decision("stop", None, "no reachable pose is predicted to see past the unverified boundary ("
                        + "; ".join(g.to_dict()["what"] for g in gaps[:3])
                        + (f"; {len(gaps) - 3} more" if len(gaps) > 3 else "") + ")", len(gaps))
    T = np.array([gaps[i].direction for i in best_seen])
    t = np.linalg.eigh(T.T @ T)[1][:, -1]
    v = best.pose.view_dir
    across = np.cross(v, t)
    pose = best.pose
    if np.linalg.norm(across) > 1e-6 and best.method == "multi-view":
        pose = replace(pose, baseline_dir=perpendicular(across, v))
    view = replace(best, pose=pose, purpose="cure",
                   reason=best.reason + f"; predicted to see past {len(best_seen)} of {len(gaps)} gap(s) "
                   "(checked by casting rays against the reconstructed surface)")
    return Decision("view", view, view.reason, len(gaps), len(best_seen))


def paper_cure_views(rec, first: SensorPose, reach: Reach, measured: np.ndarray, camera: Camera,
                     baseline_m: float) -> tuple[list[PlannedView], str]:
    """The paper's cure 1 (re-orient onto the chord AB of the most bending curve) and cure 2 (move
    back beyond C) from the stage-3 reconstruction, as candidates; and a note when they cannot be
    formed (no most bending curve, L infinite or not positive, unreachable)."""
    try:
        bent = most_bent_direction(rec.boundary, rec.boundary_plane, rec.points)
        curves, _ = measured_bending_curves(rec.boundary, rec.boundary_source, rec.boundary_plane, bent,
                                            rec.surface_vertices)
    except ValueError as e:
        return [], f"paper's cures not formed: no most bending curve ({e})"
    curve = max(curves, key=tangent_intersection_distance)
    L = tangent_intersection_distance(curve)
    fb = rec.false_boundary
    missing = fb.expected - min(fb.detected.values()) if fb.detected else 0
    out, notes = [], []
    c1 = cure_orient(curve, first)
    off = np.degrees(np.arccos(np.clip(c1.view_dir @ first.view_dir, -1, 1)))
    turn = np.degrees(np.arccos(np.clip(abs(c1.baseline_dir @ first.baseline_dir), -1, 1)))
    if off > 2.0 or turn > 10.0:
        out.append(("cure 1", c1))
    else:
        notes.append(f"cure 1 would not move the sensor ({off:.1f} deg, baseline {turn:.0f} deg)")
    if np.isfinite(L) and L > 0:
        out.append(("cure 2", cure_move_back(curve, first, missing, max(fb.expected, 1))))
    else:
        notes.append(f"cure 2 has no distance to reach: L = {L * 1e3:.0f} mm "
                     f"(a = {np.degrees(curve.a_rad):.0f}, b = {np.degrees(curve.b_rad):.0f} deg)")
    views = []
    for method, p in out:
        p = ensure_in_view(p, measured, camera, baseline_m)
        why = reach.why_not(p, measured, baseline_m)
        if why:
            notes.append(f"{method} unreachable: {why}")
            continue
        views.append(PlannedView(method, p, "cure", method, p.reason))
    return views, "; ".join(notes)


def candidate_views(first: SensorPose, g, e, reach: Reach, measured: np.ndarray, camera: Camera,
                    baseline_m: float, paper: list[PlannedView]) -> list[PlannedView]:
    """The cure candidates in order of preference: the paper's cures, then the further turns of the
    stage-2 pose (module doc)."""
    turns, _ = turned_views(first, g, e, CANDIDATE_TURNS_DEG, "cure", reach, measured, camera, baseline_m)
    return list(paper) + turns
