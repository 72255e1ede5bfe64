"""Triangulations of the flat plate in material coordinates, sized from curvature.

Units: metres. Everything here works in the material (uv) plane: a layout is
(uv, faces) with uv (V, 2) in metres and faces (F, 3) int, counter-clockwise seen
from +Z (so the mapped faces' normals agree with the top normal r_u x r_v).

Two layouts, each family naming its own (``DeformationFamily.layout``):
- strips (Flat, CylindricalBend, Fold): those surfaces are ruled along the bend axis,
  so the plate is cut by lines of constant bending coordinate s (through every
  corner and every curvature break) into trapezoids. Straight lines of constant s
  stay straight on the surface, so the facet error depends only on the s-spacing:
  fine only where the plate is curved, at any axis angle (``DeformationFamily.ruling``: the axis,
  the curved band, the curvature breaks and the smallest radius).
- grid (Twist, Dome, Dent): a tensor-product grid with per-axis spacing chosen from
  bounds on |r_uu|, |r_uv|, |r_vv| of the top and bottom surfaces (the P1
  interpolation error on a right triangle with legs hu, hv is about
  <= (M_uu hu^2 + 2 M_uv hu hv + M_vv hv^2) / 8), refined only over the family's
  ``curved_support`` (a Dent's disc).
"""

from __future__ import annotations

import math

import numpy as np

from platebench.tolerances import ceil_count, tol

from .deformations import surface_derivatives
from .spec import PlateSpec, bending_extent_m

__all__ = ["mesh_layout", "MIN_SEGMENTS", "MAX_VERTICES"]

MIN_SEGMENTS = 4          # at least this many segments along each plate direction
MAX_RULING_ASPECT = 8.0   # strip triangles: spacing along rulings <= this x finest s-spacing
MAX_VERTICES = 2_000_000  # refuse to build larger meshes (ask for a looser tolerance)


def _nodes(breaks: list[float], spacing) -> np.ndarray:
    """Sorted nodes covering the breakpoints; interval [a, b] is cut into pieces <= spacing(a, b)."""
    breaks = np.unique(np.asarray(breaks, dtype=np.float64))
    out = [breaks[:1]]
    for a, b in zip(breaks[:-1], breaks[1:]):
        h = spacing(a, b)
        n = max(1, ceil_count((b - a) / h)) if math.isfinite(h) else 1
        out.append(np.linspace(a, b, n + 1)[1:])
    return np.concatenate(out)


def _arc_spacing(radius_m: float, offset_m: float, tol_m: float) -> float:
    """Largest arc length (metres) on a radius-R circle whose chord sagitta at radius R + offset is
    <= tol, at most an arc of pi/16.

    The half angle is acos(1 - x), x = tol_m / (radius_m + offset_m), which keeps 4 digits or more
    from x = 1e-12 up (1 - x is rounded to 1.1e-16). Where 1 - x rounds to 1 (x below about 1.1e-16:
    a much smaller facet error than ``plate.MAX_FACET_ERROR_M`` on a large, nearly flat plate) it is
    the equal 2 asin(sqrt(x / 2)), which keeps its digits there, so the spacing is never 0."""
    r_eff = radius_m + offset_m
    half_angle = math.acos(max(1.0 - tol_m / r_eff, -1.0)) if tol_m < r_eff else math.pi
    if half_angle == 0.0:  # 1 - x rounded to 1: the half-angle form of the same angle
        half_angle = 2.0 * math.asin(math.sqrt(tol_m / (2.0 * r_eff)))
    return radius_m * min(2.0 * half_angle, math.pi / 16)


def _ruling_range(s: float, L: float, W: float, ca: float, sa: float) -> tuple[float, float]:
    """t-range of the line uv = s e + t g inside the rectangle |u| <= L/2, |v| <= W/2."""
    lo, hi = -math.inf, math.inf
    # u = s ca - t sa, v = s sa + t ca
    for base, slope, half in ((s * ca, -sa, L / 2), (s * sa, ca, W / 2)):
        if abs(slope) > tol.parallel:
            t1, t2 = (-half - base) / slope, (half - base) / slope
            lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
    return lo, max(lo, hi)


