"""Mitsuba renderer of a plate under passive and active lighting (the only Mitsuba scene builder).

One Mitsuba scene holds the plate, the dark ground, the overhead area light, the
projector and both stereo sensors. Switching lighting, moving the rig or the
projector, swapping the pattern or the plate only updates parameters through
``mi.traverse``, so drjit reuses its compiled kernels (the area light's transform is made an
opaque kernel input: Mitsuba's rectangle would bake it in as literals, unlike the sensors and
emitters, which keep theirs opaque); only a change of *structure*
(image size, projector kind or pattern size, material kind, integrator depth)
rebuilds the scene.

Images are linear radiance, float32, (H, W), the mean of Mitsuba's RGB channels, taken on the
render's device and copied to the host once (``scenes.render.film``). The ``box`` reconstruction filter keeps
renders bit-identical for a given seed across processes. A render of more than ``pass_samples``
samples (width x height x spp) runs in passes (``scenes.render.passes``: its module doc says which
renders keep the bytes of one Mitsuba call and what a split one equals), so that a signal or a
progress bar is served between them.
Units: metres; frames as in ``scenes.camera``; conversions in ``scenes.render.mitsuba_convert``.
"""
from __future__ import annotations

import numpy as np

from platebench.scenes.naming import CAMERAS, LIGHTINGS, image_seed
from platebench.scenes.render import runtime
from platebench.scenes.render.device_arrays import aligned, to_device
from platebench.scenes.render.film import channels_to_host, grey_to_host
from platebench.scenes.render.lens_sensor import configure_sensor, sensor_dict, sensor_kind
from platebench.scenes.render.mitsuba_convert import (
    perspective_fov_deg,
    perspective_to_world,
    spot_cutoff_deg,
    spot_to_world,
)
from platebench.scenes.render.passes import PASS_SAMPLES, render_in_passes
from platebench.scenes.scene_spec import RenderSettings, SceneSpec


