"""Lens distortion and non-square pixels, proven against OpenCV, trimesh and real renders.

The Brown-Conrady model (``scenes.lens``) against ``cv2.projectPoints``/``cv2.undistortPoints``;
the camera's project/rays/at_depth through it; the ground truth of distorted pixels against an
independent ray cast (OpenCV's inverse distortion + trimesh); a point feature rendered through
the lens sensor landing where ``Camera.project`` says; the sensor plugin rendering the same
pixels as Mitsuba's own perspective camera when it has nothing more to model.
"""
from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
import trimesh

from platebench.bench.io.codecs import decode, encode
from platebench.plates import CylindricalBend, Flat, PlateSpec, build_plate
from platebench.scenes.camera import Camera, intrinsics
from platebench.scenes.lens import BrownConrady, DistortionError
from platebench.scenes.scene_spec import RenderSettings, reference_scene, scene_for_pose
from tests.synthetic import weighted_centroid

# Distortion sets: the 1995 camera's measured barrel (Zhang 1998), a pincushion with decentring,
# a barrel with a sixth-order term and decentring.
LENSES = {
    "barrel-1995": BrownConrady(-0.228601, 0.190353),
    "pincushion-tangential": BrownConrady(0.12, -0.05, 0.0015, -0.0010),
    "k3-tangential": BrownConrady(-0.08, 0.02, -0.0008, 0.0012, 0.03),
}
UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-15)


@pytest.mark.parametrize("name", list(LENSES))
def test_model_is_opencvs_and_its_inverse_is_exact(name):
    lens = LENSES[name]
    rng = np.random.default_rng(len(name))
    xy = rng.uniform(-0.4, 0.4, size=(500, 2))
    K = np.array([[900.0, 0.0, 300.0], [0.0, 1100.0, 250.0], [0.0, 0.0, 1.0]])
    cv_uv, _ = cv2.projectPoints(np.column_stack([xy, np.ones(len(xy))]), np.zeros(3), np.zeros(3), K,
                                 lens.as_opencv())
    ours = lens.distort(xy) @ K[:2, :2].T + K[:2, 2]
    np.testing.assert_allclose(ours, cv_uv.reshape(-1, 2), atol=1e-9)
    back = lens.undistort(lens.distort(xy))
    np.testing.assert_allclose(back, xy, atol=1e-13)
    cv_back = cv2.undistortPoints(cv_uv, K, lens.as_opencv(), P=np.eye(3), criteria=UNDISTORT_CRITERIA)
    np.testing.assert_allclose(back, cv_back.reshape(-1, 2), atol=1e-9)
    # finite differences agree with the analytic Jacobian (Newton's derivative)
    e = 1e-7
    J = lens.jacobian(xy[:5])
    for k in range(2):
        dxy = np.zeros(2)
        dxy[k] = e
        fd = (lens.distort(xy[:5] + dxy) - lens.distort(xy[:5] - dxy)) / (2 * e)
        np.testing.assert_allclose(J[:, :, k], fd, atol=1e-7)


def test_model_round_trips_through_opencvs_vector_and_refuses_what_it_does_not_model():
    lens = LENSES["k3-tangential"]
    assert BrownConrady.from_opencv(lens.as_opencv()) == lens
    assert BrownConrady.from_opencv([0.1, 0.0, 0.0, 0.0]) == BrownConrady(0.1)
    with pytest.raises(ValueError, match="higher terms"):
        BrownConrady.from_opencv([0.1, 0, 0, 0, 0, 0.3, 0, 0])
    with pytest.raises(ValueError, match="not a finite number"):
        BrownConrady(k1=float("nan"))


def test_a_lens_that_folds_over_inside_the_image_is_refused():
    K = intrinsics(300.0, 640, 480)
    with pytest.raises(ValueError, match="one-to-one|folds over"):
        Camera(K, np.eye(3), np.zeros(3), 640, 480, BrownConrady(k1=-1.5))
    with pytest.raises(DistortionError):
        BrownConrady(k1=-1.5).undistort([[1.5, 1.5]])
    # an identity model is the pinhole: one representation
    assert Camera(K, np.eye(3), np.zeros(3), 640, 480, BrownConrady()).distortion is None


