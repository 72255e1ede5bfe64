"""Tests of evaluation.stats and evaluation.point_metrics on cases with known answers."""

import math

import numpy as np
import pytest
import trimesh

from platebench.bench.io.codecs import encode
from platebench.evaluation.point_metrics import (
    closest_point_on_mesh,
    match_stats,
    point_to_surface_distance,
    point_triangle_distance,
    score_points,
)
from platebench.evaluation.stats import ErrorStats, nearest_rank_quantile


def rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


# A tilted left camera looking roughly down (-Z world): OpenCV frame, x_cam = R x_world + t.
R_DOWN = np.diag([1.0, -1.0, -1.0])  # camera z = world -Z
R_TILT = rot([0.3, 1.0, 0.2], 0.35) @ R_DOWN


def flat_grid_mesh(nx=101, ny=61, sx=0.1, sy=0.06, z=lambda x, y: 0.0 * x):
    x, y = np.meshgrid(np.linspace(-sx / 2, sx / 2, nx), np.linspace(-sy / 2, sy / 2, ny))
    V = np.c_[x.ravel(), y.ravel(), z(x.ravel(), y.ravel())]
    idx = np.arange(nx * ny).reshape(ny, nx)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
    F = np.r_[np.c_[a, b, d], np.c_[a, d, c]]
    return trimesh.Trimesh(V, F, process=False)


# ----------------------------------------------------------------------------- stats


def test_error_stats_by_hand():
    # values 1, 2, 3, 4: mean 2.5; rms sqrt((1+4+9+16)/4) = sqrt(7.5);
    # p95 (numpy linear): position 0.95*3 = 2.85 -> 3 + 0.85*(4-3) = 3.85
    s = ErrorStats.from_abs([1.0, 2.0, 3.0, 4.0])
    assert s.mean == pytest.approx(2.5)
    assert s.rms == pytest.approx(math.sqrt(7.5))
    assert s.max == 4.0
    assert s.p95 == pytest.approx(3.85)
    assert s.count == 4
    d = encode(s, "depth", "mm", 1e3)
    assert d == pytest.approx(
        {"depth_mean_mm": 2500.0, "depth_rms_mm": 1e3 * math.sqrt(7.5), "depth_max_mm": 4000.0,
         "depth_p95_mm": 3850.0, "depth_count": 4}
    )


def test_error_stats_rejects_signed_nan_empty():
    with pytest.raises(ValueError, match="absolute"):
        ErrorStats.from_abs([0.1, -0.1])
    with pytest.raises(ValueError, match="non-finite"):
        ErrorStats.from_abs([0.1, np.nan])
    with pytest.raises(ValueError, match="empty"):
        ErrorStats.from_abs([])
    e = ErrorStats.from_abs([], allow_empty=True)
    assert e.count == 0 and math.isnan(e.mean)


def test_weighted_stats():
    # weights 3 and 1 on values 1 and 5: mean (3+5)/4 = 2, rms sqrt((3+25)/4) = sqrt(7)
    s = ErrorStats.from_abs([1.0, 5.0], weights=[3.0, 1.0])
    assert s.mean == pytest.approx(2.0)
    assert s.rms == pytest.approx(math.sqrt(7.0))
    assert s.p95 == 5.0  # 95 % of the weight is reached only at 5


def test_nearest_rank_quantile():
    v = [0.4, 0.1, 0.3, 0.2]  # sorted 0.1 0.2 0.3 0.4
    assert nearest_rank_quantile(v, 50) == 0.2  # rank ceil(2) = 2
    assert nearest_rank_quantile(v, 90) == 0.4  # rank ceil(3.6) = 4
    assert nearest_rank_quantile([1.0, np.inf], 50) == 1.0
    assert nearest_rank_quantile([1.0, np.inf], 99) == np.inf
    assert math.isnan(nearest_rank_quantile([], 50))


# ---------------------------------------------------------------------------- points


