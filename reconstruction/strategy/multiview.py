"""Viewpoint consistency and the boundary verdict, from measurements only (no ground truth).

Each pose measures the plate's outline by passive stereo (``ViewOutline``). A point of that outline
is either a true edge of the plate or an occluding contour (where the surface turns away from the
cameras and hides what lies beyond). A true edge stays where it is when the viewpoint moves; an
occluding contour slides over the surface, by about ``R dtheta`` for a rotation ``dtheta`` about
the contour's direction (``R``: the surface's radius of curvature across the contour).

So a measured outline point is *confirmed* (``confirm``) when another pose, whose viewing ray at
that point is turned by at least ``CONFIRM_ANGLE_RAD`` and whose camera lies at least
``CONFIRM_SLIDE_ANGLE_RAD`` out of the first pose's *contour plane* there (and the first's out of
the second's; ``contour_planes``: the plane through the camera and the outline's image tangent, the
surface's tangent plane at an occluding contour), has a measured outline point within
``CONFIRM_TOL_M`` of it. Points are compared as averages along their own outlines
(``smoothed_points``); only row-matched points (``ViewOutline.matched``) confirm or are confirmed,
and both poses must see the edge from the same side of the sheet (``outline_sense``): the plate is
a two-sided sheet, and ground truth counts a back-facing boundary point as hidden.

The verdict (``verify``) asks whether the confirmed pieces of all poses close into one loop, as a
plate's boundary does. Pieces are grouped where one leads on from another's end (``_leads_on``) or
where they run along the same edge (``OVERLAP_POINTS``). A piece bridges unconfirmed stretches up to
``BRIDGE_M`` of its own outline, and an end links along any pose's outline up to
``OUTLINE_BRIDGE_M``, never across a point that pose sees from behind the sheet; a piece shorter
than ``LINK_M`` walks the outlines only away from itself (``_linked``, ``_leaving_step``). A piece
that stops where no other confirmed piece leads on is a *gap*. ``BoundaryVerdict.verified`` is
true when a group is at least ``LOOP_MIN_FRACTION`` of the first pose's outline long (lengths over
5 mm chords), goes round its centroid (no gap over ``LOOP_MAX_ANGLE_GAP_RAD``, seen from the first
pose), no piece anywhere has a loose end, and no other group stands apart.

Real rigs: the loop measures through the commanded poses, registers them on their common edges
(``registration``, ``PoseSpread``) and confirms with ``CONFIRM_SLIDE_ANGLE_RIG_RAD``.

Limits: a contour turned ``CONFIRM_SLIDE_ANGLE_RAD`` (20 degrees) about its own direction slides
``R * 0.35``, less than ``CONFIRM_TOL_M`` when ``R`` is under about 2.9 mm (a crease): such a
contour cannot be told from an edge this way.

World frame, metres, radians. The measurements behind these rules and thresholds:
docs/findings/design-record.md.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property

import cv2
import numpy as np
from scipy.spatial import cKDTree

from platebench.scenes.camera import Camera
from platebench.tolerances import tol

MATCHED_SOURCES = ("row", "side")  # BoundaryStereo sources whose disparity was measured on the row
CONFIRM_TOL_M = 1.0e-3  # two poses' points of a true edge agree within this (row-matched: ~0.3 mm each)
CONFIRM_ANGLE_RAD = float(np.radians(25.0))  # ... when their rays differ by this much
CONFIRM_SLIDE_ANGLE_RAD = float(np.radians(20.0))  # ... of which this much about the edge's own direction
# ... and under a real rig (a ``PoseSpread``), whose registered poses still disagree by about 1 mm: this much,
# below the verification views' 30-degree turns (docs/findings/design-record.md, Real rigs)
CONFIRM_SLIDE_ANGLE_RIG_RAD = float(np.radians(27.0))
SAME_SIDE_MIN_COS = -0.5  # ... and walk it the same way: directions at most 120 degrees apart (corners, noise)
TANGENT_HALF_POINTS = 4  # outline points on either side for the local 3D direction
IMAGE_TANGENT_HALF_POINTS = 5  # outline pixels on either side for the image tangent of a contour plane
SMOOTH_HALF_M = 2.5e-3  # confirm compares row-matched points averaged over this much arc either side
MIN_PIECE_M = 2e-3  # confirmed runs shorter than this are noise, not pieces
BRIDGE_M = 6e-3  # unconfirmed runs this short inside one pose's outline are bridged (corners)
LINK_M = 4e-3  # a piece's end links to another piece within this distance ...
LEAD_M = 12e-3  # ... that leads on: has a point within this of the end, farther than LINK_M from the piece
END_SPAN_M = 8e-3  # a piece's direction out of an end: the chord from its points within this of the end
# or to one reached along some pose's measured outline within this arc length
OUTLINE_BRIDGE_M = 12e-3
# the radius about an end within which a piece is tested again when a walk asks past what was tested
# (``_Leads``): every link sought along a walk of OUTLINE_BRIDGE_M lies within it; a larger one asked
# re-tests that piece
LEAD_BASE_RADIUS_M = LEAD_M + LINK_M + OUTLINE_BRIDGE_M
# a short piece's end walks another pose's outline only the way that leaves the piece: walked this
# much arc, the outline lies farther from the piece than walked the other way, by more than the
# outline stereo's own point error
LEAVE_PROBE_M = LINK_M
LEAVE_MARGIN_M = CONFIRM_TOL_M
LOOP_MIN_FRACTION = 0.7  # a closed group of pieces is the boundary when at least this x the first pose's outline
LOOP_MAX_ANGLE_GAP_RAD = float(np.radians(60.0))  # ... and goes round its centroid (seen from the first pose)
OVERLAP_POINTS = 3  # pieces sharing this many points (within LINK_M) run along the same edge: one group
MERGE_SPACING_M = 1e-3  # the merged boundary keeps one point per this spacing
REPORT_MIN_M = 8e-3  # unconfirmed outline runs at least this long are reported
# On a real rig two poses also disagree rigidly (``PoseSpread``): ``registration`` looks for their
# common edges this many RMS of that disagreement across the edge beside ``CONFIRM_TOL_M`` (a 2-D
# Gaussian offset of RMS e lies within 1.5 e with probability 1 - exp(-1.5^2) = 0.89).
POSE_SPREAD_SIGMAS = 1.5
SPREAD_REPORT_DISTANCE_M = 0.40  # a spread's matching distance is reported here (the paper's working distance)


@dataclass(frozen=True)
class PoseSpread:
    """How far the poses of a real rig disagree about one point, as the rig's own calibration measured
    it: the RMS residuals of the hand/eye calibration's relative motions (``AX = XB``:
    ``reconstruction.calibration.hand_eye.HandEyeResult``), a commanded motion against the motion the
    camera saw. ``translation_m``: RMS length of the translation residual (metres); ``rotation_rad``:
    RMS angle of the rotation residual (radians). None of it is ground truth: a real rig has these
    numbers from its calibration."""

    translation_m: float
    rotation_rad: float

    def __post_init__(self):
        for name in ("translation_m", "rotation_rad"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"PoseSpread.{name} = {v!r}: allowed a finite value >= 0")

    def across_m(self, distance_m) -> np.ndarray:
        """RMS disagreement (metres) of two poses about a point ``distance_m`` (array) from the
        camera, in the two directions across an edge (2/3 of a 3-D offset's mean square): the
        translation and the rotation's lever arm, independent."""
        d = np.asarray(distance_m, float)
        return np.hypot(self.translation_m, d * self.rotation_rad) * np.sqrt(2.0 / 3.0)

    def pose_sigma_m(self, distance_m) -> np.ndarray:
        """RMS per axis (metres) of ONE pose's own error at ``distance_m`` from the camera: the
        residuals are of a pair of poses (sqrt 2 of one) and of a 3-D offset (sqrt 3 of an axis)."""
        d = np.asarray(distance_m, float)
        return np.hypot(self.translation_m, d * self.rotation_rad) / np.sqrt(6.0)

    def match_tol_m(self, distance_m, tol_m: float = CONFIRM_TOL_M) -> np.ndarray:
        """How far apart two unregistered poses may put one edge point ``distance_m`` from the
        camera: the point noise's ``tol_m`` and ``POSE_SPREAD_SIGMAS`` x ``across_m``, added in
        quadrature (``registration``'s candidate matches)."""
        return np.hypot(tol_m, POSE_SPREAD_SIGMAS * self.across_m(distance_m))


@dataclass(frozen=True)
class ViewOutline:
    """One pose's measured outline in the world frame (metres), closed and in outline order.

    ``points``: (N,3); ``matched``: (N,) True where the disparity was measured on the row;
    ``camera_center``: (3,) the pose's mid-baseline point; ``image_points``: (N,2) left-image
    pixels; ``method``: the boundary stereo method (``BoundaryStereo.method``); ``left``: the pose's
    left camera (projects world points into the image of ``image_points``; None when unknown, and
    then no other pose's point can be refuted by this one, ``refutation``)."""

    name: str
    points: np.ndarray
    matched: np.ndarray
    camera_center: np.ndarray
    image_points: np.ndarray
    method: str
    left: Camera | None = None

    @classmethod
    def from_stereo(cls, name: str, stereo, camera_center, left: Camera | None = None) -> "ViewOutline":
        """From a ``BoundaryStereo`` measured at a pose whose mid-baseline point is ``camera_center``
        and whose left camera is ``left``."""
        return cls(name, np.asarray(stereo.points, float), np.isin(stereo.source, MATCHED_SOURCES),
                   np.asarray(camera_center, float), np.asarray(stereo.image_points_left, float), stereo.method,
                   left)

    @property
    def arc_m(self) -> np.ndarray:
        """(N,) length of the segment from each point to the next (closed)."""
        return np.linalg.norm(np.roll(self.points, -1, axis=0) - self.points, axis=1)

    @property
    def length_m(self) -> float:
        return float(self.arc_m.sum())

    def translated(self, shift_m) -> "ViewOutline":
        """The same outline, camera and pose moved rigidly by ``shift_m`` (3,) metres in the world
        (``registration``); its image points are unchanged."""
        s = np.asarray(shift_m, float)
        left = None if self.left is None else replace(self.left, t=self.left.t - self.left.R @ s)
        out = replace(self, points=self.points + s, camera_center=self.camera_center + s, left=left)
        for kept in ("plane_normals", "image_tree", "pixel_tangents"):  # a translation turns no plane, moves no pixel
            if kept in self.__dict__:
                out.__dict__[kept] = self.__dict__[kept]
        return out

    @property
    def eye(self) -> np.ndarray:
        """(3,) the centre of the camera whose image ``image_points`` are (the left one; the
        mid-baseline point when the camera is unknown)."""
        return self.left.center if self.left is not None else self.camera_center

    @cached_property
    def plane_normals(self) -> np.ndarray:
        """(N,3) unit normals of the outline's *contour planes* (``contour_planes``)."""
        return contour_planes(self)

    @cached_property
    def tree(self) -> cKDTree:
        """KD-tree of ``points`` (built once: the loop asks a pose's outline again at every update)."""
        return cKDTree(self.points)

    @cached_property
    def pixel_tangents(self) -> np.ndarray:
        """(N,2) unit tangents of the outline in its left image (``image_tangents`` of
        ``image_points``), computed once."""
        return image_tangents(self.image_points)

    @cached_property
    def image_tree(self) -> cKDTree:
        """KD-tree of ``image_points`` (pixels; built once, as ``tree``)."""
        return cKDTree(self.image_points)


def outline_directions(points: np.ndarray, half: int = TANGENT_HALF_POINTS) -> np.ndarray:
    """(N,3) unit local directions of a closed polyline (central differences over ``half`` points)."""
    P = np.asarray(points, float)
    d = np.roll(P, -half, axis=0) - np.roll(P, half, axis=0)
    n = np.linalg.norm(d, axis=1, keepdims=True)
    return d / np.where(n > 0, n, 1.0)


def outline_sense(view: ViewOutline) -> float:
    """+1 or -1: the sign of the outline's oriented area in its left image's pixels
    (``cv2.contourArea(oriented=True)``). Walked with the orientation that makes it positive, the
    plate's inside is on the same hand in every image of its front side, and on the other hand in
    an image of its back side (a mirror image): at a true edge, two poses that see it from the same
    side walk it the same way in 3D. Only products of two senses are used."""
    uv = np.asarray(view.image_points, np.float32)
    if len(uv) < 3:
        return 1.0
    return 1.0 if cv2.contourArea(uv.reshape(-1, 1, 2), oriented=True) >= 0 else -1.0


def smoothed_points(view: ViewOutline, half_m: float = SMOOTH_HALF_M) -> np.ndarray:
    """(N,3) the outline with each row-matched point replaced by the mean of the row-matched points
    within ``half_m`` of arc length either side of it (cyclic); other points as they are. A
    row-matched point's depth noise is independent from point to point, so the average lowers it,
    while an occluding contour's points slide together and stay where they are."""
    P = np.asarray(view.points, float)
    idx = np.nonzero(view.matched)[0]
    if len(idx) < 3:
        return P.copy()
    s_all = np.concatenate([[0.0], np.cumsum(view.arc_m)])
    length, s = s_all[-1], s_all[idx]
    ss = np.concatenate([s - length, s, s + length])
    cs = np.vstack([np.zeros((1, 3)), np.cumsum(np.vstack([P[idx]] * 3), axis=0)])
    lo = np.searchsorted(ss, s - half_m, "left")
    hi = np.searchsorted(ss, s + half_m, "right")
    out = P.copy()
    out[idx] = (cs[hi] - cs[lo]) / (hi - lo)[:, None]
    return out


def ray_angles(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) angle (rad) between the rays from ``a`` and from ``b`` ((3,) or (N,3) viewpoints) to
    each of ``points`` (N,3)."""
    ra, rb = points - a, points - b
    cos = np.einsum("ij,ij->i", ra, rb) / (np.linalg.norm(ra, axis=1) * np.linalg.norm(rb, axis=1))
    return np.arccos(np.clip(cos, -1.0, 1.0))


def image_tangents(uv: np.ndarray, half: int = IMAGE_TANGENT_HALF_POINTS) -> np.ndarray:
    """(N,2) unit tangents of a closed image polyline (N,2): the principal direction of the
    ``2 half + 1`` points around each, oriented along the polyline."""
    uv = np.asarray(uv, float)
    n = len(uv)
    win = uv[(np.arange(n)[:, None] + np.arange(-half, half + 1)[None]) % n]  # (N, 2h+1, 2)
    win = win - win.mean(axis=1, keepdims=True)
    t = np.linalg.eigh(np.einsum("nki,nkj->nij", win, win))[1][:, :, -1]
    fwd = uv[(np.arange(n) + half) % n] - uv[(np.arange(n) - half) % n]
    return t * np.where(np.einsum("ni,ni->n", t, fwd) < 0, -1.0, 1.0)[:, None]


def contour_planes(view: ViewOutline) -> np.ndarray:
    """(N,3) unit normals of each outline point's *contour plane*: the plane through the camera
    centre (``ViewOutline.eye``) that contains the outline's tangent line in the image.

    Where the outline is an occluding contour, this plane is the surface's tangent plane at the
    point (the viewing ray grazes the surface along the contour's direction); where it is a true
    edge, the plane contains the edge's 3D direction. It is measured in the image alone, to a
    degree or two (the outline's pixels), whereas the 3D direction of a triangulated outline
    carries its depth noise (off by more than a contour's slide angle, so that two poses whose
    contours cross or coincide would pass as "turned about the edge"). Without a camera: the plane
    through the mid-baseline point containing the 3D direction."""
    P = np.asarray(view.points, float)
    if view.left is not None and len(P) >= 3:
        uv = np.asarray(view.image_points, float)
        _, ray = view.left.rays(uv)
        _, ahead = view.left.rays(uv + view.pixel_tangents)  # the tangent line's pixel one step on
        n = np.cross(ray, ahead)
    else:
        n = np.cross(P - view.camera_center, outline_directions(P))
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return n / np.where(norm > 0, norm, 1.0)


def slide_angles(normals: np.ndarray, points: np.ndarray, eyes: np.ndarray) -> np.ndarray:
    """(N,) angle (rad) of the ray from each point (N,3) to ``eyes`` ((3,) or (N,3)) out of the
    contour plane with unit normal ``normals`` (N,3) at that point: the turn that slides an
    occluding contour (by about R times this angle on a surface of radius R across it) and
    leaves a true edge in place."""
    r = np.asarray(eyes, float) - points
    r = r / np.linalg.norm(r, axis=1, keepdims=True)
    return np.arcsin(np.clip(np.abs(np.einsum("ij,ij->i", normals, r)), 0.0, 1.0))


def confirm(views: list[ViewOutline], tol_m: float = CONFIRM_TOL_M, min_angle_rad: float = CONFIRM_ANGLE_RAD,
            min_slide_angle_rad: float = CONFIRM_SLIDE_ANGLE_RAD, same_side: bool = True,
            front: list[np.ndarray] | None = None, front_known: list[np.ndarray] | None = None) -> list[np.ndarray]:
    """Per pose, (N,) bool: the row-matched points that another pose confirms (see module doc).
    A pair confirms a point when their points agree within ``tol_m`` (both averaged,
    ``smoothed_points``), their rays differ by ``min_angle_rad`` and each pose's camera lies
    ``min_slide_angle_rad`` out of the other's contour plane there (``slide_angles``: both ways,
    so neither outline can be a contour the other slid along). ``same_side``: the pair must walk
    the edge the same way (``outline_sense``; off only to show what the rule refuses). ``front``:
    per pose, (N,) False where it sees the point from behind the sheet (``sides``); such points
    neither confirm nor are confirmed. ``front_known``: per pose, (N,) True where it sees the point
    from the plate's front as the measured surface orients it (``sides``: known, not grazing); a
    pair then confirms a point only if one of the two does (where neither knows the front, two
    poses that both see the sheet from behind would agree on its edge)."""
    smooth = [smoothed_points(v) for v in views]
    usable = [v.matched if front is None else v.matched & np.asarray(f, bool)
              for v, f in zip(views, front if front is not None else [None] * len(views))]
    known = None if front_known is None else [np.asarray(f, bool) for f in front_known]
    matched_idx = [np.nonzero(u)[0] for u in usable]
    trees = [cKDTree(S[i]) if len(i) else None for S, i in zip(smooth, matched_idx)]
    sense = [outline_sense(v) for v in views] if same_side else None
    tangents = [outline_directions(v.points) for v in views] if same_side else None
    out = []
    for k, vk in enumerate(views):
        P = smooth[k]
        conf = np.zeros(len(P), bool)
        for j, vj in enumerate(views):
            if j == k or trees[j] is None or trees[k] is None:
                continue
            dist, nn = trees[j].query(P, distance_upper_bound=tol_m * (1 + tol.relative))
            idx = np.nonzero(usable[k] & (dist <= tol_m))[0]
            if not len(idx):
                continue
            jdx = matched_idx[j][nn[idx]]
            walk = (tangents[k], tangents[j], sense[k] * sense[j]) if same_side else None
            ok = edge_pairs(vk, vj, P, smooth[j], idx, jdx, walk, min_angle_rad, min_slide_angle_rad)
            if known is not None:  # one of the pair sees the point from the known front
                ok &= known[k][idx] | known[j][jdx]
            conf[idx[ok]] = True
        out.append(conf)
    return out


def edge_pairs(vk: ViewOutline, vj: ViewOutline, Pk: np.ndarray, Pj: np.ndarray, idx: np.ndarray, jdx: np.ndarray,
               walk: tuple | None = None, min_angle_rad: float = CONFIRM_ANGLE_RAD,
               min_slide_angle_rad: float = CONFIRM_SLIDE_ANGLE_RAD) -> np.ndarray:
    """(M,) bool: of the matched points ``Pk[idx]`` of pose k and ``Pj[jdx]`` of pose j ((N,3) each,
    metres), those a true edge could give and a contour could not (module doc): rays turned by
    ``min_angle_rad``, each camera ``min_slide_angle_rad`` out of the other's contour plane, and with
    ``walk`` = (k's (N,3) outline directions, j's, the product of their ``outline_sense``) both poses
    walking the edge the same way (the same side of the sheet). ``confirm`` and ``registration`` use it."""
    Q = Pk[idx]
    ok = (ray_angles(Q, vk.camera_center, vj.camera_center) >= min_angle_rad) \
        & (slide_angles(vk.plane_normals[idx], Q, vj.eye) >= min_slide_angle_rad) \
        & (slide_angles(vj.plane_normals[jdx], Pj[jdx], vk.eye) >= min_slide_angle_rad)
    if walk is not None:
        tk, tj, senses = walk
        ok &= np.einsum("ij,ij->i", tk[idx], tj[jdx]) * senses >= SAME_SIDE_MIN_COS
    return ok


def cyclic_runs(mask: np.ndarray) -> list[np.ndarray]:
    """Index runs of True in a cyclic boolean array, each in order (one run if all True)."""
    mask = np.asarray(mask, bool)
    n = len(mask)
    if n == 0 or not mask.any():
        return []
    if mask.all():
        return [np.arange(n)]
    start = int(np.argmin(mask))  # begin on a False
    order = (np.arange(n) + start) % n
    m = mask[order]
    out, i = [], 0
    while i < n:
        if m[i]:
            j = i
            while j < n and m[j]:
                j += 1
            out.append(order[i:j])
            i = j
        else:
            i += 1
    return out


@dataclass(frozen=True)
class Piece:
    """A stretch of one pose's outline shown to be a true edge: confirmed points, with unconfirmed
    stretches shorter than ``BRIDGE_M`` between them bridged. ``closed``: the whole outline."""

    view: str
    indices: np.ndarray  # (K,) into that pose's outline, in order
    points: np.ndarray  # (K,3)
    closed: bool = False

    @property
    def length_m(self) -> float:
        P = self.points
        seg = np.linalg.norm(np.diff(P, axis=0), axis=1).sum() if len(P) > 1 else 0.0
        return float(seg + (np.linalg.norm(P[-1] - P[0]) if self.closed else 0.0))


def pieces(views: list[ViewOutline], confirmed: list[np.ndarray],
           behind: list[np.ndarray] | None = None) -> list[Piece]:
    """Confirmed runs of at least ``MIN_PIECE_M``, joined across unconfirmed runs of at most
    ``BRIDGE_M``. A run holding a point the pose sees from behind the sheet (``behind``: per pose,
    (N,) bool; None: none known) is joined only where another pose's outline runs along all of it
    (within ``LINK_M``) inside that pose's own pieces: it saw the stretch from the front."""
    joined, refused = [], []
    for k, (v, c) in enumerate(zip(views, confirmed)):
        arc = v.arc_m
        keep = np.zeros(len(c), bool)
        for r in cyclic_runs(c):
            if arc[r[:-1]].sum() >= MIN_PIECE_M:
                keep[r] = True
        bridged = keep.copy()
        back = np.zeros(len(c), bool) if behind is None else np.asarray(behind[k], bool)
        for r in (cyclic_runs(~keep) if keep.any() else []):
            if arc[np.concatenate([[r[0] - 1], r])].sum() <= BRIDGE_M:
                if back[r].any():
                    refused.append((k, r))
                else:
                    bridged[r] = True
        joined.append(bridged)
    if refused:
        first = [b.copy() for b in joined]
        trees = [v.tree for v in views]
        for k, r in refused:
            Q = views[k].points[r]
            for other, tree in enumerate(trees):
                d, i = tree.query(Q)
                if other != k and (d <= LINK_M).all() and first[other][i].all():
                    joined[k][r] = True
                    break
    return _cut(views, joined)


def _cut(views: list[ViewOutline], joined: list[np.ndarray]) -> list[Piece]:
    """The pieces: each pose's runs of ``joined`` (N,) outline points."""
    return [Piece(v.name, r, v.points[r], closed=bool(j.all())) for v, j in zip(views, joined)
            for r in (cyclic_runs(j) if j.any() else [])]


@dataclass(frozen=True)
class Gap:
    """Where a confirmed piece stops and no other confirmed piece leads on (world frame, metres)."""

    position_m: np.ndarray  # (3,) the last confirmed point
    direction: np.ndarray  # (3,) unit, from the piece into the gap
    view: str  # the pose whose outline the piece belongs to

    @property
    def what(self) -> str:
        """The gap in words: where the piece stops (millimetres, world frame) and from which pose."""
        return (f"boundary not verified beyond ({', '.join(f'{x:.1f}' for x in self.position_m * 1e3)}) "
                f"mm, where the piece seen from {self.view} stops")


@dataclass(frozen=True)
class UnconfirmedRun:
    """A stretch of one pose's outline that no other pose confirmed (an occluding contour, an
    interpolated edge, or an edge seen by one pose only)."""

    view: str
    length_m: float
    start_m: np.ndarray
    end_m: np.ndarray
    covered: bool  # True when confirmed pieces of other poses run along it (within LINK_M)


@dataclass(frozen=True)
class BoundaryVerdict:
    """Whether the confirmed pieces close into one loop (``verified``), and what is missing."""

    verified: bool
    pieces: tuple[Piece, ...]
    gaps: tuple[Gap, ...]
    unconfirmed: tuple[UnconfirmedRun, ...]
    merged: np.ndarray  # (M,3) merged boundary points, one per MERGE_SPACING_M
    components: int
    reason: str
    confirmed: tuple[np.ndarray, ...] = ()  # per pose, (N,) the confirmed outline points (refuted ones removed)
    refuted: tuple[np.ndarray, ...] = ()  # per pose, (N,) the points confirmed by a pair but refuted (``refutation``)

    @property
    def confirmed_length_m(self) -> float:
        return float(sum(p.length_m for p in self.pieces))


def _end_direction(P: np.ndarray, at_start: bool) -> np.ndarray:
    """Unit direction leaving a piece at one end (from its last few millimetres)."""
    Q = P if not at_start else P[::-1]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))])
    k = int(np.searchsorted(s, s[-1] - 3e-3))
    d = Q[-1] - Q[min(k, len(Q) - 2)]
    n = np.linalg.norm(d)
    return d / n if n > 0 else np.zeros(3)


