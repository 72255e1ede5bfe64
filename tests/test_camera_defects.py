"""The 1995 camera's defects, each from its source and each switchable alone.

Parameter sets (``bench.config.hardware_camera``) checked against the arithmetic of their
sources; ``apply_camera_hardware`` changes only what the switched defect owns; the ground
truth is the same with every defect that is not geometry (defocus, line jitter, noise); the
grabber's line jitter moves each row by its seeded amount and nothing else.
"""
from __future__ import annotations

import numpy as np
import pytest

from platebench.bench.config import SampleConfig
from platebench.bench.config.hardware_camera import (
    CAMERA_DEFECTS,
    PULNIX_TM540_1995,
    CameraDefects,
    apply_camera_hardware,
    camera_hardware,
)
from platebench.bench.config.sample_config import ConfigError
from platebench.bench.io.codecs import encode
from platebench.scenes.sensor_model import SensorModel, jitter_rows, line_shifts_px


def test_the_1995_camera_follows_from_its_sources():
    hw = PULNIX_TM540_1995
    assert (hw.width, hw.height) == (512, 480)
    assert hw.fx_px == pytest.approx(16e-3 / (8.8e-3 / 512))  # 16 mm lens, 2/3-inch line sampled 512 times
    assert hw.pixel_aspect == pytest.approx((4 / 3) / (512 / 480))  # RS-170's 4:3 picture sampled 512 x 480
    assert hw.aperture_radius_m == pytest.approx(16e-3 / 2.8)  # f/1.4
    assert (hw.distortion.k1, hw.distortion.k2) == (-0.228601, 0.190353)  # Zhang 1998, PULNiX + 6 mm lens
    assert hw.line_jitter_px == pytest.approx(20 * 0.005)  # Beyer 1992: PLL 20 x worse than 0.005 px
    # the plate lies inside both images, through the lens, with a margin (the focal length's reason)
    cfg = apply_camera_hardware(SampleConfig(), hw)
    scene = cfg.scene.build()
    corners = np.array([[x, y, 0.0] for x in (-0.05825, 0.05825) for y in (-0.03675, 0.03675)])
    for cam in scene.rig.cameras.values():
        assert cam.distortion is not None and cam.K[1, 1] / cam.K[0, 0] == pytest.approx(1.25)
        uv = cam.project(corners)
        assert cam.in_image(uv, margin=10.0).all(), uv
    # and a 25 mm lens would not hold it in the left view: 16 mm is the longest standard one that does
    f25 = 25e-3 / (8.8e-3 / 512)
    left = scene.rig.left
    assert np.abs(corners[:, 1] - left.center[1]).max() * f25 / 0.4 > 256


def test_every_defect_is_off_by_default_and_the_default_records_read_as_before():
    d = encode(SampleConfig())
    assert "distortion" not in d["scene"] and "fy_px" not in d["scene"] and "line_jitter_px" not in d["sensor"]
    scene = SampleConfig().scene.build()
    assert scene.rig.left.distortion is None and scene.rig.left.K[0, 0] == scene.rig.left.K[1, 1]
    assert scene.aperture_radius_m == 0.0 and SampleConfig().sensor.line_jitter_px == 0.0


def _flat(d: dict, prefix="") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict) and k in ("scene", "sensor", "render", "plate"):
            out.update(_flat(v, f"{k}."))
        else:
            out[prefix + k] = v
    return out


OWNS = {"distortion": {"scene.distortion"}, "pixel_aspect": {"scene.fy_px"},
        "defocus": {"scene.aperture_radius_m"}, "line_jitter": {"sensor.line_jitter_px"},
        "noise": {"sensor.full_well_e", "sensor.read_noise_dn"}}


@pytest.mark.parametrize("name", CAMERA_DEFECTS)
def test_each_defect_switched_on_alone_changes_only_what_it_owns(name):
    base = apply_camera_hardware(SampleConfig(), PULNIX_TM540_1995, CameraDefects.none())
    alone = apply_camera_hardware(SampleConfig(), PULNIX_TM540_1995, CameraDefects.only(name))
    every = apply_camera_hardware(SampleConfig(), PULNIX_TM540_1995, CameraDefects())
    but = apply_camera_hardware(SampleConfig(), PULNIX_TM540_1995, CameraDefects().without(name))
    a, b, e, w = (_flat(encode(c)) for c in (base, alone, every, but))

    def changed(x, y):
        return {k for k in set(x) | set(y) if x.get(k) != y.get(k)}

    assert changed(a, b) == OWNS[name]
    assert changed(e, w) == OWNS[name]
    assert CameraDefects.only(name).on() == (name,)
    # the camera itself (size, focal length) is the same whatever the defects
    assert (a["scene.width"], a["scene.height"], a["scene.f_px"]) == (512, 480, PULNIX_TM540_1995.fx_px)


def test_unknown_defects_and_cameras_are_refused_in_one_line():
    with pytest.raises(ConfigError, match="camera defect 'vignetting' is not known"):
        CameraDefects.only("vignetting")
    with pytest.raises(ConfigError, match="camera hardware '1985' is not known"):
        camera_hardware("1985")


