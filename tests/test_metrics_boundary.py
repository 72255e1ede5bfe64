"""Tests of evaluation.boundary_metrics on boundaries with known distances."""

import math
import time

import numpy as np
import pytest
from scipy.integrate import quad

from platebench.bench.io.codecs import encode
from platebench.evaluation.boundary_metrics import (
    contour_pixels_distance,
    mask_contours_subpixel,
    points_to_polyline_distance,
    polyline_distance,
)


def circle(r, n, centre=(0.0, 0.0), phase=0.0):
    th = np.linspace(0, 2 * np.pi, n, endpoint=False) + phase
    return np.c_[centre[0] + r * np.cos(th), centre[1] + r * np.sin(th)]


def rectangle(x0, y0, x1, y1, per_side=1):
    """Closed rectangle, first vertex not repeated, per_side vertices per side."""
    t = np.arange(per_side) / per_side
    return np.concatenate(
        [
            np.c_[x0 + t * (x1 - x0), np.full(per_side, y0)],
            np.c_[np.full(per_side, x1), y0 + t * (y1 - y0)],
            np.c_[x1 - t * (x1 - x0), np.full(per_side, y1)],
            np.c_[np.full(per_side, x0), y1 - t * (y1 - y0)],
        ]
    )


def test_concentric_circles_2d_and_3d():
    r, d = 0.05, 1e-3
    a, b = circle(r, 2000), circle(r + d, 2000, phase=1e-3)
    s = polyline_distance(a, b)
    # polygon vs true circle differs by the sagitta r (1 - cos(pi/n)) ~ 6e-8 m
    for v in (s.est_to_gt.mean, s.est_to_gt.rms, s.gt_to_est.mean, s.mean_sym, s.rms_sym, s.hausdorff):
        assert v == pytest.approx(d, abs=2e-7)
    dd = encode(s)
    assert dd["hausdorff_mm"] == pytest.approx(1.0, abs=2e-4)
    assert dd["length_gt_mm"] == pytest.approx(2e3 * np.pi * (r + d), rel=1e-5)
    a3 = np.c_[a, np.full(len(a), 0.2)]
    b3 = np.c_[b, np.full(len(b), 0.2)]
    assert polyline_distance(a3, b3).hausdorff == pytest.approx(d, abs=2e-7)


def test_rectangle_translated_along_normal_3d():
    d = 0.4e-3
    a = np.c_[rectangle(-0.058, -0.037, 0.058, 0.037, per_side=7), np.zeros(28)]
    b = np.c_[rectangle(-0.058, -0.037, 0.058, 0.037, per_side=3), np.full(12, d)]
    s = polyline_distance(a, b)
    for v in (s.est_to_gt.mean, s.est_to_gt.max, s.gt_to_est.mean, s.gt_to_est.max, s.hausdorff, s.rms_sym):
        assert v == pytest.approx(d, rel=1e-9)


def test_rectangle_translated_in_plane():
    # W x H rectangle vs the same one shifted by d along x (d < H/2, d < W).
    # Distances from the points of A to B, by side of A:
    #   left side  (x = 0):  d everywhere                       -> integral H d
    #   right side (x = W):  min(d, y, H - y)                   -> integral H d - d^2
    #   bottom/top sides:    d - x for x < d, 0 after            -> integral d^2 / 2 each
    # total 2 H d; perimeter 2 (W + H): mean = H d / (W + H); same from B to A by symmetry.
    # Hausdorff: the left side of A is d from B (and B's right side d from A) -> d.
    W, H, d = 0.116, 0.0735, 2e-3
    a = rectangle(0, 0, W, H, per_side=50)
    b = rectangle(d, 0, W + d, H, per_side=1)
    s = polyline_distance(a, b)
    mean = H * d / (W + H)  # 0.0735 * 0.002 / 0.1895 = 7.757e-4 m
    assert s.est_to_gt.mean == pytest.approx(mean, rel=1e-4)
    assert s.gt_to_est.mean == pytest.approx(mean, rel=1e-4)
    assert s.hausdorff == pytest.approx(d, rel=1e-9)
    assert encode(s)["hausdorff_mm"] == pytest.approx(2.0)


def test_point_to_segment_not_to_vertex():
    # A dense square against a 4-vertex square on the same lines: distance 0 everywhere.
    dense, coarse = rectangle(0, 0, 1, 1, per_side=100), rectangle(0, 0, 1, 1)
    s = polyline_distance(dense, coarse, unit="px")
    assert s.hausdorff == pytest.approx(0.0, abs=1e-12)
    assert encode(s)["hausdorff_px"] == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(points_to_polyline_distance([[0.5, 0.25], [2.0, 1.0]], coarse), [0.25, 1.0])


