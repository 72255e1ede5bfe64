"""Where to look next: the verification views every plate gets, and the cure chosen from measured
geometry when the boundary is not verified (``decide``, a pure function).

Verification views (every plate gets them; they are not cures): the stage-2 pose turned about the
boundary centre by +-30 and +-60 degrees about the ruling direction ``g`` (the boundary plane's
direction across the most-bent direction ``e``: a bend's occluding contours run along ``g`` and
slide under these turns), by +-30 and +-60 degrees about ``e``, and by +-45 degrees about the
diagonals ``g+e`` and ``g-e`` (corners and oblique edges). Their baselines lie at 45 degrees
between the stage-2 outline's two main directions (``outline_axes``), so that edges along either
cross the image rows and are row-matched. A turn past the robot's reach (``Reach.max_tilt_rad``)
is taken as far as the robot reaches, where that still turns the view by ``CONFIRM_ANGLE_RAD`` or
more and no other verification view lies there (``reachable_turn_deg``; named by the turn taken).

Cures. A gap is where a confirmed piece stops (``multiview.verify``). The candidates, in order:
views aimed at the stretch beyond each gap (``beyond_gap``: the row-matched outline points 1.5 to
15 mm past the end; ``targeted_views``: the pose that measured most of it, turned by 35 and 50
degrees either way about the stretch's direction), the cure rules' views, the paper's cure 1
and cure 2 first (``cures.CURE_RULES``, asked in order by ``cure_views``), further turns of the stage-2 pose about ``g``, ``e`` and the diagonals, and
poses on a dome over the boundary centre (``dome_views``). Each is checked against the surface
model (``_Targets.check``) before anything is rendered: which gaps' stretches it would *confirm*
(``_predict``: both cameras see the points from the plate's front by ``FRONT_MARGIN_RAD``, unblocked,
on its outline, crossing its rows at ``STEEP_RAD`` or more with the best of ``BASELINE_STEPS``
baselines, turned by ``multiview.confirm``'s thresholds plus ``PREDICT_MARGIN_RAD``) and which it
*sees past* (the points 3 and 8 mm beyond the end). The candidate predicted to confirm most
stretches wins, then the one reaching most gaps, then the earlier one; where none confirms
anything, *grazing views* (``GRAZING_FRONT_MARGIN_RAD``) come before views that only see past a gap.
No candidate confirming or seeing past any gap: stop, naming the gaps. At most ``MAX_CURE_VIEWS``
cures by default (``budget``). The surface model is the poses' measured surfaces without chords
(``loop.Measurements``).

Known limits: a gap at a corner sharper than about 45 degrees in 3D cannot be linked
(``multiview._leads_on``), and the planner spends views seeing past it; beyond a gap where the
front is not known the normals face the pose that saw the end; a corner's next edge is not counted
as lying beyond the gap; refuted points may be aimed at.

World frame, metres, radians. Nothing here renders or reads ground truth. The measurements behind
these rules: docs/findings/design-record.md.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from platebench.reconstruction.paper.outline_stereo import MATCH_STEEP_DEG
from platebench.reconstruction.paper.surface_interpolation import points_in_polygon
from platebench.reconstruction.strategy.bending import measured_bending_curves, tangent_intersection_distance
from platebench.reconstruction.strategy.budget import MAX_CURE_VIEWS, MAX_CURES_ALLOWED  # noqa: F401 (re-exported)
from platebench.reconstruction.strategy.cures import CURE_PARAMETERS, CureContext, CureParameters, CureRule, cure_rules
from platebench.reconstruction.strategy.multiview import (
    CONFIRM_ANGLE_RAD,
    CONFIRM_SLIDE_ANGLE_RAD,
    BoundaryVerdict,
    Gap,
    ViewOutline,
    outline_directions,
    ray_angles,
    slide_angles,
)
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
from platebench.reconstruction.strategy.sides import FrontSide
from platebench.reconstruction.strategy.surface_model import SurfaceModel
from platebench.scenes.camera import Camera
from platebench.tolerances import tol

VERIFY_TURNS_DEG = (("g", -30.0), ("g", 30.0), ("g", -60.0), ("g", 60.0), ("e", -30.0), ("e", 30.0), ("e", -60.0),
                    ("e", 60.0), ("g+e", -45.0), ("g+e", 45.0), ("g-e", -45.0), ("g-e", 45.0))
CANDIDATE_TURNS_DEG = tuple([("g", a) for a in (-15, 15, -45, 45, -75, 75)] +
                            [("e", a) for a in (-45, 45, -60, 60, -75, 75)] +
                            [(d, a) for a in (-45, 45, -60, 60, -75, 75) for d in ("g+e", "g-e")])
FRONT_MARGIN_RAD = float(np.radians(15.0))  # a candidate sees a point from this far above the measured surface
GRAZING_FRONT_MARGIN_RAD = float(np.radians(5.0))  # ... or this far, when no candidate helps at the first (doc)
LOOK_AHEAD_M = (3e-3, 8e-3)
BEYOND_MIN_M = 1.5e-3  # the stretch beyond a gap: measured outline points from this far on along it ...
BEYOND_M = 15e-3  # ... to this far from the gap's end
BEYOND_MAX_POINTS = 24  # ... of which this many, evenly spread (ray casting cost)
BEYOND_MIN_POINTS = 3  # fewer measured points beyond a gap: nothing there to confirm
BEYOND_CONFIRM_FRACTION = 0.5  # a candidate confirms a gap's stretch when predicted to confirm this much of it
PREDICT_MARGIN_RAD = float(np.radians(5.0))  # predicted confirmations need the thresholds plus this
OUTSIDE_PX = 4.0  # the point just outside the plate beside a measured outline point, in its pose's image
STEEP_RAD = float(np.radians(MATCH_STEEP_DEG)) + PREDICT_MARGIN_RAD  # an edge row-matched by a candidate
BASELINE_STEPS = 12  # baselines tried per candidate, evenly over half a turn about its centre line
# dome_views: tilts from the vertical ... 50 as well as 60 and 75: a fold's flap hanging 120 degrees down
# leans back under the plate, its front facing 30 degrees below the horizon, so only views 45 degrees
# or more from the vertical see it FRONT_MARGIN_RAD above the sheet; its tip edge is confirmed by two
# of them turned CONFIRM_SLIDE_ANGLE_RAD apart about it, which 60 and 75 (15 apart) are not
DOME_TILTS_DEG = (20.0, 40.0, 50.0, 60.0, 75.0)
DOME_AZIMUTH_STEP_DEG = 30.0  # ... at this azimuth step
SILHOUETTE_REACH_M = 0.3  # a ray past an edge meets no measured surface this far on: the edge is on the outline
TARGETED_TURNS_DEG = (35.0, 50.0)  # turns about the measured edge beyond a gap (targeted_views) ...
TARGETED_BASES = 2  # ... of the poses that measured most of it, ...
TARGETED_GAPS = 4  # ... for this many gaps at most (those with most measured beyond them; ray casting cost)
SAME_VIEW_RAD = float(np.radians(8.0))  # a candidate this close in direction to a done pose adds nothing
MAX_VIEWS = 1 + len(VERIFY_TURNS_DEG) + MAX_CURE_VIEWS  # measuring poses at most: stage 2, verification, cures


@dataclass(frozen=True)
class PlannedView:
    """A pose to measure from, and why: ``purpose`` "verification" or "cure"; ``method``
    "verification", a cure rule's name ("cure 1", "cure 2": the paper's; ``cures.CURE_RULES``) or
    "multi-view" (a turn of the stage-2 pose, or of a pose aimed at a gap: ``targeted_views``)."""

    name: str
    pose: SensorPose
    purpose: str
    method: str
    reason: str


@dataclass(frozen=True)
class Decision:
    """What the loop does next: ``kind`` "done" (verified), "view" (measure ``view``) or "stop"."""

    kind: str
    view: PlannedView | None
    reason: str
    gaps_targeted: int = 0
    gaps_predicted_seen: int = 0  # gaps the view is predicted to see past or to confirm the edge beyond


def sensing_axes(bent_dir, plane_normal) -> tuple[np.ndarray, np.ndarray]:
    """(g, e): the ruling direction (across the bend, in the boundary plane) and the most-bent one."""
    n = unit(plane_normal)
    e = perpendicular(bent_dir, n)
    return unit(np.cross(n, e)), e


def _axis(name: str, g: np.ndarray, e: np.ndarray) -> np.ndarray:
    return {"g": g, "e": e, "g+e": unit(g + e), "g-e": unit(g - e)}[name]


def _placed(p: SensorPose, reach: Reach, measured: np.ndarray, camera: Camera,
            baseline_m: float) -> tuple[SensorPose, str | None]:
    """``p`` moved back to keep the ``measured`` points in view, and why the robot cannot reach it
    (None: it can)."""
    p = ensure_in_view(p, measured, camera, baseline_m)
    return p, reach.why_not(p, measured, baseline_m)


def _principal_direction(T: np.ndarray) -> np.ndarray:
    """(3,) unit axis of the (K,3) directions ``T`` (either sign each): the top eigenvector of T^T T."""
    return np.linalg.eigh(T.T @ T)[1][:, -1]


def outline_axes(points: np.ndarray, normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(a, b): two perpendicular unit directions across ``normal`` along which the closed outline
    ``points`` (N,3, in order) mostly runs: the orientation of the 4-fold mean of its tangents'
    directions in that plane, weighted by length (a rectangle's two edge directions, whatever its
    bend axis). A plate bent about an oblique axis keeps its edges along its own sides, not along
    the bend's ruling and most-bent directions."""
    n = unit(normal)
    u = perpendicular(np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0]), n)
    v = np.cross(n, u)
    d = np.roll(points, -1, axis=0) - points
    theta = np.arctan2(d @ v, d @ u)
    phi = float(np.angle(np.sum(np.hypot(d @ u, d @ v) * np.exp(4j * theta)))) / 4.0
    a = np.cos(phi) * u + np.sin(phi) * v
    return a, np.cross(n, a)