def test_depth_offset_along_tilted_left_axis():
    rng = np.random.default_rng(1)
    truth = rng.uniform(-0.05, 0.05, (16, 3))
    optical_axis_world = R_TILT[2]  # third row of R = camera +z in world coordinates
    est = truth + 0.3e-3 * optical_axis_world
    s = score_points(est, truth, R_TILT)
    d = encode(s)
    for k in ("depth_mean_mm", "depth_rms_mm", "depth_max_mm", "depth_p95_mm", "err3d_max_mm"):
        assert d[k] == pytest.approx(0.3, abs=1e-12)
    for k in ("x_max_mm", "y_max_mm", "xy_radial_max_mm", "xy_radial_rms_mm"):
        assert d[k] == pytest.approx(0.0, abs=1e-12)
    assert d["depth_mean_signed_mm"] == pytest.approx(0.3)  # farther from the camera
    assert d["count"] == 16


def test_depth_error_equals_difference_of_z_depths():
    # depth = (R x + t)_z, so the depth error of a point is z_cam(est) - z_cam(truth).
    rng = np.random.default_rng(2)
    t = np.array([0.01, -0.02, 0.40])
    truth = rng.uniform(-0.05, 0.05, (50, 3))
    est = truth + rng.normal(scale=1e-3, size=truth.shape)
    z = lambda X: (X @ R_TILT.T + t)[:, 2]
    uv = lambda X: (X @ R_TILT.T + t)[:, :2]
    s = score_points(est, truth, R_TILT)
    dz = z(est) - z(truth)
    assert s.depth.mean == pytest.approx(np.mean(np.abs(dz)))
    assert s.depth.max == pytest.approx(np.max(np.abs(dz)))
    assert s.depth_bias_signed == pytest.approx(np.mean(dz))
    dxy = uv(est) - uv(truth)
    assert s.xy_radial.rms == pytest.approx(np.sqrt(np.mean(np.sum(dxy**2, axis=1))))
    assert s.err3d.mean == pytest.approx(np.mean(np.linalg.norm(est - truth, axis=1)))


def test_lateral_offset_and_signed_errors_do_not_cancel():
    truth = np.zeros((4, 3))
    cam_x_world, cam_z_world = R_TILT[0], R_TILT[2]
    d = 0.7e-3
    sx = np.array([1, -1, 1, -1])[:, None]  # +d, -d along camera x: signed mean 0
    sz = np.array([1, -1, -1, 1])[:, None]  # +d, -d along camera z (depth)
    est = truth + sx * d * cam_x_world + sz * d * cam_z_world
    s = encode(score_points(est, truth, R_TILT))
    assert s["x_mean_mm"] == pytest.approx(0.7)
    assert s["x_mean_signed_mm"] == pytest.approx(0.0, abs=1e-12)
    assert s["depth_mean_mm"] == pytest.approx(0.7)
    assert s["depth_mean_signed_mm"] == pytest.approx(0.0, abs=1e-12)
    assert s["y_max_mm"] == pytest.approx(0.0, abs=1e-12)
    assert s["err3d_mean_mm"] == pytest.approx(0.7 * math.sqrt(2))


def test_score_points_bad_inputs():
    a = np.zeros((3, 3))
    with pytest.raises(ValueError, match="shape mismatch"):
        score_points(a, np.zeros((4, 3)), np.eye(3))
    with pytest.raises(ValueError, match="estimated"):
        score_points(np.zeros((3, 2)), np.zeros((3, 2)), np.eye(3))
    b = a.copy()
    b[1, 2] = np.nan
    with pytest.raises(ValueError, match="estimated.*non-finite"):
        score_points(b, a, np.eye(3))
    with pytest.raises(ValueError, match="empty"):
        score_points(np.zeros((0, 3)), np.zeros((0, 3)), np.eye(3))
    with pytest.raises(ValueError, match="R_left"):
        score_points(a, a, np.diag([2000.0, 2000.0, 1.0]))  # K, not R


# ------------------------------------------------------------------- point-to-mesh