@pytest.mark.parametrize("seed", [0, 7])
def test_line_jitter_moves_each_row_by_its_seeded_shift_and_nothing_else(seed):
    h, w = 40, 200
    ramp = np.tile(np.linspace(0.1, 0.9, w), (h, 1))  # radiance grows along u: a shift is a level change
    slope = (0.9 - 0.1) / (w - 1)
    out = SensorModel(bit_depth=16, line_jitter_px=0.3).digitize(ramp, seed=seed).astype(float) / 65535
    shifts = line_shifts_px(h, 0.3, seed)
    inner = slice(10, w - 10)
    measured = np.mean(out[:, inner] - ramp[:, inner], axis=1) / slope
    np.testing.assert_allclose(measured, shifts, atol=2e-3)
    assert np.std(shifts) > 0.15 and not np.allclose(shifts, line_shifts_px(h, 0.3, seed + 1))
    # off: the same bytes as a camera without the grabber
    assert np.array_equal(SensorModel(bit_depth=16, line_jitter_px=0.0).digitize(ramp, seed=seed),
                          SensorModel(bit_depth=16).digitize(ramp, seed=seed))
    # a row constant along u is unchanged by its shift; the noise draws are the image's own
    rows = np.tile(np.linspace(0.2, 0.8, h)[:, None], (1, w))
    noisy = SensorModel(read_noise_dn=1.0, line_jitter_px=0.3).digitize(rows, seed=seed)
    assert np.array_equal(noisy, SensorModel(read_noise_dn=1.0).digitize(rows, seed=seed))
    np.testing.assert_allclose(jitter_rows(rows, shifts), rows, atol=1e-15)


@pytest.mark.render
def test_ground_truth_is_the_same_with_the_defects_that_are_not_geometry():
    """Defocus, line jitter and noise change the images, never the truth of the pixel grid; line
    jitter and noise leave the radiance too (they live in the camera's electronics)."""
    from dataclasses import replace

    from platebench.bench.run.render import render_sample
    from platebench.scenes.scene_spec import RenderSettings
    base = apply_camera_hardware(SampleConfig(render=RenderSettings(spp=2, seed=1)), PULNIX_TM540_1995,
                                 CameraDefects.none())
    base = replace(base, scene=replace(base.scene, width=256, height=240, f_px=PULNIX_TM540_1995.fx_px / 2))
    ref, renderer = render_sample(base)
    for name in ("defocus", "line_jitter", "noise"):
        cfg = apply_camera_hardware(base, PULNIX_TM540_1995, CameraDefects.only(name))
        cfg = replace(cfg, scene=replace(cfg.scene, width=256, height=240, f_px=PULNIX_TM540_1995.fx_px / 2))
        s, renderer = render_sample(cfg, renderer)
        for cam in ("left", "right"):
            assert np.array_equal(s.gt[cam].depth64, ref.gt[cam].depth64), name
            assert np.array_equal(s.gt[cam].proj_uv, ref.gt[cam].proj_uv, equal_nan=True), name
        assert np.array_equal(s.visibility["left"].visible, ref.visibility["left"].visible)
        same_radiance = all(np.array_equal(s.radiance[k], ref.radiance[k]) for k in ref.radiance)
        assert same_radiance == (name != "defocus"), name
        assert any(not np.array_equal(s.digital[k], ref.digital[k]) for k in ref.digital), name


def _digitize_by_definition(m: SensorModel, radiance, seed: int):
    """``SensorModel.digitize`` written as its definition, step by step, each on a fresh array."""
    x = np.clip(np.asarray(radiance, np.float64) / m.radiance_full_scale, 0.0, None)
    rng = np.random.default_rng(seed)
    if m.full_well_e > 0:
        x = rng.poisson(x * m.full_well_e) / m.full_well_e
    x = np.clip(x, 0.0, 1.0) ** (1.0 / m.gamma)
    if m.line_jitter_px > 0:
        x = jitter_rows(x, line_shifts_px(x.shape[0], m.line_jitter_px, seed))
    dn = x * m.max_dn
    if m.read_noise_dn > 0:
        dn = dn + rng.normal(0.0, m.read_noise_dn, dn.shape)
    return np.clip(np.rint(dn), 0, m.max_dn).astype(np.uint8 if m.bit_depth == 8 else np.uint16)


@pytest.mark.parametrize("model", [SensorModel(), SensorModel(16), SensorModel(8, 0.7, 2.2), SensorModel(8, 1.0, 2.0),
                                   SensorModel(16, 1.0, 0.5), SensorModel(8, 1.3, 1.0, 20000.0, 0.8),
                                   SensorModel(16, 0.9, 1.8, 5000.0, 3.0, 0.1), SensorModel(8, line_jitter_px=0.3)])
def test_digitize_is_its_definition_to_the_bit(model):
    """The in-place digitiser gives the bytes of its definition and leaves its input as it was: out
    of range, at the float64 radiances whose DN lies exactly half-way and one float64 step either
    side of them (where a rounding changed by the order of the operations would show), for float32
    and float64 images, and for every sensor option."""
    rng = np.random.default_rng(11)
    half = (np.arange(model.max_dn + 1) + 0.5) / model.max_dn * model.radiance_full_scale
    edge = np.concatenate([half, np.nextafter(half, 0.0), np.nextafter(half, 2.0)])
    for seed in (0, 1, 2):
        img = rng.random((37, 211)) * 1.4 - 0.2
        img[0, :4] = [0.0, -0.0, 1.0, model.radiance_full_scale]
        for x in (img, img.astype(np.float32), edge[None], edge[None].astype(np.float32)):
            before = x.copy()
            assert np.array_equal(model.digitize(x, seed), _digitize_by_definition(model, x, seed))
            assert np.array_equal(x, before)
