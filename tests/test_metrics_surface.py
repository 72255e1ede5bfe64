"""Tests of evaluation.surface_metrics on flat and bent plates with known answers."""

import math

import numpy as np
import pytest
import trimesh

from platebench.bench.io.codecs import encode
from platebench.evaluation.surface_metrics import score_surface

LX, LY = 0.10, 0.06  # plate 100 mm x 60 mm in z = 0


def grid_mesh(nx=101, ny=61, z=lambda x, y: 0.0 * x):
    x, y = np.meshgrid(np.linspace(-LX / 2, LX / 2, nx), np.linspace(-LY / 2, LY / 2, ny))
    V = np.c_[x.ravel(), y.ravel(), z(x.ravel(), y.ravel())]
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    return trimesh.Trimesh(V, np.r_[np.c_[a, b, d], np.c_[a, d, c]], process=False)


def grid_points(x0, x1, y0, y1, step, z):
    x, y = np.meshgrid(np.arange(x0, x1 + step / 2, step), np.arange(y0, y1 + step / 2, step))
    return np.c_[x.ravel(), y.ravel(), np.full(x.size, z)]


MESH = grid_mesh()


def test_points_at_known_height_full_coverage():
    P = grid_points(-LX / 2, LX / 2, -LY / 2, LY / 2, 0.5e-3, 0.3e-3)
    P[::2, 2] = -0.3e-3  # +d and -d: absolute distances, no cancellation
    s = score_surface(P, MESH, LX * LY, sample_spacing_m=0.5e-3)
    d = encode(s)
    for k in ("dist_mean_mm", "dist_rms_mm", "dist_max_mm", "dist_p95_mm"):
        assert d[k] == pytest.approx(0.3, abs=1e-9)
    # every surface sample is within 0.5 mm * sqrt(2) / 2 = 0.354 mm of a foot point (< 1 mm radius)
    assert d["surface_coverage_frac"] == pytest.approx(1.0)
    assert d["plate_area_mm2"] == pytest.approx(6000.0)
    assert d["gt_sample_count"] == math.ceil(LX * LY / 0.5e-3**2)  # 24000
    assert d["coverage_radius_mm"] == pytest.approx(1.0)


def test_half_plate_coverage():
    # Points over x <= 0 only. Covered: x <= 0 plus a band of the coverage radius r = 1 mm
    # beyond the last column -> (50 + 1) mm / 100 mm = 0.51, up to sampling noise
    # sqrt(0.51 * 0.49 / 24000) = 0.003.
    P = grid_points(-LX / 2, 0.0, -LY / 2, LY / 2, 0.5e-3, 1e-3)
    s = score_surface(P, MESH, LX * LY, sample_spacing_m=0.5e-3)
    assert s.surface_coverage_frac == pytest.approx(0.51, abs=0.01)
    assert s.dist.max == pytest.approx(1e-3)
    # same seed -> same samples -> same number
    assert score_surface(P, MESH, LX * LY, sample_spacing_m=0.5e-3).surface_coverage_frac == s.surface_coverage_frac


def test_depth_error_does_not_uncover_but_outlier_gate_does():
    P = grid_points(-LX / 2, LX / 2, -LY / 2, LY / 2, 1e-3, 3e-3)  # 3 mm above the plate
    s = score_surface(P, MESH, LX * LY, sample_spacing_m=1e-3)
    assert s.surface_coverage_frac == pytest.approx(1.0)  # lateral test: foot points cover the plate
    g = score_surface(P, MESH, LX * LY, sample_spacing_m=1e-3, max_distance_m=2e-3)
    assert g.surface_coverage_frac == 0.0 and g.points_used_for_coverage == 0
    assert g.dist.mean == pytest.approx(3e-3)  # accuracy still counts every point
    assert encode(g)["coverage_max_distance_mm"] == pytest.approx(2.0)


def test_plate_area_normalises_coverage():
    P = grid_points(-LX / 2, LX / 2, -LY / 2, LY / 2, 0.5e-3, 0.0)
    # e.g. a two-sided plate mesh whose visible face is half the mesh area
    s = score_surface(P, MESH, 2 * LX * LY, sample_spacing_m=1e-3)
    assert s.surface_coverage_frac == pytest.approx(0.5)
    assert score_surface(P, MESH, None, sample_spacing_m=1e-3).plate_area_m2 == pytest.approx(LX * LY)


def test_bent_plate_normal_offset():
    # Plate bent about the y axis by angle 2*theta: z = |x| tan(theta) (a V fold along x = 0).
    theta = math.radians(10)
    mesh = grid_mesh(z=lambda x, y: np.abs(x) * math.tan(theta))
    # Points offset by h along the face normal over the interior of the right face
    # (x > 2 mm keeps them nearer to the right face than to the left one).
    h = 0.4e-3
    n = np.array([-math.sin(theta), 0.0, math.cos(theta)])
    x, y = np.meshgrid(np.linspace(0.002, 0.045, 40), np.linspace(-0.025, 0.025, 30))
    on = np.c_[x.ravel(), y.ravel(), x.ravel() * math.tan(theta)]
    s = score_surface(on + h * n, mesh, None, sample_spacing_m=1e-3)
    assert s.dist.mean == pytest.approx(h, rel=1e-9)
    assert s.dist.max == pytest.approx(h, rel=1e-9)


def test_bad_inputs():
    with pytest.raises(ValueError, match="vertices"):
        score_surface(np.zeros((5, 2)), MESH, LX * LY)
    with pytest.raises(ValueError, match="vertices.*non-finite"):
        score_surface(np.array([[0, 0, np.nan]]), MESH, LX * LY)
    with pytest.raises(ValueError, match="vertices: empty"):
        score_surface(np.zeros((0, 3)), MESH, LX * LY)
    with pytest.raises(ValueError, match="sample_spacing_m"):
        score_surface(np.zeros((1, 3)), MESH, LX * LY, sample_spacing_m=-1.0)
    with pytest.raises(ValueError, match="sample_spacing_m"):
        score_surface(np.zeros((1, 3)), MESH, LX * LY, sample_spacing_m=1e-6)  # too many samples


def test_coverage_faces_restricts_the_sampled_area():
    # Faces with centroid x < 0 are the left half; points cover the left half only.
    # Restricting coverage to those faces: covered ~ all of them (1.0), area 3000 mm^2.
    left = MESH.triangles_center[:, 0] < 0
    P = grid_points(-LX / 2, 0.0, -LY / 2, LY / 2, 0.5e-3, 0.0)
    s = score_surface(P, MESH, None, sample_spacing_m=1e-3, coverage_faces=left)
    assert s.plate_area_m2 == pytest.approx(LX * LY / 2)
    assert s.surface_coverage_frac == pytest.approx(1.0)
    s2 = score_surface(P, MESH, None, sample_spacing_m=1e-3, coverage_faces=np.nonzero(~left)[0])
    assert s2.surface_coverage_frac == pytest.approx(2e-3 / (LX / 2), abs=0.01)  # the 2 mm band beyond x = 0
    with pytest.raises(ValueError, match="coverage_faces"):
        score_surface(P, MESH, None, coverage_faces=np.zeros(3, bool))
