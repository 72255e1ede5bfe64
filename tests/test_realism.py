"""Physical realism: camera noise statistics, seeded noise, rough metal plates, defocus."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from platebench.bench.config import CAMERA_PRESETS, SampleConfig, SceneParams
from platebench.bench.run.render import render_sample
from platebench.reconstruction.paper.pipeline import projector_feature_rays, reconstruct
from platebench.reconstruction.paper.plate_region import ReconstructionError
from platebench.scenes.scene_spec import RenderSettings
from platebench.scenes.sensor_model import SensorModel

pytestmark = pytest.mark.render


@pytest.mark.parametrize("level", [0.1, 0.5, 0.8])
def test_noise_mean_and_variance_follow_the_camera_model(level):
    m = SensorModel(bit_depth=16, full_well_e=4000.0, read_noise_dn=20.0)
    dn = m.digitize(np.full((400, 400), level), seed=11).astype(np.float64)
    full = m.max_dn
    expected_var = level * full ** 2 / m.full_well_e + m.read_noise_dn ** 2 + 1 / 12  # shot + read + quantisation
    assert dn.mean() == pytest.approx(level * full, rel=2e-3)
    assert dn.var() == pytest.approx(expected_var, rel=0.03)


def test_noise_is_seeded():
    m = CAMERA_PRESETS["1995"][1]
    img = np.random.default_rng(0).uniform(0, 1, (64, 64))
    assert np.array_equal(m.digitize(img, seed=5), m.digitize(img, seed=5))
    assert not np.array_equal(m.digitize(img, seed=5), m.digitize(img, seed=6))


def test_noise_free_model_is_exact_quantisation():
    img = np.linspace(0, 1, 256)[None, :]
    assert np.array_equal(SensorModel().digitize(img), np.rint(img * 255).astype(np.uint8))


def _recon(cfg):
    sample, _ = render_sample(cfg)
    proj = sample.scene.projector
    return sample, reconstruct(sample.digital, sample.scene.rig, projector_feature_rays(proj.camera, proj.pattern),
                               proj.pattern)


@pytest.mark.parametrize("alpha", [0.1, 0.4])
def test_rough_metal_plate_squares_are_found_or_a_clear_reason_is_given(alpha):
    cfg = SampleConfig(scene=SceneParams(width=480, height=360, material={"kind": "roughconductor", "metal": "Al",
                                                                          "alpha": alpha}),
                       render=RenderSettings(spp=8))
    try:
        sample, rec = _recon(cfg)
    except ReconstructionError as e:  # a clear, reported reason is acceptable
        assert str(e)
        return
    assert len(rec.points) == 16
    g = sample.gt["left"]
    assert np.all(g.feature[np.rint(rec.uv_left[:, 1]).astype(int), np.rint(rec.uv_left[:, 0]).astype(int)] >= 0)


def test_defocus_blurs_edges_but_squares_are_still_matched():
    base = SampleConfig(scene=SceneParams(width=480, height=360), render=RenderSettings(spp=16))
    blurred = dataclasses.replace(base, scene=dataclasses.replace(base.scene, aperture_radius_m=0.004,
                                                                  focus_distance_m=0.33))
    s0, r0 = _recon(base)
    s1, r1 = _recon(blurred)

    def edge_pixels(img):  # pixels between dark and bright: the blur width of the square edges
        return int(np.sum((img > 30) & (img < 140)))

    assert edge_pixels(s1.digital["left_active"]) > 1.5 * edge_pixels(s0.digital["left_active"])
    assert len(r1.points) == 16