def test_point_to_flat_mesh_known_height():
    mesh = flat_grid_mesh()
    rng = np.random.default_rng(3)
    P = np.c_[rng.uniform(-0.045, 0.045, 500), rng.uniform(-0.025, 0.025, 500), np.full(500, 0.5e-3)]
    P[::2, 2] = -0.5e-3  # below the plate: absolute distance
    d = point_to_surface_distance(P, mesh)
    np.testing.assert_allclose(d, 0.5e-3, rtol=0, atol=1e-15)
    # beyond the edge x = 0.05: distance to the edge line
    Q = np.array([[0.052, 0.0, 0.0015]])
    assert point_to_surface_distance(Q, mesh)[0] == pytest.approx(math.hypot(0.002, 0.0015))


def test_point_to_mesh_exact_against_brute_force_and_trimesh_in_mm():
    mesh = flat_grid_mesh(nx=61, ny=41, z=lambda x, y: 0.5 * x**2 + 0.1 * x * y)
    rng = np.random.default_rng(4)
    P = rng.uniform([-0.06, -0.04, -0.004], [0.06, 0.04, 0.008], (400, 3))
    P[:20, 2] += 0.08  # some points far above the plate
    closest, d, face = closest_point_on_mesh(P, mesh)
    T = mesh.triangles
    brute = np.array(
        [point_triangle_distance(np.repeat(p[None], len(T), 0), T[:, 0], T[:, 1], T[:, 2]).min() for p in P]
    )
    np.testing.assert_allclose(d, brute, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(closest - P, axis=1), d, atol=1e-15)
    # trimesh's closest_point is reliable in millimetres (not in metres, see the docstring)
    mesh_mm = trimesh.Trimesh(mesh.vertices * 1e3, mesh.faces, process=False)
    _, d_mm, _ = trimesh.proximity.closest_point(mesh_mm, P * 1e3)
    np.testing.assert_allclose(d * 1e3, d_mm, atol=1e-9)


