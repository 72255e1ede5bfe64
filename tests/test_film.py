"""The channel mean taken on the render's device: numpy's mean bit for bit, subnormals flushed.

``scenes.render.film`` reduces a render's RGB tensor to the bench's grey image where the render
lives and copies it to the host once. Checked on real renders (a grey diffuse plate, whose
channels agree, and rough aluminium, whose channels differ) against numpy's ``mean(axis=2)`` of
the same tensor, and on a tensor holding subnormal floats.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from platebench.plates import CylindricalBend, PlateSpec, build_plate
from platebench.scenes.naming import image_seed
from platebench.scenes.render import runtime
from platebench.scenes.render.film import FLOAT32_TINY, channels_to_host, count_subnormal, grey_to_host
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.scene_spec import Material, RenderSettings, reference_scene

pytestmark = pytest.mark.render


@pytest.mark.parametrize("material", [Material(), Material(kind="roughconductor", metal="Al", alpha=0.2)])
@pytest.mark.parametrize("bend_deg", [9.0, 31.0])
def test_device_channel_mean_is_numpys_mean_bit_for_bit(material, bend_deg):
    mi = runtime.mitsuba()
    scene = dataclasses.replace(reference_scene(width=96, height=72, f_px=150.0), material=material)
    plate = build_plate(PlateSpec(0.1165, 0.0735, deformation=CylindricalBend(np.radians(bend_deg))))
    r = PlateRenderer(scene, plate)
    for light in ("passive", "active"):
        r.set_lighting(light)
        img = mi.render(r.scene, sensor=0, spp=2, seed=image_seed(3, "left", light))
        host = np.asarray(img, dtype=np.float32)
        assert host.max() > 0
        if material.kind == "roughconductor":  # aluminium reflects the three channels differently
            assert not np.array_equal(host[..., 0], host[..., 2])
        grey = grey_to_host(mi, img)
        assert grey.shape == host.shape[:2] and grey.dtype == np.float32
        assert np.array_equal(grey.view(np.uint32), host.mean(axis=2).view(np.uint32))
        assert np.array_equal(channels_to_host(mi, img), host)
    # and what the renderer hands out is that image
    assert np.array_equal(r.render("left", "active", RenderSettings(spp=2, seed=3)), grey)


def test_subnormals_are_flushed_on_the_device_and_counted():
    mi = runtime.mitsuba()
    rng = np.random.default_rng(5)
    a = rng.uniform(0.0, 1.0, (6, 5, 3)).astype(np.float32)
    a[0, 0, :] = np.float32(1e-39)  # a pixel whose three channels are subnormal: so is its mean
    a[1, 2, 1] = np.float32(-3e-40)
    a[2, 3, :] = (np.float32(2e-38), np.float32(1e-45), np.float32(0.0))  # mean 6.7e-39: subnormal
    assert count_subnormal(a) == 5  # 2e-38 is a normal float32
    img = mi.TensorXf(a)
    grey = grey_to_host(mi, img)
    assert count_subnormal(grey) == 0
    assert grey[0, 0] == 0.0 and grey[2, 3] == 0.0
    expect = a.mean(axis=2)
    expect[np.abs(expect) < FLOAT32_TINY] = 0.0
    assert np.array_equal(grey, expect)
    chans = channels_to_host(mi, img)
    assert count_subnormal(chans) == 0 and chans[2, 3, 0] == np.float32(2e-38) and chans[1, 2, 1] == 0.0
