"""Passive boundary stereo (paper sections II, IV-B): the plate outline matched along rows.

In conventional geometry a boundary point has the same row v in both images, so each
*side* edge (running across the rows) is matched row by row: disparity
d = u_left - u_right, triangulated with the left camera. Edges running *along* the
rows (the top and bottom of the outline) cannot be matched by position along a row.
For them we use the corners: each corner is the intersection of straight-line fits to
the side edge and to the top/bottom edge near it, matched between the images, and the
disparity along a top/bottom edge is interpolated linearly in u between its two corner
disparities. That is exact for a straight 3D edge (inverse depth, hence disparity, is
affine along the image of a 3D line) and first-order for a gently curved one.

Where the corner method does not apply (no four corners, or curved top/bottom edges), the general
outline stereo of ``outline_stereo`` is used instead (``boundary_stereo`` chooses and records it).

Pixel coordinates: OpenCV, pixel centres at integers. Output points: world frame, metres.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.reconstruction.paper.boundary_types import BoundaryStereo
from platebench.reconstruction.paper.outline_stereo import match_outlines
from platebench.reconstruction.paper.plate_region import (
    PlateMask,
    PlateRegion,
    ReconstructionError,
    plate_mask,
    quadrilateral_corners,
)
from platebench.reconstruction.paper.subpixel_edges import column_edges, row_edges
from platebench.scenes.camera import triangulate_rectified
from platebench.scenes.rig import StereoRig
from platebench.tolerances import tol

SMOOTH_PX = 21  # Savitzky-Golay window (quadratic) along each edge: the outline of a smooth plate is smooth
CORNER_MARGIN_PX = 6  # edge samples this close to a corner are dropped (the area method needs a clean edge)
CORNER_FIT_PX = 30  # edge length used to fit the curves that meet at a corner
SEARCH_PX = 10
STRAIGHT_PX = 1.5  # a top/bottom image edge this close to its corners' chord is straight (a straight 3D edge)


@dataclass(frozen=True)
class ImageOutline:
    """Sub-pixel outline of the plate in one image, as four edges and four corners."""

    corners: np.ndarray  # (4,2) TL, TR, BR, BL (u, v)
    left: tuple[np.ndarray, np.ndarray]  # rows v, u  (TL -> BL)
    right: tuple[np.ndarray, np.ndarray]  # rows v, u  (TR -> BR)
    top: tuple[np.ndarray, np.ndarray]  # cols u, v  (TL -> TR)
    bottom: tuple[np.ndarray, np.ndarray]  # cols u, v  (BL -> BR)


def outline_edges(image: np.ndarray, region: PlateRegion) -> ImageOutline:
    """Sub-pixel samples of the four edges and refined corners of the plate outline."""
    img = np.asarray(image, np.float64)
    H, W = img.shape
    tl, tr, br, bl = region.corners
    m = CORNER_MARGIN_PX
    thr, bg = region.threshold, region.background_level

    def extents(mask2d):
        has = mask2d.any(axis=1)
        first = np.argmax(mask2d, axis=1)
        last = mask2d.shape[1] - 1 - np.argmax(mask2d[:, ::-1], axis=1)
        return np.where(has, first, -1), np.where(has, last, -1)

    row_first, row_last = extents(region.mask)
    col_first, col_last = extents(region.mask.T)

    def samples(lines, first, last, size, from_start: bool, edges):
        """Sub-pixel edge along each line (row or column), scanning inward from the mask's extent."""
        base = (first if from_start else last)[lines]
        step = SEARCH_PX if from_start else -SEARCH_PX
        pos = edges(img, lines, thr, bg, np.clip(base - step, 0, size - 1), np.clip(base + step, 0, size - 1))
        ok = np.isfinite(pos) & (base >= 0)
        return lines[ok], pos[ok]

    def side(rows, from_left: bool):
        return samples(rows, row_first, row_last, W, from_left, row_edges)

    def tb(cols, from_top: bool):
        return samples(cols, col_first, col_last, H, from_top, column_edges)

    left = side(np.arange(int(np.ceil(tl[1])) + m, int(np.floor(bl[1])) - m + 1), True)
    right = side(np.arange(int(np.ceil(tr[1])) + m, int(np.floor(br[1])) - m + 1), False)
    top = tb(np.arange(int(np.ceil(tl[0])) + m, int(np.floor(tr[0])) - m + 1), True)
    bottom = tb(np.arange(int(np.ceil(bl[0])) + m, int(np.floor(br[0])) - m + 1), False)
    for name, (a, _) in (("left", left), ("right", right), ("top", top), ("bottom", bottom)):
        if a.size < 4:
            raise ReconstructionError(f"plate outline: too few sub-pixel samples on its {name} edge ({a.size})")
    left, right, top, bottom = (_smooth(e) for e in (left, right, top, bottom))
    corners = np.array([
        _corner(left, top, near_start_side=True, near_start_tb=True),
        _corner(right, top, near_start_side=True, near_start_tb=False),
        _corner(right, bottom, near_start_side=False, near_start_tb=False),
        _corner(left, bottom, near_start_side=False, near_start_tb=True),
    ])
    return ImageOutline(corners, left, right, top, bottom)


