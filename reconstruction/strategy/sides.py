"""Which side of the sheet a pose sees, from the measured surface alone.

The bench's plate is a two-sided sheet of no thickness: seen from behind, its edge shows where the
front view shows it, and two poses that both see it from behind agree on it. Ground truth, like a
plate of real thickness (whose back edge is another curve), counts a boundary point seen only
from behind as hidden. So a confirmation counts only where both poses see the plate's front.

The front is found the way surface reconstruction orients point clouds (Hoppe et al., "Surface
reconstruction from unorganized points", SIGGRAPH 1992): a normal at each measured surface point
from the plane through its nearest neighbours, the normals made to agree along a minimum spanning
tree of the neighbour graph (weighted by how much neighbouring normals disagree), starting from a
seed whose front is known: the plate lies on the table front up, and every deformation the bench
makes keeps the plate's middle level, so the measured point whose normal is nearest the vertical
is front where its normal points up. (A 300-degree curl's tips turn their backs up, at 30 degrees
from the vertical; the middle of the plate, level, wins. The stage-2 sensor is no seed: on such a
curl its centre line passes between the tips, whose backs it sees.) The plate's middle rests on
the table, at the world frame's height 0: the level points within ``SEED_TABLE_M`` of it vote, and
the part that holds most of them is the plate's middle. (A flap folded over the plate is level
too, but faces down, 13 mm or more above the table, and the poses may see more of a fold's
flap than of the plate beneath it: the largest part is not the middle.) The orientation is carried
over the surface, not taken from any one pose: a pose can see the front of one part of a curl and
the back of another.

World frame, metres. Nothing here renders or reads ground truth.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, minimum_spanning_tree
from scipy.spatial import cKDTree

from platebench.tolerances import tol

NEIGHBOURS = 10  # points in each normal's plane fit
JOIN_M = 12e-3  # points this close are neighbours in the spanning tree (the layers of a curl stay apart)
SIDE_CANDIDATES = 8  # nearest surface points tried for a point's side ...
SAME_SHEET_M = 3e-3  # ... the first whose tangent plane passes this close to it
TANGENTIAL_RAD = float(np.radians(30.0))  # neighbours joined only along the sheet (two layers face across)
SEED_VERTICAL_COS = 0.95
# A point whose neighbours fit no plane (the smallest spread of the fit over this share of the
# next) takes no part in the orientation: its neighbours lie on two layers (a fold's flap 13 mm
# above the plate seen past its edge, whose fitted normals come out horizontal and would carry the
# orientation across). The ratio's figures on a fold: docs/findings/design-record.md.
PLANAR_MAX_RATIO = 0.15
TABLE_Z_M = 0.0  # the table's height in the world frame, where the plate's middle rests
# Level points this near the table vote: above the world registration's error (an estimated hand/eye
# transform, ``sense --realism 1995``) and below the height of a flap folded over the plate
# (docs/findings/design-record.md gives both).
SEED_TABLE_M = 5e-3
# A part of the surface not joined to the plate's middle within JOIN_M (one pose's row of squares
# near a steep corner, 18-24 mm from the nearest other centre: the squares between them are cut by
# the outline or stretched apart by the slope) is joined to an oriented part by its best link of at
# most BRIDGE_JOIN_M that lies along both sheets within BRIDGE_TANGENTIAL_RAD: a link across two
# layers runs along their normals (a flap folded over the plate lies 13 mm or more above it, a
# link to it at least 36 mm long to pass 20 degrees). Without the bridge the stage-2 outline beside
# such a row has no known front and no pair can confirm it.
BRIDGE_JOIN_M = 25e-3
BRIDGE_TANGENTIAL_RAD = float(np.radians(20.0))
GRAZING_RAD = float(np.radians(10.0))  # a side is called only this far from grazing
GRAZING_SIN = float(np.sin(GRAZING_RAD))  # normals this near the vertical vote on which way is up
# A point's side is read from the nearest measured surface point this close whose tangent plane passes
# within SAME_SHEET_M of it. At a plate's corner the squares are cut by both edges, so the nearest
# centre may lie well over a grid spacing from the corner's outline. The tangent-plane test, not this reach, bounds the normal's error on a curved sheet (about
# sqrt(2 SAME_SHEET_M / R)) and keeps another layer out (a flap 13 mm over the plate).
SIDE_RADIUS_M = 25e-3
# Where no tangent plane within SIDE_RADIUS_M passes SAME_SHEET_M from a point, its side is read off
# the nearest oriented centre's osculating quadric (``jets``): a curved sheet leaves its tangent plane
# by d^2 / 2R, 5.8 mm at 22 mm from a centre on a 42 mm radius. The quadric z = c + g.t + t^T A t / 2 in the centre's
# tangent frame is fitted to the oriented centres within JET_RADIUS_M whose normals agree with its
# own within JET_AGREE_RAD (another layer faces the other way), at least JET_MIN_POINTS of them, spread
# JET_MIN_SPREAD_M or more each way across the plane (a row of centres fixes no curvature), fitting it
# to JET_MAX_RMS_M (a crease or two layers fit no quadric). A point is on the quadric's sheet when it
# lies within SAME_SHEET_M of it, and read only where the quadric's normal has turned at most
# JET_MAX_TURN_RAD from the centre's (a quadric extrapolated farther than that leaves the sheet).
JET_RADIUS_M = 15e-3
JET_AGREE_RAD = float(np.radians(60.0))
JET_MIN_POINTS = 8
JET_MIN_SPREAD_M = 3e-3
JET_MAX_RMS_M = 0.5e-3  # above the centres' own depth noise (RMS)
JET_MAX_TURN_RAD = float(np.radians(45.0))
# A quadric is read up to JET_REACH_M from its centre (a tangent plane up to SIDE_RADIUS_M): its own
# sheet test and turn limit, not the reach, bound where it holds (the steep ends of a tight curl lie
# farther than SIDE_RADIUS_M from the nearest centre).
JET_REACH_M = 35e-3
SPARSE_GRID_MAX_SQUARES = 24  # a projected grid of at most this many squares is sparse (the paper's: 16; the bench's: 72)
SPARSE_FIT_M = 20e-3  # ``sparse_front_side``: normals fitted over this radius; sides read ...
SPARSE_JOIN_M = 25e-3  # ... centres joined this far apart (a pose's squares lie about 16 mm apart) ...
SPARSE_RADIUS_M = 40e-3  # ... this far from an oriented centre ...
SPARSE_SHEET_M = 6e-3  # ... whose tangent plane passes this close (a boundary triangulated to a few mm)
SPARSE_MAX_TURN_RAD = float(np.radians(30.0))  # sparse centres orient a sheet only if joined normals turn less


@dataclass(frozen=True)
class FrontSide:
    """Measured surface points (S,3) with unit normals (S,3) toward the plate's front; ``known``
    (S,) False where the point's normal could not be oriented (not joined to the seed); the
    distances (metres) within which ``normals_at`` reads a side."""

    points: np.ndarray
    normals: np.ndarray
    known: np.ndarray
    radius_m: float = SIDE_RADIUS_M  # ``normals_at``: how far from a point its side is read
    same_sheet_m: float = SAME_SHEET_M  # ``normals_at``: how close to the point the tangent plane passes
    max_turn_rad: float = 0.0  # the largest angle between the normals of neighbours joined in the oriented part
    fallback: "FrontSide | None" = None  # read where this one knows no side (``normals_at``)
    jets: "Jets | None" = None  # the oriented points' osculating quadrics (``fit_jets``), read past the planes

    def normals_at(self, points: np.ndarray) -> np.ndarray:
        """(N,3) the front's unit normal at ``points`` (N,3): that of the nearest oriented surface
        point within ``radius_m`` whose tangent plane passes within ``same_sheet_m`` of the
        point (on a tight fold the nearest measured point can lie on the other face); where there
        is none, the normal at the point of the osculating quadric (``jets``) of the nearest oriented
        point within ``JET_REACH_M`` whose quadric passes within ``same_sheet_m`` of it (module doc,
        ``JET_RADIUS_M``); where there is none, the ``fallback``'s; NaN where none has one."""
        P = np.atleast_2d(np.asarray(points, float))
        out = self._own_normals_at(P)
        if self.fallback is not None:
            miss = ~np.all(np.isfinite(out), axis=1)
            if miss.any():
                out[miss] = self.fallback.normals_at(P[miss])
        return out

    @cached_property
    def _known_tree(self) -> cKDTree:
        """The KD-tree of the oriented points (built once: ``normals_at`` is asked many times)."""
        return cKDTree(self.points[self.known])

    def _own_normals_at(self, P: np.ndarray) -> np.ndarray:
        out = np.full((len(P), 3), np.nan)
        if not self.known.any() or not len(P):
            return out
        S, N = self.points[self.known], self.normals[self.known]
        k = min(SIDE_CANDIDATES, len(S))
        reach = max(self.radius_m, JET_REACH_M) if self.jets is not None else self.radius_m
        d, i = self._known_tree.query(P, k=k, distance_upper_bound=reach)
        d, i = d.reshape(len(P), k), i.reshape(len(P), k)
        ok = np.isfinite(d)
        ii = np.where(ok, i, 0)
        on_sheet = ok & (d <= self.radius_m) & (
            np.abs(np.einsum("nkj,nkj->nk", N[ii], P[:, None, :] - S[ii])) <= self.same_sheet_m)
        has = on_sheet.any(axis=1)
        out[has] = N[ii[np.arange(len(P)), np.argmax(on_sheet, axis=1)]][has]
        if self.jets is not None and not has.all():
            rest = np.nonzero(~has)[0]
            out[rest] = self.jets.normals_at(P[rest], np.nonzero(self.known)[0][ii[rest]], ok[rest], self.same_sheet_m)
        return out

    def oriented_share(self, points: np.ndarray) -> float:
        """The share of ``points`` (N,3) (a boundary, evenly spaced) where ``normals_at`` knows the
        front; 0.0 for none."""
        P = np.atleast_2d(np.asarray(points, float))
        return float(np.mean(np.all(np.isfinite(self.normals_at(P)), axis=1))) if len(P) else 0.0

    def side(self, points: np.ndarray, eyes: np.ndarray, front_rad: float = GRAZING_RAD,
             normals: np.ndarray | None = None) -> np.ndarray:
        """(N,) +1 where a camera at ``eyes`` ((3,) or (N,3)) sees ``points`` (N,3) from the front,
        at least ``front_rad`` above the sheet, -1 from behind (more than ``GRAZING_RAD``), 0
        unknown (``normals_at``) or in between, near grazing (the normal is read a few millimetres
        away, where a curl has turned by as much). ``normals``: ``normals_at(points)`` when the
        caller has it already (several eyes or angles asked of the same points)."""
        P = np.atleast_2d(np.asarray(points, float))
        n = self.normals_at(P) if normals is None else normals
        r = np.broadcast_to(np.asarray(eyes, float), P.shape) - P
        with np.errstate(invalid="ignore"):
            sin = np.einsum("ij,ij->i", n, r) / np.linalg.norm(r, axis=1)
        out = np.zeros(len(P), int)
        out[sin > np.sin(front_rad)] = 1
        out[sin < -GRAZING_SIN] = -1
        return out