@pytest.mark.parametrize("name", list(LENSES))
@pytest.mark.parametrize("seed", [0, 1])
def test_project_rays_and_at_depth_invert_each_other_through_the_lens(name, seed):
    rng = np.random.default_rng(seed)
    base = Camera.look_at(rng.normal(size=3) * 0.3 + [0, 0, 0.5], rng.normal(size=3) * 0.05, 800.0, 640, 480)
    K = base.K.copy()
    K[1, 1] = 1.25 * K[0, 0]  # non-square pixels
    K[0, 1] = 2.0  # and skew
    K[0, 2] += 7.3  # off-centre principal point
    cam = dataclasses.replace(base, K=K, distortion=LENSES[name])
    uv = rng.uniform([0, 0], [640, 480], size=(300, 2))
    z = rng.uniform(0.2, 1.5, size=300)
    P = cam.at_depth(uv, z)
    np.testing.assert_allclose(cam.project(P), uv, atol=1e-9)
    np.testing.assert_allclose(cam.depth(P), z, atol=1e-12)
    # the ray through a pixel is OpenCV's: undistortPoints then R^T (OpenCV's model has no skew)
    K[0, 1] = 0.0
    cam = dataclasses.replace(cam, K=K)
    o, d = cam.rays(uv)
    xy = cv2.undistortPoints(uv.reshape(-1, 1, 2), K, LENSES[name].as_opencv(), P=np.eye(3),
                             criteria=UNDISTORT_CRITERIA).reshape(-1, 2)
    d_cv = np.column_stack([xy, np.ones(len(xy))]) @ cam.R
    d_cv /= np.linalg.norm(d_cv, axis=1)[:, None]
    np.testing.assert_allclose(d, d_cv, atol=1e-12)
    assert np.allclose(o, cam.center)


def test_camera_dict_keeps_the_lens_and_a_pinhole_dict_is_unchanged():
    cam = Camera(intrinsics(900.0, 512, 480, fy_px=1125.0), np.eye(3), np.zeros(3), 512, 480, LENSES["barrel-1995"])
    d = encode(cam)
    assert d["distortion_k1_k2_p1_p2_k3"] == LENSES["barrel-1995"].as_opencv().tolist()
    back = decode(Camera, d)
    assert back.distortion == cam.distortion and np.array_equal(back.K, cam.K)
    assert "distortion_k1_k2_p1_p2_k3" not in encode(cam.pinhole)


# -- rendering and ground truth (real Mitsuba) --------------------------------------------------------
def _independent_cast(cam: Camera, mesh: trimesh.Trimesh):
    """(H,W) z-depth and (H,W,3) points of every pixel centre: OpenCV's inverse distortion for the
    ray, trimesh for the hit; inf/NaN where the ray misses."""
    vv, uu = np.mgrid[0:cam.height, 0:cam.width]
    uv = np.column_stack([uu.ravel(), vv.ravel()]).astype(float)
    dist = np.zeros(5) if cam.distortion is None else cam.distortion.as_opencv()
    xy = cv2.undistortPoints(uv.reshape(-1, 1, 2), cam.K, dist, P=np.eye(3), criteria=UNDISTORT_CRITERIA)
    d = np.column_stack([xy.reshape(-1, 2), np.ones(len(uv))]) @ cam.R
    d /= np.linalg.norm(d, axis=1)[:, None]
    locs, ray_idx, _ = mesh.ray.intersects_location(np.repeat(cam.center[None], len(d), 0), d, multiple_hits=False)
    depth = np.full(len(uv), np.inf)
    depth[ray_idx] = cam.depth(locs)
    pts = np.full((len(uv), 3), np.nan)
    pts[ray_idx] = locs
    return depth.reshape(cam.height, cam.width), pts.reshape(cam.height, cam.width, 3)


CASES = [  # lens, fy / fx, plate bend (deg), rig shift: another place and another plate
    ("barrel-1995", 1.25, 10.0, (0.0, 0.0)),
    ("pincushion-tangential", 1.0, 40.0, (0.012, -0.007)),
    ("k3-tangential", 0.8, 25.0, (-0.01, 0.015)),
]


