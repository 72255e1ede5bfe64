"""The paper's boundary plane: the plane closest to a closed 3D boundary polyline.

Chen & Zheng (1995, section III) define the boundary plane as the plane minimising
the contour integral of the point-to-plane distance along the detected boundary,

    J(n, d) = ∮ |D(s)| ds,   D(s) = n · x(s) - d,   |n| = 1,

an arc-length-weighted L1 fit. Its normal orients the cameras and the projector in
the second and third sensing stages (section IV-B).

Everything here is exact for the polyline: along a segment D is linear in s, so
∫|D| ds and ∫D² ds have closed forms per segment (the former split at the sign
change). Frames: all points are in whatever right-handed frame the boundary is given
in (the world frame, metres); the plane is n · x = d in that frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.tolerances import tol as TOL

__all__ = [
    "BoundaryPlane",
    "fit_boundary_plane",
    "least_squares_plane",
    "plane_frame",
    "boundary_l1_objective",
]

# 2-point Gauss-Legendre abscissae on [0, 1] (exact for linear integrands).
_GL = np.array([0.5 - 0.5 / np.sqrt(3.0), 0.5 + 0.5 / np.sqrt(3.0)])


@dataclass(frozen=True)
class BoundaryPlane:
    """A plane n · x = offset fitted to a closed boundary (metres, boundary's frame).

    point: (3,) the arc-length centroid of the boundary projected onto the plane.
    normal: (3,) unit normal; normal[2] >= 0 unless the fit was given ``toward``.
    offset: d in n · x = d (m).
    objective_m2: the fitted objective: ∮|D| ds (m², method "irls") or ∮D² ds
        (m³, method "least_squares"), evaluated exactly on the polyline.
    iterations: iterations run, Newton and IRLS steps together (0 for least squares).
    method: "irls" or "least_squares".
    """

    point: np.ndarray
    normal: np.ndarray
    offset: float
    objective_m2: float
    iterations: int
    method: str

    def signed_distance(self, points) -> np.ndarray:
        """Signed distances (m) of (..., 3) points from the plane, positive along normal."""
        return np.asarray(points, dtype=np.float64) @ self.normal - self.offset


def _checked_boundary(boundary) -> np.ndarray:
    pts = np.asarray(boundary, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"boundary must be an (N, 3) array, got shape {pts.shape}")
    if pts.shape[0] < 3:
        raise ValueError(f"boundary needs at least 3 points, got {pts.shape[0]}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("boundary has NaN or infinite coordinates")
    if np.array_equal(pts[0], pts[-1]):
        raise ValueError("boundary's last point repeats its first; pass the closed polyline without the repeat")
    return pts


def _segments(pts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Start points, end points and lengths of the closed polyline's segments."""
    a, b = pts, np.roll(pts, -1, axis=0)
    lengths = np.linalg.norm(b - a, axis=1)
    if not lengths.sum() > 0.0:
        raise ValueError("boundary has zero length (all points coincide)")
    return a, b, lengths


def _segment_abs_integrals(da: np.ndarray, db: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """Exact ∫|D| ds per segment for D linear from da to db over each length."""
    abs_a, abs_b = np.abs(da), np.abs(db)
    same = da * db >= 0.0
    total = abs_a + abs_b
    crossing = np.divide(da * da + db * db, 2.0 * total, out=np.zeros_like(total), where=total > 0)
    return lengths * np.where(same, 0.5 * total, crossing)


def boundary_l1_objective(boundary, normal, offset: float) -> float:
    """Exact ∮|n · x(s) - d| ds (m²) along the closed polyline ``boundary`` (N, 3).

    ``normal`` need not be unit length: it is normalised (and ``offset`` with it).
    """
    pts = _checked_boundary(boundary)
    n = np.asarray(normal, dtype=np.float64)
    norm = np.linalg.norm(n)
    if n.shape != (3,) or not norm > 0:
        raise ValueError(f"normal must be a non-zero 3-vector, got {normal!r}")
    a, b, lengths = _segments(pts)
    return float(_segment_abs_integrals(a @ n / norm - offset / norm, b @ n / norm - offset / norm, lengths).sum())


def _arc_centroid_and_scatter(a, b, lengths):
    """Exact arc-length centroid and ∮(x-c)(x-c)^T ds of a polyline."""
    centroid = (lengths[:, None] * (a + b)).sum(axis=0) / (2.0 * lengths.sum())
    ra, rb = a - centroid, b - centroid
    w = lengths[:, None, None]
    scatter = (w * (2 * ra[:, :, None] * ra[:, None, :] + ra[:, :, None] * rb[:, None, :]
                    + rb[:, :, None] * ra[:, None, :] + 2 * rb[:, :, None] * rb[:, None, :])).sum(axis=0) / 6.0
    return centroid, scatter


def _orient(normal: np.ndarray, toward) -> np.ndarray:
    if toward is None:
        ref = np.array([0.0, 0.0, 1.0])
        key = normal[2] if normal[2] != 0 else (normal[1] if normal[1] != 0 else normal[0])
    else:
        ref = np.asarray(toward, dtype=np.float64)
        if ref.shape != (3,) or not np.all(np.isfinite(ref)) or not np.linalg.norm(ref) > 0:
            raise ValueError(f"toward must be a finite non-zero 3-vector, got {toward!r}")
        key = normal @ ref
    return -normal if key < 0 else normal


def _make_plane(normal, offset, centroid, objective, iterations, method, toward) -> BoundaryPlane:
    oriented = _orient(normal, toward)
    if oriented is not normal:  # _orient returned -normal
        offset = -offset
    point = centroid - (centroid @ oriented - offset) * oriented
    return BoundaryPlane(point=point, normal=oriented, offset=float(offset),
                         objective_m2=float(objective), iterations=iterations, method=method)


def least_squares_plane(boundary, toward=None) -> BoundaryPlane:
    """Arc-length-weighted L2 plane: minimises ∮D(s)² ds exactly (m³).

    The optimum passes through the arc-length centroid and its normal is the
    eigenvector of the smallest eigenvalue of the exact segment scatter matrix
    ∮(x - c)(x - c)^T ds; that eigenvalue is the objective.

    Args:
        boundary: (N, 3) closed polyline in metres, first point not repeated.
        toward: optional 3-vector; the normal is oriented to have n · toward >= 0
            (default: normal[2] >= 0).

    Raises:
        ValueError: malformed boundary, or all its points collinear.
    """
    pts = _checked_boundary(boundary)
    a, b, lengths = _segments(pts)
    centroid, scatter = _arc_centroid_and_scatter(a, b, lengths)
    evals, evecs = np.linalg.eigh(scatter)
    if not evals[1] > TOL.relative * evals[2]:
        raise ValueError("boundary points are collinear; a plane through them is not unique")
    normal = evecs[:, 0]
    return _make_plane(normal, normal @ centroid, centroid, max(evals[0], 0.0), 0, "least_squares", toward)


def _arc_length_median(ha, hb, lengths, atom_tol):
    """Exact weighted median of h(s) = n · x(s) over arc length (the L1-optimal offset).

    Each segment spreads its length uniformly over [min(ha, hb), max(ha, hb)];
    segments whose height span is below ``atom_tol`` count as a point mass.
    """
    lo, hi = np.minimum(ha, hb), np.maximum(ha, hb)
    span = hi - lo
    atom = span <= atom_tol
    ramp = ~atom
    slope = np.zeros_like(lengths)
    slope[ramp] = lengths[ramp] / span[ramp]
    pos = np.concatenate([lo[ramp], hi[ramp], lo[atom]])
    dslope = np.concatenate([slope[ramp], -slope[ramp], np.zeros(atom.sum())])
    jump = np.concatenate([np.zeros(2 * ramp.sum()), lengths[atom]])
    order = np.argsort(pos, kind="stable")
    pos, dslope, jump = pos[order], dslope[order], jump[order]
    slopes = np.cumsum(dslope)  # slope of the CDF just after each event
    gained = np.concatenate([[0.0], slopes[:-1] * np.diff(pos)])  # mass gained before each event
    cdf_before = np.cumsum(gained) + np.concatenate([[0.0], np.cumsum(jump)[:-1]])
    cdf_after = cdf_before + jump
    half = 0.5 * lengths.sum()
    k = min(int(np.searchsorted(cdf_after, half)), pos.size - 1)
    if k > 0 and cdf_before[k] >= half and slopes[k - 1] > 0:
        return float(pos[k - 1] + (half - cdf_after[k - 1]) / slopes[k - 1])
    return float(pos[k])


def _newton_terms(a, b, lengths, centroid, n, d):
    """Exact gradient and Hessian of ∮|D| ds about the plane (n, d), in tangent coordinates.

    ∮|D| ds is continuously differentiable in the plane's parameters wherever the
    polyline crosses the plane transversally (|D| is integrated across its kink), and
    twice differentiable but for a vertex or a segment lying on the plane. Parameters:
    the normal turned in its tangent plane, n(u, v) = (n + u e1 + v e2) / sqrt(1 + u² + v²),
    and the offset about the arc-length centroid c, D = n · (x - c) - δ. With
    g(x) = (e1 · (x - c), e2 · (x - c), -1), exactly on the polyline:

        gradient = ∮ sign(D) g ds,
        Hessian  = Σ_crossings 2 g gᵀ / |dD/ds|  -  ∮ sign(D) n · (x - c) ds · diag(1, 1, 0),

    the first term from d sign(D)/dD = 2 δ(D) (each crossing weighted by the inverse
    slope of D along the arc there), the second from ∂²n/∂u² = ∂²n/∂v² = -n.

    Args:
        a, b: (M, 3) segment start and end points (m); lengths: (M,) their lengths (m).
        centroid: (3,) the arc-length centroid c (m); n: (3,) unit normal; d: offset (m).

    Returns:
        (gradient (3,) in m² per (rad, rad, m), crossing term (3, 3), curvature term (3, 3),
        basis (2, 3) = (e1, e2)); the Hessian is the sum of the two terms.
    """
    basis = _tangent_basis(n)
    ra, rb = a - centroid, b - centroid
    delta = d - n @ centroid
    da, db = ra @ n - delta, rb @ n - delta
    cross = da * db < 0
    t = np.where(cross, np.divide(da, da - db, out=np.zeros_like(da), where=cross), 1.0)
    # pieces [0, t] (sign of da) and [t, 1] (sign of db); a piece of zero length adds nothing
    sign_a = np.sign(np.where(cross | (da != 0), da, db))
    sign_b = np.sign(np.where(cross | (db != 0), db, da))
    mid_a = ra + 0.5 * t[:, None] * (rb - ra)
    mid_b = ra + 0.5 * (1.0 + t)[:, None] * (rb - ra)
    wa, wb = sign_a * t * lengths, sign_b * (1.0 - t) * lengths
    grad = np.empty(3)
    grad[:2] = basis @ (wa @ mid_a + wb @ mid_b)
    grad[2] = -(wa.sum() + wb.sum())
    curvature = wa @ (mid_a @ n) + wb @ (mid_b @ n)
    crossing = np.zeros((3, 3))
    if cross.any():
        xc = (ra + t[:, None] * (rb - ra))[cross]
        g = np.c_[xc @ basis.T, -np.ones(len(xc))]
        weight = 2.0 * lengths[cross] / np.abs(db[cross] - da[cross])
        crossing = (weight[:, None] * g).T @ g
    return grad, crossing, np.diag([-curvature, -curvature, 0.0]), basis


def _newton_step(a, b, lengths, centroid, n, d, scale_m: float):
    """The normal after one Newton step on the exact ∮|D| ds (:func:`_newton_terms`), or None.

    Where the Hessian is not positive definite (far from the optimum, on a deep bend) the
    step takes the crossing term alone, positive semi-definite, as long as the gradient
    is more than its rounding (``tol.relative`` times the arc length times the boundary's
    size): at a saddle (a symmetric curl's least-squares plane) that step would follow the
    rounding, so None is returned and the caller takes the reweighting step.

    Args:
        a, b, lengths, centroid, n, d: as :func:`_newton_terms`; scale_m: the boundary's size (m).
    """
    grad, crossing, curvature, basis = _newton_terms(a, b, lengths, centroid, n, d)
    trials = [crossing + curvature]
    if np.linalg.norm(grad[:2]) > TOL.relative * lengths.sum() * scale_m:
        trials.append(crossing)
    for trial in trials:
        try:
            factor = np.linalg.cholesky(trial)
            break
        except np.linalg.LinAlgError:
            continue
    else:
        return None
    step = -np.linalg.solve(factor.T, np.linalg.solve(factor, grad))
    n_new = n + step[:2] @ basis
    return n_new / np.linalg.norm(n_new)


def fit_boundary_plane(boundary, toward=None, tol: float = TOL.plane_fit_converged,
                       max_iterations: int = 500) -> BoundaryPlane:
    """The paper's boundary plane: minimises ∮|D(s)| ds along the closed polyline.

    Iteratively reweighted least squares, started from :func:`least_squares_plane`.
    Each iteration (1) splits every segment where the current plane crosses it and
    puts 2 Gauss-Legendre nodes on each piece (so the quadrature of |D| and of any
    linear function times sign(D) is exact), (2) fits the weighted total-least-
    squares plane (weighted PCA) with node weights ds / max(|D|, eps), and (3) resets
    the offset to the exact arc-length median of n · x(s), the exact L1-optimal
    offset for that normal. A fixed point satisfies the exact optimality conditions
    of ∮|D| ds. IRLS converges linearly (15 to 35 iterations a decade on plate-like
    boundaries), so each iteration first tries a Newton step on the exact objective
    (:func:`_newton_step`; quadratic near an optimum where no vertex or segment lies on
    the plane) and keeps it, with the exact median offset, where it does not raise the
    objective beyond its rounding; else the IRLS step is taken. Iteration stops when the
    normal moves less than ``tol`` (radians) and the offset about the arc-length centroid
    less than ``tol`` times the boundary's size. The iterate with the smallest exact
    objective is returned. The objective is not convex: on a deep curl it has two mirror
    minima, and the fit returns the one its steps reach from the least-squares plane.

    Args:
        boundary: (N, 3) closed polyline in metres, first point not repeated.
        toward: optional 3-vector; the normal is oriented to have n · toward >= 0
            (default: normal[2] >= 0).
        tol: convergence tolerance (radians for the normal; relative for the offset).
        max_iterations: iteration cap (Newton and IRLS steps together).

    Returns:
        BoundaryPlane with method "irls" and objective_m2 = ∮|D| ds (m²).

    Raises:
        ValueError: malformed boundary, collinear points, or bad tol/max_iterations.
    """
    if not (np.isfinite(tol) and tol > 0):
        raise ValueError(f"tol must be a positive number, got {tol!r}")
    if int(max_iterations) != max_iterations or max_iterations < 1:
        raise ValueError(f"max_iterations must be a positive integer, got {max_iterations!r}")
    ls = least_squares_plane(boundary)
    pts = _checked_boundary(boundary)
    a, b, lengths = _segments(pts)
    centroid, _ = _arc_centroid_and_scatter(a, b, lengths)
    scale = float(np.max(np.abs(pts - centroid)))  # the boundary's size (m)
    eps = TOL.relative * scale
    atom_tol = TOL.relative * scale

    def objective(n, d):
        return float(_segment_abs_integrals(a @ n - d, b @ n - d, lengths).sum())

    n = ls.normal
    d = _arc_length_median(a @ n, b @ n, lengths, atom_tol)
    best = (objective(n, d), n, d)
    iterations = 0
    value_now = best[0]
    for iterations in range(1, int(max_iterations) + 1):
        n_new = _newton_step(a, b, lengths, centroid, n, d, scale)
        if n_new is not None:  # kept unless it raises the objective beyond rounding
            d_new = _arc_length_median(a @ n_new, b @ n_new, lengths, atom_tol)
            value = objective(n_new, d_new)
            if value > value_now + TOL.relative * max(value_now, eps * lengths.sum()):
                n_new = None
        if n_new is None:
            n_new = _irls_normal(a, b, lengths, n, d, eps)
            d_new = _arc_length_median(a @ n_new, b @ n_new, lengths, atom_tol)
            value = objective(n_new, d_new)
        step = float(np.arctan2(np.linalg.norm(np.cross(n, n_new)), n @ n_new))
        moved = abs((d_new - n_new @ centroid) - (d - n @ centroid))  # the offset about the centroid
        n, d, value_now = n_new, d_new, value
        if value < best[0]:
            best = (value, n, d)
        if step < tol and moved < tol * scale:
            break
    value, n, d = best
    return _make_plane(n, d, centroid, value, iterations, "irls", toward)


def _irls_normal(a, b, lengths, n, d, eps):
    """The next normal of the reweighting step about the plane (n, d) (``fit_boundary_plane``, steps
    1 and 2): the weighted total-least-squares normal, node weights ds / max(|D|, eps), same side as n."""
    da, db = a @ n - d, b @ n - d
    cross = da * db < 0
    t_split = np.where(cross, np.divide(da, da - db, out=np.full_like(da, 0.5), where=cross), 0.5)
    # pieces [0, t_split] and [t_split, 1] of every segment, 2 GL nodes each
    t0 = np.stack([np.zeros_like(t_split), t_split], axis=1)
    width = np.stack([t_split, 1.0 - t_split], axis=1)
    t = (t0[:, :, None] + width[:, :, None] * _GL).reshape(len(a), 4)
    q = (0.5 * lengths[:, None] * np.repeat(width, 2, axis=1)).ravel()
    x = (a[:, None, :] + t[:, :, None] * (b - a)[:, None, :]).reshape(-1, 3)
    w = q / np.maximum(np.abs(x @ n - d), eps)
    c = (w @ x) / w.sum()
    r = x - c
    _, evecs = np.linalg.eigh((w[:, None] * r).T @ r)
    return evecs[:, 0] if evecs[:, 0] @ n >= 0 else -evecs[:, 0]


def _tangent_basis(normal: np.ndarray) -> np.ndarray:
    """(2,3) orthonormal (e1, e2) across the unit ``normal``, right-handed with it: e1 is the world
    X axis projected onto the plane (world Y where X is nearly along the normal), e2 = normal x e1."""
    seed = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = seed - (seed @ normal) * normal
    e1 /= np.linalg.norm(e1)
    return np.stack([e1, np.cross(normal, e1)])


def plane_frame(plane: BoundaryPlane) -> tuple[np.ndarray, np.ndarray]:
    """An orthonormal right-handed frame on the plane, for 2D work in it.

    Returns (R, origin): R is (3, 3) with rows (e_x, e_y, e_z) = the frame axes
    expressed in the boundary's (world) frame, e_z = plane.normal; e_x is the world
    X axis projected onto the plane (world Y if X is nearly normal to it), e_y =
    e_z × e_x. origin = plane.point. Conversions:

        local = R @ (world - origin),   world = origin + R.T @ local

    (row-vector arrays: ``local = (world - origin) @ R.T``, ``world = local @ R + origin``).
    This is a pose in the bench's convention (docs/architecture.md) x_local = R x_world + t with
    t = -R @ origin.
    """
    ez = np.asarray(plane.normal, dtype=np.float64)
    ez = ez / np.linalg.norm(ez)
    ex, ey = _tangent_basis(ez)
    return np.stack([ex, ey, ez]), np.asarray(plane.point, dtype=np.float64).copy()