def reachable_turn_deg(first: SensorPose, axis: np.ndarray, deg: float, reach: Reach) -> float:
    """The largest whole-degree turn of ``first`` about ``axis`` toward ``deg`` whose view stays within
    the robot's tilt (``Reach.max_tilt_rad``) all the way from 0 (0 when the first degree leaves it)."""
    step = 1.0 if deg > 0 else -1.0
    best = 0.0
    for k in range(1, int(abs(deg)) + 1):
        if reach.tilts_past(rotated_pose(first, axis, np.radians(k * step))):
            break
        best = k * step
    return best


def turned_views(first: SensorPose, g, e, turns, purpose: str, reach: Reach, measured: np.ndarray,
                 camera: Camera, baseline_m: float, edges=None,
                 clamp_min_deg: float | None = None) -> tuple[list[PlannedView], list[str]]:
    """The stage-2 pose turned as listed ((axis name, degrees)), kept in view, with a diagonal
    baseline (at 45 degrees between ``edges``, the outline's two main directions, default g and
    e); the second list's notes name the turns left out ("left out: ..."). With
    ``clamp_min_deg``, a turn whose view tilts past the robot's reach is taken as far as the robot
    reaches (``reachable_turn_deg``) where that still turns the view direction by ``clamp_min_deg``
    or more and no view already planned lies there (``_close``), named by the turn taken, and
    noted ("held at the reach: ...")."""
    views, skipped = [], []
    ea, eb = edges if edges is not None else (g, e)
    for ax, deg in turns:
        name = f"turn {ax} {deg:+.0f}"
        p = rotated_pose(first, _axis(ax, g, e), np.radians(deg))
        p = replace(p, baseline_dir=diagonal_baseline(p.view_dir, ea, eb),
                    reason=f"stage-2 pose turned {deg:+.0f} deg about {ax} through the boundary centre")
        tilts_past = reach.tilts_past(p)
        p, why = _placed(p, reach, measured, camera, baseline_m)
        if why and clamp_min_deg is not None and tilts_past:
            held = reachable_turn_deg(first, _axis(ax, g, e), deg, reach)
            q = rotated_pose(first, _axis(ax, g, e), np.radians(held))
            moved_deg = float(np.degrees(np.arccos(np.clip(q.view_dir @ first.view_dir, -1.0, 1.0))))
            if moved_deg >= clamp_min_deg and not _close(q, first):
                q = replace(q, baseline_dir=diagonal_baseline(q.view_dir, ea, eb),
                            reason=f"stage-2 pose turned {held:+.0f} deg about {ax} through the boundary centre, "
                                   f"as far toward {deg:+.0f} deg as the robot reaches")
                q, why_q = _placed(q, reach, measured, camera, baseline_m)
                if not why_q and not any(_close(q, v.pose) for v in views):
                    skipped.append(f"held at the reach: {name}: {why}; taken at {held:+.0f} deg")
                    name, p, why = f"turn {ax} {held:+.0f}", q, None
        if why:
            skipped.append(f"left out: {name}: {why}")
            continue
        views.append(PlannedView(name, p, purpose, "verification" if purpose == "verification" else "multi-view",
                                 p.reason))
    return views, skipped


