"""Ground truth proven by independent paths: trimesh ray casting and the analytic cylinder."""
from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from platebench.bench.io.images import read_exr, read_pfm, read_png
from platebench.bench.io.sample_files import load_calibration
from platebench.plates import CylindricalBend, Dent, Dome, Fold, PlateSpec, Twist, build_plate
from platebench.scenes.camera import Camera
from platebench.scenes.render.ground_truth import GroundTruthCaster
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.lens import BrownConrady
from platebench.scenes.scene_spec import reference_scene, scene_for_pose

pytestmark = pytest.mark.render


def test_gt_depth_equals_trimesh_ray_cast_of_written_sample(small_sample_dir):
    """Read plate.ply + calib.json like a user would and cast rays with trimesh (embree)."""
    d = small_sample_dir
    mesh = trimesh.load(d / "plate.ply", process=False, force="mesh")
    calib = load_calibration(d)
    for cam_name in ("left", "right"):
        cam: Camera = getattr(calib.rig, cam_name)
        vv, uu = np.mgrid[0:cam.height, 0:cam.width]
        origin, dirs = cam.rays(np.column_stack([uu.ravel(), vv.ravel()]).astype(float))
        locs, ray_idx, _ = mesh.ray.intersects_location(np.repeat(origin[None], len(dirs), 0), dirs,
                                                        multiple_hits=False)
        tm_depth = np.full(cam.width * cam.height, np.inf)
        tm_depth[ray_idx] = cam.depth(locs)
        tm_depth = tm_depth.reshape(cam.height, cam.width)
        gt = read_exr(d / "gt" / f"{cam_name}_depth.exr")
        both = np.isfinite(gt) & np.isfinite(tm_depth)
        # Masks agree except possibly on rays grazing the outline.
        disagree = np.isfinite(gt) ^ np.isfinite(tm_depth)
        assert both.sum() > 10000
        assert disagree.sum() <= 0.002 * both.sum()
        assert np.abs(gt[both] - tm_depth[both]).max() <= 1e-6


def test_gt_points_lie_on_the_analytic_cylinder(small_sample):
    sample, _ = small_sample
    spec = sample.config.plate
    R = spec.length_m / spec.deformation.angle_rad  # bend up: axis along Y at height R
    for cam in ("left", "right"):
        g = sample.gt[cam]
        vv, uu = np.nonzero(g.mask)
        o, d = sample.scene.rig.cameras[cam].rays(np.column_stack([uu, vv]).astype(float))
        P = o + d * (g.depth64[g.mask] / (d @ sample.scene.rig.cameras[cam].R[2]))[:, None]
        r = np.hypot(P[:, 0], P[:, 2] - R)
        assert np.abs(r - R).max() < 1e-6  # mesh facet error < 1 um
        n = g.normals[g.mask].astype(np.float64)
        n_true = np.column_stack([-P[:, 0], np.zeros(len(P)), R - P[:, 2]]) / r[:, None]
        assert np.degrees(np.arccos(np.clip((n * n_true).sum(1), -1, 1))).max() < 0.02


def test_disparity_file_and_feature_maps(small_sample_dir):
    d = small_sample_dir
    calib = load_calibration(d)
    disp = read_pfm(d / "gt" / "disp0GT.pfm")
    depth = read_exr(d / "gt" / "left_depth.exr")
    on = np.isfinite(depth)
    assert np.all(np.isinf(disp[~on]))
    np.testing.assert_allclose(disp[on], calib.rig.left.f_px * calib.rig.baseline_m / depth[on], rtol=1e-6)
    # Every one of the 16 squares lights pixels in both cameras; ids are 0..15.
    for cam in ("left", "right"):
        ids = read_png(d / "gt" / f"{cam}_feature.png").astype(int) - 1
        assert set(np.unique(ids[ids >= 0]).tolist()) == set(range(16))
        proj = read_exr(d / "gt" / f"{cam}_proj.exr")
        off = ~np.isfinite(read_exr(d / "gt" / f"{cam}_depth.exr"))
        assert np.all(np.isnan(proj[off]))
        assert np.isfinite(proj[~off]).mean() > 0.99  # the projector lights the whole plate


def test_reference_plate_has_no_false_boundary(small_sample_dir):
    vis = json.loads((small_sample_dir / "gt" / "visibility.json").read_text())
    for cam in ("left", "right"):
        assert vis[cam]["false_boundary"] is False
        assert vis[cam]["visible_fraction"] == 1.0


def test_strong_bend_hides_boundary_behind_the_plate():
    """A 300 degree bend curls the ends over: cameras above cannot see its true edges."""
    plate = build_plate(PlateSpec(length_m=0.1165, width_m=0.0735,
                                  deformation=CylindricalBend(np.radians(300), "up")))
    scene = reference_scene(width=320, height=240)
    r = PlateRenderer(scene, plate)
    vis = GroundTruthCaster(r).boundary_visibility("left")
    assert vis.false_boundary
    assert 0.0 < vis.visible_fraction < 0.9
    assert vis.hidden_segments
    # Independent check of occlusion with trimesh on the points the caster calls visible.
    P = plate.boundary[vis.visible]
    C = scene.rig.left.center
    dirs = (P - C) / np.linalg.norm(P - C, axis=1, keepdims=True)
    locs, idx, _ = plate.mesh.ray.intersects_location(np.repeat(C[None], len(P), 0), dirs, multiple_hits=False)
    first = np.full(len(P), np.inf)
    first[idx] = np.linalg.norm(locs - C, axis=1)
    assert np.all(first >= np.linalg.norm(P - C, axis=1) - 1e-4)