def area_light_to_world(spec: SceneSpec) -> np.ndarray:
    """4x4 to_world of the passive area light (Mitsuba's rectangle: [-1, 1]^2 in z = 0, normal +z).

    Fixed (default): level at ``area_height_m`` above the rig's centre, facing -Z. Following the rig
    (``lighting.follows_rig``): on the rig's centre line, ``behind_rig_m`` behind the mid-baseline
    point, facing along the cameras' view (world X, Y edges for a rig looking straight down)."""
    light = spec.lighting
    a = light.area_size_m / 2
    if not light.follows_rig:
        cx, cy = (float(c) for c in spec.rig.center[:2])
        return np.array([[a, 0, 0, cx], [0, a, 0, cy], [0, 0, -1.0, light.area_height_m], [0, 0, 0, 1]])
    f = np.asarray(spec.rig.left.R[2], float)  # view direction (world)
    c = spec.rig.center - f * light.behind_rig_m
    seed = np.array([1.0, 0.0, 0.0]) if abs(f[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = seed - f * (seed @ f)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(f, e1)
    M = np.eye(4)
    M[:3, 0], M[:3, 1], M[:3, 2], M[:3, 3] = a * e1, a * e2, f, c
    return M


def area_light_distance_m(spec: SceneSpec) -> float:
    """Distance (m) from the area light to the plate centre (the world origin) along its axis."""
    light = spec.lighting
    if not light.follows_rig:
        return light.area_height_m
    return float(max(spec.rig.left.depth(np.zeros((1, 3)))[0], 0.0) + light.behind_rig_m)


def _structure(spec: SceneSpec) -> tuple:
    p = spec.projector
    m = spec.material
    return (spec.rig.left.width, spec.rig.left.height, p.kind, p.pattern.width, p.pattern.height,
            m.kind, m.metal if m.kind == "roughconductor" else None, spec.max_depth, spec.aperture_radius_m > 0,
            _sensor_kind(spec))


def _sensor_kind(spec: SceneSpec) -> str:
    return sensor_kind(spec.rig.cameras.values(), spec.aperture_radius_m)


class PlateRenderer:
    """Renders a plate in a scene; update plate/scene freely, kernels are reused."""

    def __init__(self, spec: SceneSpec, plate, variant: str | None = None, pass_samples: int = PASS_SAMPLES):
        self.mi = runtime.mitsuba(variant)
        self.pass_samples = int(pass_samples)  # the most samples of one mi.render call (scenes.render.passes)
        self.variant = self.mi.variant()
        self._spec = None
        self._plate = None
        self._structure = None
        self.scene_builds = 0
        self.set_scene(spec)
        self.set_plate(plate)

    # -- building -------------------------------------------------------------
    def _bsdf(self, spec: SceneSpec) -> dict:
        m = spec.material
        if m.kind == "roughconductor":
            inner = {"type": "roughconductor", "material": m.metal, "distribution": "ggx", "alpha": m.alpha}
        else:
            inner = {"type": "diffuse", "reflectance": {"type": "rgb", "value": [m.albedo] * 3}}
        return {"type": "twosided", "material": inner}

    def _empty_mesh(self, name: str, bsdf: dict | None):
        """A mesh sized for the current plate (one placeholder triangle before any plate);
        set_plate fills its buffers through traverse."""
        mi = self.mi
        props = mi.Properties()
        if bsdf is not None:
            props["bsdf"] = mi.load_dict(bsdf)
        if self._plate is None:
            v, f = np.array([0, 0, 0, 1e-3, 0, 0, 0, 1e-3, 0], np.float32), np.array([0, 1, 2], np.uint32)
        else:
            v = np.asarray(self._plate.mesh.vertices, np.float32).ravel()
            f = np.asarray(self._plate.mesh.faces, np.uint32).ravel()
        mesh = mi.Mesh(name, v.size // 3, f.size // 3, props=props)
        params = mi.traverse(mesh)
        params["vertex_positions"] = type(params["vertex_positions"])(v)
        params["faces"] = type(params["faces"])(f)
        params.update()
        return mesh

    def _build(self, spec: SceneSpec) -> None:
        mi = self.mi
        cam = spec.rig.left
        film = {"type": "hdrfilm", "width": cam.width, "height": cam.height,
                "rfilter": {"type": "box"}, "pixel_format": "rgb", "sample_border": False}
        kind = _sensor_kind(spec)
        sensors = {name: sensor_dict(mi, c, name, kind, film, {"type": "independent"}, spec.aperture_radius_m,
                                     spec.focus_m)
                   for name, c in spec.rig.cameras.items()}
        proj = spec.projector
        pat = np.zeros((proj.pattern.height, proj.pattern.width, 1), np.float32)
        if proj.kind == "spot":
            emitter = {"type": "spot", "cutoff_angle": spot_cutoff_deg(proj.camera, proj.cutoff_rad),
                       "beam_width": spot_cutoff_deg(proj.camera, proj.cutoff_rad),
                       "intensity": {"type": "uniform", "value": 1.0},
                       "texture": {"type": "bitmap", "data": mi.TensorXf(pat), "raw": True,
                                   "filter_type": "nearest", "wrap_mode": "clamp"},
                       "to_world": mi.ScalarTransform4f(spot_to_world(proj.camera).tolist())}
        else:
            emitter = {"type": "projector", "fov_axis": "x", "fov": perspective_fov_deg(proj.camera, "projector"),
                       "irradiance": {"type": "bitmap", "data": mi.TensorXf(pat), "raw": True,
                                      "filter_type": "nearest", "wrap_mode": "clamp"},
                       "to_world": mi.ScalarTransform4f(perspective_to_world(proj.camera).tolist())}
        self._plate_mesh = self._empty_mesh("plate", self._bsdf(spec))
        scene = {"type": "scene",
                 "integrator": {"type": "path", "max_depth": spec.max_depth, "hide_emitters": True},
                 "left": sensors["left"], "right": sensors["right"],
                 "plate": self._plate_mesh,
                 "ground": {"type": "rectangle",
                            "to_world": mi.ScalarTransform4f().translate([0, 0, spec.ground_z_m]).scale(2.0),
                            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb",
                                                                         "value": [spec.ground_albedo] * 3}}},
                 "light": {"type": "rectangle",
                           "to_world": mi.ScalarTransform4f(),
                           "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [1.0] * 3}}},
                 "projector": emitter}
        self.scene = mi.load_dict(scene)
        self.params = mi.traverse(self.scene)
        self.sensors = {name: self.scene.sensors()[i] for i, name in enumerate(CAMERAS)}
        # Ground-truth scene: the plate alone (rays hit nothing else).
        self._gt_mesh = self._empty_mesh("plate_gt", None)
        self.gt_scene = mi.load_dict({"type": "scene", "plate": self._gt_mesh})
        self.gt_params = mi.traverse(self.gt_scene)
        self.scene_builds += 1

    # -- updates --------------------------------------------------------------
    def set_scene(self, spec: SceneSpec) -> None:
        """Adopt a new scene description, by parameter update when the structure allows."""
        structure = _structure(spec)
        if structure != self._structure:
            self._build(spec)
            self._structure = structure
            if self._plate is not None:
                self._load_plate(self._plate)
        p = self.params
        mi = self.mi
        import drjit as dr  # noqa: PLC0415  (runtime.mitsuba() has chosen libLLVM already)
        kind = _sensor_kind(spec)
        for name, cam in spec.rig.cameras.items():
            configure_sensor(mi, p, self.sensors[name], cam, name, kind, spec.aperture_radius_m, spec.focus_m)
        proj = spec.projector
        if proj.kind == "spot":
            p["projector.to_world"] = mi.Transform4f(spot_to_world(proj.camera).tolist())
        else:
            p["projector.to_world"] = mi.Transform4f(perspective_to_world(proj.camera).tolist())
        # The area light rides with the rig. Mitsuba's rectangle would bake a literal transform into
        # the render kernel, so every new pose would compile it again;
        # opaque, the transform is a kernel input and one kernel serves every pose.
        light = mi.Transform4f(area_light_to_world(spec).tolist())
        dr.make_opaque(light)
        p["light.to_world"] = light
        if spec.material.kind == "diffuse":
            p["plate.bsdf.brdf_0.reflectance.value"] = [spec.material.albedo] * 3
        elif spec.material.kind == "roughconductor":
            p["plate.bsdf.brdf_0.alpha.value"] = spec.material.alpha
        p.update()
        self._spec = spec
        self._light_strengths()

    def _light_strengths(self) -> None:
        """Scale lights so a white plate at the rig's target shows ``plate_radiance``."""
        spec = self._spec
        L = spec.lighting.plate_radiance
        # Radiance L from a white Lambertian surface needs irradiance E = pi L.
        # Mitsuba's projector gives E = pi * scale * texture / d^2 on axis; a spot I / d^2.
        d = max(float(spec.projector.camera.center[2]), 1e-3)  # height above the plate plane z = 0
        self._proj_scale = L * d ** 2 * (1.0 if spec.projector.kind == "pinhole" else np.pi)
        h = area_light_distance_m(spec)
        s = spec.lighting.area_size_m
        # Irradiance under a square of side s at height h (exact, on axis).
        a = s / 2.0
        E_per_radiance = 4.0 * (a / np.sqrt(a * a + h * h)) * np.arctan(a / np.sqrt(a * a + h * h))
        self._area_radiance = np.pi * L / E_per_radiance

    def set_plate(self, plate) -> None:
        """Swap the plate geometry (vertex and face buffers) without recompiling kernels."""
        self._plate = plate
        self._load_plate(plate)

    def _load_plate(self, plate) -> None:
        v = np.asarray(plate.mesh.vertices, np.float32).ravel()
        f = np.asarray(plate.mesh.faces, np.uint32).ravel()
        if self.variant.startswith("scalar") and len(self.params["plate.vertex_positions"]) != v.size:
            # Scalar variants cannot resize buffers through traverse: rebuild (no kernels to lose).
            self._build(self._spec)
            self.set_scene(self._spec)
            return
        for params in (self.params, self.gt_params):
            # Construct with the buffer's own type (dynamic in every variant, scalar too).
            params["plate.vertex_positions"] = to_device(type(params["plate.vertex_positions"]), v)
            params["plate.faces"] = to_device(type(params["plate.faces"]), f)
            params.update()

    def set_lighting(self, lighting: str) -> None:
        """Switch the lights for ``lighting`` (passive: area light; active: projector + ambient)."""
        p = self.params
        amb = self._spec.lighting.ambient
        area = self._area_radiance * (1.0 if lighting == "passive" else amb)
        p["light.emitter.radiance.value"] = [float(area)] * 3
        # Emitter sampling picks a light in proportion to these weights: give none to a
        # light that is off, or half the samples are wasted (binomial noise).
        p["light.emitter.sampling_weight"] = 1.0 if area > 0 else 0.0
        p["projector.sampling_weight"] = 1.0 if lighting == "active" else 0.0
        level = self._proj_scale if lighting == "active" else 0.0
        spot = self._spec.projector.kind == "spot"
        p["projector.intensity.value" if spot else "projector.scale"] = float(level)
        self._set_projector_image(self._spec.projector.pattern.image[..., None])

    def _set_projector_image(self, image: np.ndarray) -> None:
        """Load (Hp, Wp, C) float32 values in [0, 1], C = 1 or 3, into the projector's texture
        (a parameter update; the channel count is the kernel's only change, compiled once each)."""
        mi, p = self.mi, self.params
        tex = mi.TensorXf(aligned(np.asarray(image, np.float32)))
        p["projector.texture.data" if self._spec.projector.kind == "spot" else "projector.irradiance.data"] = tex
        p.update()

    @property
    def patterns_per_launch(self) -> int:
        """Projector patterns one launch can render (``render_patterns``): 3 when the plate is grey
        (diffuse; every light is white), so that the RGB channels are independent renders of three
        patterns; 1 for a conductor, whose channels reflect differently."""
        return 3 if self._spec.material.kind == "diffuse" else 1

    def render_patterns(self, camera: str, patterns: np.ndarray, settings: RenderSettings = RenderSettings(),
                        on_pass=None) -> np.ndarray:
        """(k, H, W) float32 active images of ``camera`` under each of ``k <= patterns_per_launch``
        projector patterns ((k, Hp, Wp) values in [0, 1]) in one launch, along the same camera paths.

        With a grey plate, pattern c goes into the projector's colour channel c and image c is
        channel c of the render: the path tracer treats the channels alike (the BSDFs and the other
        lights are grey, Russian roulette reads the path's grey throughput, the projector is not
        importance-sampled by its texture), so image c is, to the last bit, channel c of a render
        of pattern c alone with the same seed; its channel mean, ``render``'s image, agrees to
        float32 rounding. With a conductor, one pattern per launch and its channel mean. The scene's
        own pattern is back in place at the next ``set_lighting``. Rendered in passes as ``render``."""
        pats = np.asarray(patterns, np.float32)
        k = len(pats)
        if pats.ndim != 3 or not 1 <= k <= self.patterns_per_launch:
            raise ValueError(f"render_patterns: got patterns of shape {pats.shape}; allowed (k, Hp, Wp) with k from "
                             f"1 to {self.patterns_per_launch}")
        if camera not in CAMERAS:
            raise ValueError(f"camera = {camera!r} is not allowed: choose one of {CAMERAS}")
        self.set_lighting("active")
        if self.patterns_per_launch == 3:
            image = np.zeros((*pats.shape[1:], 3), np.float32)
            image[..., :k] = np.moveaxis(pats, 0, -1)
        else:
            image = pats[0][..., None]
        self._set_projector_image(image)
        seed = image_seed(settings.seed, camera, "active")
        if self.patterns_per_launch == 3:
            img = self._render(camera, settings.spp, seed, channels_to_host, on_pass)
            return np.ascontiguousarray(np.moveaxis(img[..., :k], -1, 0))
        return self._render(camera, settings.spp, seed, grey_to_host, on_pass)[None]

    def _render(self, camera: str, spp: int, seed: int, to_host, on_pass) -> np.ndarray:
        return render_in_passes(self.mi, self.scene, CAMERAS.index(camera), spp, seed, to_host, self.pass_samples,
                                on_pass)

    # -- rendering ------------------------------------------------------------
    def render(self, camera: str, lighting: str, settings: RenderSettings = RenderSettings(),
               on_pass=None) -> np.ndarray:
        """Linear radiance image (H, W) float32 of one camera under one lighting, in passes of at most
        ``pass_samples`` samples (``scenes.render.passes``); ``on_pass(done_spp, spp)`` after each."""
        if camera not in CAMERAS:
            raise ValueError(f"camera = {camera!r} is not allowed: choose one of {CAMERAS}")
        if lighting not in LIGHTINGS:
            raise ValueError(f"lighting = {lighting!r} is not allowed: choose one of {LIGHTINGS}")
        self.set_lighting(lighting)
        return self._render(camera, settings.spp, image_seed(settings.seed, camera, lighting), grey_to_host, on_pass)

    def render_all(self, settings: RenderSettings = RenderSettings()) -> dict[str, np.ndarray]:
        """The four images of a sample, keyed ``left_passive`` ... ``right_active``."""
        out = {}
        for lighting in LIGHTINGS:
            for camera in CAMERAS:
                out[f"{camera}_{lighting}"] = self.render(camera, lighting, settings)
        return out

    @property
    def spec(self) -> SceneSpec:
        return self._spec

    @property
    def plate(self):
        return self._plate