def verification_views(first: SensorPose, g, e, reach: Reach, measured: np.ndarray, camera: Camera,
                       baseline_m: float) -> tuple[list[PlannedView], list[str]]:
    """The views every plate gets (module doc); ``measured``: the stage-2 outline (N,3, in order),
    whose main directions set the baselines (``outline_axes``)."""
    return turned_views(first, g, e, VERIFY_TURNS_DEG, "verification", reach, measured, camera, baseline_m,
                        outline_axes(measured, -first.view_dir), clamp_min_deg=float(np.degrees(CONFIRM_ANGLE_RAD)))


def _close(a: SensorPose, b: SensorPose) -> bool:
    return float(np.arccos(np.clip(a.view_dir @ b.view_dir, -1, 1))) < SAME_VIEW_RAD and \
        abs(a.distance_m - b.distance_m) < 0.05 * max(a.distance_m, b.distance_m)


@dataclass(frozen=True)
class Beyond:
    """The boundary just beyond a gap as the poses measured so far saw it: their row-matched outline
    points at least ``BEYOND_MIN_M`` on along the gap's direction and at most ``BEYOND_M``
    (straight-line distance) from its end, not confirmed (when the confirmations are given).
    ``points`` (K,3); ``tangents`` (K,3) the outline's local 3D direction there, made to lie in
    its contour plane; ``centers`` (K,3) the mid-baseline point of the pose that measured each;
    ``views`` (K,) its index in ``done``; ``normals`` (K,3) its contour plane's unit normal
    (``multiview.contour_planes``); ``eyes`` (K,3) that pose's camera centre
    (``ViewOutline.eye``); ``outside`` (K,3) a point just off the plate beside each
    (``outside_points``)."""

    points: np.ndarray
    tangents: np.ndarray
    centers: np.ndarray
    views: np.ndarray
    normals: np.ndarray
    eyes: np.ndarray
    outside: np.ndarray