DEVICE_CASES = {  # plate deformation, thickness, camera lens, projector kind, rig turned off the vertical
    "bend 120 down about 30 deg, thick": (CylindricalBend(np.radians(120.0), "down", np.radians(30.0)), 0.002,
                                         None, "pinhole", 0.15),
    "dent, lens, spot": (Dent(0.003, 0.02, 0.01, -0.005), 0.0, BrownConrady(-0.2286, 0.1904, 0.001, -0.0005), "spot",
                         0.0),
    "fold 150, thick": (Fold(np.radians(150.0), 0.01, 0.02, "up", np.radians(60.0)), 0.001, None, "pinhole", 0.3),
    "twist, lens": (Twist(np.radians(40.0)), 0.0, BrownConrady(0.12, -0.05), "pinhole", 0.1),
    "bowl": (Dome(-0.004), 0.0, None, "spot", 0.0),
}


@pytest.mark.parametrize("case", sorted(DEVICE_CASES))
def test_maps_computed_on_the_device_equal_the_numpy_definitions(case):
    """The drjit maps (``ground_truth_device``) against the numpy definitions of the same maps
    evaluated from the same Mitsuba hits (``GroundTruthCaster(on_device=False)``): every plate
    family's analytic normals, lenses, thickness (side walls: face normals), spot and pinhole
    projectors, a tilted rig."""
    deformation, thickness, lens, projector, tilt = DEVICE_CASES[case]
    scene = reference_scene(width=96, height=72, f_px=150.0, fy_px=None if lens is None else 165.0,
                            distortion=lens, projector_kind=projector)
    c = 0.4 * np.array([np.sin(tilt), 0.3 * np.sin(tilt), np.cos(tilt)])
    scene = scene_for_pose(c, np.zeros(3), np.array([1.0, 0.2, 0.0]), scene)
    r = PlateRenderer(scene, build_plate(PlateSpec(0.1165, 0.0735, thickness_m=thickness, deformation=deformation)))
    if r.variant.startswith("scalar"):
        pytest.skip("scalar variant: the maps are computed in numpy only")
    dev, ref = GroundTruthCaster(r), GroundTruthCaster(r, on_device=False)
    for cam in ("left", "right"):
        a, b = dev.camera(cam), ref.camera(cam)
        assert b.mask.sum() > 500 and np.array_equal(a.mask, b.mask)
        m = b.mask
        assert np.all(np.isinf(a.depth64[~m])) and np.all(np.isnan(a.points[~m]))
        assert np.abs(a.depth64[m] - b.depth64[m]).max() <= 1e-12
        assert np.abs(a.points[m] - b.points[m]).max() <= 1e-9
        assert np.abs(a.normals[m] - b.normals[m]).max() <= 1e-6
        assert np.array_equal(np.isnan(a.proj_uv), np.isnan(b.proj_uv))
        lit = ~np.isnan(b.proj_uv[..., 0])
        assert lit.sum() > 100 and np.abs(a.proj_uv[lit] - b.proj_uv[lit]).max() <= 1e-3
        assert np.mean(a.feature == b.feature) >= 0.9999 and (a.feature >= 0).sum() > 0


@pytest.mark.parametrize("target_x_m, seen", [(0.09, True), (0.6, False)])
def test_device_maps_of_a_plate_at_the_image_edge_or_out_of_view(target_x_m, seen):
    """Only the pixels of the plate's projected window are cast on the device (``plate_window``); a
    plate cut by the image border is mapped as the numpy definitions map it from every pixel, and
    one out of view gives empty maps."""
    scene = reference_scene(width=96, height=72, f_px=150.0)
    scene = scene_for_pose(np.array([target_x_m, 0.0, 0.3]), np.array([target_x_m, 0.0, 0.0]),
                           np.array([1.0, 0.0, 0.0]), scene)
    r = PlateRenderer(scene, build_plate(PlateSpec(0.1165, 0.0735, deformation=CylindricalBend(np.radians(40.0)))))
    if r.variant.startswith("scalar"):
        pytest.skip("scalar variant: the maps are computed in numpy only")
    for cam in ("left", "right"):
        a, b = GroundTruthCaster(r).camera(cam), GroundTruthCaster(r, on_device=False).camera(cam)
        assert np.array_equal(a.mask, b.mask) and bool(b.mask.any()) == seen
        if seen:  # cut by the border: the plate reaches an image edge
            assert b.mask[:, 0].any() or b.mask[:, -1].any() or b.mask[0].any() or b.mask[-1].any()
            assert np.abs(a.depth64[b.mask] - b.depth64[b.mask]).max() <= 1e-12
        assert np.array_equal(np.isinf(a.depth64), ~b.mask) and np.array_equal(a.feature, b.feature)