class _PieceIndex:
    """All pieces' points in one KD-tree, to find the pieces near a point in one query."""

    def __init__(self, all_pieces: list[Piece]):
        self.tree = cKDTree(np.vstack([p.points for p in all_pieces]))
        self.label = np.concatenate([np.full(len(p.points), i) for i, p in enumerate(all_pieces)])

    def near(self, x: np.ndarray, radius: float) -> set:
        """The pieces with a point within ``radius`` (m) of ``x`` (3,)."""
        return self.near_each(np.asarray(x, float)[None], radius)[0]

    def near_each(self, X: np.ndarray, radius: float) -> list[set]:
        """``near`` of each point of ``X`` (K,3), in one query."""
        label = self.label
        return [set(label[h].tolist()) for h in self.tree.query_ball_point(X, radius)]


def _outward(points: np.ndarray, end: np.ndarray) -> np.ndarray:
    """(3,) unit direction out of a piece at ``end``: from the mean of its points within
    ``END_SPAN_M`` of the end to the end (a chord over several millimetres; a row-matched piece's
    last points zigzag by a millimetre or more, which turns a direction taken over its last few
    points by tens of degrees). Zero when no other point lies that close."""
    near = points[np.linalg.norm(points - end, axis=1) <= END_SPAN_M]
    d = end - near.mean(axis=0) if len(near) else np.zeros(3)
    n = np.linalg.norm(d)
    return d / n if n > tol.unit_norm else np.zeros(3)