def beyond_gap(gap: Gap, done: list[ViewOutline], confirmed=()) -> Beyond:
    """The stretch beyond ``gap`` as measured so far (``Beyond``); ``confirmed``: per pose of
    ``done``, (N,) the points already confirmed (left out). Known limit: where a piece stops at a
    corner, the next edge leaves at about 90 degrees to the gap's direction and is not counted."""
    P, T, C, V, N, E, O = [], [], [], [], [], [], []
    for k, v in enumerate(done):
        rel = v.points - gap.position_m
        m = v.matched & (rel @ gap.direction >= BEYOND_MIN_M) & (np.linalg.norm(rel, axis=1) <= BEYOND_M)
        if k < len(confirmed):
            if len(confirmed[k]) != len(m):
                raise ValueError(f"confirmed[{k}] has {len(confirmed[k])} entries for {len(m)} outline points")
            m &= ~np.asarray(confirmed[k], bool)
        if m.any():
            n = v.plane_normals[m]
            t = outline_directions(v.points)[m]
            t = t - n * np.einsum("ij,ij->i", t, n)[:, None]
            P.append(v.points[m])
            T.append(t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), tol.zero_length))
            C.append(np.repeat(v.camera_center[None], int(m.sum()), 0))
            V.append(np.full(int(m.sum()), k))
            N.append(n)
            E.append(np.repeat(v.eye[None], int(m.sum()), 0))
            O.append(outside_points(v, np.nonzero(m)[0]))
    if not P:
        z = np.zeros((0, 3))
        return Beyond(z, z, z, np.zeros(0, int), z, z, z)
    P, T, C, V, N, E, O = (np.vstack(P), np.vstack(T), np.vstack(C), np.concatenate(V), np.vstack(N), np.vstack(E),
                           np.vstack(O))
    keep = np.unique(np.linspace(0, len(P) - 1, min(len(P), BEYOND_MAX_POINTS)).round().astype(int))
    return Beyond(P[keep], T[keep], C[keep], V[keep], N[keep], E[keep], O[keep])


def outside_points(view: ViewOutline, idx: np.ndarray) -> np.ndarray:
    """(K,3) for the outline points ``idx`` of ``view``: the point ``OUTSIDE_PX`` off the plate
    beside each in the pose's image (across the outline, on the background's side), at the
    point's depth. Where the plate's edge is on a candidate's silhouette, the candidate's rays
    through these points meet nothing; where they meet the plate, the edge lies in front of the
    plate's own surface in its images (an inner edge, which no outline shows). Without the
    pose's camera: the points themselves."""
    P = view.points[idx]
    cam = view.left
    if cam is None or len(view.points) < 3:
        return P.copy()
    uv = view.image_points[idx]
    t = view.pixel_tangents[idx]
    n2 = np.column_stack([-t[:, 1], t[:, 0]])
    out = np.where(points_in_polygon(uv + n2 * OUTSIDE_PX, view.image_points)[:, None], -n2, n2)
    uv_out = uv + out * OUTSIDE_PX
    return cam.at_depth(uv_out, cam.depth(P))


def _seen_by(pose: SensorPose, points: np.ndarray, normals: np.ndarray, model: SurfaceModel,
             baseline_m: float, front_margin_rad: float = FRONT_MARGIN_RAD) -> np.ndarray:
    """(K,) both cameras of ``pose`` see each point from the outer side of the surface measured there
    (at least ``front_margin_rad`` above it) and no measured surface blocks the way."""
    ok = np.ones(len(points), bool)
    for c in pose.camera_centers(baseline_m):
        to_c = c - points
        ok &= np.einsum("ij,ij->i", to_c, normals) / np.linalg.norm(to_c, axis=1) >= np.sin(front_margin_rad)
        if ok.any():
            idx = np.nonzero(ok)[0]
            ok[idx[model.blocked(np.repeat(c[None], len(idx), 0), points[idx])]] = False
    return ok


def _turned_enough(beyond: Beyond, center: np.ndarray,
                   slide_angle_rad: float = CONFIRM_SLIDE_ANGLE_RAD) -> np.ndarray:
    """(K,) a pose at ``center`` is turned from each point's measuring pose by ``CONFIRM_ANGLE_RAD``
    and lies out of its contour plane by ``slide_angle_rad`` (the slide angle the loop confirms
    with: ``CONFIRM_SLIDE_ANGLE_RAD``, or ``CONFIRM_SLIDE_ANGLE_RIG_RAD`` under a real rig), and
    the measuring pose out of the plane the pose would see (through ``center`` and the measured
    edge's direction) by as much, each with ``PREDICT_MARGIN_RAD`` to spare
    (``multiview.confirm``'s rule, before rendering)."""
    P = beyond.points
    slide = slide_angle_rad + PREDICT_MARGIN_RAD
    theirs = np.cross(center - P, beyond.tangents)
    theirs /= np.maximum(np.linalg.norm(theirs, axis=1, keepdims=True), tol.zero_length)
    return (ray_angles(P, beyond.centers, center) >= CONFIRM_ANGLE_RAD + PREDICT_MARGIN_RAD) & \
        (slide_angles(beyond.normals, P, center) >= slide) & (slide_angles(theirs, P, beyond.eyes) >= slide)


