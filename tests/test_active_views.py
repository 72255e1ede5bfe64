"""Active stereo at every measuring pose: the projector check of the square centres (analytic rays,
real renders at turned poses, squares matched one array position off), and the merged multi-view
reconstruction of a sensing run scored against ground truth."""
from __future__ import annotations

import math

import numpy as np
import pytest

from platebench.reconstruction.paper.false_boundary import FeatureRays
from platebench.reconstruction.strategy.active_views import (
    ACTIVE_RAY_TOL_M,
    merge,
    nearest_feature_ray,
    on_feature_rays,
)


def _fan(n=5, spacing=0.01, depth=0.4):
    """n x n rays from the origin through a grid of ``spacing`` at z = ``depth``."""
    g = (np.arange(n) - (n - 1) / 2) * spacing
    X, Y = np.meshgrid(g, g)
    hits = np.column_stack([X.ravel(), Y.ravel(), np.full(n * n, depth)])
    d = hits / np.linalg.norm(hits, axis=1, keepdims=True)
    return FeatureRays(np.zeros((n * n, 3)), d, np.arange(100, 100 + n * n)), hits


def test_nearest_feature_ray_gives_the_exact_distance_to_the_nearest_ray():
    rays, hits = _fan()
    rng = np.random.default_rng(0)
    k = rng.integers(0, len(hits), 20)
    # move each point by 0.7 mm perpendicular to its own ray (less than half the 10 mm spacing)
    d = rays.directions[k]
    perp = np.cross(d, [0.0, 1.0, 0.0])
    perp /= np.linalg.norm(perp, axis=1, keepdims=True)
    P = hits[k] + 0.7e-3 * perp
    ids, dist = nearest_feature_ray(P, rays)
    assert np.array_equal(ids, rays.ids[k])
    np.testing.assert_allclose(dist, 0.7e-3, rtol=1e-9)
    # a point behind the rays' origin is measured to the origin
    ids, dist = nearest_feature_ray(np.array([[0.0, 0.0, -0.002]]), rays)
    assert dist[0] == pytest.approx(0.002)


def test_the_projector_check_keeps_centres_on_rays_and_drops_the_rest_and_shared_features():
    rays, hits = _fan()
    uv = np.arange(2 * len(hits), dtype=float).reshape(-1, 2)
    P = hits.copy()
    P[3] += [ACTIVE_RAY_TOL_M * 2, 0, 0]  # off every ray (spacing 10 mm)
    P[7] = [np.nan] * 3  # no disparity
    P[9] = hits[10] + [0, 0.2e-3, 0]  # claims feature 110 beside the true centre of 110: both dropped
    a = on_feature_rays("v", P, uv, rays)
    dropped = {3, 7, 9, 10}
    keep = [i for i in range(len(P)) if i not in dropped]
    assert a.matched == len(P) and a.rejected == len(dropped)
    np.testing.assert_array_equal(a.feature_id, rays.ids[keep])
    np.testing.assert_array_equal(a.uv_left, uv[keep])
    assert a.ray_distance_m.max() < 1e-12


def test_merge_offsets_every_poses_faces_into_one_mesh():
    from platebench.reconstruction.strategy.active_views import ActivePoints
    from platebench.reconstruction.strategy.surface_model import Membrane

    tri = np.array([[0, 1, 2]])
    m1 = Membrane("a", np.eye(3), tri, np.zeros(3))
    m2 = Membrane("b", np.eye(3) + 1, tri, np.zeros(3))
    a1 = ActivePoints("a", np.ones((2, 3)), np.zeros((2, 2)), np.zeros(2, int), np.zeros(2), 2, 0)
    a2 = ActivePoints.empty("b")
    r = merge(np.zeros((4, 3)), [a1, a2], [m1, m2])
    assert r.views == ("a", "b") and len(r.points) == 2 and list(r.point_view) == [0, 0]
    np.testing.assert_array_equal(r.surface_faces, [[0, 1, 2], [3, 4, 5]])
    np.testing.assert_array_equal(r.surface_vertices[r.surface_faces[1]], np.eye(3) + 1)


