"""Energy-minimising surface interpolation of scattered heights (paper section V-D).

Chen & Zheng interpolate the plate surface from the 16 triangulated square centres
with the energy-minimising method of Terzopoulos (1988). Here the surface is a
height field z(x, y) on a regular grid, found by minimising the discrete
controlled-continuity energy

    E(z) = (1 - tau) * sum(z_x² + z_y²)                     (membrane)
         + tau       * sum(z_xx² + 2 z_xy² + z_yy²)         (thin plate)
         + data_weight * sum_k (B_k z - h_k)²                (data)

over the whole rectangular grid, with natural boundary conditions (difference terms
that would leave the grid are simply absent). Derivatives are finite differences in
grid units (z differences between neighbouring nodes, in metres, without division
by the step), as in Terzopoulos's discrete formulation, so every term is in m² and
``tau`` mixes the two smoothness terms at the grid scale. B_k z is the bilinear
interpolation of the grid at sample k from the 4 nodes of its cell. With
``data_weight=None`` (the default) the samples are interpolated exactly: the
smoothness energy is minimised subject to B z = h (the limit of an infinite data
weight), solved as one sparse KKT system.

Frames: points, domain polygon and heights are in one planar frame, metres; usually
the boundary-plane frame of ``reconstruction.paper.boundary_plane.plane_frame`` (x, y in
the plane, z along its normal) or world x, y with z up for a near-horizontal plate.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from platebench.tolerances import ceil_count, is_rotation, tol

if TYPE_CHECKING:
    import scipy.sparse as sp

# scipy.sparse and matplotlib.path are imported where they are used (they take a while to import, and
# the modules that import this one for points_in_polygon or the types need neither)

__all__ = ["SurfaceGrid", "interpolate_surface", "surface_grid_to_mesh", "points_in_polygon"]


@dataclass(frozen=True)
class SurfaceGrid:
    """A height field on a regular grid (metres, in the frame of the input points).

    x: (nx,) node x coordinates, ascending, step ``step``.
    y: (ny,) node y coordinates, ascending.
    z: (ny, nx) heights; z[i, j] is at (x[j], y[i]); NaN outside the domain polygon.
    mask: (ny, nx) bool, True for nodes inside (or on) the domain polygon.
    step: grid step (m).
    tau: the thin-plate weight used (0 = membrane, 1 = thin plate).
    """

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    mask: np.ndarray
    step: float
    tau: float


def points_in_polygon(points_xy, polygon, margin: float = 0.0) -> np.ndarray:
    """(M,) bool: points inside the closed polygon (K, 2), or within ``margin`` of its edges."""
    from matplotlib.path import Path  # noqa: PLC0415

    points_xy = np.asarray(points_xy, dtype=np.float64)
    polygon = np.asarray(polygon, dtype=np.float64)
    inside = Path(polygon).contains_points(points_xy)
    outside = np.flatnonzero(~inside)
    if margin > 0 and outside.size:
        from scipy.spatial import cKDTree  # noqa: PLC0415
        a, b = polygon, np.roll(polygon, -1, axis=0)
        ab = b - a
        ab2 = np.maximum((ab * ab).sum(-1), tol.tiny)
        # a point within ``margin`` of an edge lies within half its length plus ``margin`` of its midpoint:
        # only those candidates are measured (exactly, as every point would be)
        reach = 0.5 * np.sqrt(ab2) + margin
        near = cKDTree(points_xy[outside]).query_ball_point(0.5 * (a + b), reach * (1.0 + tol.relative) + tol.tiny)
        edge = np.repeat(np.arange(len(polygon)), [len(n) for n in near])
        if edge.size:
            idx = outside[np.concatenate(near).astype(int)]
            rel = points_xy[idx] - a[edge]
            t = np.clip((rel * ab[edge]).sum(-1) / ab2[edge], 0, 1)
            dist = np.linalg.norm(rel - t[:, None] * ab[edge], axis=-1)
            inside[idx[dist <= margin]] = True
    return inside


def _tau(smoothness) -> float:
    if isinstance(smoothness, str):
        named = {"thin_plate": 1.0, "membrane": 0.0}
        if smoothness not in named:
            raise ValueError(f"smoothness must be 'thin_plate', 'membrane' or a weight in [0, 1], got {smoothness!r}")
        return named[smoothness]
    tau = float(smoothness)
    if not 0.0 <= tau <= 1.0:
        raise ValueError(f"smoothness weight tau must be in [0, 1], got {smoothness!r}")
    return tau


def _diff_matrices(n: int) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """1D first ((n-1) x n) and second ((n-2) x n) difference matrices."""
    import scipy.sparse as sp  # noqa: PLC0415

    first = sp.diags([-np.ones(n - 1), np.ones(n - 1)], [0, 1], shape=(n - 1, n))
    second = sp.diags([np.ones(n - 2), -2 * np.ones(n - 2), np.ones(n - 2)], [0, 1, 2], shape=(max(n - 2, 0), n))
    return first.tocsr(), second.tocsr()


def _smoothness_matrix(nx: int, ny: int, tau: float) -> sp.csr_matrix:
    """Hessian H of the smoothness energy z^T H z over an (ny, nx) row-major grid."""
    import scipy.sparse as sp  # noqa: PLC0415

    fx, sx = _diff_matrices(nx)
    fy, sy = _diff_matrices(ny)
    ix, iy = sp.identity(nx, format="csr"), sp.identity(ny, format="csr")
    h = sp.csr_matrix((nx * ny, nx * ny))
    if tau < 1.0:
        dx, dy = sp.kron(iy, fx), sp.kron(fy, ix)
        h = h + (1.0 - tau) * (dx.T @ dx + dy.T @ dy)
    if tau > 0.0:
        dxx, dyy, dxy = sp.kron(iy, sx), sp.kron(sy, ix), sp.kron(fy, fx)
        h = h + tau * (dxx.T @ dxx + 2.0 * dxy.T @ dxy + dyy.T @ dyy)
    return h.tocsr()


def _bilinear_matrix(points_xy, x0, y0, step, nx, ny) -> sp.csr_matrix:
    """(M, nx*ny) rows of bilinear interpolation weights of each point's cell corners."""
    import scipy.sparse as sp  # noqa: PLC0415

    fx, fy = (points_xy[:, 0] - x0) / step, (points_xy[:, 1] - y0) / step
    j = np.clip(np.floor(fx).astype(int), 0, nx - 2)
    i = np.clip(np.floor(fy).astype(int), 0, ny - 2)
    tx, ty = fx - j, fy - i
    rows = np.repeat(np.arange(len(points_xy)), 4)
    cols = np.stack([i * nx + j, i * nx + j + 1, (i + 1) * nx + j, (i + 1) * nx + j + 1], axis=1).ravel()
    vals = np.stack([(1 - tx) * (1 - ty), tx * (1 - ty), (1 - tx) * ty, tx * ty], axis=1).ravel()
    return sp.csr_matrix((vals, (rows, cols)), shape=(len(points_xy), nx * ny))


