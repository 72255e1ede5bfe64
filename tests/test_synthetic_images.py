"""Rung 1 of the ladder: the paper's image processing on synthetic images with known sub-pixel
geometry (exact area anti-aliasing, 8-bit), before any render.

Plate regions and corners, sub-pixel outline edges, passive boundary stereo of a planar
quadrilateral at a known depth, and square centres; each against the exact answer, over a
family of positions, angles and sizes (not one case).
"""
from __future__ import annotations

import numpy as np
import pytest

from platebench.reconstruction.paper.passive_boundary import match_boundary, outline_edges
from platebench.reconstruction.paper.plate_region import extract_plate_region
from platebench.reconstruction.paper.squares import extract_squares
from platebench.scenes.rig import StereoRig
from tests.synthetic import coverage, polygon_image, square

SHAPE = (240, 320)


def _quad(rng, center=(160, 120), half=(90, 60), jitter=6.0, angle_deg=0.0):
    """A convex quadrilateral near an axis-aligned rectangle, sub-pixel corners."""
    a = np.radians(angle_deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    hx, hy = half
    base = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]], float)
    return np.asarray(center) + base @ R.T + rng.uniform(-jitter, jitter, (4, 2))


def test_exact_coverage_is_exact():
    """The generator itself: area and centroid of a coverage map match the polygon's."""
    P = np.array([[50.3, 40.7], [200.1, 45.2], [190.6, 150.9], [60.2, 140.4]])
    cov = coverage(P, SHAPE)
    x, y = P[:, 0], P[:, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    assert cov.sum() == pytest.approx(area, rel=1e-12)


@pytest.mark.parametrize("seed", range(6))
def test_plate_region_corners_and_area(seed):
    rng = np.random.default_rng(seed)
    P = _quad(rng, angle_deg=rng.uniform(-4, 4))
    img = polygon_image([P], SHAPE)
    region = extract_plate_region(img, "synthetic")
    err = np.linalg.norm(region.corners - P, axis=1)  # ordered TL, TR, BR, BL like P
    assert err.max() < 1.5, err  # approxPolyDP corners: integer contour pixels
    assert region.mask.sum() == pytest.approx(coverage(P, SHAPE).sum(), rel=0.02)


@pytest.mark.parametrize("seed", range(6))
def test_outline_edges_are_sub_pixel_exact(seed):
    """Side edges (rows) and top/bottom edges (columns) within 0.05 px of the true lines; refined
    corners within 0.15 px (8-bit quantisation only)."""
    rng = np.random.default_rng(100 + seed)
    P = _quad(rng, angle_deg=rng.uniform(-3, 3))
    img = polygon_image([P], SHAPE)
    outline = outline_edges(img, extract_plate_region(img, "synthetic"))

    def u_on_line(a, b, v):  # u of line a-b at row v
        return a[0] + (b[0] - a[0]) * (v - a[1]) / (b[1] - a[1])

    def v_on_line(a, b, u):
        return a[1] + (b[1] - a[1]) * (u - a[0]) / (b[0] - a[0])

    tl, tr, br, bl = P
    rows, us = outline.left
    assert np.abs(us - u_on_line(tl, bl, rows)).max() < 0.05
    rows, us = outline.right
    assert np.abs(us - u_on_line(tr, br, rows)).max() < 0.05
    cols, vs = outline.top
    assert np.abs(vs - v_on_line(tl, tr, cols)).max() < 0.05
    cols, vs = outline.bottom
    assert np.abs(vs - v_on_line(bl, br, cols)).max() < 0.05
    assert np.linalg.norm(outline.corners - P, axis=1).max() < 0.15


@pytest.mark.parametrize("disparity", [8.0, 12.37, 25.61])
def test_passive_boundary_stereo_of_a_fronto_parallel_quad(disparity):
    """A quadrilateral at one depth seen by a conventional pair: the right image is the left one
    shifted by the disparity d = f B / Z; every boundary point triangulates to that depth."""
    f, B, W, H = 400.0, 0.05, SHAPE[1], SHAPE[0]
    Z = f * B / disparity
    rig = StereoRig.conventional(center=(0.0, 0.0, Z), target=(0.0, 0.0, 0.0), baseline_m=B, f_px=f, width=W,
                                 height=H)
    rng = np.random.default_rng(int(disparity * 100))
    P = _quad(rng, center=(165, 118), half=(80, 55), jitter=5.0, angle_deg=1.5)
    left = polygon_image([P], SHAPE)
    right = polygon_image([P - [disparity, 0.0]], SHAPE)
    out_l = outline_edges(left, extract_plate_region(left, "left"))
    out_r = outline_edges(right, extract_plate_region(right, "right"))
    st = match_boundary(out_l, out_r, rig)
    assert np.abs(st.disparity - disparity).max() < 0.1
    depth = rig.left.depth(st.points)
    assert np.abs(depth - Z).max() < Z * 0.1 / disparity  # 0.1 px of disparity
    assert np.abs(st.corner_row_mismatch_px).max() < 0.2


@pytest.mark.parametrize("seed", range(4))
def test_square_centres_are_unbiased(seed):
    """Intensity-weighted centroids of anti-aliased squares (10-20 px, rotated a little) within
    0.03 px of the true centres."""
    rng = np.random.default_rng(200 + seed)
    centres = np.array([[60 + 50 * i + rng.uniform(-3, 3), 60 + 60 * j + rng.uniform(-3, 3)]
                        for i in range(5) for j in range(3)])
    sides = rng.uniform(10, 20, len(centres))
    polys = [square(c, s, np.radians(rng.uniform(-5, 5))) for c, s in zip(centres, sides)]
    img = polygon_image(polys, SHAPE, background=5.0, level=230.0)
    det = extract_squares(img, None, "synthetic")
    assert len(det.squares) == len(centres)
    found = np.array([s.centroid for s in det.squares])
    d = np.linalg.norm(found[:, None] - centres[None], axis=2)
    assert d.min(axis=1).max() < 0.03


@pytest.mark.parametrize("seed", range(3))
def test_outline_stereo_matches_the_steep_edges_despite_spurs_on_a_shallow_one(seed):
    """The general outline stereo on a plate whose bottom edge runs nearly along the rows, with
    one-pixel spurs and dents on it in the left image only (what a noisy render gives at a
    grazing edge). A row the spurs cross holds an extra run in one image; ignoring runs and gaps
    of ``NOTCH_PX`` keeps the two images' sequences alike, so the steep side edges on those rows
    are still matched, at the true disparity."""
    from platebench.reconstruction.paper.outline_stereo import NOTCH_PX, match_outlines
    from platebench.reconstruction.paper.plate_region import plate_mask

    f, B, W, H = 400.0, 0.05, SHAPE[1], SHAPE[0]
    d = 20.0 + seed * 3.3
    Z = f * B / d
    rig = StereoRig.conventional(center=(0.0, 0.0, Z), target=(0.0, 0.0, 0.0), baseline_m=B, f_px=f, width=W,
                                 height=H)
    rng = np.random.default_rng(300 + seed)
    tilt = np.radians(8.0 + seed)  # bottom edge: 8-10 degrees off the rows
    P = np.array([[100.3, 60.2], [220.7, 58.9], [225.4, 60.4 + 125 * np.tan(tilt) + 100], [98.1, 160.6]])
    left = polygon_image([P], SHAPE)
    right = polygon_image([P - [d, 0.0]], SHAPE)
    clean = match_outlines(left, right, plate_mask(left, "left"), plate_mask(right, "right"), rig)
    mask = plate_mask(left, "left").mask
    rows_hit = []
    for u in rng.choice(np.arange(110, 210), 12, replace=False):
        col = np.nonzero(mask[:, u])[0]
        v = col.max()  # last plate pixel of this column: on the bottom edge
        if rng.uniform() < 0.5:
            left[v + 1, u] = left[v - 3, u]  # a one-pixel spur below the edge
            rows_hit.append(v + 1)
        else:
            left[v, u] = left[v + 3, u]  # a one-pixel dent into it
            rows_hit.append(v)
    st = match_outlines(left, right, plate_mask(left, "left"), plate_mask(right, "right"), rig)

    def side_points(s, v):  # the matched side-edge points on row v
        uv = s.image_points_left
        return (s.source == "row") & ((uv[:, 0] < 112) | (uv[:, 0] > 214)) & (np.abs(uv[:, 1] - v) < 0.5)
    checked = 0
    for v in set(rows_hit):
        n_clean = int(side_points(clean, v).sum())
        if n_clean:  # a side edge crosses this row: matched with the spurs too, at the true disparity
            on_row = side_points(st, v)
            assert on_row.sum() == n_clean, f"row {v}: side edges not matched"
            assert np.abs(st.disparity[on_row] - d).max() < 0.15
            checked += 1
    assert checked >= 2 and NOTCH_PX >= 1