def _on_silhouette(pose: SensorPose, outside: np.ndarray, model: SurfaceModel, baseline_m: float) -> np.ndarray:
    """(K,) both cameras of ``pose`` see the background just beside each point (their rays through
    ``outside`` (K,3), on past it, meet no measured surface): the edge is on their outlines."""
    ok = np.ones(len(outside), bool)
    for c in pose.camera_centers(baseline_m):
        d = outside - c
        far = outside + d / np.linalg.norm(d, axis=1, keepdims=True) * SILHOUETTE_REACH_M
        ok &= ~model.blocked(outside, far)
    return ok


def row_angles(pose: SensorPose, points: np.ndarray, tangents: np.ndarray, baselines: np.ndarray) -> np.ndarray:
    """(B,K) the angle (rad, 0 to pi/2) at which the edge through each point (K,3) along its
    tangent (K,3) crosses the image rows of a rig at ``pose`` with each of the baseline
    directions ``baselines`` (B,3) (perpendicular to the centre line): rows run along the
    baseline (conventional geometry), and the edge's image direction follows the pinhole's
    perspective."""
    z = pose.view_dir
    x0 = perpendicular(baselines[0], z)
    y0 = np.cross(z, x0)
    rel = points - pose.center
    X, Y, Z = rel @ x0, rel @ y0, rel @ z
    Tx, Ty, Tz = tangents @ x0, tangents @ y0, tangents @ z
    edge = np.arctan2(Ty * Z - Y * Tz, Tx * Z - X * Tz)  # (K,) image direction against x0
    beta = np.arctan2(baselines @ y0, baselines @ x0)  # (B,) each baseline's direction against x0
    a = np.abs((edge[None, :] - beta[:, None] + np.pi / 2) % np.pi - np.pi / 2)
    return a


def baseline_choices(pose: SensorPose) -> np.ndarray:
    """(BASELINE_STEPS,3) baselines evenly over half a turn about the centre line, the pose's own first."""
    z = pose.view_dir
    x0 = perpendicular(pose.baseline_dir, z)
    y0 = np.cross(z, x0)
    b = np.arange(BASELINE_STEPS) * np.pi / BASELINE_STEPS
    return np.cos(b)[:, None] * x0 + np.sin(b)[:, None] * y0


def _predict(pose: SensorPose, look: np.ndarray, look_normals: np.ndarray, beyond: Beyond,
             beyond_normals: np.ndarray, model: SurfaceModel, baseline_m: float,
             front_margin_rad: float = FRONT_MARGIN_RAD,
             slide_angle_rad: float = CONFIRM_SLIDE_ANGLE_RAD) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """((L,) which ``look`` points ``pose`` sees (``_seen_by``), (K,) which ``beyond`` points it is
    predicted to confirm, and the baseline (3,) that makes most of them cross its image rows
    steeply). A point is predicted confirmed when the pose is turned enough from the pose that
    measured it (``_turned_enough``), sees it (``_seen_by``), shows it on its outline
    (``_on_silhouette``) and, with the chosen baseline, crosses its rows at ``STEEP_RAD`` or more
    (``outline_stereo`` matches only such crossings). Normals (L,3)/(K,3): the measured surface's
    there; ``front_margin_rad``: how far above the measured surface the cameras must be (``_seen_by``);
    ``slide_angle_rad``: the loop's confirmation slide angle (``_turned_enough``).
    One ray cast per camera for the seeing, one for the silhouettes."""
    turned = _turned_enough(beyond, pose.center, slide_angle_rad) if len(beyond.points) else np.zeros(0, bool)
    b_idx = np.nonzero(turned)[0]
    pts = np.vstack([look, beyond.points[b_idx]])
    vis = _seen_by(pose, pts, np.vstack([look_normals, beyond_normals[b_idx]]), model, baseline_m, front_margin_rad) \
        if len(pts) else np.zeros(0, bool)
    conf = np.zeros(len(beyond.points), bool)
    b_idx = b_idx[vis[len(look):]]
    baseline = pose.baseline_dir
    if len(b_idx):
        b_idx = b_idx[_on_silhouette(pose, beyond.outside[b_idx], model, baseline_m)]
    if len(b_idx):
        choices = baseline_choices(pose)
        steep = row_angles(pose, beyond.points[b_idx], beyond.tangents[b_idx], choices) >= STEEP_RAD
        best = int(np.argmax(steep.sum(axis=1)))
        baseline = choices[best]
        conf[b_idx[steep[best]]] = True
    return vis[:len(look)], conf, baseline


def predicted_confirmed(pose: SensorPose, beyond: Beyond, normals: np.ndarray, model: SurfaceModel,
                        baseline_m: float, slide_angle_rad: float = CONFIRM_SLIDE_ANGLE_RAD) -> np.ndarray:
    """(K,) the points of ``beyond`` that ``pose`` is predicted to confirm (``_predict``; ``normals``
    (K,3): the measured surface's normal there, toward the measuring side; ``slide_angle_rad``: the
    loop's confirmation slide angle)."""
    return _predict(pose, np.zeros((0, 3)), np.zeros((0, 3)), beyond, normals, model, baseline_m,
                    slide_angle_rad=slide_angle_rad)[1]


