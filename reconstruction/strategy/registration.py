"""Registering a real rig's poses on the edges they measured in common (a translation per pose).

On a robot each pose stands where the arm put it, not where it was told, and the loop measures through
the commanded poses: the outlines of two poses then disagree about a true edge by their relative pose
error, a millimetre or two on a PUMA-class arm at 0.4 m, while ``multiview.confirm`` tells an edge from
an occluding contour by agreement within ``CONFIRM_TOL_M`` (1 mm). Widening that distance by the rig's
spread lets contours of radius up to a few millimetres pass as edges. Instead the poses are brought back into one
frame, and confirmation keeps its distance.

The error is close to a translation of the whole outline: a rotation error of a few milliradians
about the camera moves every point of a 0.1 m plate 0.4 m away by nearly the same amount (it
varies by the rotation times the plate's size, 0.3 mm for 3 mrad). So each pose ``v`` gets a
translation ``t_v`` (metres, world frame) that minimises, over pairs of poses and their candidate
matches,

* the distance *across* the edge between a point of one pose and its nearest point of the other
  (``(I - tau tau^T)(P_k + t_k - Q_j - t_j)``, ``tau`` the second outline's unit direction there:
  along an edge a nearest point slides freely), with Huber weights of scale ``HUBER_M``
  (iteratively reweighted least squares), and
* ``|t_v|^2 / sigma^2``, a prior that keeps the translations as small as the rig's spread
  (``PoseSpread.across_m`` at the poses' distance, ``sigma``) and fixes the common shift.

Candidate matches are the pairs ``confirm`` would accept (``multiview.edge_pairs``: rays turned,
cameras out of each other's contour planes, the same side of the sheet) within the spread's distance
(``PoseSpread.match_tol_m``). A contour among them slides by a different amount for every
partner pose, so no single translation of its pose agrees with all of them, and the true edges it
shares with the same partners outweigh it; with the Huber weights a stretch of contour moves a pose
by a fraction of its slide. Matching is redone ``ROUNDS`` times with the translations found. The
normal equations are 3 x (number of poses) square: small and dense.

World frame, metres.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from platebench.reconstruction.strategy.multiview import (
    PoseSpread,
    ViewOutline,
    edge_pairs,
    outline_directions,
    outline_sense,
    smoothed_points,
)
from platebench.tolerances import tol

__all__ = ["register_translations", "PoseShifts", "HUBER_M", "ROUNDS", "IRLS_STEPS", "MATCHES_PER_PAIR"]

HUBER_M = 0.5e-3  # residuals across the edge beyond this are weighted down (Huber scale)
ROUNDS = 3  # matching rounds (each with the translations found so far)
IRLS_STEPS = 6  # reweighting steps per round
MATCHES_PER_PAIR = 80  # candidate matches of a pair kept (evenly spread along the first outline)
MIN_MATCHES = 10  # a pair with fewer candidate matches does not take part


@dataclass(frozen=True)
class PoseShifts:
    """Each pose's registration: ``shifts_m`` maps a view's name to its (3,) translation (metres, world
    frame). File form: view name -> [x, y, z] in millimetres."""

    shifts_m: dict

    def norms_mm(self) -> np.ndarray:
        """(V,) the length of each pose's shift, millimetres."""
        return np.array([np.linalg.norm(s) * 1e3 for s in self.shifts_m.values()])


def _pair_matches(P, Q, Q_idx, tree, vk: ViewOutline, vj: ViewOutline, walk, tol_k, usable_k):
    """Indices (into P, into Q) of the candidate matches of pose k's points ``P`` in pose j's
    usable points ``Q[Q_idx]`` (both translated; ``tree`` holds ``Q[Q_idx]``): within ``tol_k`` and
    passing ``multiview.edge_pairs``, at most ``MATCHES_PER_PAIR`` of them."""
    dist, nn = tree.query(P, distance_upper_bound=float(tol_k.max(initial=0.0)) * (1 + tol.relative))
    idx = np.nonzero(usable_k & (dist <= tol_k))[0]
    if not len(idx):
        return idx, idx
    jdx = Q_idx[nn[idx]]
    ok = edge_pairs(vk, vj, P, Q, idx, jdx, walk)
    idx, jdx = idx[ok], jdx[ok]
    if len(idx) > MATCHES_PER_PAIR:
        keep = np.linspace(0, len(idx) - 1, MATCHES_PER_PAIR).round().astype(int)
        idx, jdx = idx[keep], jdx[keep]
    return idx, jdx


def register_translations(views: list[ViewOutline], spread: PoseSpread, usable: list[np.ndarray] | None = None
                          ) -> np.ndarray:
    """(V, 3) translations (metres) that bring each pose's outline into one frame (module doc).
    ``usable``: per pose, (N,) points that may match (default: the row-matched ones; the loop also
    leaves out points seen from behind the sheet). A pose with no candidate match keeps 0."""
    V = len(views)
    t = np.zeros((V, 3))
    if V < 2:
        return t
    smooth = [smoothed_points(v) for v in views]
    use = [v.matched if usable is None else v.matched & np.asarray(usable[i], bool) for i, v in enumerate(views)]
    tangents = [outline_directions(v.points) for v in views]
    sense = [outline_sense(v) for v in views]
    dists = np.concatenate([np.linalg.norm(S - v.camera_center, axis=1) for S, v in zip(smooth, views)])
    tols = [spread.match_tol_m(np.linalg.norm(S - v.camera_center, axis=1)) for S, v in zip(smooth, views)]
    sigma = max(float(spread.pose_sigma_m(np.median(dists))), tol.zero_length)  # the prior: one pose's error
    for _ in range(ROUNDS):
        shifted = [S + t[v] for v, S in enumerate(smooth)]
        idxs = [np.nonzero(u)[0] for u in use]
        trees = [cKDTree(S[i]) if len(i) else None for S, i in zip(shifted, idxs)]
        pairs = []
        for k in range(V):
            for j in range(k + 1, V):
                if trees[j] is None or not len(idxs[k]):
                    continue
                idx, jdx = _pair_matches(shifted[k], shifted[j], idxs[j], trees[j], views[k], views[j],
                                         (tangents[k], tangents[j], sense[k] * sense[j]), tols[k], use[k])
                if len(idx) < MIN_MATCHES:
                    continue
                tau = tangents[j][jdx]
                Pi = np.eye(3)[None] - tau[:, :, None] * tau[:, None, :]  # (M,3,3) across the edge
                d = smooth[k][idx] - smooth[j][jdx]  # untranslated difference
                pairs.append((k, j, Pi, d))
        if not pairs:
            return t
        for _ in range(IRLS_STEPS):
            A = np.zeros((3 * V, 3 * V))
            b = np.zeros(3 * V)
            for k, j, Pi, d in pairs:
                r = np.einsum("mij,mj->mi", Pi, d + t[k] - t[j])
                n = np.linalg.norm(r, axis=1)
                w = np.where(n <= HUBER_M, 1.0, HUBER_M / np.maximum(n, tol.zero_length))
                S = np.einsum("m,mij->ij", w, Pi)
                s = np.einsum("m,mij,mj->i", w, Pi, d)
                sk, sj = slice(3 * k, 3 * k + 3), slice(3 * j, 3 * j + 3)
                A[sk, sk] += S
                A[sj, sj] += S
                A[sk, sj] -= S
                A[sj, sk] -= S
                b[sk] -= s
                b[sj] += s
            A += np.eye(3 * V) * (HUBER_M / sigma) ** 2  # the prior, in the same units as a full-weight match
            t = np.linalg.solve(A, b).reshape(V, 3)
    return t
