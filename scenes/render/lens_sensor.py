"""The bench's Mitsuba sensor for cameras ``perspective`` cannot model: Brown-Conrady distortion,
non-square pixels, an off-centre principal point, skew; with a thin lens when the aperture is open.

A Python ``mi.Sensor`` registered with ``mi.register_sensor`` (Mitsuba 3's custom-plugin
mechanism). In the JIT variants its ``sample_ray`` is traced once into the render kernel, so
every camera ray is generated *through* the lens model, exactly as ``Camera.rays`` generates it
in float64: film sample -> OpenCV pixel -> K^-1 -> inverse distortion (``_NEWTON_STEPS`` Newton
steps on the 2 x 2 Jacobian, from the distorted point; float32 converges in 3-4 at the bench's
distortions) -> camera ray -> world (``mitsuba_convert.lens_sensor_params``). With an aperture the
ray is the thin lens's: from a point of the aperture disk (radius ``aperture_radius_m``, in the
lens plane z = 0) through the point of the chief ray on the focus plane z = ``focus_distance_m``
(camera frame; Mitsuba's ``thinlens`` focuses the same plane). The importance weight is 1,
as for Mitsuba's ``perspective`` (pixels are sampled uniformly).

Every camera parameter is an opaque drjit variable (``dr.make_opaque``), so a new pose, K or
lens is a kernel *input*: one compiled kernel serves them all (``tests/test_kernel_reuse.py``).
"""
from __future__ import annotations

import numpy as np

from platebench.scenes.camera import Camera
from platebench.scenes.render.mitsuba_convert import (
    lens_sensor_params,
    needs_lens_sensor,
    perspective_fov_deg,
    perspective_to_world,
)

__all__ = ["PLUGIN", "ensure_registered", "sensor_dict", "configure_sensor", "sensor_kind"]

PLUGIN = "platebench_lens"
_NEWTON_STEPS = 6
_CLASSES: dict = {}  # variant -> the sensor class registered for it


def _make_class(mi):
    import drjit as dr  # noqa: PLC0415  (runtime.mitsuba() has chosen libLLVM already)

    jit = dr.is_jit_v(mi.Float)

    def opaque(*vs):
        if jit:
            dr.make_opaque(*vs)

    class LensSensor(mi.Sensor):
        """OpenCV camera (K, R, t, Brown-Conrady) with an optional thin lens; see module doc."""

        def __init__(self, props):
            super().__init__(props)
            self.m_needs_sample_3 = bool(props.get("thin_lens", False))
            self.camera_name = str(props.get("camera", ""))
            self.set_parameters(np.eye(3), np.zeros(3), 1.0, 1.0, 0.0, 0.0, 0.0, np.zeros(5), 0.0, 1.0)

        def set_parameters(self, R_cw, center, fx, fy, cx, cy, skew, dist, aperture_radius_m, focus_distance_m):
            """Camera-to-world rotation (3x3), centre (m), K entries (px), OpenCV distortion
            (k1, k2, p1, p2, k3), aperture radius and focus distance (m)."""
            self.R_cw = mi.Matrix3f(np.asarray(R_cw, np.float32))
            self.C = mi.Point3f(*(float(c) for c in center))
            self.K = [mi.Float(float(v)) for v in (fx, fy, cx, cy, skew)]
            self.dist = [mi.Float(float(v)) for v in dist]
            self.lens = [mi.Float(float(aperture_radius_m)), mi.Float(float(focus_distance_m))]
            opaque(self.R_cw, self.C, *self.K, *self.dist, *self.lens)

        def _chief_direction(self, sample2):
            """Camera-frame unit direction of the chief ray through film position ``sample2``."""
            size = self.film().crop_size()
            fx, fy, cx, cy, skew = self.K
            k1, k2, p1, p2, k3 = self.dist
            yd = (sample2.y * size.y - 0.5 - cy) / fy
            xd = (sample2.x * size.x - 0.5 - cx - skew * yd) / fx
            x, y = mi.Float(xd), mi.Float(yd)
            for _ in range(_NEWTON_STEPS):  # exact inverse of scenes.lens.BrownConrady.distort
                r2 = x * x + y * y
                radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
                dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)
                ex = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x) - xd
                ey = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y - yd
                a = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x
                b = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y
                d = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x
                det = a * d - b * b
                x, y = x - (d * ex - b * ey) / det, y - (a * ey - b * ex) / det
            return dr.normalize(mi.Vector3f(x, y, 1.0))

        def sample_ray(self, time, sample1, sample2, sample3, active=True):
            wavelengths, weight = self.sample_wavelengths(dr.zeros(mi.SurfaceInteraction3f), sample1, active)
            d = self._chief_direction(sample2)
            if self.m_needs_sample_3:
                radius, focus = self.lens
                disk = mi.warp.square_to_uniform_disk_concentric(sample3) * radius
                aperture = mi.Vector3f(disk.x, disk.y, 0.0)
                d = dr.normalize(d * (focus / d.z) - aperture)
                origin = self.C + self.R_cw @ aperture
            else:
                origin = self.C
            return mi.Ray3f(mi.Point3f(origin), self.R_cw @ d, time, wavelengths), weight

        def sample_ray_differential(self, time, sample1, sample2, sample3, active=True):
            ray, weight = self.sample_ray(time, sample1, sample2, sample3, active)
            return mi.RayDifferential3f(ray), weight

        def to_string(self):
            return f"PlateBenchLensSensor[camera={self.camera_name!r}]"

    return LensSensor