def test_coarse_polyline_not_favoured():
    # A square inscribed in a circle of radius r: its 4 vertices lie ON the circle, but
    # along a side p(t) = (r (1 - t), r t) the distance to the circle is
    # r - |p(t)| = r (1 - sqrt(1 - 2t + 2t^2)); mean over t in [0, 1], max r (1 - 1/sqrt(2)).
    r = 0.05
    sq = np.array([[r, 0], [0, r], [-r, 0], [0, -r]])
    s = polyline_distance(sq, circle(r, 5000))
    mean = r * (1 - quad(lambda t: math.sqrt(1 - 2 * t + 2 * t * t), 0, 1)[0])  # = r * 0.18840...
    assert s.est_to_gt.mean == pytest.approx(mean, rel=1e-4)
    # tolerance: sagitta of the 5000-gon r (1 - cos(pi/5000)) = 1e-8 m plus the stated
    # accuracy of the max, 1e-4 x sample spacing (0.283 m / 4000) = 7e-9 m
    assert s.est_to_gt.max == pytest.approx(r * (1 - 1 / math.sqrt(2)), abs=2e-8)
    assert s.hausdorff == pytest.approx(r * (1 - 1 / math.sqrt(2)), abs=2e-8)


def test_open_polyline_and_list_of_polylines():
    a = np.array([[0.0, 0.0], [1.0, 0.0]])
    b = np.array([[0.0, 0.5], [1.0, 0.5]])
    s = polyline_distance(a, b, closed=False, unit="px")
    assert s.est_to_gt.mean == pytest.approx(0.5) and s.hausdorff == pytest.approx(0.5)
    # two closed curves vs two: each matched to the nearer one
    s2 = polyline_distance([circle(1.0, 500), circle(3.0, 500)], [circle(1.1, 500), circle(2.9, 500)], unit="px")
    assert s2.est_to_gt.mean == pytest.approx(0.1, abs=1e-3)
    assert s2.hausdorff == pytest.approx(0.1, abs=1e-3)


def test_speed_5000_by_5000():
    a = np.c_[circle(0.05, 5000), np.zeros(5000)]
    b = np.c_[circle(0.052, 5000, phase=3e-4), 1e-3 * np.sin(np.linspace(0, 6 * np.pi, 5000))]
    polyline_distance(a[:100], b[:100])  # warm-up
    t = time.perf_counter()
    s = polyline_distance(a, b)
    assert time.perf_counter() - t < 1.5  # typically 0.15-0.4 s; margin for a loaded machine
    assert 2e-3 <= s.hausdorff <= math.hypot(2e-3, 1e-3) + 1e-6