@dataclass(frozen=True)
class _Targets:
    """What a candidate is checked against, for all gaps at once (one ray cast per camera): the
    gaps' ends and where they were seen from, the points ``LOOK_AHEAD_M`` past them, and the
    measured stretches beyond them (``Beyond``, concatenated), each with the measured surface's
    normal."""

    ends: np.ndarray  # (G,3)
    seen_from: np.ndarray  # (G,3)
    look: np.ndarray  # (G*A,3), A = len(LOOK_AHEAD_M)
    look_normals: np.ndarray  # (G*A,3)
    beyond: Beyond  # (K points) all gaps' stretches
    beyond_normals: np.ndarray  # (K,3)
    beyond_gap: np.ndarray  # (K,) the gap of each
    beyond_count: np.ndarray  # (G,) points beyond each gap

    def check(self, pose: SensorPose, model: SurfaceModel, baseline_m: float,
              front_margin_rad: float = FRONT_MARGIN_RAD,
              slide_angle_rad: float = CONFIRM_SLIDE_ANGLE_RAD) -> tuple[list[int], list[int], np.ndarray]:
        """(the gaps ``pose`` sees past: turned ``CONFIRM_ANGLE_RAD`` from the pose that saw the end,
        both cameras see the look-ahead points; the gaps whose measured stretch ``pose`` is
        predicted to confirm: ``BEYOND_CONFIRM_FRACTION`` of it, at least ``BEYOND_MIN_POINTS``;
        the baseline that lets it match most of them, ``_predict``, with ``front_margin_rad``)."""
        G, A = len(self.ends), len(LOOK_AHEAD_M)
        gap_ok = ray_angles(self.ends, self.seen_from, pose.center) >= CONFIRM_ANGLE_RAD
        look_idx = np.nonzero(np.repeat(gap_ok, A))[0]
        vis, confirmed, baseline = _predict(pose, self.look[look_idx], self.look_normals[look_idx], self.beyond,
                                            self.beyond_normals, model, baseline_m, front_margin_rad,
                                            slide_angle_rad)
        look_vis = np.zeros(G * A, bool)
        look_vis[look_idx] = vis
        seen = np.nonzero(gap_ok & look_vis.reshape(G, A).all(axis=1))[0]
        conf_n = np.bincount(self.beyond_gap[confirmed], minlength=G)
        conf = np.nonzero((self.beyond_count >= BEYOND_MIN_POINTS) &
                          (conf_n >= BEYOND_CONFIRM_FRACTION * np.maximum(self.beyond_count, 1)))[0]
        return seen.tolist(), conf.tolist(), baseline


def _targets(gaps: list[Gap], beyonds: list[Beyond], done: list[ViewOutline], model: SurfaceModel,
             front: FrontSide | None = None) -> _Targets:
    """``_Targets`` of the gaps. Normals: the surface model's, turned toward the pose that saw the
    gap's end; past the end (off the measured surface) and where the model has none, the normal at
    the end, or the direction to that pose. Known limit: beyond the end the normal is turned toward
    the pose that saw the end, not the one that measured the point (``confirm`` pairs the
    candidate with the latter; on a curl the two can see the sheet from opposite sides)."""
    centers = {v.name: v.camera_center for v in done}
    seen_from = np.array([centers.get(g.view, done[0].camera_center) for g in gaps])
    ends = np.array([g.position_m for g in gaps])
    G, A = len(gaps), len(LOOK_AHEAD_M)
    counts = np.array([len(b.points) for b in beyonds])
    bgap = np.repeat(np.arange(G), counts)
    look = np.array([g.position_m + g.direction * d for g in gaps for d in LOOK_AHEAD_M])
    allb = Beyond(*(np.concatenate([getattr(b, f) for b in beyonds])
                    for f in ("points", "tangents", "centers", "views", "normals", "eyes", "outside")))
    n = model.normals_near(np.vstack([ends, allb.points]), np.vstack([seen_from, seen_from[bgap]]))
    if front is not None:  # the plate's front where it is known: a candidate must see that side
        nf = front.normals_at(np.vstack([ends, allb.points]))
        n = np.where(np.all(np.isfinite(nf), axis=1)[:, None], nf, n)
    bad = ~np.all(np.isfinite(n), axis=1)
    to_pose = (seen_from - ends) / np.linalg.norm(seen_from - ends, axis=1, keepdims=True)
    gap_n = np.where(bad[:G, None], to_pose, n[:G])
    b_n = np.where(bad[G:, None], gap_n[bgap], n[G:])
    return _Targets(ends, seen_from, look, np.repeat(gap_n, A, 0), allb, b_n, bgap, counts)