class _Leads:
    """What leads on from one end ``end`` of piece ``own`` (``_leads_on``'s rule), per other piece:
    the distance from the end to that piece's nearest point that leads on. The rule's test of a
    point does not depend on where the link is sought from, only the radius does, so each piece is
    tested once per end (over its points within the largest radius asked so far), not once per
    outline point walked. Whether a piece leads on within a radius is the same answer whatever
    larger radius it was tested within (its nearest leading point within that radius): every piece
    is first tested within LEAD_M, the radius asked from the end itself, and a piece asked past that
    again within ``LEAD_BASE_RADIUS_M`` or the radius asked."""

    def __init__(self, end: np.ndarray, own: int, trees: list, all_pieces: list[Piece], index: _PieceIndex):
        self.end, self.own, self.trees, self.pieces, self.index = end, own, trees, all_pieces, index
        self.outward = _outward(all_pieces[own].points, end)
        self.tested = np.full(len(all_pieces), -1.0)  # (P,) m: the radius each piece was tested within
        self.best = np.full(len(all_pieces), np.inf)  # (P,) m: its nearest point that leads on, within it

    def _leading(self, near: np.ndarray) -> np.ndarray:
        """(K,) bool: which points ``near`` (K,3) lead on from the end (``_leads_on``'s test of a point)."""
        d, k = self.trees[self.own].query(near)
        off_end = np.linalg.norm(self.pieces[self.own].points[k] - self.end, axis=1) <= LINK_M
        ahead = (near - self.end) @ self.outward >= -LINK_M
        return (d > LINK_M) & (off_end | ahead)

    def _test(self, i: int, radius: float) -> None:
        tested = max(radius, LEAD_BASE_RADIUS_M)
        P = self.pieces[i].points
        r = np.linalg.norm(P - self.end, axis=1)
        inside = r <= tested
        near = P[inside]
        best = np.inf
        if len(near):
            lead = r[inside][self._leading(near)]
            best = float(lead.min()) if len(lead) else np.inf
        self.tested[i], self.best[i] = tested, best

    def _test_all(self) -> None:
        """``_test`` of every piece within LEAD_M (the radius asked from the end itself), in one pass
        over the index's points (the same points, the same test of each): done once, before any piece
        is tested alone."""
        X, label = self.index.tree.data, self.index.label
        # the ball's own distance test may differ in the last bits: a ball wider by a relative slack,
        # then the exact test below
        cand = np.asarray(self.index.tree.query_ball_point(self.end, LEAD_M * (1.0 + tol.relative)), int)
        near = X[cand]
        r = np.linalg.norm(near - self.end, axis=1)
        inside = r <= LEAD_M
        near, r, lab = near[inside], r[inside], label[cand[inside]]
        best = np.full(len(self.pieces), np.inf)
        if len(near):
            lead = self._leading(near)
            np.minimum.at(best, lab[lead], r[lead])
        self.tested[:], self.best = LEAD_M, best

    def within(self, pieces: list[int], radius: float) -> list[int]:
        """The ``pieces`` with a point that leads on within ``radius`` (m) of the end, in the order
        given (all pieces at once the first time; then each piece again when asked past the radius
        it was tested within). A few pieces per call, asked once per outline point walked: plain
        Python over them, no arrays built."""
        if pieces and self.tested[0] < 0:
            self._test_all()
        for i in pieces:
            if self.tested[i] < radius:
                self._test(i, radius)
        best = self.best
        return [i for i in pieces if best[i] <= radius]