def test_bad_inputs():
    with pytest.raises(ValueError, match="dimension mismatch"):
        polyline_distance(np.zeros((4, 2)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match="truth.*non-finite"):
        polyline_distance(circle(1, 10), np.r_[circle(1, 9), [[np.nan, 0]]])
    with pytest.raises(ValueError, match="empty"):
        polyline_distance(np.zeros((0, 2)), circle(1, 10))
    with pytest.raises(ValueError, match="estimated"):
        polyline_distance(np.zeros((5, 4)), circle(1, 10))
    with pytest.raises(ValueError, match="unit"):
        polyline_distance(circle(1, 10), circle(1, 10), unit="mm")


# ------------------------------------------------------------------- image contours


def test_mask_contour_is_half_pixel_outside_pixel_centres():
    m = np.zeros((40, 60), bool)
    x0, x1, y0, y1 = 10, 50, 5, 30
    m[y0 : y1 + 1, x0 : x1 + 1] = True
    (c,) = mask_contours_subpixel(m)
    # straight edges lie between the last pixel centre inside and the first outside
    assert set(np.round(c[:, 0], 9)) >= {x0 - 0.5, x1 + 0.5}
    assert c[:, 0].min() == x0 - 0.5 and c[:, 0].max() == x1 + 0.5
    assert c[:, 1].min() == y0 - 0.5 and c[:, 1].max() == y1 + 0.5
    # corners are cut by the chord between the two edge midpoints of the corner pixel
    assert [x0 - 0.5, y0] in c.tolist() and [x0, y0 - 0.5] in c.tolist()


def test_contour_pixels_distance_inset_rectangle():
    # Mask pixels x0..x1, y0..y1: true boundary on x = x0 - 0.5 etc., corners chamfered
    # by chords from (x0 - 0.5, y0) to (x0, y0 - 0.5). The estimate is the rectangle
    # inset by 1.5 px from the true edges, i.e. with corners (x0 + 1, y0 + 1) ... .
    # est -> gt: every estimated point is exactly 1.5 px from the nearest true edge
    #   (the chamfer is farther: at the corner (x0+1, y0+1) it is 2.5/sqrt(2) = 1.77 px).
    # gt -> est: the chamfer chord points are farthest, at its ends (x0 - 0.5, y0):
    #   distance to the estimated corner (x0 + 1, y0 + 1) = sqrt(1.5^2 + 1^2) = sqrt(3.25).
    m = np.zeros((80, 100), bool)
    x0, x1, y0, y1 = 20, 70, 10, 60
    m[y0 : y1 + 1, x0 : x1 + 1] = True
    est = np.array([[x0 + 1, y0 + 1], [x1 - 1, y0 + 1], [x1 - 1, y1 - 1], [x0 + 1, y1 - 1]], float)
    s = contour_pixels_distance(m, est)
    d = encode(s)
    assert d["est_to_gt_mean_px"] == pytest.approx(1.5, abs=1e-9)
    assert d["est_to_gt_max_px"] == pytest.approx(1.5, abs=1e-9)
    assert d["hausdorff_px"] == pytest.approx(math.sqrt(3.25), abs=1e-9)


def test_contour_pixels_distance_disk_offset():
    H, W = 140, 160
    yy, xx = np.mgrid[0:H, 0:W]
    cx, cy, R = 80.3, 70.6, 50.2
    m = (xx - cx) ** 2 + (yy - cy) ** 2 <= R**2
    s0 = contour_pixels_distance(m, circle(R, 2000, (cx, cy)))
    assert s0.mean_sym < 0.25 and s0.hausdorff < 0.6  # rasterisation only
    s3 = contour_pixels_distance(m, circle(R + 3.0, 2000, (cx, cy)))
    assert s3.est_to_gt.mean == pytest.approx(3.0, abs=0.25)


def test_mask_contours_match_marching_squares():
    contourpy = pytest.importorskip("contourpy")
    H, W = 90, 120
    yy, xx = np.mgrid[0:H, 0:W]
    r2 = (xx - 60.3) ** 2 + (yy - 44.8) ** 2
    ring = (r2 <= 38.6**2) & (r2 >= 12.2**2)
    ellipse = (((xx - 60) * 0.92 + (yy - 45) * 0.39) / 50) ** 2 + ((-(xx - 60) * 0.39 + (yy - 45) * 0.92) / 20) ** 2 <= 1
    edge = xx <= 30  # touches the image border: pixels beyond it count as outside
    for m in (ring, ellipse, edge):
        ours = mask_contours_subpixel(m)
        gen = contourpy.contour_generator(z=np.pad(m.astype(float), 1), name="serial")
        ref = [ln[:-1] - 1 for ln in gen.lines(0.5)]  # closed lines repeat their first point
        assert len(ours) == len(ref)
        s = polyline_distance(ours, ref, unit="px")
        assert s.hausdorff < 1e-9
        assert s.length_est == pytest.approx(s.length_gt)


def test_single_pixel_and_bad_mask():
    m = np.zeros((5, 5), bool)
    m[2, 3] = True
    (c,) = mask_contours_subpixel(m)
    assert sorted(map(tuple, c.tolist())) == sorted([(3.5, 2.0), (3.0, 2.5), (2.5, 2.0), (3.0, 1.5)])
    with pytest.raises(ValueError, match="mask_true"):
        contour_pixels_distance(m.astype(np.uint8), circle(1, 10))
    with pytest.raises(ValueError, match="mask_true.*empty"):
        contour_pixels_distance(np.zeros((5, 5), bool), circle(1, 10))


def brute_distance(P, poly, closed):
    """Distance from points P to the polyline, every segment tried (independent reference)."""
    A = poly if closed else poly[:-1]
    B = np.roll(poly, -1, axis=0) if closed else poly[1:]
    best = np.full(len(P), np.inf)
    for a, b in zip(A, B):
        ab = b - a
        t = np.clip((P - a) @ ab / (ab @ ab), 0, 1)
        best = np.minimum(best, np.linalg.norm(P - a - t[:, None] * ab, axis=1))
    return best


def test_random_polylines_against_dense_sampling():
    # The directed max must be the supremum along the source (to within the stated
    # tolerance) and the mean its arc-length average; checked against 50k samples.
    from platebench.evaluation.boundary_metrics import _ArcParam

    rng = np.random.default_rng(0)
    for trial in range(6):
        D = 2 + trial % 2
        closed = trial % 3 != 0
        a = rng.normal(size=(rng.integers(3, 30), D))
        b = 1.5 * rng.normal(size=(rng.integers(3, 30), D))
        s = polyline_distance(a, b, closed=closed, unit="px")
        for src, dst, st in ((a, b, s.est_to_gt), (b, a, s.gt_to_est)):
            pa = _ArcParam(src, closed)
            ss = np.linspace(0, pa.L, 50_001)
            d = brute_distance(pa.at(ss), dst, closed)
            assert st.max >= d.max() - 1e-12
            assert st.max <= d.max() + 1e-4 * s.sample_spacing + pa.L / 50_000
            assert st.mean == pytest.approx(np.trapezoid(d, ss) / pa.L, rel=1e-4)