def open_ends(verdict: BoundaryVerdict) -> list[Gap]:
    """The verdict's gaps; with none (separate groups with no loose end), the ends of the
    unconfirmed outline runs no other pose covers, each looking along the run."""
    gaps = list(verdict.gaps)
    if not gaps:
        for u in verdict.unconfirmed:
            if not u.covered:
                d = u.end_m - u.start_m
                n = float(np.linalg.norm(d))
                if n > 0:
                    gaps += [Gap(u.start_m, d / n, u.view), Gap(u.end_m, -d / n, u.view)]
    return gaps


def targeted_views(beyonds: list[Beyond], done_poses: list[SensorPose], reach: Reach, measured: np.ndarray,
                   camera: Camera, baseline_m: float) -> list[PlannedView]:
    """Per gap, the pose that measured most of the stretch beyond it, turned about that stretch's
    own direction (through its target) by ``TARGETED_TURNS_DEG``: the turn that slides an
    occluding contour and leaves an edge where it is, so the pair confirms the stretch or refutes
    it. Baseline across the stretch (its edge crosses the image rows); unreachable ones left out."""
    out = []
    order = sorted(range(len(beyonds)), key=lambda i: -len(beyonds[i].points))[:TARGETED_GAPS]
    for i in sorted(order):
        b = beyonds[i]
        if len(b.points) < BEYOND_MIN_POINTS:
            continue
        counts = np.bincount(b.views)
        for k in np.argsort(-counts, kind="stable")[:TARGETED_BASES]:
            if counts[k] < BEYOND_MIN_POINTS:
                continue
            t = _principal_direction(b.tangents[b.views == k])
            base = done_poses[k]
            for deg in TARGETED_TURNS_DEG:
                for sgn in (-1.0, 1.0):
                    p = rotated_pose(base, t, sgn * np.radians(deg))
                    p = replace(p, baseline_dir=perpendicular(np.cross(p.view_dir, t), p.view_dir),
                                reason=f"pose {k} turned {sgn * deg:+.0f} deg about the edge it measured "
                                       f"beyond gap {i + 1}")
                    p, why = _placed(p, reach, measured, camera, baseline_m)
                    if why is None:
                        out.append(PlannedView(f"gap {i + 1} pose {k} turn {sgn * deg:+.0f}", p, "cure",
                                               "multi-view", p.reason))
    return out


def decide(verdict: BoundaryVerdict, done: list[ViewOutline], done_poses: list[SensorPose],
           candidates: list[PlannedView], model: SurfaceModel, baseline_m: float,
           max_views: int = MAX_VIEWS, reach: Reach | None = None, camera: Camera | None = None,
           front: FrontSide | None = None, slide_angle_rad: float = CONFIRM_SLIDE_ANGLE_RAD) -> Decision:
    """The next step of the loop (module doc). ``done``/``done_poses``: the poses measured so far.
    With ``reach`` and ``camera``, the poses turned about the edge beyond each gap
    (``targeted_views``) are candidates too. ``slide_angle_rad``: the slide angle the loop confirms
    with (``Measurements.slide_angle_rad``), so that a view is predicted to confirm only what the
    verdict will accept."""
    if verdict.verified:
        return Decision("done", None, "boundary verified: " + verdict.reason)
    gaps = open_ends(verdict)
    if not gaps:
        return Decision("stop", None, f"not verified ({verdict.reason}) but no piece end to look past")
    if len(done) >= max_views:
        return Decision("stop", None, f"view budget spent ({len(done)} poses); {len(gaps)} gap(s) remain: "
                        + "; ".join(g.what for g in gaps[:3]), len(gaps))
    beyonds = [beyond_gap(g, done, verdict.confirmed) for g in gaps]
    targets = _targets(gaps, beyonds, done, model, front)
    if reach is not None and camera is not None:
        measured = np.vstack([v.points for v in done])
        candidates = targeted_views(beyonds, done_poses, reach, measured, camera, baseline_m) + list(candidates)
    fresh = [c for c in candidates if not any(_close(c.pose, p) for p in done_poses)]
    checked: dict[float, list] = {}

    def check_all(margin):
        if margin not in checked:
            checked[margin] = [targets.check(c.pose, model, baseline_m, margin, slide_angle_rad) for c in fresh]
        return checked[margin]

    best, best_seen, best_conf, best_baseline = None, [], [], None
    # a view predicted to confirm first (seen well above the surface, then grazing), then one that sees past
    for margin, confirming in ((FRONT_MARGIN_RAD, True), (GRAZING_FRONT_MARGIN_RAD, True),
                               (FRONT_MARGIN_RAD, False), (GRAZING_FRONT_MARGIN_RAD, False)):
        best_score = (0, 0)
        for cand, (seen, conf, baseline) in zip(fresh, check_all(margin)):
            reached = sorted(set(seen) | set(conf))
            score = (len(conf), len(reached))
            if (conf or not confirming) and score > best_score:
                best, best_score, best_seen, best_conf, best_baseline = cand, score, reached, conf, baseline
        if best is not None:
            if margin != FRONT_MARGIN_RAD:
                best = replace(best, reason=best.reason + f" (a grazing view: {np.degrees(margin):.0f} to "
                               f"{np.degrees(FRONT_MARGIN_RAD):.0f} deg above the measured surface)")
            break
    if best is None:
        return Decision("stop", None, "no reachable pose is predicted to see past the unverified boundary ("
                        + "; ".join(g.what for g in gaps[:3])
                        + (f"; {len(gaps) - 3} more" if len(gaps) > 3 else "") + ")", len(gaps))
    pose = best.pose
    if best.method == "multi-view":  # the paper's cures keep their own baselines
        if best_conf:  # the baseline that matches most of the edges it is to confirm (``_predict``)
            pose = replace(pose, baseline_dir=best_baseline)
        else:  # it only sees past the gaps: their edges across the image rows
            v = pose.view_dir
            across = np.cross(v, _principal_direction(np.array([gaps[i].direction for i in best_seen])))
            if np.linalg.norm(across) > tol.unit_norm:
                pose = replace(pose, baseline_dir=perpendicular(across, v))
    view = replace(best, pose=pose, purpose="cure",
                   reason=best.reason + f"; predicted to see past or confirm the edge beyond {len(best_seen)} of "
                   f"{len(gaps)} gap(s) (confirm: {len(best_conf)}) "
                   "(checked by casting rays against the reconstructed surface)")
    return Decision("view", view, view.reason, len(gaps), len(best_seen))


