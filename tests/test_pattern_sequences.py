"""Pattern sequences at the cost of a few renders, exactly: three patterns per launch, complements by linearity.

``render_pattern_sequence`` renders only the frames a sequence needs (``plan_sequence``), three to
a launch in the colour channels of a grey scene, and derives each complementary frame as
``I(white) + I(black) - I(pattern)``. Checked against renders of each pattern alone with the
same seed (real Mitsuba renders).
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from platebench.bench.run.pattern_sequences import frame_seed, plan_sequence, render_pattern_sequence
from platebench.plates import CylindricalBend, PlateSpec, build_plate
from platebench.reconstruction.peers.graycode import graycode_sequence
from platebench.reconstruction.peers.phase_shift import phase_shift_sequence
from platebench.scenes.naming import image_seed
from platebench.scenes.pattern import Pattern
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.scene_spec import Lighting, Material, RenderSettings, reference_scene
from platebench.scenes.sensor_model import SensorModel


def test_plan_renders_one_frame_of_each_complementary_pair():
    full = graycode_sequence(64, 32)  # 6 column + 5 row planes, each with its inverse, black, white
    plan = plan_sequence(full.images)
    assert len(full.images) == 24 and len(plan.rendered) == 13 and len(plan.complement) == 11
    for i, j in plan.complement.items():
        assert np.array_equal(full.images[i].astype(int), 255 - full.images[j].astype(int))
    assert plan.rendered[plan.black] == full.black and plan.rendered[plan.white] == full.white
    cols = graycode_sequence(1024, 768).columns_only()
    assert len(plan_sequence(cols.images).rendered) == 12  # 10 planes + black + white of 22 frames
    phase = phase_shift_sequence(1024, 768)  # 4 fringes (rounded: no exact complements) + 7 planes
    assert plan_sequence(phase.images).rendered == tuple(range(len(phase.images)))
    rng = np.random.default_rng(4)
    a = rng.integers(0, 256, (3, 5, 7)).astype(np.uint8)
    one_pair = np.stack([a[0], 255 - a[0], a[1]])
    p = plan_sequence(one_pair)  # one complement: cheaper to render it than black and white
    assert p.rendered == (0, 1, 2) and not p.complement
    three = np.stack([a[0], a[1], 255 - a[0], a[2], 255 - a[2], 255 - a[1]])
    p = plan_sequence(three)
    assert p.rendered == (0, 1, 3, -1, -2) and p.complement == {2: 0, 4: 3, 5: 1}


def _renderer(material=Material(), ambient=0.0):
    scene = reference_scene(width=80, height=60, f_px=125.0, material=material, lighting=Lighting(ambient=ambient))
    return PlateRenderer(scene, build_plate(PlateSpec(0.1165, 0.0735, deformation=CylindricalBend(np.radians(25.0)))))


@pytest.mark.render
def test_three_patterns_in_one_launch_are_the_renders_of_each_alone():
    r = _renderer()
    assert r.patterns_per_launch == 3
    seq = graycode_sequence(r.spec.projector.pattern.width, r.spec.projector.pattern.height)
    pats = seq.images[[0, 3, 6]].astype(np.float32) / np.float32(255)
    s = RenderSettings(spp=2, seed=9)
    packed = r.render_patterns("right", pats, s)
    assert packed.shape == (3, 60, 80) and packed.max() > 0.1
    for i in range(3):  # the same image in every channel position, to the bit
        assert np.array_equal(packed[i], r.render_patterns("right", pats[i:i + 1], s)[0])
        shifted = r.render_patterns("right", np.roll(pats, 1, axis=0), s)
        assert np.array_equal(shifted[(i + 1) % 3], packed[i])
        # ... and the bench's own image of that pattern (its channel mean) to float32 rounding
        r.set_scene(dataclasses.replace(r.spec, projector=r.spec.projector.with_pattern(Pattern(pats[i]))))
        alone = r.render("right", "active", s)
        assert np.abs(alone - packed[i]).max() <= 2.4e-7 * max(float(alone.max()), 1e-30)
    assert not np.array_equal(packed[0], packed[1])


@pytest.mark.render
def test_complement_by_linearity_equals_its_render():
    r = _renderer(ambient=0.3)
    rng = np.random.default_rng(11)
    g = rng.uniform(0.0, 1.0, (r.spec.projector.pattern.height, r.spec.projector.pattern.width)).astype(np.float32)
    s = RenderSettings(spp=3, seed=5)
    white, black, img = r.render_patterns("left", np.stack([np.ones_like(g), np.zeros_like(g), g]), s)
    inverse = r.render_patterns("left", (np.float32(1) - g)[None], s)[0]
    assert black.max() > 0  # the ambient light in the active image
    assert np.abs((white + black - img) - inverse).max() <= 1e-5 * float(white.max())


@pytest.mark.render
def test_sequence_frames_are_the_digitized_renders_of_each_frame():
    r = _renderer()
    seq = graycode_sequence(r.spec.projector.pattern.width, r.spec.projector.pattern.height).columns_only()
    settings, sensor = RenderSettings(spp=2, seed=3), SensorModel(full_well_e=20000.0, read_noise_dn=1.0)
    builds = r.scene_builds
    cap = render_pattern_sequence(r, seq.images, settings, sensor)
    assert r.scene_builds == builds and cap.launches == 4  # 12 frames rendered, three to a launch
    one = RenderSettings(spp=2, seed=frame_seed(3, 0))
    for i in (0, 1, seq.black, seq.white):  # a plane, its inverse (derived), black, white
        alone = r.render_patterns("left", seq.images[i:i + 1].astype(np.float32)[None][0] / np.float32(255), one)[0]
        expect = sensor.digitize(alone, seed=image_seed(frame_seed(3, i), "left", "active"))
        diff = np.abs(cap["left"][i].astype(int) - expect.astype(int))
        assert diff.max() <= 1 and np.mean(diff == 0) >= 0.999, (i, diff.max(), np.mean(diff == 0))
    # the scene's own pattern is back: the sample's active image renders as before the sequence
    before = _renderer().render("left", "active", settings)
    assert np.array_equal(r.render("left", "active", settings), before)


@pytest.mark.render
def test_a_conductor_renders_one_pattern_per_launch():
    r = _renderer(Material(kind="roughconductor", metal="Al", alpha=0.3))
    assert r.patterns_per_launch == 1
    pats = np.zeros((2, r.spec.projector.pattern.height, r.spec.projector.pattern.width), np.float32)
    with pytest.raises(ValueError, match="from 1 to 1"):
        r.render_patterns("left", pats, RenderSettings(spp=1))
    seq = graycode_sequence(r.spec.projector.pattern.width, r.spec.projector.pattern.height).columns_only()
    assert render_pattern_sequence(r, seq.images, RenderSettings(spp=1)).launches == 12
