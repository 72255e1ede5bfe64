"""Moving the rig reuses the compiled render kernel (a real Mitsuba render, kernel history read back).

A sensing run renders the plate from dozens of poses. If anything that moves with the rig entered
the render kernel as a literal, every new pose would compile that kernel again (0.5-0.7 s of LLVM
time a pose at 640 x 480, about half a study's time on a machine with an empty kernel cache).
drjit's kernel history tells whether a launch was compiled or found in its in-memory cache.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from platebench.plates import CylindricalBend, PlateSpec, build_plate
from platebench.scenes.lens import BrownConrady
from platebench.scenes.render import runtime
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.scene_spec import RenderSettings, reference_scene, scene_for_pose

pytestmark = pytest.mark.render

BIG_KERNEL_OPS = 1000  # the path tracer's kernel has ~2000 operations; buffer updates a few dozen


def _render_kernels(dr, r, scene, settings) -> list[dict]:
    """The big kernels launched while rendering all four images at ``scene``, each marked
    ``fresh`` when it was not in drjit's in-memory cache (compiled, or loaded from the disk cache:
    either way a kernel this process had not run, as a pose-dependent literal would make)."""
    dr.kernel_history()  # clears it
    r.set_scene(scene)
    r.render_all(settings)
    return [{"ops": k["operation_count"], "fresh": (not k["cache_hit"]) or bool(k["cache_disk"])}
            for k in dr.kernel_history() if k.get("operation_count", 0) > BIG_KERNEL_OPS]


LENSES = {  # the camera: Mitsuba's perspective, or the bench's lens sensor (distortion, non-square pixels, aperture)
    "perspective": {},
    "lens-sensor": {"fy_px": 125.0, "distortion": BrownConrady(-0.2, 0.1, 0.001, -0.002)},
}


@pytest.mark.parametrize("projector_kind,lens", [("spot", "perspective"), ("pinhole", "perspective"),
                                                 ("pinhole", "lens-sensor")])
def test_new_poses_reuse_the_render_kernel(projector_kind, lens):
    mi = runtime.mitsuba()
    if mi.variant().startswith("scalar"):
        pytest.skip("scalar variant: no kernels")
    import drjit as dr  # noqa: PLC0415  (after runtime.mitsuba(): libLLVM chosen)

    base = reference_scene(width=64, height=48, f_px=100.0, projector_kind=projector_kind, **LENSES[lens])
    base = dataclasses.replace(base, lighting=dataclasses.replace(base.lighting, follows_rig=True))
    plate = build_plate(PlateSpec(length_m=0.2, width_m=0.1, deformation=CylindricalBend(angle_rad=np.radians(120.0))))
    settings = RenderSettings(spp=1, seed=3)
    rng = np.random.default_rng(7)

    def pose(k: int):
        c = np.array([0.08 * np.cos(k), 0.08 * np.sin(k), 0.4]) + rng.uniform(-0.01, 0.01, 3)
        return scene_for_pose(c, rng.uniform(-0.01, 0.01, 3), np.array([np.cos(0.3 * k), np.sin(0.3 * k), 0.0]), base)

    r = PlateRenderer(pose(0), plate)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        _render_kernels(dr, r, pose(0), settings)  # the first pose may compile
        later = [_render_kernels(dr, r, pose(k), settings) for k in (1, 2, 3)]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
        dr.kernel_history()
    for k, kernels in enumerate(later, start=1):
        assert len(kernels) == 4, f"pose {k}: expected the 4 renders' kernels in the history, got {kernels}"
        fresh = [c["ops"] for c in kernels if c["fresh"]]
        assert not fresh, f"pose {k} needed new render kernels ({fresh} operations): a pose-dependent literal"


def test_another_lens_or_aperture_reuses_the_lens_sensors_kernel():
    """The lens sensor's K, distortion, aperture and focus are kernel inputs: a camera with another
    lens (same structure: image size, thin lens on) renders with the compiled kernels."""
    mi = runtime.mitsuba()
    if mi.variant().startswith("scalar"):
        pytest.skip("scalar variant: no kernels")
    import drjit as dr  # noqa: PLC0415

    plate = build_plate(PlateSpec(length_m=0.1, width_m=0.07, deformation=CylindricalBend(angle_rad=np.radians(20.0))))
    settings = RenderSettings(spp=1, seed=1)

    def scene(k1, fy, aperture, focus):
        s = reference_scene(width=64, height=48, f_px=100.0, fy_px=fy, distortion=BrownConrady(k1, 0.05))
        return dataclasses.replace(s, aperture_radius_m=aperture, focus_distance_m=focus)

    r = PlateRenderer(scene(-0.2, 125.0, 0.004, 0.40), plate)
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        _render_kernels(dr, r, scene(-0.2, 125.0, 0.004, 0.40), settings)
        later = [_render_kernels(dr, r, scene(k1, fy, a, f), settings)
                 for k1, fy, a, f in ((-0.1, 120.0, 0.003, 0.38), (0.15, 90.0, 0.006, 0.45))]
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
        dr.kernel_history()
    assert r.scene_builds == 1
    for kernels in later:
        assert len(kernels) == 4 and not [c["ops"] for c in kernels if c["fresh"]], kernels


def _ground_truth_kernels(dr, r) -> list[dict]:
    """Every kernel launched while casting a sample's ground truth at the renderer's scene and plate,
    marked ``fresh`` when this process had not run it (``_render_kernels``)."""
    from platebench.scenes.render.ground_truth import GroundTruthCaster  # noqa: PLC0415
    dr.kernel_history()
    GroundTruthCaster(r).all()
    return [{"ops": k.get("operation_count", 0), "fresh": (not k["cache_hit"]) or bool(k["cache_disk"])}
            for k in dr.kernel_history() if k["type"] == dr.KernelType.JIT]


@pytest.mark.parametrize("projector_kind,lens", [("spot", "perspective"), ("pinhole", "lens-sensor")])
def test_another_plate_pose_and_lens_reuse_the_ground_truth_kernels(projector_kind, lens):
    """The ground-truth maps are computed in drjit kernels on the renderer's device; the camera,
    the projector, the lens and the plate's bend enter them as opaque values and the mesh as buffers,
    so another plate of the same family, seen from another pose through another lens, is cast with
    the kernels compiled for the first."""
    mi = runtime.mitsuba()
    if mi.variant().startswith("scalar"):
        pytest.skip("scalar variant: no kernels")
    import drjit as dr  # noqa: PLC0415

    def scene(k: int):
        extra = dict(LENSES[lens])
        if extra:
            extra = {"fy_px": 125.0 + 5 * k, "distortion": BrownConrady(-0.2 + 0.05 * k, 0.1, 0.001, -0.002)}
        base = reference_scene(width=64, height=48, f_px=100.0 + 3 * k, projector_kind=projector_kind, **extra)
        c = np.array([0.03 * k, -0.02 * k, 0.4 + 0.01 * k])
        return scene_for_pose(c, np.zeros(3), np.array([np.cos(0.2 * k), np.sin(0.2 * k), 0.0]), base)

    def plate(k: int):
        return build_plate(PlateSpec(length_m=0.12 + 0.01 * k, width_m=0.07, thickness_m=0.001,
                                     deformation=CylindricalBend(np.radians(20.0 + 40 * k), ("up", "down")[k % 2],
                                                                 np.radians(15.0 * k))))

    r = PlateRenderer(scene(0), plate(0))
    dr.set_flag(dr.JitFlag.KernelHistory, True)
    try:
        first = _ground_truth_kernels(dr, r)
        later = []
        for k in (1, 2):
            r.set_scene(scene(k))
            r.set_plate(plate(k))
            later.append(_ground_truth_kernels(dr, r))
    finally:
        dr.set_flag(dr.JitFlag.KernelHistory, False)
        dr.kernel_history()
    assert max(c["ops"] for c in first) > 200, f"the float64 map kernel is missing from the history: {first}"
    for k, kernels in enumerate(later, start=1):
        assert len(kernels) == len(first), (k, first, kernels)
        fresh = [c["ops"] for c in kernels if c["fresh"]]
        assert not fresh, f"plate {k}: the ground truth compiled kernels again ({fresh} operations): a literal"