def _smooth(edge):
    """Quadratic Savitzky-Golay smoothing of an edge's sub-pixel positions (Monte Carlo/pixel noise)."""
    from scipy.signal import savgol_filter  # noqa: PLC0415  (scipy.signal takes a second to import)

    a, b = edge
    win = min(SMOOTH_PX, a.size - (1 - a.size % 2))
    if win < 5 or np.any(np.diff(a) != 1):
        return a, b  # too short, or samples missing: keep raw
    return a, savgol_filter(b, win, 2)


def _corner(side, tb, near_start_side: bool, near_start_tb: bool) -> np.ndarray:
    """Intersect quadratic fits u(v) of the side edge and v(u) of the top/bottom edge near a corner.

    Quadratic, because a bent plate's edges curve in the image close to its corners (perspective of
    an edge that recedes in depth); straight-line fits put the corner off by pixels there.
    """
    rows, us = side
    cols, vs = tb
    k = CORNER_FIT_PX
    rs, uu = (rows[:k], us[:k]) if near_start_side else (rows[-k:], us[-k:])
    cs, vv = (cols[:k], vs[:k]) if near_start_tb else (cols[-k:], vs[-k:])
    ps = np.polyfit(rs, uu, 2 if len(rs) > 5 else 1)
    pt = np.polyfit(cs, vv, 2 if len(cs) > 5 else 1)
    # Fixed point: start at the ends of the two fitted stretches, alternate the two curves.
    # Curves that do not meet near the stretches diverge to inf/nan: no corner. That is an error
    # (``boundary_stereo`` then uses the general outline stereo), never a NaN corner, whose
    # disparity would silently drop the corner and its top/bottom edge from the boundary.
    v, step = float(rs[0] if near_start_side else rs[-1]), np.inf
    with np.errstate(over="ignore", invalid="ignore"):
        for _ in range(50):
            u = float(np.polyval(ps, v))
            v_new = float(np.polyval(pt, u))
            step = abs(v_new - v)
            if step < tol.fit_converged:
                break
            v = v_new
        corner = np.array([float(np.polyval(ps, v)), v])
    if not np.all(np.isfinite(corner)) or not step < tol.fit_moving_px:  # diverged, or still moving (a cycle)
        raise ReconstructionError("plate outline: the edge fits near a corner do not meet (corner not found)")
    return corner