@dataclass(frozen=True)
class Jets:
    """Osculating quadrics of oriented surface points (module doc, ``JET_RADIUS_M``), fitted when
    first asked for (``coef``; a front is read past its tangent planes at few points). ``points``
    (S,3) and their unit ``normals`` (S,3) toward the front; ``known`` (S,) those oriented (only
    they carry or fit a quadric); ``frames`` (S,3,3) rows u, v, n (n the point's normal, u and v
    across it). A quadric is z = c + gu tu + gv tv + (Auu tu^2 + 2 Auv tu tv + Avv tv^2) / 2 in its
    point's frame (metres, about the point)."""

    points: np.ndarray
    normals: np.ndarray
    known: np.ndarray
    frames: np.ndarray
    _coef: np.ndarray  # (S,6) fitted so far, NaN where none fits
    _done: np.ndarray  # (S,) True where a fit was tried

    def coef(self, idx: np.ndarray) -> np.ndarray:
        """(..., 6) the quadrics of the points ``idx`` (any shape of indices), NaN where none fits."""
        idx = np.asarray(idx, int)
        todo = np.unique(idx[~self._done[idx]])
        if len(todo):
            self._fit(todo)
        return self._coef[idx]

    @cached_property
    def _oriented(self) -> tuple[np.ndarray, cKDTree | None]:
        """The oriented points' indices (M,) and their search tree (None for none), built once."""
        oriented = np.nonzero(self.known)[0]
        return oriented, (cKDTree(self.points[oriented]) if len(oriented) else None)

    def _fit(self, todo: np.ndarray) -> None:
        oriented, tree = self._oriented
        P, N = self.points, self.normals
        for i in todo:
            self._done[i] = True
            if tree is None or not self.known[i]:
                continue
            j = oriented[np.asarray(tree.query_ball_point(P[i], JET_RADIUS_M), int)]
            j = j[N[j] @ N[i] >= np.cos(JET_AGREE_RAD)]
            if len(j) < JET_MIN_POINTS:
                continue
            t = (P[j] - P[i]) @ self.frames[i].T
            if np.linalg.eigvalsh(np.cov(t[:, :2].T))[0] < JET_MIN_SPREAD_M ** 2:
                continue
            tu, tv = t[:, 0], t[:, 1]
            A = np.column_stack([np.ones(len(j)), tu, tv, 0.5 * tu ** 2, tu * tv, 0.5 * tv ** 2])
            x, *_ = np.linalg.lstsq(A, t[:, 2], rcond=None)
            if np.sqrt(np.mean((A @ x - t[:, 2]) ** 2)) <= JET_MAX_RMS_M:
                self._coef[i] = x

    def normals_at(self, P: np.ndarray, idx: np.ndarray, ok: np.ndarray, same_sheet_m: float) -> np.ndarray:
        """(N,3) the unit normal at each point of ``P`` (N,3) of the first quadric of its candidate
        points ``idx`` (N,K, nearest first; used where ``ok`` (N,K)) that passes within
        ``same_sheet_m`` of it with its normal turned at most ``JET_MAX_TURN_RAD`` from the
        candidate's; NaN where none does."""
        out = np.full((len(P), 3), np.nan)
        if not len(P):
            return out
        idx = np.where(ok, idx, 0)
        c = self.coef(idx)
        c[~ok] = np.nan
        F = self.frames[idx]  # (N,K,3,3)
        d = np.einsum("nkij,nkj->nki", F, P[:, None, :] - self.points[idx])  # (tu, tv, w) in each frame
        tu, tv, w = d[..., 0], d[..., 1], d[..., 2]
        z = c[..., 0] + c[..., 1] * tu + c[..., 2] * tv + 0.5 * (c[..., 3] * tu ** 2 + 2 * c[..., 4] * tu * tv
                                                               + c[..., 5] * tv ** 2)
        gu = c[..., 1] + c[..., 3] * tu + c[..., 4] * tv
        gv = c[..., 2] + c[..., 4] * tu + c[..., 5] * tv
        with np.errstate(invalid="ignore"):
            good = ok & np.isfinite(z) & (np.abs(w - z) <= same_sheet_m) & (
                1.0 / np.sqrt(1.0 + gu ** 2 + gv ** 2) >= np.cos(JET_MAX_TURN_RAD))
        has = good.any(axis=1)
        if has.any():
            r = np.nonzero(has)[0]
            k = np.argmax(good, axis=1)[has]
            local = np.column_stack([-gu[r, k], -gv[r, k], np.ones(len(r))])
            n = np.einsum("ni,nij->nj", local, F[r, k])
            out[r] = n / np.linalg.norm(n, axis=1, keepdims=True)
        return out


