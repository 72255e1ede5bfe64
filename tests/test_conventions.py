"""Camera and projector conventions proven on real Mitsuba renders.

A feature at a known 3D point must appear where K, R, t project it (<= 0.05 px), for
both cameras and through the projector (both Mitsuba light models); disparity must
equal f B / Z at every plate pixel.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from platebench.plates import Flat, PlateSpec, build_plate
from platebench.scenes.pattern import Pattern
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.scene_spec import RenderSettings, reference_scene
from tests.synthetic import weighted_centroid

pytestmark = pytest.mark.render

TOL_PX = 0.05


@pytest.fixture(scope="module")
def offset_scene():
    # Rig looks straight down at an off-centre target, so the plate centre lands off the
    # principal point in both image axes: mirrored axes or half-pixel shifts would show.
    # A black ground (albedo 0) so the flat-field ratio is 0 off the plate.
    scene = reference_scene(width=320, height=240, f_px=600.0, target=(0.021, -0.013, 0.0))
    return dataclasses.replace(scene, ground_albedo=0.0)


def test_square_feature_lands_where_K_R_t_project_it(offset_scene):
    small = build_plate(PlateSpec(length_m=0.012, width_m=0.008, deformation=Flat()))
    big = build_plate(PlateSpec(length_m=0.6, width_m=0.6, deformation=Flat()))
    r = PlateRenderer(offset_scene, small)
    settings = RenderSettings(spp=256, seed=1)
    imgs_small = {c: r.render(c, "passive", settings) for c in ("left", "right")}
    r.set_plate(big)
    for cam_name in ("left", "right"):
        flat_field = r.render(cam_name, "passive", settings)
        coverage = np.clip(imgs_small[cam_name] / flat_field, 0.0, 1.0)
        measured = weighted_centroid(coverage)
        cam = offset_scene.rig.cameras[cam_name]
        expected = cam.project(np.zeros((1, 3)))[0]  # plate centre; fronto-parallel, so centroid maps exactly
        assert np.abs(expected - np.array([cam.width / 2 - 0.5, cam.height / 2 - 0.5])).min() > 10
        err = np.abs(measured - expected)
        assert err.max() <= TOL_PX, f"{cam_name}: rendered centroid {measured} vs K,R,t {expected}"
        # Area agrees too (f and pixel pitch): 12 x 8 mm at 0.4 m with f = 600 px.
        assert coverage.sum() == pytest.approx(0.012 * 0.008 * (600 / 0.4) ** 2, rel=0.01)


@pytest.mark.parametrize("kind", ["pinhole", "spot"])
def test_projector_texel_lands_where_projector_K_R_t_send_it(kind):
    scene = reference_scene(width=320, height=240, f_px=600.0, projector_kind=kind)
    proj = scene.projector
    W, H = proj.pattern.width, proj.pattern.height
    img = np.zeros((H, W), np.float32)
    u0, v0 = 640, 250  # an off-centre 16 x 16 texel square (6 camera px)
    img[v0:v0 + 16, u0:u0 + 16] = 1.0
    scene = dataclasses.replace(scene, projector=proj.with_pattern(Pattern(img)))
    plate = build_plate(PlateSpec(length_m=0.6, width_m=0.6, deformation=Flat()))
    r = PlateRenderer(scene, plate)
    centre_px = np.array([[u0 + 7.5, v0 + 7.5]])
    o, d = scene.projector.camera.rays(centre_px)
    hit = o + d[0] * (-o[2] / d[0, 2])  # on the plane z = 0
    for cam_name in ("left", "right"):
        image = r.render(cam_name, "active", RenderSettings(spp=256, seed=2))
        cam = scene.rig.cameras[cam_name]
        expected = cam.project(hit[None])[0]
        measured = weighted_centroid(image)
        assert np.abs(measured - expected).max() <= TOL_PX, f"{kind} {cam_name}: {measured} vs {expected}"


def test_disparity_is_fB_over_Z_at_every_plate_pixel(small_sample):
    sample, _ = small_sample
    rig = sample.scene.rig
    g = sample.gt["left"]
    vv, uu = np.nonzero(g.mask)
    P = g.points[g.mask].astype(np.float64)
    # Recompute from the float64 depth: project the exact GT point into the right camera.
    P = rig.left.at_depth(np.column_stack([uu, vv]).astype(float), g.depth64[g.mask])
    u_right = rig.right.project(P)[:, 0]
    disparity = uu - u_right
    assert g.mask.sum() > 5000
    np.testing.assert_allclose(disparity, rig.left.f_px * rig.baseline_m / g.depth64[g.mask], atol=1e-7)
    # Same row in both images (conventional geometry).
    np.testing.assert_allclose(rig.right.project(P)[:, 1], vv, atol=1e-7)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_at_depth_inverts_project_and_depth_on_a_skewed_turned_camera(seed):
    """``Camera.at_depth`` (pixel and z-depth -> world point) against ``project`` and ``depth``: a
    camera looking from a random place, with a skew term, at random pixels and depths."""
    from platebench.scenes.camera import Camera
    rng = np.random.default_rng(seed)
    cam = Camera.look_at(rng.normal(size=3) * 0.4 + [0, 0, 0.5], rng.normal(size=3) * 0.05, 900.0, 640, 480)
    cam = dataclasses.replace(cam, K=cam.K + np.array([[0.0, 3.0, 0.0], [0, 0, 0], [0, 0, 0]]))
    uv = rng.uniform([0, 0], [640, 480], size=(50, 2))
    z = rng.uniform(0.2, 1.5, size=50)
    P = cam.at_depth(uv, z)
    np.testing.assert_allclose(cam.project(P), uv, atol=1e-9)
    np.testing.assert_allclose(cam.depth(P), z, atol=1e-12)