def cure_context(rec, first: SensorPose) -> CureContext:
    """What the cure rules read (``cures.CureContext``) from the stage-3 reconstruction ``rec`` and the
    stage-2 pose ``first``; ValueError when ``rec`` has no most bending curve."""
    bent = most_bent_direction(rec.boundary, rec.boundary_plane, rec.points)
    curves, _ = measured_bending_curves(rec.boundary, rec.boundary_source, rec.boundary_plane, bent,
                                        rec.surface_vertices)
    curve = max(curves, key=tangent_intersection_distance)
    fb = rec.false_boundary
    missing = fb.expected - min(fb.detected.values()) if fb.detected else 0
    return CureContext(curve, first, missing, fb.expected)


def paper_cure_views(rec, first: SensorPose, reach: Reach, measured: np.ndarray, camera: Camera,
                     baseline_m: float, rules: tuple[CureRule, ...] | None = None,
                     params: CureParameters = CURE_PARAMETERS) -> tuple[list[PlannedView], str]:
    """The cure rules' views from the stage-3 reconstruction (``cure_context``, ``cure_views``): the
    paper's cure 1 (re-orient onto the chord AB of the most bending curve) and cure 2 (move back
    beyond C) and any rule registered after them, as candidates; and a note when they cannot be
    formed (no most bending curve, a rule proposing nothing, unreachable)."""
    try:
        ctx = cure_context(rec, first)
    except ValueError as e:
        return [], f"paper's cures not formed: no most bending curve ({e})"
    return cure_views(ctx, reach, measured, camera, baseline_m, rules, params)


def cure_views(ctx: CureContext, reach: Reach, measured: np.ndarray, camera: Camera, baseline_m: float,
               rules: tuple[CureRule, ...] | None = None,
               params: CureParameters = CURE_PARAMETERS) -> tuple[list[PlannedView], str]:
    """Each cure rule's proposal for ``ctx`` under ``params`` (``rules``: default the registered ones,
    ``cures.cure_rules()``, in their order), kept in view of the ``measured`` points (N,3) and
    reachable, as a cure candidate named and typed by the rule's name; and the rules' notes (why a
    rule proposed nothing, or its pose is unreachable), joined by "; "."""
    out, notes = [], []
    for rule in cure_rules() if rules is None else rules:
        proposal = rule.propose(ctx, params)
        if proposal.pose is not None:
            out.append((rule.name, proposal.pose))
        elif proposal.note:
            notes.append(proposal.note)
    views = []
    for method, p in out:
        p, why = _placed(p, reach, measured, camera, baseline_m)
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
    return list(paper) + turns + dome_views(first, reach, measured, camera, baseline_m)


def dome_views(first: SensorPose, reach: Reach, measured: np.ndarray, camera: Camera,
               baseline_m: float) -> list[PlannedView]:
    """Poses on a dome over the boundary centre: every ``DOME_TILTS_DEG`` from the vertical at
    every ``DOME_AZIMUTH_STEP_DEG`` of azimuth, at the stage-2 pose's distance, looking at its
    target (kept in view; unreachable ones left out). The turns of the stage-2 pose are few and
    follow its axes; these reach every side at the robot's whole tilt range."""
    out = []
    for tilt in DOME_TILTS_DEG:
        for az in np.arange(0.0, 360.0, DOME_AZIMUTH_STEP_DEG):
            t, a = np.radians(tilt), np.radians(az)
            d = np.array([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)])
            view = -d
            p = SensorPose(first.target + d * first.distance_m, first.target.copy(),
                           perpendicular(np.array([-np.sin(a), np.cos(a), 0.0]), view),
                           f"dome pose {tilt:.0f} deg from the vertical at azimuth {az:.0f} deg")
            p, why = _placed(p, reach, measured, camera, baseline_m)
            if why is None:
                out.append(PlannedView(f"dome {tilt:.0f}/{az:.0f}", p, "cure", "multi-view", p.reason))
    return out