def interpolate_surface(points_xy, heights, domain_polygon, grid_step: float, smoothness="thin_plate",
                        data_weight: float | None = None, margin: float | None = None) -> SurfaceGrid:
    """Interpolate scattered heights by minimising the controlled-continuity energy.

    Args:
        points_xy: (M, 2) sample positions (m), M >= 3, not all collinear.
        heights: (M,) sample heights (m).
        domain_polygon: (K, 2) closed polygon (first vertex not repeated), the
            surface's domain; the result is masked to it (nodes on its edges count
            as inside).
        grid_step: node spacing (m), > 0.
        smoothness: "thin_plate" (tau = 1), "membrane" (tau = 0) or a weight tau in
            [0, 1] mixing (1 - tau) membrane + tau thin plate.
        data_weight: None for exact interpolation (hard constraints B z = h), or a
            positive weight (dimensionless: data and smoothness terms are both in m²)
            for a smoothing fit that trades data misfit for smoothness.
        margin: extra grid around the bounding box of the polygon and the points
            (m); default 2 grid steps. The grid origin is the box's lower-left corner
            minus the margin, so a rectangle's corners fall on nodes when the margin
            and its sides are multiples of the step.

    Returns:
        SurfaceGrid; z is NaN at nodes outside the polygon.

    Raises:
        ValueError: malformed inputs, or samples that do not determine the surface.
    """
    import scipy.sparse as sp  # noqa: PLC0415
    from scipy.sparse.linalg import MatrixRankWarning, spsolve  # noqa: PLC0415

    pts = np.asarray(points_xy, dtype=np.float64)
    h = np.asarray(heights, dtype=np.float64)
    poly = np.asarray(domain_polygon, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points_xy must be an (M, 2) array, got shape {pts.shape}")
    if pts.shape[0] < 3:
        raise ValueError(f"need at least 3 sample points, got {pts.shape[0]}")
    if h.shape != (pts.shape[0],):
        raise ValueError(f"heights must have shape ({pts.shape[0]},) to match points_xy, got {h.shape}")
    if not (np.all(np.isfinite(pts)) and np.all(np.isfinite(h))):
        raise ValueError("points_xy and heights must be finite (no NaN or inf)")
    if poly.ndim != 2 or poly.shape[1] != 2 or poly.shape[0] < 3 or not np.all(np.isfinite(poly)):
        raise ValueError(f"domain_polygon must be a finite (K, 2) array with K >= 3, got shape {poly.shape}")
    if not (np.isfinite(grid_step) and grid_step > 0):
        raise ValueError(f"grid_step must be a positive number of metres, got {grid_step!r}")
    if margin is None:
        margin = 2.0 * grid_step
    if not (np.isfinite(margin) and margin >= 0):
        raise ValueError(f"margin must be a non-negative number of metres, got {margin!r}")
    if data_weight is not None and not (np.isfinite(data_weight) and data_weight > 0):
        raise ValueError(f"data_weight must be None (exact interpolation) or a positive number, got {data_weight!r}")
    tau = _tau(smoothness)
    centred = pts - pts.mean(axis=0)
    sv = np.linalg.svd(centred, compute_uv=False)
    if tau == 1.0 and not sv[1] > tol.unit_norm * max(sv[0], grid_step):
        raise ValueError("sample points are collinear; a thin-plate surface through them is not unique")

    both = np.vstack([pts, poly])
    x0, y0 = both.min(axis=0) - margin
    x1, y1 = both.max(axis=0) + margin
    nx = ceil_count((x1 - x0) / grid_step) + 1
    ny = ceil_count((y1 - y0) / grid_step) + 1
    nx, ny = max(nx, 3), max(ny, 3)
    x = x0 + grid_step * np.arange(nx)
    y = y0 + grid_step * np.arange(ny)

    hess = _smoothness_matrix(nx, ny, tau)
    bmat = _bilinear_matrix(pts, x0, y0, grid_step, nx, ny)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MatrixRankWarning)
        try:
            if data_weight is None:
                kkt = sp.bmat([[hess, bmat.T], [bmat, None]], format="csc")
                solution = spsolve(kkt, np.concatenate([np.zeros(nx * ny), h]))[: nx * ny]
            else:
                normal = (hess + data_weight * (bmat.T @ bmat)).tocsc()
                solution = spsolve(normal, data_weight * (bmat.T @ h))
        except MatrixRankWarning:
            solution = np.full(nx * ny, np.nan)
    if not np.all(np.isfinite(solution)):
        raise ValueError(
            "the samples do not determine the surface (singular system): samples coincide or "
            "crowd one grid cell; use a smaller grid_step or a finite data_weight"
        )
    z = solution.reshape(ny, nx)
    gx, gy = np.meshgrid(x, y)
    mask = points_in_polygon(np.c_[gx.ravel(), gy.ravel()], poly, margin=tol.inside_outline * grid_step).reshape(ny, nx)
    return SurfaceGrid(x=x, y=y, z=np.where(mask, z, np.nan), mask=mask, step=float(grid_step), tau=tau)