def match_boundary(left: ImageOutline, right: ImageOutline, rig: StereoRig) -> BoundaryStereo:
    """Match the two outlines row by row (sides) and through the corners (top/bottom)."""
    pts_uv, disp, src = [], [], []

    def add(u, v, d, kind):
        pts_uv.append(np.column_stack([u, v]))
        disp.append(np.asarray(d, float))
        src.extend([kind] * len(np.atleast_1d(u)))

    cl, cr = left.corners, right.corners
    cd = cl[:, 0] - cr[:, 0]
    if np.any(cd <= 0):
        raise ReconstructionError("passive stereo: a plate corner has non-positive disparity (images swapped?)")

    def side(ledge, redge, reverse):
        rows, ia, ib = np.intersect1d(ledge[0], redge[0], return_indices=True)
        u_l, u_r = ledge[1][ia], redge[1][ib]
        order = np.argsort(rows)[::-1] if reverse else np.argsort(rows)
        return u_l[order], rows[order].astype(float), (u_l - u_r)[order]

    def top_bottom(edge, c0, c1, d0, d1, reverse):
        u, v = edge
        d = d0 + (d1 - d0) * (u - c0[0]) / (c1[0] - c0[0])
        order = np.argsort(u)[::-1] if reverse else np.argsort(u)
        return u[order], v[order], d[order]

    add(cl[0, 0], cl[0, 1], cd[0], "corner")
    add(*top_bottom(left.top, cl[0], cl[1], cd[0], cd[1], False), "top-bottom")
    add(cl[1, 0], cl[1, 1], cd[1], "corner")
    add(*side(left.right, right.right, False), "side")
    add(cl[2, 0], cl[2, 1], cd[2], "corner")
    add(*top_bottom(left.bottom, cl[3], cl[2], cd[3], cd[2], True), "top-bottom")
    add(cl[3, 0], cl[3, 1], cd[3], "corner")
    add(*side(left.left, right.left, True), "side")
    uv = np.vstack(pts_uv)
    d = np.concatenate([np.atleast_1d(x) for x in disp])
    P = triangulate_rectified(uv[:, 0], uv[:, 1], uv[:, 0] - d, rig.left, rig.baseline_m)
    ok = np.all(np.isfinite(P), axis=1)
    return BoundaryStereo(P[ok], uv[ok], d[ok], np.array(src)[ok], np.abs(cl[:, 1] - cr[:, 1]))


def _max_chord_deviation_px(edge, c0, c1) -> float:
    """Largest distance (px) of a top/bottom edge's samples from the line through its corners."""
    u, v = edge
    d = np.asarray(c1, float) - np.asarray(c0, float)
    n = np.array([-d[1], d[0]]) / max(np.linalg.norm(d), tol.zero_length)
    return float(np.max(np.abs((np.column_stack([u, v]) - c0) @ n))) if len(u) else 0.0


def corner_method_applies(outline: ImageOutline) -> bool:
    """The paper's corner-based stereo interpolates disparity linearly between corners along the
    top and bottom edges: exact only when those edges are straight in 3D, hence in the image."""
    tl, tr, br, bl = outline.corners
    return max(_max_chord_deviation_px(outline.top, tl, tr),
               _max_chord_deviation_px(outline.bottom, bl, br)) <= STRAIGHT_PX


def boundary_stereo(left_image: np.ndarray, right_image: np.ndarray, rig: StereoRig
                    ) -> tuple[dict, BoundaryStereo]:
    """The plate regions of both passive images and the matched 3D boundary, by the paper's corner
    method where it applies (a quadrilateral outline with straight top and bottom edges in both
    images), else by the general outline stereo (``outline_stereo.match_outlines``). The method
    used is ``BoundaryStereo.method``; ``regions`` maps camera -> PlateRegion or PlateMask."""
    images = {"left": left_image, "right": right_image}
    masks: dict[str, PlateMask] = {c: plate_mask(images[c], f"{c}_passive") for c in images}
    corners = {c: quadrilateral_corners(m) for c, m in masks.items()}
    if all(q is not None for q in corners.values()):
        regions = {c: PlateRegion(m.mask, m.contour, corners[c], m.threshold, m.tsai_threshold,
                                  m.background_level, m.plate_level) for c, m in masks.items()}
        try:
            outlines = {c: outline_edges(images[c], regions[c]) for c in images}
            if all(corner_method_applies(o) for o in outlines.values()):
                return regions, match_boundary(outlines["left"], outlines["right"], rig)
        except ReconstructionError:
            pass  # e.g. too few samples on an edge: the general method below does not need edges
    return masks, match_outlines(images["left"], images["right"], masks["left"], masks["right"], rig)
