"""Metrics for sparse 3D points (the paper's square centres, grid corners, ...).

Conventions (docs/architecture.md): metres in, millimetres out; world frame +Z up;
camera frame OpenCV (x right, y down, z forward) with x_cam = R x_world + t.

Point errors are split in the LEFT camera's frame, as the paper reports them
(depth error within 2 mm, x/y error within 1 mm):

    e       = estimated - truth                    (world frame, metres)
    e_cam   = R_left @ e                           (only the rotation matters)
    depth   = |e_cam_z|   error along the left optical axis (z-depth error)
    x, y    = |e_cam_x|, |e_cam_y|                 lateral errors in the image axes
    xy_radial = sqrt(e_cam_x^2 + e_cam_y^2)        lateral error norm (radial, in the image plane)
    err3d   = |e|                                  full 3D error norm

Each gets mean / RMS / max / p95 of the ABSOLUTE value. The per-axis x/y figures
(``x_*``, ``y_*``) and the radial one (``xy_radial_*``) are different numbers: for
equal independent axis errors the radial RMS is sqrt(2) times the per-axis RMS. Signed means are
reported separately (``*_mean_signed_mm``); a positive depth bias means the
estimate lies farther from the left camera than the truth.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable

import numpy as np

from platebench.tolerances import is_rotation, tol

from .stats import ErrorStats, check_array

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

__all__ = [
    "PointScore",
    "MatchScore",
    "score_points",
    "point_to_surface_distance",
    "match_stats",
]


# --------------------------------------------------------------------------- points


@dataclass(frozen=True)
class PointScore:
    """Per-axis error statistics of N 3D points (values in metres; the JSON form,
    ``bench.io.codecs.evaluation``, in mm)."""

    depth: ErrorStats
    x: ErrorStats
    y: ErrorStats
    xy_radial: ErrorStats
    err3d: ErrorStats
    depth_bias_signed: float
    x_bias_signed: float
    y_bias_signed: float
    count: int
    # per-point error vectors in the left camera frame, (N, 3) metres, read-only
    errors_cam: np.ndarray = field(repr=False, compare=False)


def _check_rotation(R, name: str = "R_left") -> np.ndarray:
    R = check_array(R, name, shape=(3, 3))
    if not is_rotation(R):
        raise ValueError(
            f"{name}: not a proper rotation matrix (R R^T != I or det <= 0); pass the "
            "world-to-camera rotation R of x_cam = R x_world + t, not K or [R|t]"
        )
    return R


def score_points(estimated, truth, R_left) -> PointScore:
    """Score N estimated 3D points against their true positions (rows correspond).

    Args:
        estimated: (N, 3) world coordinates in metres, finite.
        truth: (N, 3) world coordinates in metres, finite.
        R_left: (3, 3) rotation of the left camera, x_cam = R_left x_world + t.

    Missing detections must be removed by the caller (and counted with
    :func:`match_stats`); NaN is rejected here.
    """
    est = check_array(estimated, "estimated", shape=(None, 3))
    tru = check_array(truth, "truth", shape=(None, 3))
    if est.shape != tru.shape:
        raise ValueError(f"estimated/truth: shape mismatch {est.shape} vs {tru.shape}")
    R = _check_rotation(R_left)
    e = est - tru
    e_cam = e @ R.T  # rows: R @ e_i
    ex, ey, ez = e_cam[:, 0], e_cam[:, 1], e_cam[:, 2]
    e_cam = np.array(e_cam)
    e_cam.setflags(write=False)
    return PointScore(
        depth=ErrorStats.from_abs(np.abs(ez), name="depth error"),
        x=ErrorStats.from_abs(np.abs(ex), name="x error"),
        y=ErrorStats.from_abs(np.abs(ey), name="y error"),
        xy_radial=ErrorStats.from_abs(np.hypot(ex, ey), name="xy radial error"),
        err3d=ErrorStats.from_abs(np.linalg.norm(e, axis=1), name="3D error"),
        depth_bias_signed=float(ez.mean()),
        x_bias_signed=float(ex.mean()),
        y_bias_signed=float(ey.mean()),
        count=int(len(e)),
        errors_cam=e_cam,
    )


# ------------------------------------------------------------ exact nearest search


RADIUS_CLASS_RATIO = 2.0  # primitives are searched in classes whose radii differ by at most this factor
RADIUS_CLASSES_MAX = 12  # ... and at most this many classes (radii below max / 2^12 share the first)


def radius_classes(radii: np.ndarray) -> list[np.ndarray]:
    """Indices of the primitives grouped by bounding radius, smallest first: class k holds the radii
    in [r0 2^k, r0 2^(k+1)) (``RADIUS_CLASS_RATIO`` = 2), r0 = max(smallest radius, largest / 2^12).
    One class when the radii are within a factor 2 (a uniform mesh)."""
    r = np.asarray(radii, dtype=np.float64)
    r_max = float(r.max()) if len(r) else 0.0
    if r_max <= 0.0:
        return [np.arange(len(r))]
    r0 = max(float(r.min()), r_max * RADIUS_CLASS_RATIO ** -RADIUS_CLASSES_MAX)
    k = np.floor(np.log(np.maximum(r, r0) / r0) / np.log(RADIUS_CLASS_RATIO)).astype(int)
    return [np.nonzero(k == c)[0] for c in np.unique(k)]


def pruned_min_distance(
    points: np.ndarray,
    centers: np.ndarray,
    radii,
    exact: Callable[[np.ndarray, np.ndarray], np.ndarray],
    *,
    k: int = 8,
    chunk_pairs: int = 1 << 20,
    tree: cKDTree | None = None,
    lower: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
    by_radius: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """Exact distance from each point to the nearest of M primitives (segments, triangles).

    Primitive j must lie inside the ball of radius ``radii[j]`` (a scalar for all)
    around ``centers[j]`` (a segment's midpoint and half length, a triangle's
    centroid and its largest centroid-vertex distance). ``exact(P, J)`` returns
    the exact distances from points P (K, D) to primitives J (K,).

    For each point, the ``k`` primitives with the nearest centres give a first bound, the best
    exact distance among them; the answer is final once the k-th centre is so far that
    |p - c_k| - max(r) >= best (no other primitive can be closer). Otherwise every primitive whose
    centre lies within best + max(r) is a candidate (one ball query). A candidate is evaluated
    only if its lower bound |p - c_j| - r_j (and ``lower``'s, when given) is below the best distance
    found so far. The result is exact, not an approximation: bit for bit the smallest ``exact``
    over all primitives (the bounds are compared with a relative slack of ``tol.relative``, so a
    primitive that wins by one ulp is not pruned by a bound computed by another formula). Ties go
    to the nearer centre. Returns (distance, index of the nearest primitive).

    Primitives of very different sizes (a mesh refined only where it bends: the study's dents have
    triangles of 0.15 mm and 17 mm) are searched class by class (``radius_classes``), smallest
    first, each class with its own largest radius in the bound and the best distance so far
    carried over: one bound with the largest radius of all lists every centre within 17 mm of the
    point. The minimum over classes is the minimum over all.
    ``by_radius=False``: one class whatever the radii (the earlier search; ``perf score``'s baseline).
    ``tree``: a prebuilt ``cKDTree(centers)`` to reuse (used when there is one class). ``lower(P, J)``: an
    optional cheap lower bound of ``exact(P, J)`` (e.g. the distance to the
    primitive's bounding box) that skips more exact evaluations.
    """
    from scipy.spatial import cKDTree  # noqa: PLC0415  (scipy.spatial takes a while to import)

    P = np.asarray(points, dtype=np.float64)
    centers = np.asarray(centers, dtype=np.float64)
    r = np.broadcast_to(np.asarray(radii, dtype=np.float64), (len(centers),))
    best = np.full(len(P), np.inf)
    best_j = np.full(len(P), -1, dtype=np.int64)
    classes = radius_classes(r) if by_radius else [np.arange(len(centers))]
    if len(classes) == 1:
        _pruned_search(P, centers, r, exact, lower, k, chunk_pairs, tree if tree is not None else cKDTree(centers),
                       best, best_j)
        return best, best_j
    for ids in classes:
        found = np.full(len(P), -1, dtype=np.int64)
        _pruned_search(P, centers[ids], r[ids], lambda Q, J, ids=ids: exact(Q, ids[J]),
                       None if lower is None else (lambda Q, J, ids=ids: lower(Q, ids[J])),
                       k, chunk_pairs, cKDTree(centers[ids]), best, found)
        hit = found >= 0
        best_j[hit] = ids[found[hit]]
    return best, best_j


def _pruned_search(P, centers, r, exact, lower, k, chunk_pairs, tree, best, best_j) -> None:
    """``pruned_min_distance`` over one class of primitives: lowers ``best`` (N,) in place where a
    primitive of the class is nearer, and sets ``best_j`` there (indices into ``centers``).

    Two passes. The ``k`` nearest centres give each point an upper bound (the best exact
    distance among them). A point is final when its k-th centre lies at least
    ``max(r)`` beyond that bound; for the others, every primitive that can be nearer has its centre
    within bound + ``max(r)`` (|p - c_j| - r_j <= distance), and one ball query per point
    (``cKDTree.query_ball_point``) lists exactly those, however many: no k to grow, and no sorted
    k-nearest list of thousands of centres when the point lies centimetres off a fine mesh (the
    inside of a curl is nearly equidistant from much of it). Among equal distances the primitive
    with the nearer centre wins, as in the k-nearest order."""
    n, m = len(P), len(centers)
    r_max = float(r.max())
    # the pruning compares bounds computed by other formulas than the exact distance (the tree's
    # distances, a bounding box's): a relative slack keeps a primitive that ties to the last bit
    bound = best * (1.0 + tol.relative)

    def candidates(rows, J, dc):
        """The (row, primitive, centre distance) triples that can still beat ``best``."""
        lb = dc - r[J]
        keep = lb < bound[rows]
        if lower is not None and keep.any():
            idx = np.nonzero(keep)[0]
            keep[idx] = np.maximum(lb[idx], lower(P[rows[idx]], J[idx])) < bound[rows[idx]]
        return rows[keep], J[keep], dc[keep]

    def lower_best(rows, J, dc):
        """Lower ``best``/``best_j`` of the points ``rows`` to their nearest primitive among ``J``
        (strictly nearer only; ties go to the nearer centre)."""
        if rows.size == 0:
            return
        d = exact(P[rows], J)
        order = np.lexsort((dc, d, rows))
        rows, J, d = rows[order], J[order], d[order]
        first = np.ones(rows.size, dtype=bool)
        first[1:] = rows[1:] != rows[:-1]
        rows, J, d = rows[first], J[first], d[first]
        better = d < best[rows]
        best[rows[better]] = d[better]
        best_j[rows[better]] = J[better]
        bound[rows[better]] = d[better] * (1.0 + tol.relative)

    k = min(int(k), m)
    todo = []
    for chunk in np.array_split(np.arange(n), max(1, math.ceil(n * k / chunk_pairs))):
        D, J = tree.query(P[chunk], k=k, workers=-1)
        D, J = D.reshape(len(chunk), k), J.reshape(len(chunk), k)
        rows = np.repeat(chunk, k)
        lower_best(*candidates(rows, J.ravel(), D.ravel()))
        if k < m:
            todo.append(chunk[D[:, -1] - r_max < bound[chunk]])
    todo = np.concatenate(todo) if todo else np.empty(0, dtype=np.int64)
    if todo.size == 0:
        return
    # every centre within the bound + max(r) (a relative slack: the tree's distances are rounded)
    radius = (bound[todo] + r_max) * (1.0 + tol.relative)
    counts = tree.query_ball_point(P[todo], radius, return_length=True, workers=-1)
    ends = np.cumsum(counts)
    start = 0
    while start < todo.size:
        stop = max(start + 1, int(np.searchsorted(ends, ends[start] - counts[start] + chunk_pairs, "right")))
        chunk = todo[start:stop]
        lists = tree.query_ball_point(P[chunk], radius[start:stop], workers=-1)
        J = np.fromiter(itertools.chain.from_iterable(lists), dtype=np.int64, count=int(counts[start:stop].sum()))
        rows = np.repeat(chunk, counts[start:stop])
        diff = P[rows] - centers[J]
        lower_best(*candidates(rows, J, np.sqrt(np.einsum("ij,ij->i", diff, diff))))
        start = stop


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[:, 0] * v[:, 0] + u[:, 1] * v[:, 1] + u[:, 2] * v[:, 2]


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.stack(
        [
            u[:, 1] * v[:, 2] - u[:, 2] * v[:, 1],
            u[:, 2] * v[:, 0] - u[:, 0] * v[:, 2],
            u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0],
        ],
        axis=1,
    )


def _seg_closest(ap: np.ndarray, ab: np.ndarray) -> np.ndarray:
    """Offset from a to the point of segment [a, a + ab] closest to a + ap."""
    den = _dot(ab, ab)
    t = np.clip(_dot(ap, ab) / np.where(den > 0, den, 1.0), 0.0, 1.0)
    return t[:, None] * ab


def _seg_dist2(ap: np.ndarray, ab: np.ndarray) -> np.ndarray:
    q = ap - _seg_closest(ap, ab)
    return _dot(q, q)


def _triangle_setup(P, a, b, c):
    ab, ac, ap = b - a, c - a, P - a
    nrm = _cross(ab, ac)
    nn = _dot(nrm, nrm)
    ok = nn > 0
    inv = np.where(ok, 1.0 / np.where(ok, nn, 1.0), 0.0)
    s = _dot(_cross(ap, ac), nrm) * inv
    t = _dot(_cross(ab, ap), nrm) * inv
    inside = ok & (s >= 0) & (t >= 0) & (s + t <= 1)
    h = _dot(ap, nrm)
    return ab, ac, ap, nrm, inv, inside, h


def point_triangle_distance(P: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Exact distance from points P (K, 3) to triangles (a, b, c) (each (K, 3)), row by row.

    Projection inside the triangle: distance to its plane; otherwise the nearest
    of its three edges. Degenerate (zero-area) triangles reduce to their edges.
    Scale-free (no absolute tolerances), unlike ``trimesh.triangles.closest_point``,
    which mishandles millimetre-sized triangles given in metres.
    """
    ab, ac, ap, nrm, inv, inside, h = _triangle_setup(P, a, b, c)
    d2 = np.where(inside, h * h * inv, 0.0)
    out = ~inside
    if out.any():
        apo, abo, aco = ap[out], ab[out], ac[out]
        d2[out] = np.minimum(
            np.minimum(_seg_dist2(apo, abo), _seg_dist2(apo, aco)),
            _seg_dist2(apo - abo, aco - abo),
        )
    return np.sqrt(d2)


def closest_point_on_triangle(P: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Closest point (K, 3) of triangle (a, b, c) to each point P, row by row (see
    :func:`point_triangle_distance`)."""
    ab, ac, ap, nrm, inv, inside, h = _triangle_setup(P, a, b, c)
    Q = P - (h * inv)[:, None] * nrm
    out = ~inside
    if out.any():
        apo, abo, aco, ao = ap[out], ab[out], ac[out], a[out]
        cands = np.stack(
            [
                ao + _seg_closest(apo, abo),
                ao + _seg_closest(apo, aco),
                ao + abo + _seg_closest(apo - abo, aco - abo),
            ]
        )  # (3, K', 3)
        d2 = ((cands - P[out][None]) ** 2).sum(axis=2)
        Q[out] = cands[np.argmin(d2, axis=0), np.arange(len(ao))]
    return Q


def _mesh_arrays(mesh, name: str = "mesh") -> np.ndarray:
    try:
        tri = np.asarray(mesh.triangles, dtype=np.float64)
    except AttributeError:
        raise ValueError(f"{name}: expected a trimesh.Trimesh, got {type(mesh).__name__}") from None
    if tri.ndim != 3 or tri.shape[0] == 0:
        raise ValueError(f"{name}: mesh has no faces")
    if not np.all(np.isfinite(tri)):
        raise ValueError(f"{name}: mesh has non-finite vertices")
    return tri


def closest_point_on_mesh(points, mesh, by_radius: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Exact closest point on ``mesh`` for each point: (closest (N,3), distance (N,), face index (N,)).

    Exact point-to-triangle distances (:func:`point_triangle_distance`) with a
    KD-tree over triangle centroids and a rigorous pruning bound
    (:func:`pruned_min_distance`). Not ``trimesh.proximity.closest_point``: its
    per-triangle test uses absolute tolerances (trimesh's ``tol.zero``, 1e-12 on squared
    lengths) that misclassify millimetre-sized triangles in metres, so that it returns
    distances too large on a plate mesh in metres (docs/findings/design-record.md).
    """
    P = check_array(points, "points", shape=(None, 3))
    tri = _mesh_arrays(mesh)
    a, b, c = (np.ascontiguousarray(tri[:, i]) for i in range(3))
    centroids = tri.mean(axis=1)
    radii = np.linalg.norm(tri - centroids[:, None, :], axis=2).max(axis=1)

    lo, hi = tri.min(axis=1), tri.max(axis=1)

    def exact(Q, J):
        return point_triangle_distance(Q, a[J], b[J], c[J])

    def box_distance(Q, J):  # distance to the triangle's axis-aligned bounding box
        g = np.maximum(np.maximum(lo[J] - Q, Q - hi[J]), 0.0)
        return np.sqrt(_dot(g, g))

    dist, face = pruned_min_distance(P, centroids, radii, exact, lower=box_distance, by_radius=by_radius)
    closest = closest_point_on_triangle(P, a[face], b[face], c[face])
    return closest, dist, face


def point_to_surface_distance(points, mesh) -> np.ndarray:
    """Absolute (unsigned) distance in metres from each point (N, 3) to the surface of ``mesh``.

    Exact point-to-triangle distance (see :func:`closest_point_on_mesh`, which
    explains why this does not call ``trimesh.proximity.closest_point``). NaN
    points are rejected.
    """
    return closest_point_on_mesh(points, mesh)[1]


# ----------------------------------------------------------------------- matching


@dataclass(frozen=True)
class MatchScore:
    """Feature detection and left-right correspondence counts.

    Definitions (ids are ints or (row, col) feature ids):
      expected  - features that should be measured (e.g. the 16 projected squares
                  inside the plate);
      visible   - expected features that the ground truth says both cameras see;
      reported  - one entry per point/pair the method returned, identified by the
                  ground-truth id of its LEFT-image feature;
      correct   - reported pairs whose right-image feature has the same GT id.

      correct_match_rate  = correct / reported   (precision of the correspondences;
                            NaN when nothing was reported)
      detection_rate      = |unique reported ids in visible| / |visible|  (recall)
      correct_visible_rate = |visible ids with at least one correct pair| / |visible|
                            (end-to-end: visible features measured correctly)
    """

    expected: int
    visible: int
    reported: int
    duplicate: int
    detected_visible: int
    detected_not_visible: int
    missed: int
    correct: int
    wrong: int
    correct_match_rate: float
    detection_rate: float
    correct_visible_rate: float


def _id_list(ids, name: str) -> list:
    arr = np.asarray(ids)
    if arr.size == 0:
        return []
    if arr.ndim == 1:
        if not np.issubdtype(arr.dtype, np.integer):
            raise ValueError(f"{name}: feature ids must be integers, got dtype {arr.dtype}")
        return [int(v) for v in arr]
    if arr.ndim == 2:
        if not np.issubdtype(arr.dtype, np.integer):
            raise ValueError(f"{name}: feature ids must be integers, got dtype {arr.dtype}")
        return [tuple(int(v) for v in row) for row in arr]
    raise ValueError(f"{name}: expected ids of shape (N,) or (N, 2), got {arr.shape}")


def match_stats(detected_ids, expected_ids, visible_ids, matched_pairs_correct) -> MatchScore:
    """Count detections and correct correspondences (see :class:`MatchScore` for definitions).

    Args:
        detected_ids: (N,) or (N, 2) int, GT id of each reported pair's left feature.
        expected_ids: (E,) or (E, 2) int.
        visible_ids: (V,) or (V, 2) int, a subset of expected_ids.
        matched_pairs_correct: (N,) bool, one per reported pair.
    Empty inputs are allowed (rates are then NaN where undefined).
    """
    det = _id_list(detected_ids, "detected_ids")
    exp = set(_id_list(expected_ids, "expected_ids"))
    vis = set(_id_list(visible_ids, "visible_ids"))
    ok = np.asarray(matched_pairs_correct)
    if ok.size == 0:
        ok = np.zeros(0, dtype=bool)
    if ok.ndim != 1 or ok.dtype != np.bool_:
        raise ValueError(f"matched_pairs_correct: expected a 1-D bool array, got {ok.dtype} {ok.shape}")
    if len(ok) != len(det):
        raise ValueError(
            f"matched_pairs_correct/detected_ids: length mismatch {len(ok)} vs {len(det)}"
        )
    if not vis <= exp:
        raise ValueError(f"visible_ids: {len(vis - exp)} id(s) not in expected_ids")
    uniq = set(det)
    correct_vis = {i for i, c in zip(det, ok) if c and i in vis}
    n_corr = int(np.count_nonzero(ok))
    return MatchScore(
        expected=len(exp),
        visible=len(vis),
        reported=len(det),
        duplicate=len(det) - len(uniq),
        detected_visible=len(uniq & vis),
        detected_not_visible=len(uniq - vis),
        missed=len(vis - uniq),
        correct=n_corr,
        wrong=len(det) - n_corr,
        correct_match_rate=n_corr / len(det) if det else math.nan,
        detection_rate=len(uniq & vis) / len(vis) if vis else math.nan,
        correct_visible_rate=len(correct_vis) / len(vis) if vis else math.nan,
    )