@pytest.mark.parametrize("seed", [5, 6])
def test_point_to_mesh_exact_on_a_mesh_of_mixed_triangle_sizes(seed):
    """A dent plate's mesh: triangles of 0.15 mm in the dent and up to 14 mm on the flat around it
    (searched in radius classes, ``radius_classes``); the distances and nearest faces are the
    brute-force minimum over every triangle."""
    from platebench.evaluation.point_metrics import radius_classes
    from platebench.plates import Dent, PlateSpec, build_plate

    mesh = build_plate(PlateSpec(0.1165, 0.0735, deformation=Dent(0.003, 0.02))).mesh
    T = mesh.triangles
    r = np.linalg.norm(T - T.mean(axis=1)[:, None], axis=2).max(axis=1)
    assert r.max() / np.median(r) > 20 and len(radius_classes(r)) >= 2  # the case the classes are for
    rng = np.random.default_rng(seed)
    V = mesh.vertices[rng.choice(len(mesh.vertices), 150)]
    P = np.vstack([V + rng.normal(0.0, 2e-3, V.shape),  # near the surface, dent and flat
                   rng.uniform([-0.07, -0.05, -0.02], [0.07, 0.05, 0.03], (50, 3))])  # and around it
    closest, d, face = closest_point_on_mesh(P, mesh)
    brute = np.array([point_triangle_distance(np.repeat(p[None], len(T), 0), T[:, 0], T[:, 1], T[:, 2]).min()
                      for p in P])
    np.testing.assert_allclose(d, brute, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(closest_point_on_mesh(P, mesh, by_radius=False)[1], d)  # the one-class search
    own = point_triangle_distance(P, T[face, 0], T[face, 1], T[face, 2])  # the face returned is a nearest one
    np.testing.assert_allclose(own, d, rtol=0, atol=1e-15)
    mesh_mm = trimesh.Trimesh(mesh.vertices * 1e3, mesh.faces, process=False)
    _, d_mm, _ = trimesh.proximity.closest_point(mesh_mm, P * 1e3)
    np.testing.assert_allclose(d * 1e3, d_mm, atol=1e-9)


@pytest.mark.parametrize("axis_deg, seed", [(29.0, 7), (31.0, 9)])
def test_point_to_mesh_is_the_brute_force_minimum_to_the_last_bit(axis_deg, seed):
    """Points 10 to 30 cm off a 200-degree curl's outline, where the triangles sharing the nearest
    vertex tie to within rounding, and points inside the curl, where much of the mesh is nearly
    equidistant: each distance is bit for bit the smallest exact distance over every triangle (no
    bound computed by another formula, the tree's distances or a bounding box's, may prune the
    triangle that wins by one ulp), and the face returned gives it."""
    from platebench.plates import CylindricalBend, PlateSpec, build_plate

    plate = build_plate(PlateSpec(0.1165, 0.0735, deformation=CylindricalBend(math.radians(200.0), "up",
                                                                              math.radians(axis_deg))))
    mesh, T = plate.mesh, plate.mesh.triangles
    rng = np.random.default_rng(seed)
    u = rng.normal(size=(1000, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    B = np.asarray(plate.boundary)[rng.choice(len(plate.boundary), len(u))]
    lo, hi = mesh.bounds
    P = np.vstack([B + rng.uniform(0.1, 0.3, (len(u), 1)) * u, lo + rng.uniform(size=(100, 3)) * (hi - lo)])
    closest, d, face = closest_point_on_mesh(P, mesh)
    brute = np.array([point_triangle_distance(np.repeat(p[None], len(T), 0), T[:, 0], T[:, 1], T[:, 2]).min()
                      for p in P])
    np.testing.assert_array_equal(d, brute)
    np.testing.assert_array_equal(point_triangle_distance(P, T[face, 0], T[face, 1], T[face, 2]), d)

def test_radius_classes_split_by_factors_of_two():
    from platebench.evaluation.point_metrics import radius_classes

    assert [c.tolist() for c in radius_classes(np.array([1.0, 1.5, 1.9]))] == [[0, 1, 2]]
    assert [c.tolist() for c in radius_classes(np.array([8.0, 1.0, 2.5, 1.2, 0.0]))] == [[4], [1, 3], [2], [0]]


def test_point_to_mesh_bad_input():
    mesh = flat_grid_mesh(nx=5, ny=5)
    with pytest.raises(ValueError, match="points.*non-finite"):
        point_to_surface_distance(np.array([[0, 0, np.nan]]), mesh)
    with pytest.raises(ValueError, match="points"):
        point_to_surface_distance(np.zeros((2, 2)), mesh)


# ---------------------------------------------------------------------- matching


def test_match_stats_by_hand():
    expected = np.array([(r, c) for r in range(4) for c in range(4)])  # 16 squares
    visible = expected[:14]  # (3, 2) and (3, 3) hidden from one camera
    # 15 reported pairs: 13 visible ids, (0, 0) twice, and (3, 3) which is not visible
    detected = np.array([tuple(v) for v in visible[:13]] + [(0, 0), (3, 3)])
    correct = np.ones(15, dtype=bool)
    correct[[4, 14]] = False  # pair 4 (id (1, 0)) and the (3, 3) pair are mismatched
    m = encode(match_stats(detected, expected, visible, correct))
    assert m["expected_count"] == 16 and m["visible_count"] == 14
    assert m["reported_count"] == 15 and m["duplicate_count"] == 1
    assert m["detected_visible_count"] == 13  # unique visible ids among the reports
    assert m["detected_not_visible_count"] == 1  # (3, 3)
    assert m["missed_count"] == 1  # visible id (3, 1) never reported
    assert m["correct_count"] == 13 and m["wrong_count"] == 2
    assert m["correct_match_rate_frac"] == pytest.approx(13 / 15)
    assert m["detection_rate_frac"] == pytest.approx(13 / 14)
    # visible ids with a correct pair: 13 reported visible ids minus (1, 0) -> 12
    assert m["correct_visible_rate_frac"] == pytest.approx(12 / 14)


def test_match_stats_empty_and_errors():
    m = match_stats([], [1, 2], [1], np.zeros(0, bool))
    assert m.reported == 0 and math.isnan(m.correct_match_rate) and m.detection_rate == 0.0
    with pytest.raises(ValueError, match="length mismatch"):
        match_stats([1, 2], [1, 2], [1], np.array([True]))
    with pytest.raises(ValueError, match="visible_ids"):
        match_stats([1], [1, 2], [3], np.array([True]))