@pytest.mark.render
@pytest.mark.parametrize("name,aspect,bend,shift", CASES)
def test_distorted_pixel_ground_truth_matches_an_independent_ray_cast(name, aspect, bend, shift):
    from platebench.scenes.render.ground_truth import GroundTruthCaster
    from platebench.scenes.render.renderer import PlateRenderer
    f = 300.0
    base = reference_scene(width=240, height=180, f_px=f, fy_px=f * aspect, distortion=LENSES[name])
    scene = scene_for_pose(np.array([shift[0], shift[1], 0.4]), np.array([shift[1], 0.0, 0.0]),
                           base.rig.left.R[0], base)
    assert scene.rig.left.distortion == LENSES[name] and scene.rig.left.K[1, 1] == f * aspect
    plate = build_plate(PlateSpec(0.1165, 0.0735, deformation=CylindricalBend(np.radians(bend))))
    caster = GroundTruthCaster(PlateRenderer(scene, plate))
    for cam_name, cam in scene.rig.cameras.items():
        g = caster.camera(cam_name)
        depth, pts = _independent_cast(cam, plate.mesh)
        both = g.mask & np.isfinite(depth)
        assert both.sum() > 3000
        assert (g.mask ^ np.isfinite(depth)).sum() <= 0.003 * both.sum()  # rays grazing the outline
        assert np.abs(g.depth64[both] - depth[both]).max() <= 1e-6
        assert np.abs(g.points[both].astype(np.float64) - pts[both]).max() <= 1e-6 + 4e-8  # float32 storage
        # projector coordinates: the projector's pinhole projection of the true surface point
        proj = scene.projector.camera.project(pts[both])
        lit = np.isfinite(g.proj_uv[both][:, 0])
        assert lit.sum() > 1000
        np.testing.assert_allclose(g.proj_uv[both][lit], proj[lit], atol=2e-4)
        # boundary visibility: a visible boundary point projects (OpenCV, through the lens) inside the image
        vis = caster.boundary_visibility(cam_name)
        P = np.asarray(plate.boundary, float)
        uv, _ = cv2.projectPoints(P, cv2.Rodrigues(cam.R)[0], cam.t, cam.K, cam.distortion.as_opencv())
        uv = uv.reshape(-1, 2)
        inside = (uv[:, 0] >= -0.5) & (uv[:, 0] <= cam.width - 0.5) & (uv[:, 1] >= -0.5) & (uv[:, 1] <= cam.height - 0.5)
        assert vis.visible.any() and np.all(inside[vis.visible])


@pytest.mark.render
@pytest.mark.parametrize("name,aspect,target", [("barrel-1995", 1.25, (0.09, 0.003, 0.0)),
                                                ("pincushion-tangential", 0.9, (-0.095, -0.004, 0.0))])
def test_point_feature_rendered_through_the_lens_lands_where_project_says(name, aspect, target):
    """A small square far off the principal point, rendered by the lens sensor (spp 256): its
    flat-field coverage centroid is where ``Camera.project`` sends its centre (< 0.05 px), in
    both cameras; the image of a 6 x 4 mm square is bent by < 0.01 px across it at these lenses."""
    from platebench.scenes.render.renderer import PlateRenderer
    # the rig looks at ``target``, so the square (at the world origin) lands far off the principal point
    scene = dataclasses.replace(reference_scene(width=320, height=320, f_px=500.0, fy_px=500.0 * aspect,
                                                distortion=LENSES[name], target=target), ground_albedo=0.0)
    small = build_plate(PlateSpec(length_m=0.006, width_m=0.004, deformation=Flat()))
    big = build_plate(PlateSpec(length_m=0.6, width_m=0.6, deformation=Flat()))
    r = PlateRenderer(scene, small)
    settings = RenderSettings(spp=256, seed=4)
    imgs = {c: r.render(c, "passive", settings) for c in ("left", "right")}
    r.set_plate(big)
    for cam_name, cam in scene.rig.cameras.items():
        coverage = np.clip(imgs[cam_name] / r.render(cam_name, "passive", settings), 0.0, 1.0)
        expected = cam.project(np.zeros((1, 3)))[0]
        pinhole = cam.pinhole.project(np.zeros((1, 3)))[0]
        assert np.linalg.norm(expected - pinhole) > 0.5  # the lens moves it by 10 times the tolerance
        err = np.abs(weighted_centroid(coverage) - expected)
        assert err.max() <= 0.05, f"{cam_name}: centroid {weighted_centroid(coverage)} vs {expected}"


@pytest.mark.render
def test_lens_sensor_renders_mitsubas_perspective_pixels_when_it_has_nothing_more_to_model():
    """A square-pixel, centred, distortion-free camera forced through the plugin (fy 1e-6 px off)
    renders the pixels of Mitsuba's own perspective sensor: same rays, same sample streams."""
    from platebench.plates import reference_spec
    from platebench.scenes.render.lens_sensor import PLUGIN
    from platebench.scenes.render.renderer import PlateRenderer
    plate = build_plate(reference_spec())
    s0 = reference_scene(width=200, height=150, f_px=300.0)
    s1 = reference_scene(width=200, height=150, f_px=300.0, fy_px=300.0 + 1e-6)
    r = PlateRenderer(s0, plate)
    a = {c: r.render(c, "active", RenderSettings(4, 5)) for c in ("left", "right")}
    r.set_scene(s1)
    assert r._structure[-1] == PLUGIN
    b = {c: r.render(c, "active", RenderSettings(4, 5)) for c in ("left", "right")}
    for c in a:
        assert a[c].mean() > 0.01
        assert np.abs(a[c] - b[c]).mean() < 1e-5 * a[c].mean()
        assert np.mean(np.abs(a[c] - b[c]) > 1e-3) < 1e-3  # a few pixels on the plate's outline at most