def surface_grid_to_mesh(grid: SurfaceGrid, frame=None) -> tuple[np.ndarray, np.ndarray]:
    """Triangle mesh of the grid cells whose 4 corners are all inside the mask.

    Each such cell gives two triangles, wound counter-clockwise seen from +z of the
    grid frame (face normals point to +z). Only nodes used by a face become vertices.

    Args:
        grid: a SurfaceGrid.
        frame: optional (R, origin) as returned by ``plane_frame``: R (3, 3) has the
            grid frame's axes as rows, expressed in world coordinates, and origin
            (3,) is the grid frame's origin in world. Vertices are then mapped
            ``world = origin + R.T @ local`` (i.e. ``local @ R + origin`` row-wise).
            Without a frame, vertices stay in the grid's own frame.

    Returns:
        vertices (V, 3) float64 in metres, faces (F, 3) int64 indices into vertices.

    Raises:
        ValueError: frame not a proper rotation and a 3-vector.
    """
    mask = np.asarray(grid.mask, bool)
    ny, nx = mask.shape
    cell = mask[:-1, :-1] & mask[:-1, 1:] & mask[1:, :-1] & mask[1:, 1:]
    ci, cj = np.nonzero(cell)
    a = ci * nx + cj
    b, c, d = a + 1, a + nx + 1, a + nx
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    used = np.unique(faces)
    remap = np.full(nx * ny, -1, dtype=np.int64)
    remap[used] = np.arange(used.size)
    gx, gy = np.meshgrid(grid.x, grid.y)
    local = np.c_[gx.ravel(), gy.ravel(), np.asarray(grid.z).ravel()][used]
    vertices = local
    if frame is not None:
        rotation, origin = (np.asarray(v, dtype=np.float64) for v in frame)
        if rotation.shape != (3, 3) or origin.shape != (3,):
            raise ValueError(f"frame must be (R (3, 3), origin (3,)), got shapes {rotation.shape}, {origin.shape}")
        if not is_rotation(rotation):
            raise ValueError("frame rotation R must be orthonormal with det +1")
        vertices = local @ rotation + origin
    return vertices, remap[faces].astype(np.int64)