def _leads_on(candidates, near_to: np.ndarray, leads: _Leads) -> list[int]:
    """The pieces of ``candidates`` (those within LINK_M of ``near_to``), in order, that lead on
    from the end: each has a point within LEAD_M of the end
    (``leads.end``; plus the distance from ``near_to`` to it) that is farther than LINK_M from the
    piece ``leads.own`` the end belongs to, and off *this* end: the nearest point of ``own`` to it
    lies within LINK_M of ``end``, or it lies ahead of the end (at most LINK_M behind it along
    ``_outward``: at a right-angled corner the nearest point of a zigzag piece can lie several
    millimetres back). A piece that runs alongside ``own`` and on past its other end leads on from
    that end, not from this one: its points off ``own`` lie behind this end."""
    radius = LEAD_M + float(np.linalg.norm(near_to - leads.end))
    return leads.within(sorted(candidates), radius)


def _linked(end: np.ndarray, own: int, trees: list, all_pieces: list[Piece], views: list[ViewOutline],
            index: _PieceIndex | None = None, behind: list[np.ndarray] | None = None) -> list[int]:
    """Pieces (other than ``own``) that an end links to: one that passes within LINK_M of the end
    and leads on; else one reached from the end along a pose's measured outline within
    OUTLINE_BRIDGE_M of arc (a steep corner confirmed by no pair of poses, say), and not past a
    point that pose sees from behind the sheet (``behind``, as ``pieces``). The outlines are
    walked both ways from the end of a piece at least 2 LINK_M long (``_leads_on`` tells which
    pieces lie off this end), and only away from the piece from the end of a shorter one (module
    doc, "Short pieces")."""
    index = index or _PieceIndex(all_pieces)
    leads = _Leads(end, own, trees, all_pieces, index)

    def hits(near_to, near=None):
        near = index.near(near_to, LINK_M) if near is None else near
        return _leads_on(near - {own}, near_to, leads)
    out = hits(end)
    if out:
        return out
    piece = all_pieces[own]
    short = piece.length_m <= 2 * LINK_M and not piece.closed
    if short:  # walk away from the piece: its own outline's way on from this end, in each pose's terms
        mine = next(v for v in views if v.name == piece.view)
        at_start = np.linalg.norm(end - piece.points[0]) <= np.linalg.norm(end - piece.points[-1])
        away = (-1 if at_start else 1) * outline_sense(mine)
    for n, v in enumerate(views):
        d = np.linalg.norm(v.points - end, axis=1)
        k = int(np.argmin(d))
        if d[k] > LINK_M:
            continue
        back = None if behind is None else np.asarray(behind[n], bool)
        if short:
            step = int(away * outline_sense(v))
            if v.name != piece.view and _leaving_step(v, k, trees[own]) == -step:
                continue  # the senses say one way, the outline's own points the other: no walk
            steps = (step,)
        else:
            steps = (1, -1)
        for step in steps:
            walk = list(_walk(v, k, step, OUTLINE_BRIDGE_M))
            if back is not None:  # not past a point seen from behind
                walk = walk[:next((w for w, j in enumerate(walk) if back[j]), len(walk))]
            if not walk:
                continue
            # the pieces near every point of the walk in one query, then tested in the walk's order
            for j, near in zip(walk, index.near_each(v.points[walk], LINK_M)):
                hit = hits(v.points[j], near) if near - {own} else []
                if hit:
                    return hit
    return []