# ------------------------------------------------------------------ rendered
@pytest.mark.render
@pytest.mark.parametrize("tilt_deg, distance_m", [(29.0, 0.395), (31.0, 0.405), (46.0, 0.40)])
def test_turned_pose_measures_squares_on_the_plate_and_rejects_squares_matched_one_off(tilt_deg, distance_m):
    """The reference plate seen from a pose turned about the plate's width axis, projector between
    the cameras: every matched square centre passes the projector check and lies on the true
    surface (exact closest point on the plate's mesh); the same squares matched one array position
    off (left i with right i+1) triangulate millimetres off every feature ray and are all rejected."""
    from platebench.bench.config import SampleConfig, SceneParams
    from platebench.bench.run.sensing.sensor import ACTIVE, PASSIVE, SimulatedSensor, plate_masks
    from platebench.evaluation.point_metrics import closest_point_on_mesh
    from platebench.reconstruction.paper.pipeline import projector_feature_rays, square_stereo
    from platebench.reconstruction.strategy.poses import SensorPose
    from platebench.scenes.camera import triangulate_rectified
    from platebench.scenes.scene_spec import RenderSettings

    s = SimulatedSensor(SampleConfig(scene=SceneParams(width=320, height=240), render=RenderSettings(spp=2)))
    a = math.radians(tilt_deg)
    pose = SensorPose(distance_m * np.array([math.sin(a), 0.0, math.cos(a)]), np.zeros(3),
                      np.array([math.cos(a), 0.0, -math.sin(a)]), "turned")
    shot = s.shoot(pose, PASSIVE + ACTIVE)
    masks = {c: m.mask for c, m in plate_masks(shot.digital).items()}
    sq = square_stereo(shot.digital, masks, shot.scene.rig)
    rays = projector_feature_rays(shot.scene.projector.camera, shot.scene.projector.pattern)
    good = on_feature_rays("turned", sq.points, sq.uv_left, rays)
    assert len(sq.points) >= 6 and good.rejected == 0
    assert closest_point_on_mesh(good.points, s.plate.mesh)[1].max() < 1e-3
    L, R = [], []
    for gl, gr in sq.matches.group_pairs:
        A, B = sq.groups["left"][gl], sq.groups["right"][gr]
        L += [sq.detections["left"].squares[i].centroid for i in A[:-1]]
        R += [sq.detections["right"].squares[j].centroid for j in B[1:]]
    L, R = np.array(L), np.array(R)
    assert len(L) >= 4
    P = triangulate_rectified(L[:, 0], 0.5 * (L[:, 1] + R[:, 1]), R[:, 0], shot.scene.rig.left,
                              shot.scene.rig.baseline_m)
    bad = on_feature_rays("one off", P, L, rays)
    assert len(bad.points) == 0 and bad.rejected == len(P)
    finite = np.all(np.isfinite(P), axis=1)
    assert nearest_feature_ray(P[finite], rays)[1].min() > 3 * ACTIVE_RAY_TOL_M