def fit_jets(points: np.ndarray, normals: np.ndarray, known: np.ndarray) -> Jets:
    """The osculating quadrics (``Jets``, fitted when asked for) of the surface ``points`` (S,3)
    whose unit ``normals`` (S,3) are oriented toward the front where ``known`` (S,)."""
    P, N = np.asarray(points, float), np.asarray(normals, float)
    S = len(P)
    helper = np.where(np.abs(N[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    u = np.cross(N, helper)
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), tol.unit_norm)
    frames = np.stack([u, np.cross(N, u), N], axis=1)
    return Jets(P, N, np.asarray(known, bool).copy(), frames, np.full((S, 6), np.nan), np.zeros(S, bool))


def front_side(points: np.ndarray, up=(0.0, 0.0, 1.0), join_m: float = JOIN_M, radius_m: float = SIDE_RADIUS_M,
               same_sheet_m: float = SAME_SHEET_M, fit_radius_m: float | None = None) -> FrontSide:
    """Orient the normals of the measured surface ``points`` (S,3) toward the plate's front (module
    doc). Each connected part (points within ``join_m`` of one another, normals fitted to the
    ``NEIGHBOURS`` nearest or, given ``fit_radius_m``, to all within it) is made consistent from
    its point whose normal is nearest ``up`` (the table's normal, world +Z); in the part that holds
    the plate's middle (the most points within ``SEED_VERTICAL_COS`` of the vertical and
    ``SEED_TABLE_M`` of the table, module doc; the largest part where none is), those points vote
    which way is up (the level middle against the few that a neighbourhood straddling a curl's
    opening makes level; where none lies on the table, every level point of the largest part). The
    other parts stay unknown unless a link along the sheet joins them (``BRIDGE_JOIN_M``): a flap
    folded over the plate is level too, but faces down."""
    P = np.asarray(points, float)
    S = len(P)
    if S < NEIGHBOURS:
        return FrontSide(P, np.zeros((S, 3)), np.zeros(S, bool), radius_m, same_sheet_m)
    kd = cKDTree(P)
    _, nn = kd.query(P, k=min(NEIGHBOURS, S))
    W = P[nn] - P[nn].mean(axis=1, keepdims=True)
    cov = np.einsum("ski,skj->sij", W, W)
    if fit_radius_m is not None:  # sparse, clustered points: every neighbour within the radius (at least NEIGHBOURS)
        for i, near in enumerate(kd.query_ball_point(P, fit_radius_m)):
            if len(near) > NEIGHBOURS:
                Q = P[near] - P[near].mean(axis=0)
                cov[i] = Q.T @ Q
    lam, vec = np.linalg.eigh(cov)
    normals = vec[:, :, 0]
    # the sparse fit (over fit_radius_m) spans bends by design: its crease check reads the turn across them
    planar = lam[:, 0] <= PLANAR_MAX_RATIO * lam[:, 1] if fit_radius_m is None else np.ones(S, bool)
    pairs = kd.query_pairs(join_m, output_type="ndarray")
    known = np.zeros(S, bool)
    if not len(pairs):
        return FrontSide(P, normals, known, radius_m, same_sheet_m)
    rows, cols = pairs[:, 0], pairs[:, 1]
    off = P[cols] - P[rows]
    length = np.linalg.norm(off, axis=1)
    rows, cols, off = rows[length > 0], cols[length > 0], off[length > 0] / length[length > 0, None]  # no repeats
    along = np.maximum(np.abs(np.einsum("ij,ij->i", normals[rows], off)),
                       np.abs(np.einsum("ij,ij->i", normals[cols], off)))
    keep = (along <= np.sin(TANGENTIAL_RAD)) & planar[rows] & planar[cols]  # one sheet: along it, not across
    rows, cols = rows[keep], cols[keep]
    w = 1.0 - np.abs(np.einsum("ij,ij->i", normals[rows], normals[cols])) + tol.unit_norm
    sym = minimum_spanning_tree(coo_matrix((w, (rows, cols)), shape=(S, S)))
    sym = sym + sym.T
    u = np.asarray(up, float)
    todo = np.ones(S, bool)
    parts = []
    while todo.any():  # each connected part of the surface, from its most level point
        seed = int(np.nonzero(todo)[0][np.argmax(np.abs(normals[todo] @ u))])
        order, pred = breadth_first_order(sym, seed, directed=False, return_predecessors=True)
        for i in order[1:]:
            if normals[i] @ normals[pred[i]] < 0:
                normals[i] = -normals[i]
        todo[order] = False
        parts.append((order, pred))
    is_level = np.abs(normals @ u) >= SEED_VERTICAL_COS
    on_table = is_level & (np.abs(P @ u - TABLE_Z_M) <= SEED_TABLE_M)
    # the plate's middle: the part with most level points on the table (else the largest); they vote which way is up
    main, pred = max(parts, key=lambda p: (int(on_table[p[0]].sum()), len(p[0])))
    level = main[on_table[main] if on_table[main].any() else is_level[main]]
    turn = 0.0
    if len(main) >= NEIGHBOURS and len(level):
        if np.sum(np.sign(normals[level] @ u)) < 0:
            normals[main] = -normals[main]
        known[main] = True
        child = main[1:]  # each joined to its predecessor in the spanning tree
        turn = float(np.arccos(np.clip(np.einsum("ij,ij->i", normals[child], normals[pred[child]]), -1.0, 1.0)).max(
            initial=0.0))
        turn = max(turn, _bridge_parts(P, normals, known, [p[0][planar[p[0]]] for p in parts if p[0] is not main],
                                       kd, join_m, planar))
    jets = fit_jets(P, normals, known) if fit_radius_m is None else None  # the sparse fit spans bends: no quadric
    return FrontSide(P, normals, known, radius_m, same_sheet_m, turn, jets=jets)


def _bridge_parts(P: np.ndarray, normals: np.ndarray, known: np.ndarray, others: list[np.ndarray], kd: cKDTree,
                  join_m: float, planar: np.ndarray) -> float:
    """Join the parts ``others`` (index arrays of their points that fit a plane, ``planar``; each
    part oriented within itself) to the oriented points that fit a plane (``known``, updated in
    place with ``normals``) by their best link of at most
    ``max(BRIDGE_JOIN_M, join_m)`` lying along both sheets within ``BRIDGE_TANGENTIAL_RAD``
    (``BRIDGE_JOIN_M``); repeated while a part joins. Returns the largest turn between the
    normals of a link used (radians; 0.0 for none)."""
    reach = max(BRIDGE_JOIN_M, join_m)
    turn = 0.0
    todo = [o for o in others if len(o)]
    while todo:
        best = None
        for k, part in enumerate(todo):
            for i, near in zip(part, kd.query_ball_point(P[part], reach)):
                j = np.asarray(near, int)
                j = j[known[j] & planar[j]]
                if not len(j):
                    continue
                off = P[j] - P[i]
                length = np.linalg.norm(off, axis=1)
                j, off = j[length > 0], off[length > 0] / length[length > 0, None]
                along = np.maximum(np.abs(off @ normals[i]), np.abs(np.einsum("ij,ij->i", normals[j], off)))
                ok = along <= np.sin(BRIDGE_TANGENTIAL_RAD)
                if not ok.any():
                    continue
                agree = np.abs(normals[j[ok]] @ normals[i])
                m = int(np.argmax(agree))
                if best is None or agree[m] > best[0]:
                    best = (float(agree[m]), k, i, int(j[ok][m]))
        if best is None:
            break
        _, k, i, j = best
        part = todo.pop(k)
        if normals[i] @ normals[j] < 0:
            normals[part] = -normals[part]
        known[part] = True
        turn = max(turn, float(np.arccos(np.clip(best[0], -1.0, 1.0))))
    return turn


def sparse_front_side(points: np.ndarray, up=(0.0, 0.0, 1.0)) -> FrontSide:
    """``front_side`` for square centres too sparse for its fixed distances (the paper's 4x4 grid:
    16 squares about 16 mm apart from each pose, the poses' centres clustered and ending up to
    15 mm inside the plate's edges): each normal fitted to every centre within ``SPARSE_FIT_M``
    (ten nearest neighbours from a cluster give a plane of noise), centres joined within
    ``SPARSE_JOIN_M``, and a side read within
    ``SPARSE_RADIUS_M`` of a centre whose tangent plane passes within ``SPARSE_SHEET_M``."""
    return front_side(points, up, join_m=SPARSE_JOIN_M, radius_m=SPARSE_RADIUS_M, same_sheet_m=SPARSE_SHEET_M,
                      fit_radius_m=SPARSE_FIT_M)


__all__ = ["FrontSide", "Jets", "fit_jets", "front_side", "NEIGHBOURS", "JOIN_M", "SIDE_RADIUS_M", "SEED_VERTICAL_COS",
           "SPARSE_GRID_MAX_SQUARES", "SPARSE_MAX_TURN_RAD",
           "sparse_front_side"]