def _walk(view: ViewOutline, k: int, step: int, length_m: float):
    """The indices of ``view``'s outline from its point ``k`` (not included) the way ``step`` (+1 or
    -1), while the arc walked before each is at most ``length_m`` (so the first point past it is
    the last); at most once round."""
    arc, n = view.arc_m, len(view.points)
    walked, j = 0.0, k
    for _ in range(n - 1):
        if walked > length_m:
            return
        nxt = (j + step) % n
        walked += arc[j if step > 0 else nxt]
        j = nxt
        yield j


def _leaving_step(view: ViewOutline, k: int, piece_tree: cKDTree) -> int | None:
    """+1 or -1: the index step along ``view``'s outline from its point ``k`` that leaves the piece
    whose points ``piece_tree`` holds: walked ``LEAVE_PROBE_M`` of arc that way, the outline lies at
    least ``LEAVE_MARGIN_M`` farther from the piece than walked the other way. None when neither
    way does (the outline's points do not tell; ``outline_sense`` then decides alone).
    ``outline_sense`` tells the same from the images' orientations, which a curled plate breaks:
    seen from inside and outside the curl, one edge is walked the same way in 3D by outlines of
    opposite senses, and where the points say the other way, the outline is not walked (where they
    do not tell, it is: short pieces' links run through such outlines)."""
    far = {}
    for step in (1, -1):
        j = k
        for j in _walk(view, k, step, LEAVE_PROBE_M):
            pass
        far[step] = float(piece_tree.query(view.points[j])[0])
    if abs(far[1] - far[-1]) < LEAVE_MARGIN_M:
        return None
    return 1 if far[1] > far[-1] else -1