@pytest.mark.render
@pytest.mark.parametrize("axis_deg, distance_m", [(29.0, 0.40), (31.0, 0.405)])
def test_merged_reconstruction_of_a_240_degree_curl_is_measured_from_every_pose(tmp_path, axis_deg, distance_m):
    """Convex 240 degrees, which no single pose sees whole: the merged reconstruction holds square
    centres from several poses, all on the true surface, and its surface (the poses' visible
    surfaces) covers far more of the plate than the stage-3 pose's; its files are written for
    ``platebench evaluate``."""
    from dataclasses import replace

    from platebench.bench.config import SampleConfig, SceneParams
    from platebench.bench.config.sample_config import parse_grid
    from platebench.bench.run.sensing import SensingOptions, run_sensing
    from platebench.plates import CylindricalBend
    from platebench.scenes.scene_spec import RenderSettings

    # at 320 x 240 the study's 6 x 12 grid (made for 640 x 480) gives 3-pixel squares: a coarser one
    cfg = SampleConfig(scene=SceneParams(width=320, height=240, pattern=parse_grid("5x10@18")),
                       render=RenderSettings(spp=2))
    cfg = replace(cfg, plate=replace(cfg.plate, deformation=CylindricalBend(math.radians(240), "down",
                                                                            math.radians(axis_deg))))
    s = run_sensing(cfg, tmp_path, SensingOptions(working_distance_m=distance_m, verify_grid=None))  # 5x10@18 everywhere
    m = s.final.merged
    assert m.points > s.final.accuracy.points_scored if s.final.accuracy else m.points > 0
    assert m.points_rms_mm < 0.5
    # no mismatched array (tens of mm deep); a square cut by an occluding contour may be biased by
    # a few mm (the study: worst 0.4-5.5 mm per plate), but nearly all lie on the plate
    assert m.points_max_mm < 6.0
    assert m.surface_coverage_frac > 0.9  # the merged surface covers the curl that no single pose sees whole
    npz = np.load(tmp_path / "multiview.npz")
    from platebench.evaluation.point_metrics import closest_point_on_mesh
    from platebench.plates import build_plate
    d = closest_point_on_mesh(npz["active_points"], build_plate(cfg.plate).mesh)[1]
    assert len(d) == m.points and np.mean(d < 2e-3) > 0.95, np.sort(d)[-20:]
    assert len(set(npz["active_view"].tolist())) >= 5
    assert (tmp_path / "merged_points.ply").is_file() and (tmp_path / "merged_surface.ply").is_file()


@pytest.mark.parametrize("distance_m", [0.395, 0.405])
def test_centres_matched_k_squares_off_miss_every_ray_only_with_the_projector_beside_the_rig(distance_m):
    """A flat plate square to the rig at 0.4 m, the study's grid: pair every left square with the
    right image of the square k positions along its row (k = 1..8, both ways) and triangulate.
    From the mid-baseline point the projector sees half the stereo parallax, so even k land exactly
    on a feature's ray; ``projector_pose`` (30 mm across the baseline) keeps every such centre
    well outside ``ACTIVE_RAY_TOL_M`` (geometry only, no render)."""
    from platebench.bench.config import SampleConfig, SceneParams
    from platebench.bench.config.sample_config import parse_grid
    from platebench.reconstruction.paper.pipeline import projector_feature_rays
    from platebench.reconstruction.strategy.active_views import projector_pose
    from platebench.reconstruction.strategy.poses import SensorPose
    from platebench.scenes.camera import triangulate_rectified
    from platebench.scenes.scene_spec import scene_for_pose

    base = SampleConfig(scene=SceneParams(width=640, height=480, pattern=parse_grid("6x12@12"))).scene.build()
    pose = SensorPose(np.array([0.0, 0.0, distance_m]), np.zeros(3), np.array([1.0, 0.0, 0.0]))

    def worst(projector):
        sc = scene_for_pose(pose.center, pose.target, pose.baseline_dir, base, projector_center=projector.center,
                            projector_target=projector.target)
        rays = projector_feature_rays(sc.projector.camera, sc.projector.pattern)
        X = rays.origins - (rays.origins[:, 2] / rays.directions[:, 2])[:, None] * rays.directions  # on z = 0
        uvl, uvr = sc.rig.left.project(X), sc.rig.right.project(X)
        at = {(f.row, f.col): k for k, f in enumerate(sc.projector.pattern.features)}
        assert [f.id for f in sc.projector.pattern.features] == list(rays.ids)
        out = {}
        for k in range(1, 9):
            pairs = [(i, at[(r, c + k)]) for (r, c), i in at.items() if (r, c + k) in at]
            pairs += [(j, i) for i, j in pairs]
            i, j = np.array(pairs).T
            P = triangulate_rectified(uvl[i, 0], uvl[i, 1], uvr[j, 0], sc.rig.left, sc.rig.baseline_m)
            out[k] = nearest_feature_ray(P[np.all(np.isfinite(P), axis=1)], rays)[1].min()
        return out

    mid = worst(pose)
    assert max(mid[k] for k in (2, 4, 6, 8)) < 1e-6  # the degenerate placement
    beside = worst(projector_pose(pose))
    assert min(beside.values()) > 1.5 * ACTIVE_RAY_TOL_M
