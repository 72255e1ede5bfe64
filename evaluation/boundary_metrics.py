"""Distances between boundary polylines (3D in metres, or 2D image contours in pixels).

Polyline convention: an (N, D) array of vertices, D = 2 or 3; closed polylines do
NOT repeat the first vertex at the end (the closing segment from vertex N-1 to vertex 0 is implied).
A list of such arrays stands for several polylines (e.g. outer boundary + holes).

Directed distance from polyline A to polyline B
-----------------------------------------------
The distance from a point p to B is the exact Euclidean distance to the nearest
point of any SEGMENT of B (not to the nearest vertex), so a coarse B is not
penalised for having few vertices. A itself is sampled uniformly by arc length,
independently of its vertices (sample i of a polyline of length L with n samples
sits at arc length (i + 1/2) L / n, spacing <= ``sample_spacing``, by default
1/4000 of the shorter boundary), so a coarse A is not favoured either: the
directed mean / RMS / p95 are arc-length averages of the distance along A
(midpoint rule; weight L/n per sample when there are several polylines). The
directed max is the supremum of the distance along A to within
1e-4 x sample_spacing: it is evaluated at the samples and at every vertex of A,
then refined between them wherever a larger value is possible (see
``_directed``); so the Hausdorff distance is that of the continuous curves.

    mean_sym    = (mean(est->gt) + mean(gt->est)) / 2
    rms_sym     = sqrt((rms(est->gt)^2 + rms(gt->est)^2) / 2)
    hausdorff   = max(max(est->gt), max(gt->est))

The nearest-segment search is exact (KD-tree over segment midpoints with a
pruning bound, see ``point_metrics.pruned_min_distance``).

Image contours (``contour_pixels_distance``): pixel centres at integer
coordinates (OpenCV), points given as (u, v) = (column, row). The true contour of
a boolean mask is its sub-pixel boundary: the polyline through the midpoints
between each mask pixel and its 4-neighbours outside the mask (the same curve as
marching squares at level 0.5 on the 0/1 image, apart from the saddle-point
choice). For a mask made of the pixels whose centres lie inside a shape, this
curve is within about half a pixel of the shape's boundary, with no bias on
straight edges (an edge of pixels x0..x1 gives the line x = x1 + 0.5). Pixels
beyond the image border count as outside the mask.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from platebench.tolerances import ceil_count, tol

from .point_metrics import pruned_min_distance
from .stats import ErrorStats, check_array

__all__ = [
    "BoundaryScore",
    "polyline_distance",
    "points_to_polyline_distance",
    "mask_contours_subpixel",
    "contour_pixels_distance",
]

BOUNDARY_UNITS = {"m": ("mm", 1e3), "px": ("px", 1.0)}  # a boundary's unit -> (file key suffix, scale)
_MAX_SAMPLES = 2_000_000


@dataclass(frozen=True)
class BoundaryScore:
    """Directed and symmetric distances between an estimated and a true boundary.

    Values are in the input unit (``unit``: "m" or "px"); the JSON form (``bench.io.codecs.evaluation``)
    reports mm for metres and px for pixels.
    """

    est_to_gt: ErrorStats
    gt_to_est: ErrorStats
    mean_sym: float
    rms_sym: float
    hausdorff: float
    length_est: float
    length_gt: float
    sample_spacing: float
    unit: str = "m"


# ----------------------------------------------------------------------- helpers


def _as_polylines(x, name: str, closed: bool, dim: int | None = None) -> list[np.ndarray]:
    """Normalise one (N, D) array or a list of them; validate."""
    if isinstance(x, (list, tuple)) and len(x) > 0 and np.ndim(x[0]) == 2:
        items = list(x)
    else:
        items = [x]
    out = []
    for i, item in enumerate(items):
        nm = name if len(items) == 1 else f"{name}[{i}]"
        a = check_array(item, nm, shape=(None, None))
        if a.shape[1] not in (2, 3):
            raise ValueError(f"{nm}: expected (N, 2) or (N, 3) vertices, got {a.shape}")
        if dim is not None and a.shape[1] != dim:
            raise ValueError(f"{nm}: dimension mismatch, {a.shape[1]}-D vs {dim}-D")
        dim = a.shape[1]
        if a.shape[0] < 2 and not (closed and a.shape[0] == 1):
            raise ValueError(f"{nm}: a polyline needs at least 2 vertices, got {a.shape[0]}")
        out.append(a)
    return out


def _segments(polys: list[np.ndarray], closed: bool) -> tuple[np.ndarray, np.ndarray]:
    A, B = [], []
    for p in polys:
        if closed:
            A.append(p)
            B.append(np.roll(p, -1, axis=0))
        else:
            A.append(p[:-1])
            B.append(p[1:])
    return np.concatenate(A), np.concatenate(B)


def _length(polys: list[np.ndarray], closed: bool) -> float:
    A, B = _segments(polys, closed)
    return float(np.linalg.norm(B - A, axis=1).sum())


def _subdivide(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Split every segment into equal pieces no longer than h (same geometry).

    Returns the pieces (A', B') and, for each piece, the index of its segment.
    """
    L = np.linalg.norm(B - A, axis=1)
    n = np.maximum(1, np.ceil(L / h).astype(np.int64)) if h > 0 else np.ones(len(A), dtype=np.int64)
    seg = np.repeat(np.arange(len(A)), n)
    start = np.cumsum(n) - n
    k = np.arange(seg.size) - np.repeat(start, n)
    t0 = (k / n[seg])[:, None]
    t1 = ((k + 1) / n[seg])[:, None]
    d = (B - A)[seg]
    return A[seg] + t0 * d, A[seg] + t1 * d, seg