def _merge_points(ps: list[Piece]) -> np.ndarray:
    kept: list[np.ndarray] = []
    tree = None
    for p in sorted(ps, key=lambda q: -q.length_m):
        P = p.points
        if tree is not None:
            P = P[tree.query(P)[0] > MERGE_SPACING_M]
        if len(P):
            # thin along the piece itself
            step = max(1, int(round(MERGE_SPACING_M / max(np.median(np.linalg.norm(np.diff(p.points, axis=0),
                                                                                      axis=1)), tol.zero_length))))
            kept.append(P[::step])
            tree = cKDTree(np.vstack(kept))
    return np.vstack(kept) if kept else np.zeros((0, 3))


def verify(views: list[ViewOutline], model=None, confirmed: list[np.ndarray] | None = None,
           refuted: list[np.ndarray] | None = None, behind: list[np.ndarray] | None = None) -> BoundaryVerdict:
    """Confirm, cut into pieces, link the pieces' ends and decide (see module doc).

    ``refuted``: per pose, (N,) points to count as unconfirmed although a pair confirmed them
    (``refutation.refute``); recorded in ``BoundaryVerdict.refuted``.
    ``behind``: per pose, (N,) True where that pose sees its outline point from behind the sheet
    (``sides``): no piece is bridged, and no outline walked, across such a point.
    ``model`` (a ``surface_model.SurfaceModel``) is accepted for the facing shortcut of ``confirm``
    but not used: the outline membranes cut chords under a bend, so their normals near an
    occluding contour are wrong. Every confirmation needs the turn about the edge's own direction."""
    names = [v.name for v in views]
    if len(set(names)) != len(names):  # pieces, the unconfirmed runs and refutation are keyed by name
        raise ValueError(f"verify: every view needs its own name; repeated: {sorted({n for n in names if names.count(n) > 1})}")
    if confirmed is None:
        confirmed = confirm(views)
    if refuted is not None:
        confirmed = [c & ~r for c, r in zip(confirmed, refuted)]
    return replace(_decide(views, confirmed, behind), refuted=tuple(refuted) if refuted is not None else ())