def _zip_strip(ta: np.ndarray, tb: np.ndarray, ia: np.ndarray, ib: np.ndarray) -> np.ndarray:
    """Triangulate between two point rows on parallel lines (row a at smaller s), CCW."""
    keys = np.concatenate([ta[1:], tb[1:]])
    is_a = np.concatenate([np.ones(len(ta) - 1, bool), np.zeros(len(tb) - 1, bool)])
    order = np.argsort(keys, kind="stable")
    is_a = is_a[order]
    i = np.cumsum(is_a)        # index in row a after each step
    j = np.cumsum(~is_a)       # index in row b after each step
    tri = np.where(is_a[:, None],
                   np.stack([ia[i - 1], ib[j], ia[np.minimum(i, len(ia) - 1)]], axis=1),
                   np.stack([ia[i], ib[j - 1], ib[np.minimum(j, len(ib) - 1)]], axis=1))
    return tri


def _strip_layout(spec: PlateSpec, tol_m: float, refine: float):
    L, W = spec.length_m, spec.width_m
    ruling = spec.deformation.ruling(L, W)
    a = ruling.axis_rad
    ca, sa = math.cos(a), math.sin(a)
    S = bending_extent_m(L, W, a)
    corners = [(x * ca + y * sa) for x in (-L / 2, L / 2) for y in (-W / 2, W / 2)]
    breaks = [-S / 2, S / 2] + corners + list(ruling.breaks_m)
    coarse = S / MIN_SEGMENTS / refine
    curved = (-S / 2, S / 2)
    fine = coarse
    if ruling.curved_m is not None:
        curved = ruling.curved_m
        fine = min(coarse, _arc_spacing(ruling.radius_m, spec.thickness_m, tol_m) / refine)
    span = curved[1] - curved[0]
    s_nodes = _nodes(breaks, lambda lo, hi: fine if (lo >= curved[0] - tol.relative * S
                                                     and hi <= curved[1] + tol.relative * S
                                                     and span > 0) else coarse)
    ranges = np.array([_ruling_range(s, L, W, ca, sa) for s in s_nodes])
    lengths = ranges[:, 1] - ranges[:, 0]
    longest = lengths.max()
    h_t = min(longest / MIN_SEGMENTS, max(MAX_RULING_ASPECT * fine, longest / 64)) / refine
    counts = np.where(lengths > tol.unit_norm * max(L, W), np.maximum(1, np.ceil(lengths / h_t - tol.step_count)), 0)
    counts = counts.astype(int) + 1
    if counts.sum() > MAX_VERTICES:
        raise ValueError(f"plate mesh would need {counts.sum()} vertices; use a larger max_facet_error_m")
    uv_rows, t_rows, idx_rows, start = [], [], [], 0
    for s, (t0, t1), n in zip(s_nodes, ranges, counts):
        t = np.linspace(t0, t1, n) if n > 1 else np.array([0.5 * (t0 + t1)])
        uv_rows.append(np.column_stack([s * ca - t * sa, s * sa + t * ca]))
        t_rows.append(t)
        idx_rows.append(np.arange(start, start + n))
        start += n
    half = np.array([L / 2, W / 2])
    uv = np.clip(np.concatenate(uv_rows), -half, half)
    on_edge = np.abs(np.abs(uv) - half) < tol.relative * max(L, W)
    uv = np.where(on_edge, np.sign(uv) * half, uv)  # rulings end exactly on the outline
    faces = np.concatenate([_zip_strip(t_rows[k], t_rows[k + 1], idx_rows[k], idx_rows[k + 1])
                            for k in range(len(s_nodes) - 1)])
    return uv, faces


def _support(spec: PlateSpec) -> tuple[tuple[float, float], tuple[float, float]]:
    """((u0, u1), (v0, v1)): the part of the plate that is curved (the family's ``curved_support``)."""
    return spec.deformation.curved_support(spec.length_m, spec.width_m)