@pytest.mark.render
def test_a_distorted_sample_written_by_the_cli_reconstructs_through_its_lens(tmp_path):
    """``render --config`` with ``[scene.distortion]`` and ``fy_px``: calib.json keeps the lens, and
    ``reconstruct`` (the true calibration) undistorts the images before the paper's pipeline."""
    import json

    from platebench.bench.io.sample_files import load_calibration
    from tests.conftest import run_cli
    cfg = tmp_path / "lens.toml"
    cfg.write_text("[scene]\nwidth = 640\nheight = 480\nf_px = 1000.0\nfy_px = 1250.0\n"
                   "[scene.distortion]\nk1 = -0.228601\nk2 = 0.190353\n[render]\nspp = 4\n")
    sample, recon = tmp_path / "s", tmp_path / "r"
    for args in (("render", "--config", cfg, "--out", sample), ("reconstruct", sample, "--out", recon),
                 ("evaluate", sample, recon)):
        p = run_cli(*args)
        assert p.returncode == 0, p.stderr
    calib = load_calibration(sample)
    assert calib.rig.left.distortion == LENSES["barrel-1995"] and calib.rig.left.K[1, 1] == 1250.0
    meta = json.loads((sample / "sample.json").read_text())
    assert meta["config"]["scene"]["distortion"] == {"k1": -0.228601, "k2": 0.190353}
    score = json.loads((recon / "score.json").read_text())
    assert score["points"]["count"] == 16 and score["matching"]["correct_match_count"] == 16
    assert score["points"]["depth_rms_mm"] < 0.2, score["points"]


@pytest.mark.render
def test_defocus_through_the_distorted_lens_is_the_thin_lens_blur_about_the_chief_ray():
    """The lens sensor with an aperture: a small square off focus (camera 0.40 m away, focused at
    0.50 m) is blurred by the thin lens's disc (radius R |1 - z_f / z| on the focus plane, seen
    through the lens's local Jacobian and K: per axis a variance of r^2 / 4 added to the sharp
    image's; measured within 5 % at two seeds) about its chief ray, which the lens bends to where
    ``Camera.project`` sends the square's centre (1.3 px from the pinhole's place; the blurred
    centroid's Monte Carlo noise at spp 128 is 0.04-0.08 px)."""
    from platebench.scenes.render.renderer import PlateRenderer
    radius_m, focus_m, z = 0.020, 0.50, 0.40
    sharp_scene = dataclasses.replace(reference_scene(width=320, height=320, f_px=500.0, fy_px=625.0,
                                                      distortion=LENSES["barrel-1995"], target=(0.07, 0.0, 0.0)),
                                      ground_albedo=0.0)
    blur_scene = dataclasses.replace(sharp_scene, aperture_radius_m=radius_m, focus_distance_m=focus_m)
    small = build_plate(PlateSpec(length_m=0.006, width_m=0.004, deformation=Flat()))
    big = build_plate(PlateSpec(length_m=0.6, width_m=0.6, deformation=Flat()))
    settings = RenderSettings(spp=128, seed=6)
    stats = {}
    for key, scene in (("sharp", sharp_scene), ("blur", blur_scene)):
        r = PlateRenderer(scene, small)
        imgs = {c: r.render(c, "passive", settings) for c in ("left", "right")}
        r.set_plate(big)
        for c in ("left", "right"):
            w = np.clip(imgs[c] / r.render(c, "passive", settings), 0.0, 1.0)
            m = weighted_centroid(w)
            vv, uu = np.mgrid[0:w.shape[0], 0:w.shape[1]]
            var = np.array([((uu - m[0]) ** 2 * w).sum(), ((vv - m[1]) ** 2 * w).sum()]) / w.sum()
            stats[key, c] = (m, var)
    r_focus_plane = radius_m * abs(1.0 - focus_m / z)  # blur disc radius on the focus plane (m)
    for c, cam in blur_scene.rig.cameras.items():
        expected = cam.project(np.zeros((1, 3)))[0]
        m_blur, var_blur = stats["blur", c]
        assert np.abs(m_blur - expected).max() <= 0.15, (c, m_blur, expected)
        assert np.linalg.norm(expected - cam.pinhole.project(np.zeros((1, 3)))[0]) > 1.0
        # the disc (radius rho in normalised coordinates) seen through the lens's local Jacobian and K
        rho = r_focus_plane / focus_m
        xn = cam.to_camera(np.zeros((1, 3)))[:, :2] / cam.to_camera(np.zeros((1, 3)))[:, 2:]
        J = cam.K[:2, :2] @ cam.distortion.jacobian(xn)[0]
        added = var_blur - stats["sharp", c][1]
        assert added.min() > 4.0  # a blur disc of 5-6 px radius
        np.testing.assert_allclose(added, rho ** 2 / 4 * np.diag(J @ J.T), rtol=0.08)
