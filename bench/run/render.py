"""Render one sample in memory: the plate, the four images and all ground truth.

``render_sample(cfg)`` builds the plate and scene, renders the four images through one
``PlateRenderer`` (pass it back for the next sample: kernels are reused, the plate and the
scene are swapped by parameter update) and casts the ground truth. ``posed_scene`` re-places
the rig for a sweep's pose axes. Writing the sample is ``bench.io.sample_files.write_sample``.

Under a realism preset with a robot or estimates (``cfg.realism``, ``bench.config.realism``), the
commanded rig is acquired as a real rig would acquire it (``bench.run.realism.realise``, draw
``cfg.realism.seed``): the images and the ground truth come from the cameras really placed, and the
sample's calibration is what the method is told (the commanded poses, the estimated intrinsics).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from platebench.bench import interrupts
from platebench.bench.config import RigPose, SampleConfig
from platebench.bench.io.codecs import decode
from platebench.bench.io.realism_records import DrawReport
from platebench.bench.run.realism import realise_sample
from platebench.plates import Plate, build_plate
from platebench.scenes.naming import IMAGE_NAMES, image_seed
from platebench.scenes.render.ground_truth import GroundTruthCaster
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.rig import StereoRig
from platebench.scenes.scene_spec import SceneSpec, scene_for_pose

__all__ = ["RenderedSample", "render_sample", "render_images", "ground_truth_at", "posed_scene"]


@dataclass(frozen=True)
class RenderedSample:
    """A rendered sample in memory: config, plate, scene, images, ground truth, timings.

    ``radiance``/``digital``: image name (``scenes.naming.IMAGE_NAMES``) -> (H, W) array: linear
    float32 radiance, and the camera's uint8/uint16 output; ``gt``: camera -> CameraGroundTruth;
    ``visibility``: camera -> BoundaryVisibility of the true boundary; ``timings_s`` in seconds.
    """

    config: SampleConfig
    plate: Plate
    scene: SceneSpec
    radiance: dict  # name -> (H,W) float32 linear
    digital: dict  # name -> (H,W) uint8/uint16 camera output
    gt: dict  # camera -> CameraGroundTruth
    visibility: dict  # camera -> BoundaryVisibility
    timings_s: dict
    variant: str
    told: StereoRig | None = None  # the rig the method is told, when it is not the one rendered (realism)
    acquisition: DrawReport | None = None  # what the realism's draw missed by (``bench.run.realism.Acquisition.report``)

    @property
    def calibration_rig(self) -> StereoRig:
        """The conventional rig a method is given: the told rig, or the rendered one."""
        return self.told if self.told is not None else self.scene.rig


def _between_passes(name: str, on_pass):
    """The ``on_pass(done_spp, spp)`` of image ``name``'s render: a signal recorded but swallowed is raised
    here (``bench.interrupts.check``), then ``on_pass(name, done_spp, spp)`` if given."""
    def passed(done: int, spp: int) -> None:
        interrupts.check()
        if on_pass is not None:
            on_pass(name, done, spp)
    return passed


def render_sample(cfg: SampleConfig, renderer: PlateRenderer | None = None, progress=None,
                  scene=None, on_pass=None) -> tuple[RenderedSample, PlateRenderer]:
    """Build the plate and scene, render the four images and cast all ground truth.

    Pass the ``renderer`` of a previous sample to reuse its compiled kernels (plate and
    scene are swapped by parameter update). ``progress(step_name)`` is called per step;
    ``on_pass(image_name, done_spp, spp)`` after each pass of an image's render
    (``scenes.render.passes``), where a pending interrupt is raised first.
    ``scene`` (a SceneSpec) replaces ``cfg.scene.build()``: a rig placed by the sensing loop.
    Without ``scene``, a realism preset that moves the camera or estimates the calibration acquires
    the commanded rig with its errors (see the module doc).
    """
    step = progress or (lambda name: None)
    t0 = time.perf_counter()
    timings = {}
    step("plate")
    plate = build_plate(cfg.plate)
    told = report = None
    if scene is None:
        scene = cfg.scene.build()
        if not cfg.realism.is_ideal:
            step("realism")
            acq = realise_sample(cfg, scene.rig)
            scene, told, report = scene.with_rig(acq.taken), acq.told, acq.report
    timings["plate_s"] = time.perf_counter() - t0
    t = time.perf_counter()
    if renderer is None:
        renderer = PlateRenderer(scene, plate, cfg.variant)
    else:
        renderer.set_scene(scene)
        renderer.set_plate(plate)
    timings["scene_s"] = time.perf_counter() - t
    radiance, digital = {}, {}
    for name in IMAGE_NAMES:
        step(f"render {name}")
        t = time.perf_counter()
        cam, light = name.split("_")
        radiance[name] = renderer.render(cam, light, cfg.render, on_pass=_between_passes(name, on_pass))
        digital[name] = cfg.sensor.digitize(radiance[name], seed=image_seed(cfg.render.seed, cam, light))
        timings[f"render_{name}_s"] = time.perf_counter() - t
    step("ground truth")
    t = time.perf_counter()
    caster = GroundTruthCaster(renderer)
    gt, vis = caster.all()
    timings["ground_truth_s"] = time.perf_counter() - t
    timings["total_s"] = time.perf_counter() - t0
    return RenderedSample(cfg, plate, scene, radiance, digital, gt, vis, timings, renderer.variant, told,
                          report), renderer




def posed_scene(scene: SceneSpec, distance_m: float, pose: dict) -> SceneSpec:
    """``scene`` with the rig tilted by ``tilt_deg`` from vertical toward azimuth ``azimuth_deg``
    (from +X around +Z; ``pose``: a sweep sample's pose table, ``config.RigPose``), its mid-baseline
    point ``distance_m`` from the plate centre, looking at it; the baseline stays as close to the
    reference baseline direction as the tilt allows."""
    p = decode(RigPose, pose)
    tilt = math.radians(p.tilt_deg)
    az = math.radians(p.azimuth_deg)
    center = distance_m * np.array([math.sin(tilt) * math.cos(az), math.sin(tilt) * math.sin(az), math.cos(tilt)])
    baseline_dir = np.asarray(scene.rig.left.R[0], float)  # camera +x (the baseline) in the world frame
    return scene_for_pose(center, np.zeros(3), baseline_dir, scene)


def render_images(cfg: SampleConfig, renderer: PlateRenderer | None, scene: SceneSpec, plate: Plate,
                  names=IMAGE_NAMES) -> tuple[dict, dict, dict, PlateRenderer]:
    """Only the images ``names`` of ``plate`` at ``scene`` (e.g. the passive pair of a sensing view),
    and the true boundary's visibility from both cameras (cheap: no dense ground-truth maps).

    Returns (radiance, digital, visibility: camera -> BoundaryVisibility, renderer); the plate is
    swapped into a passed renderer only when it is another plate."""
    if renderer is None:
        renderer = PlateRenderer(scene, plate, cfg.variant)
    else:
        renderer.set_scene(scene)
        if renderer.plate is not plate:
            renderer.set_plate(plate)
    radiance, digital = {}, {}
    for name in names:
        cam, light = name.split("_")
        radiance[name] = renderer.render(cam, light, cfg.render, on_pass=_between_passes(name, None))
        digital[name] = cfg.sensor.digitize(radiance[name], seed=image_seed(cfg.render.seed, cam, light))
    caster = GroundTruthCaster(renderer)
    vis = {c: caster.boundary_visibility(c) for c in ("left", "right")}
    return radiance, digital, vis, renderer


def ground_truth_at(renderer: PlateRenderer) -> tuple[dict, dict]:
    """Dense ground truth (camera -> CameraGroundTruth) and boundary visibility at the renderer's
    current scene and plate."""
    return GroundTruthCaster(renderer).all()