def _decide(views: list[ViewOutline], confirmed: list[np.ndarray],
            behind: list[np.ndarray] | None = None) -> BoundaryVerdict:
    ps = pieces(views, confirmed, behind)
    if not ps:
        return BoundaryVerdict(False, (), (), _unconfirmed(views, confirmed, []), np.zeros((0, 3)), 0,
                               "no outline point was confirmed by a second pose", tuple(confirmed))
    trees = [cKDTree(p.points) for p in ps]
    index = _PieceIndex(ps)
    parent = list(range(len(ps)))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    gaps, gap_piece = [], []
    for i, p in enumerate(ps):
        if p.closed:
            continue
        for at_start in (True, False):
            end = p.points[0] if at_start else p.points[-1]
            links = _linked(end, i, trees, ps, views, index, behind)
            for j in links:
                parent[find(i)] = find(j)
            if not links:
                gaps.append(Gap(end.copy(), _end_direction(p.points, at_start), p.view))
                gap_piece.append(i)
    for i, p in enumerate(ps):  # pieces of different poses running along the same edge are one group
        near = index.label[np.concatenate([np.asarray(h, int) for h in index.tree.query_ball_point(p.points, LINK_M)])]
        others, counts = np.unique(near[near != i], return_counts=True)
        for j in others[counts >= OVERLAP_POINTS]:
            parent[find(i)] = find(int(j))
    main = [i for i, p in enumerate(ps) if p.length_m >= LINK_M]
    groups: dict = {}
    for i in main:
        groups.setdefault(find(i), []).append(i)
    components = len(groups)
    open_groups = {find(i) for i in gap_piece}
    need = LOOP_MIN_FRACTION * _smooth_length(views[0].points)
    loops = []
    for root, members in groups.items():
        if root in open_groups:
            continue
        pts = _merge_points([p for i, p in enumerate(ps) if find(i) == root])  # short pieces of it too
        if len(pts) * MERGE_SPACING_M >= need and _angular_gap(pts, views[0].camera_center) <= LOOP_MAX_ANGLE_GAP_RAD:
            loops.append((root, members, pts))
    unconf = _unconfirmed(views, confirmed, ps)
    if loops and not gaps and components == 1:
        root, members, merged = loops[0]
        return BoundaryVerdict(True, tuple(ps), (), unconf, merged, components,
                               "the confirmed pieces close into one loop", tuple(confirmed))
    if loops and not gaps:  # two closed groups: a plate has one boundary, so one of them is not it
        reason = (f"the confirmed pieces form {components} separate groups closed on themselves; a plate's "
                  "boundary is one loop")
        return BoundaryVerdict(False, tuple(ps), (), unconf, _merge_points(ps), components, reason,
                               tuple(confirmed))
    if loops:  # a loop, but loose ends elsewhere: part of the boundary may run on from them
        reason = (f"the confirmed pieces close into a loop, but {len(gaps)} piece end(s) elsewhere have no "
                  "confirmed piece leading on")
        return BoundaryVerdict(False, tuple(ps), tuple(gaps), unconf, _merge_points(ps), components, reason,
                               tuple(confirmed))
    merged = _merge_points(ps)
    if gaps:
        reason = f"{len(gaps)} piece end(s) where no confirmed piece leads on"
    elif components != 1:
        reason = f"the confirmed pieces form {components} separate groups, none a loop as long as the outline"
    else:
        reason = "the confirmed pieces close into a loop shorter than the outline"
    return BoundaryVerdict(False, tuple(ps), tuple(gaps), unconf, merged, components, reason, tuple(confirmed))