def _point_segment_distance(P: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
    ab = B - A
    ap = P - A
    den = np.einsum("ij,ij->i", ab, ab)
    t = np.einsum("ij,ij->i", ap, ab) / np.where(den > 0, den, 1.0)
    t = np.clip(np.where(den > 0, t, 0.0), 0.0, 1.0)
    return np.linalg.norm(ap - t[:, None] * ab, axis=1)


class _SegmentSet:
    """The segments of the destination polylines, with an exact nearest-segment query.

    Segments longer than the median length are split into equal pieces (same
    geometry) so that the KD-tree over piece midpoints prunes well.
    """

    def __init__(self, A: np.ndarray, B: np.ndarray):
        from scipy.spatial import cKDTree  # noqa: PLC0415  (scipy.spatial takes a while to import)

        L = np.linalg.norm(B - A, axis=1)
        h = max(float(np.median(L)), float(L.sum()) / 1_000_000)
        self.A0, self.B0 = A, B
        self.A, self.B, self.seg = _subdivide(A, B, h)
        self.mid = 0.5 * (self.A + self.B)
        self.r = 0.5 * np.linalg.norm(self.B - self.A, axis=1)
        self.tree = cKDTree(self.mid)

    def query(self, P: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(exact distance, index of the nearest original segment) for points P."""
        d, j = pruned_min_distance(
            P, self.mid, self.r, lambda Q, J: _point_segment_distance(Q, self.A[J], self.B[J]), tree=self.tree
        )
        return d, self.seg[j]

    def distance_to(self, P: np.ndarray, j: np.ndarray) -> np.ndarray:
        """Exact distance from P[i] to original segment j[i]."""
        return _point_segment_distance(P, self.A0[j], self.B0[j])


class _ArcParam:
    """Arc-length parametrisation of one polyline."""

    def __init__(self, p: np.ndarray, closed: bool):
        self.A, self.B = _segments([p], closed)
        self.seglen = np.linalg.norm(self.B - self.A, axis=1)
        self.cum = np.concatenate([[0.0], np.cumsum(self.seglen)])
        self.L = float(self.cum[-1])
        self.closed = closed

    def at(self, s: np.ndarray) -> np.ndarray:
        if self.closed and self.L > 0:
            s = np.mod(s, self.L)
        j = np.clip(np.searchsorted(self.cum, s, side="right") - 1, 0, len(self.seglen) - 1)
        t = np.clip((s - self.cum[j]) / np.where(self.seglen[j] > 0, self.seglen[j], 1.0), 0.0, 1.0)
        return self.A[j] + t[:, None] * (self.B[j] - self.A[j])

    def vertex_positions(self) -> np.ndarray:
        return self.cum[:-1] if self.closed else self.cum


def _directed(src: list[np.ndarray], dst: _SegmentSet, closed: bool, spacing: float, name: str) -> ErrorStats:
    """Directed distance statistics from the polylines ``src`` to the segment set ``dst``.

    Mean / RMS / p95 from uniform arc-length samples (midpoint rule). The max is
    the supremum along ``src`` to within ``1e-4 * spacing``: distances are also
    taken at every vertex of ``src``, so every interval between consecutive
    evaluated positions is straight, and an interval is subdivided (8 parts,
    repeatedly) only while it could hold a larger value than the running max
    plus the tolerance. Upper bound on an interval [l, r] whose ends have the
    nearest segments jl and jr: along a straight interval the distance f_j to
    one segment is convex, so d(s) <= min(f_jl(s), f_jr(s)) <= min of the two
    chords of f_jl and f_jr between l and r (their crossing point bounds the
    interval; jl == jr gives max(d_l, d_r)); also d is 1-Lipschitz, so
    d(s) <= (d_l + d_r + length) / 2.
    """
    params = [_ArcParam(p, closed) for p in src]
    pos, poly, is_sample, weights = [], [], [], []
    for i, pa in enumerate(params):
        if pa.L > 0:
            n = max(1, ceil_count(pa.L / spacing))
            s = (np.arange(n) + 0.5) * (pa.L / n)
        else:
            n, s = 1, np.zeros(1)
        v = pa.vertex_positions() if pa.L > 0 else np.zeros(0)
        allpos = np.concatenate([s, v])
        order = np.argsort(allpos, kind="stable")
        pos.append(allpos[order])
        is_sample.append(order < n)
        poly.append(np.full(len(allpos), i))
        weights.append(np.full(n, pa.L / n))
    pos_all = np.concatenate(pos)
    poly_all = np.concatenate(poly)

    def points_at(pids: np.ndarray, s: np.ndarray) -> np.ndarray:
        out = np.empty((len(s), src[0].shape[1]))
        for i in np.unique(pids):
            sel = pids == i
            out[sel] = params[i].at(s[sel])
        return out

    d_all, j_all = dst.query(points_at(poly_all, pos_all))
    samp = np.concatenate(is_sample)
    w = np.concatenate(weights)
    ds = d_all[samp]
    st = ErrorStats.from_abs(ds, name=name, weights=w) if w.sum() > 0 else ErrorStats.from_abs(ds, name=name)

    # --- refine the maximum between evaluated positions
    cur = float(d_all.max())
    refine = tol.sup_refine * spacing
    il, ir, ipoly, sl, sr = [], [], [], [], []
    start = 0
    for i, pa in enumerate(params):
        m = len(pos[i])
        idx = np.arange(start, start + m)
        if m > 1:
            il.append(idx[:-1])
            ir.append(idx[1:])
            sl.append(pos_all[idx[:-1]])
            sr.append(pos_all[idx[1:]])
            ipoly.append(np.full(m - 1, i))
        if closed and pa.L > 0:  # wrap-around interval from the last position to L (= 0)
            il.append(idx[-1:])
            ir.append(idx[:1])
            sl.append(pos_all[idx[-1:]])
            sr.append(pos_all[idx[:1]] + pa.L)
            ipoly.append(np.array([i]))
        start += m
    if il:
        il_, ir_ = np.concatenate(il), np.concatenate(ir)
        dl, dr, jl, jr = d_all[il_], d_all[ir_], j_all[il_], j_all[ir_]
        sl_, sr_, ip = np.concatenate(sl), np.concatenate(sr), np.concatenate(ipoly)
        parts = 8
        frac = np.arange(1, parts) / parts
        for _ in range(64):
            bound = np.minimum(0.5 * (dl + dr + (sr_ - sl_)), np.maximum(dl, dr))
            sw = np.nonzero(jl != jr)[0]
            if sw.size:
                pts_l = points_at(ip[sw], sl_[sw])
                pts_r = points_at(ip[sw], sr_[sw])
                fl_r = dst.distance_to(pts_r, jl[sw])  # f_jl at the right end (>= dr)
                fr_l = dst.distance_to(pts_l, jr[sw])  # f_jr at the left end (>= dl)
                a = fl_r - dl[sw]  # chord of f_jl: dl + a u
                b = dr[sw] - fr_l  # chord of f_jr: fr_l + b u
                den = a - b
                u = np.clip(np.where(den > 0, (fr_l - dl[sw]) / np.where(den > 0, den, 1.0), 0.0), 0.0, 1.0)
                chord = np.maximum(np.maximum(dl[sw], dr[sw]), dl[sw] + a * u)
                bound[sw] = np.minimum(0.5 * (dl[sw] + dr[sw] + (sr_[sw] - sl_[sw])), chord)
            cand = bound > cur + refine
            if not cand.any() or np.count_nonzero(cand) > _MAX_SAMPLES:  # (safety cap, never hit in tests)
                break
            cl, cr, cp = sl_[cand], sr_[cand], ip[cand]
            s_new = cl[:, None] + (cr - cl)[:, None] * frac[None, :]  # (C, parts-1)
            d_new, j_new = dst.query(points_at(np.repeat(cp, parts - 1), s_new.ravel()))
            cur = max(cur, float(d_new.max()))
            d_new = d_new.reshape(-1, parts - 1)
            j_new = j_new.reshape(-1, parts - 1)
            S = np.concatenate([cl[:, None], s_new, cr[:, None]], axis=1)
            Dd = np.concatenate([dl[cand][:, None], d_new, dr[cand][:, None]], axis=1)
            Jj = np.concatenate([jl[cand][:, None], j_new, jr[cand][:, None]], axis=1)
            sl_, sr_ = S[:, :-1].ravel(), S[:, 1:].ravel()
            dl, dr = Dd[:, :-1].ravel(), Dd[:, 1:].ravel()
            jl, jr = Jj[:, :-1].ravel(), Jj[:, 1:].ravel()
            ip = np.repeat(cp, parts)
    return ErrorStats(st.mean, st.rms, cur, st.p95, st.count)


def _default_spacing(est, gt, closed: bool) -> float:
    lengths = [L for L in (_length(est, closed), _length(gt, closed)) if L > 0]
    return min(lengths) / 4000.0 if lengths else 1.0


# ------------------------------------------------------------------------ public


def points_to_polyline_distance(points, polyline, *, closed: bool = True) -> np.ndarray:
    """Exact distance from each point (N, D) to the nearest segment of ``polyline``.

    ``polyline`` is an (M, D) array or a list of them (see module doc).
    """
    P = check_array(points, "points", shape=(None, None))
    polys = _as_polylines(polyline, "polyline", closed, dim=P.shape[1])
    A, B = _segments(polys, closed)
    return _SegmentSet(A, B).query(P)[0]


def polyline_distance(
    estimated,
    truth,
    *,
    closed: bool = True,
    sample_spacing: float | None = None,
    unit: str = "m",
) -> BoundaryScore:
    """Distances between an estimated and a true boundary polyline (see module doc).

    Args:
        estimated: (N, D) vertices (D = 2 or 3) or a list of such polylines.
        truth: (M, D) vertices or a list; same D as ``estimated``.
        closed: polylines are closed (first vertex not repeated). False: open.
        sample_spacing: arc-length spacing of the samples on each side, in the
            input unit. Default: 1/4000 of the shorter of the two total lengths.
        unit: "m" (inputs in metres, report mm) or "px" (report px).
    """
    if unit not in BOUNDARY_UNITS:
        raise ValueError(f"unit: expected one of {sorted(BOUNDARY_UNITS)}, got {unit!r}")
    est = _as_polylines(estimated, "estimated", closed)
    gt = _as_polylines(truth, "truth", closed, dim=est[0].shape[1])
    L_est, L_gt = _length(est, closed), _length(gt, closed)
    if sample_spacing is None:
        spacing = _default_spacing(est, gt, closed)
    else:
        spacing = float(sample_spacing)
        if not (spacing > 0 and math.isfinite(spacing)):
            raise ValueError(f"sample_spacing: must be a positive finite number, got {sample_spacing!r}")
    spacing = max(spacing, (L_est + L_gt) / _MAX_SAMPLES)
    e2g = _directed(est, _SegmentSet(*_segments(gt, closed)), closed, spacing, "est_to_gt distance")
    g2e = _directed(gt, _SegmentSet(*_segments(est, closed)), closed, spacing, "gt_to_est distance")
    return BoundaryScore(
        est_to_gt=e2g,
        gt_to_est=g2e,
        mean_sym=0.5 * (e2g.mean + g2e.mean),
        rms_sym=math.sqrt(0.5 * (e2g.rms**2 + g2e.rms**2)),
        hausdorff=max(e2g.max, g2e.max),
        length_est=L_est,
        length_gt=L_gt,
        sample_spacing=spacing,
        unit=unit,
    )


# Freeman-style 8-neighbour directions in image coordinates (x right, y down):
# code c -> (dx, dy); even codes are the 4-neighbours.
_DIRS = np.array([(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)])
_CODE = {(int(dx), int(dy)): c for c, (dx, dy) in enumerate(_DIRS)}


def _crack_walk(contour: np.ndarray, outside, sense: int) -> list[tuple[float, float]]:
    """Midpoints to outside 4-neighbours, emitted pixel by pixel along the contour.

    At pixel k, the 8 directions are swept from the direction of pixel k-1 to
    that of pixel k+1, turning by ``sense``; every outside 4-neighbour met on the
    way contributes the midpoint between the two pixel centres.
    """
    n = len(contour)
    out: list[tuple[float, float]] = []
    for k in range(n):
        x, y = int(contour[k, 0]), int(contour[k, 1])
        px, py = contour[k - 1]
        nx, ny = contour[(k + 1) % n]
        b = _CODE.get((int(np.sign(px - x)), int(np.sign(py - y))))
        f = _CODE.get((int(np.sign(nx - x)), int(np.sign(ny - y))))
        if b is None or f is None:  # repeated point; should not happen with cv2 output
            continue
        steps = 8 if b == f else ((f - b) * sense) % 8
        for i in range(1, steps):  # directions strictly between b and f
            c = (b + sense * i) % 8
            if c % 2 == 0:
                dx, dy = _DIRS[c]
                if outside(x + dx, y + dy):
                    out.append((x + 0.5 * dx, y + 0.5 * dy))
    return out


def mask_contours_subpixel(mask) -> list[np.ndarray]:
    """Sub-pixel boundary curves of a boolean mask, as closed (N, 2) polylines in (u, v) px.

    Uses ``cv2.findContours(RETR_LIST, CHAIN_APPROX_NONE)`` for the ordered
    boundary pixels of every component and hole, then replaces each boundary
    pixel by the midpoints between it and its 4-neighbours outside the mask (see
    module doc). A single-pixel component becomes a diamond of 4 midpoints.
    """
    import cv2

    m = np.asarray(mask)
    if m.ndim != 2 or m.dtype != np.bool_:
        raise ValueError(f"mask_true: expected a 2-D bool array, got {m.dtype} {m.shape}")
    if not m.any():
        raise ValueError("mask_true: mask is empty (no True pixel)")
    H, W = m.shape
    padded = np.zeros((H + 2, W + 2), dtype=np.uint8)
    padded[1:-1, 1:-1] = m
    res = cv2.findContours(padded, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    contours = res[-2]

    def outside(x, y):  # coordinates in the padded image
        return padded[y, x] == 0

    curves = []
    for c in contours:
        c = c.reshape(-1, 2).astype(np.int64)
        if len(c) == 1:
            x, y = c[0]
            pts = [(x + 0.5, y), (x, y + 0.5), (x - 0.5, y), (x, y - 0.5)]
        else:
            cand = [_crack_walk(c, outside, s) for s in (1, -1)]
            pts = max(cand, key=len)
        arr = np.asarray(pts, dtype=np.float64) - 1.0  # undo the padding
        # drop consecutive duplicates (can occur where a pixel is visited twice)
        keep = np.ones(len(arr), dtype=bool)
        keep[1:] = np.any(np.diff(arr, axis=0) != 0, axis=1)
        arr = arr[keep]
        if len(arr) > 1 and np.all(arr[0] == arr[-1]):
            arr = arr[:-1]
        curves.append(arr)
    return curves


def contour_pixels_distance(mask_true, contour_est, *, sample_spacing_px: float | None = None) -> BoundaryScore:
    """Distance in pixels between an estimated closed image contour and the true mask's boundary.

    Args:
        mask_true: (H, W) bool, True on the object (e.g. the GT plate mask).
        contour_est: (N, 2) closed contour in (u, v) = (column, row) px, pixel
            centres at integer coordinates; or a list of such contours.
        sample_spacing_px: arc-length sample spacing (default: 0.1 px, or
            1/4000 of the shorter boundary if that is finer).
    The true boundary is :func:`mask_contours_subpixel` of the mask. Returns a
    :class:`BoundaryScore` with ``unit="px"`` (keys ``hausdorff_px``, ...).
    """
    gt = mask_contours_subpixel(mask_true)
    est = _as_polylines(contour_est, "contour_est", True)
    for i, e in enumerate(est):
        if e.shape[1] != 2:
            raise ValueError(f"contour_est: expected (N, 2) pixel coordinates, got {e.shape}")
    if sample_spacing_px is None:
        sample_spacing_px = min(0.1, _default_spacing(est, gt, True))
    return polyline_distance(est, gt, closed=True, sample_spacing=sample_spacing_px, unit="px")