def ensure_registered(mi) -> str:
    """Register the sensor plugin for Mitsuba's current variant (once); returns its name."""
    variant = mi.variant()
    if variant not in _CLASSES:
        cls = _make_class(mi)
        mi.register_sensor(PLUGIN, lambda props: cls(props))
        _CLASSES[variant] = cls
    return PLUGIN


def sensor_kind(cameras, aperture_radius_m: float) -> str:
    """Which Mitsuba sensor renders these cameras: ``"perspective"``/``"thinlens"`` (Mitsuba's
    own, when every camera is a centred square-pixel pinhole) or ``PLUGIN``."""
    if any(needs_lens_sensor(c) for c in cameras):
        return PLUGIN
    return "thinlens" if aperture_radius_m > 0 else "perspective"


def sensor_dict(mi, cam: Camera, name: str, kind: str, film: dict, sampler: dict,
                aperture_radius_m: float = 0.0, focus_distance_m: float | None = None) -> dict:
    """The ``mi.load_dict`` entry of one camera's sensor of ``kind`` (``sensor_kind``)."""
    if kind == PLUGIN:
        ensure_registered(mi)
        # ``camera`` names the sensor: Mitsuba's loader merges identical dicts into one object, and
        # the plugin's cameras differ only in parameters set after loading.
        return {"type": PLUGIN, "camera": name, "thin_lens": aperture_radius_m > 0, "film": dict(film),
                "sampler": dict(sampler)}
    lens = {"type": "perspective"}
    if kind == "thinlens":  # same pinhole mapping at the focus plane, plus blur
        lens = {"type": "thinlens", "aperture_radius": float(aperture_radius_m), "focus_distance": focus_distance_m}
    return {**lens, "fov_axis": "x", "fov": perspective_fov_deg(cam, name), "near_clip": 1e-3, "far_clip": 100.0,
            "to_world": mi.ScalarTransform4f(perspective_to_world(cam).tolist()),
            "film": dict(film), "sampler": dict(sampler)}


def configure_sensor(mi, params, sensor, cam: Camera, name: str, kind: str,
                     aperture_radius_m: float = 0.0, focus_distance_m: float | None = None) -> None:
    """Point a loaded sensor of ``kind`` at ``cam`` (and the lens) without recompiling: the
    plugin's opaque parameters, or Mitsuba's through ``params`` (``mi.traverse``; the caller
    calls ``params.update()``)."""
    if kind == PLUGIN:
        p = lens_sensor_params(cam)
        sensor.set_parameters(p["R_cw"], p["center"], p["fx"], p["fy"], p["cx"], p["cy"], p["skew"],
                              p["distortion"], aperture_radius_m, focus_distance_m or 1.0)
        return
    params[f"{name}.to_world"] = mi.Transform4f(perspective_to_world(cam).tolist())
    params[f"{name}.x_fov"] = perspective_fov_deg(cam, name)
    if kind == "thinlens":
        params[f"{name}.aperture_radius"] = aperture_radius_m
        params[f"{name}.focus_distance"] = focus_distance_m