def _angular_gap(points: np.ndarray, viewpoint: np.ndarray) -> float:
    """Largest gap (rad) between the directions of ``points`` from their centroid, projected on the
    plane across the direction to ``viewpoint``: small for a closed loop around the plate, large
    (a half turn and more) for a stretch of boundary that does not go round."""
    P = np.asarray(points, float)
    c = P.mean(axis=0)
    n = np.asarray(viewpoint, float) - c
    n /= np.linalg.norm(n)
    a = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    a /= np.linalg.norm(a)
    b = np.cross(n, a)
    ang = np.sort(np.arctan2((P - c) @ b, (P - c) @ a))
    return float(np.max(np.diff(np.concatenate([ang, [ang[0] + 2 * np.pi]]))))


def _smooth_length(points: np.ndarray, step_m: float = 5e-3) -> float:
    """Length (m) of a closed outline measured by chords about ``step_m`` long (pixel zigzag and
    depth noise do not add to it, as they do to the point-to-point length)."""
    P = np.asarray(points, float)
    if len(P) < 3:
        return 0.0
    raw = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    k = max(1, int(len(P) * float(np.median(raw)) / step_m))
    Q = P[:: max(1, len(P) // k)]
    return float(np.linalg.norm(np.roll(Q, -1, axis=0) - Q, axis=1).sum())


def _unconfirmed(views: list[ViewOutline], confirmed: list[np.ndarray], ps: list[Piece]) -> tuple:
    """Each pose's unconfirmed outline runs of at least REPORT_MIN_M (not bridged into a piece)."""
    by_view: dict[str, np.ndarray] = {}
    for p in ps:
        m = by_view.setdefault(p.view, np.zeros(0, int))
        by_view[p.view] = np.concatenate([m, p.indices])
    others = {v.name: [p.points for p in ps if p.view != v.name] for v in views}
    out = []
    for v in views:
        inside = np.zeros(len(v.points), bool)
        inside[by_view.get(v.name, np.zeros(0, int))] = True
        arc = v.arc_m
        other = None  # the KD-tree of the other poses' pieces, built when a run first asks
        for r in cyclic_runs(~inside):
            length = float(arc[r[:-1]].sum())
            if length < REPORT_MIN_M:
                continue
            if other is None and others[v.name]:
                other = cKDTree(np.vstack(others[v.name]))
            covered = bool(other is not None and np.mean(other.query(v.points[r])[0] <= LINK_M) > 0.9)
            out.append(UnconfirmedRun(v.name, length, v.points[r[0]].copy(), v.points[r[-1]].copy(), covered))
    return tuple(out)