def _second_derivative_bounds(spec: PlateSpec, samples: int = 65) -> tuple[float, float, float]:
    """(M_uu, M_uv, M_vv): bounds (1/m) on |r_uu|, |r_uv|, |r_vv| of the top and bottom surfaces.

    Used only for sizing the grid (the mesh itself is exact at its vertices): sampled
    on a grid over the curved support with central second differences of the exact
    map, for both the top surface and its offset by -thickness along the normal,
    times a 15 % margin.
    """
    (u0, u1), (v0, v1) = _support(spec)
    h = 1e-3 * min(u1 - u0, v1 - v0)
    uu, vv = np.meshgrid(np.linspace(u0, u1, samples), np.linspace(v0, v1, samples), indexing="ij")
    base = np.column_stack([uu.ravel(), vv.ravel()])
    steps = [(du, dv) for du in (-1, 0, 1) for dv in (-1, 0, 1)]
    uv = np.concatenate([base + h * np.array(step) for step in steps])
    r, r_u, r_v = surface_derivatives(spec, uv)
    n = np.cross(r_u, r_v)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    bounds = np.zeros(3)
    for offset in {0.0, spec.thickness_m}:
        p = dict(zip(steps, np.split(r - offset * n, len(steps))))
        second = (p[1, 0] - 2 * p[0, 0] + p[-1, 0],
                  0.25 * (p[1, 1] - p[1, -1] - p[-1, 1] + p[-1, -1]),
                  p[0, 1] - 2 * p[0, 0] + p[0, -1])
        norms = [np.linalg.norm(x, axis=1).max() / h**2 for x in second]
        bounds = np.maximum(bounds, norms)
    return tuple(1.15 * bounds)


def _grid_spacing(bounds: tuple[float, float, float], extents: tuple[float, float],
                  caps: tuple[float, float], tol_m: float) -> tuple[float, float]:
    """Per-axis spacings (hu, hv) keeping (M_uu hu^2 + 2 M_uv hu hv + M_vv hv^2) / 8 <= tol_m
    with the fewest grid nodes over the curved extents (a search over the ratio hv / hu)."""
    m_uu, m_uv, m_vv = bounds
    ratio = np.logspace(-4, 4, 801)
    denom = m_uu + 2 * m_uv * ratio + m_vv * ratio**2
    with np.errstate(divide="ignore"):
        hu = np.minimum(np.sqrt(8.0 * tol_m / denom), caps[0])
    hv = np.minimum(ratio * hu, caps[1])
    count = (np.ceil(extents[0] / hu) + 1) * (np.ceil(extents[1] / hv) + 1)
    best = int(np.argmin(count))
    return float(hu[best]), float(hv[best])


def _grid_layout(spec: PlateSpec, tol_m: float, refine: float):
    L, W = spec.length_m, spec.width_m
    support = _support(spec)
    caps = (L / MIN_SEGMENTS, W / MIN_SEGMENTS)
    extents = (support[0][1] - support[0][0], support[1][1] - support[1][0])
    hu, hv = _grid_spacing(_second_derivative_bounds(spec), extents, caps, tol_m)
    axes = []
    for (lo, hi), half, h, cap in zip(support, (L / 2, W / 2), (hu, hv), caps):
        axes.append(_nodes([-half, lo, hi, half],
                           lambda a, b, lo=lo, hi=hi, h=h, cap=cap:
                           (h if (a >= lo and b <= hi) else cap) / refine))
    nu, nv = len(axes[0]), len(axes[1])
    if nu * nv > MAX_VERTICES:
        raise ValueError(f"plate mesh would need {nu * nv} vertices; use a larger max_facet_error_m")
    uu, vv = np.meshgrid(axes[0], axes[1], indexing="ij")
    uv = np.column_stack([uu.ravel(), vv.ravel()])
    idx = np.arange(nu * nv).reshape(nu, nv)
    p00, p10 = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
    p01, p11 = idx[:-1, 1:].ravel(), idx[1:, 1:].ravel()
    faces = np.concatenate([np.stack([p00, p10, p01], 1), np.stack([p10, p11, p01], 1)])
    return uv, faces


def mesh_layout(spec: PlateSpec, tol_m: float, refine: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Top-surface triangulation in material coords for a facet error of about tol_m metres.

    Returns uv (V, 2) metres and faces (F, 3) int, CCW seen from +Z. refine > 1
    shrinks every spacing by that factor (used when a measured error is too large).
    The spacing accounts for the bottom offset surface when thickness_m > 0.
    """
    layout = spec.deformation.layout
    if layout == "grid":
        return _grid_layout(spec, tol_m, refine)
    if layout == "strips":
        return _strip_layout(spec, tol_m, refine)
    raise ValueError(f"deformation family {spec.deformation.family!r} has layout {layout!r}: "
                     "allowed 'strips' or 'grid'")
