"""Named presets: camera (resolution + sensor model) and sensor noise levels.

The "1995" camera is a PULNiX TM-540-like CCD (512 x 480, 8-bit, noisy), the paper's; "modern"
a current machine-vision camera; "ideal" is noise-free. These presets set only the frame size (the
field of view kept) and the sensor model of ``bench.config.hardware_camera``'s parameter sets;
``apply_camera_hardware`` puts a whole camera (focal lengths, lens, aperture, line jitter) in. Noise presets set the shot noise
(electrons at full scale) and the read noise (DN) of the sensor model.
"""
from __future__ import annotations

from dataclasses import replace

from platebench.bench.config.hardware_camera import (
    BASLER_ACA2040_55UM,
    PULNIX_TM540_1995,
    CameraDefects,
    apply_camera_hardware,
    camera_hardware,
)
from platebench.bench.config.realism import CAMERA_SOURCES, Realism, RealismError, realism_preset
from platebench.bench.config.sample_config import ConfigError, SampleConfig
from platebench.scenes.lens import BrownConrady
from platebench.scenes.sensor_model import SensorModel

__all__ = ["CAMERA_PRESETS", "NOISE_PRESETS", "with_camera_preset", "noise_preset_of", "with_realism"]

NOISE_PRESETS = {
    "none": {"full_well_e": 0.0, "read_noise_dn": 0.0},
    "low": {"full_well_e": 20000.0, "read_noise_dn": 0.5},
    "medium": {"full_well_e": 5000.0, "read_noise_dn": 1.0},
    "high": {"full_well_e": 1000.0, "read_noise_dn": 2.0},
}



CAMERA_PRESETS = {  # frame size and sensor model of the cameras in bench.config.hardware_camera (their sources)
    "ideal": ({}, SensorModel()),
    "1995": ({"width": PULNIX_TM540_1995.width, "height": PULNIX_TM540_1995.height}, PULNIX_TM540_1995.sensor),
    "modern": ({"width": BASLER_ACA2040_55UM.width, "height": BASLER_ACA2040_55UM.height},
               BASLER_ACA2040_55UM.sensor),
}


def with_camera_preset(cfg: SampleConfig, name: str) -> SampleConfig:
    """``cfg`` with a camera preset's resolution (field of view kept) and sensor model."""
    if name not in CAMERA_PRESETS:
        raise ConfigError(f"--camera = {name!r} is not known: choose one of {', '.join(CAMERA_PRESETS)}")
    scene_over, sensor = CAMERA_PRESETS[name]
    return replace(cfg, scene=replace(cfg.scene, **scene_over), sensor=sensor)



def with_realism(cfg: SampleConfig, realism: "Realism | str") -> SampleConfig:
    """``cfg`` under a realism preset (a name or a ``Realism``), the realism recorded in it. Its camera:
    "ideal" keeps ``cfg``'s (noise-free); otherwise ``hardware_camera.apply_camera_hardware`` with the
    camera defects that are on, each at its scale (distortion coefficients, fy/fx - 1, aperture radius,
    line jitter and noise std multiplied by it; shot noise through the full well over the scale squared)."""
    try:
        rz = realism_preset(realism) if isinstance(realism, str) else realism
    except RealismError as e:
        raise ConfigError(str(e)) from None
    if rz.camera == "ideal":
        return replace(cfg, sensor=replace(cfg.sensor, full_well_e=0.0, read_noise_dn=0.0, line_jitter_px=0.0),
                       realism=rz)
    hw = camera_hardware(rz.camera)
    k = {s: rz.scale(s) for s in CAMERA_SOURCES}
    if k["distortion"] != 1.0:
        hw = replace(hw, distortion=BrownConrady.from_opencv(hw.distortion.as_opencv() * k["distortion"]))
    if k["pixel_aspect"] != 1.0:
        hw = replace(hw, fy_px=hw.fx_px * (1.0 + (hw.fy_px / hw.fx_px - 1.0) * k["pixel_aspect"]))
    if k["defocus"] != 1.0 and hw.f_number is not None:
        hw = replace(hw, f_number=hw.f_number / k["defocus"])  # aperture radius = focal length / (2 N)
    s = hw.sensor
    hw = replace(hw, line_jitter_px=hw.line_jitter_px * k["line_jitter"],
                 sensor=replace(s, read_noise_dn=s.read_noise_dn * k["noise"],
                                full_well_e=s.full_well_e / k["noise"] ** 2 if s.full_well_e > 0 and k["noise"] > 0
                                else s.full_well_e))
    out = apply_camera_hardware(cfg, hw, CameraDefects(**{d: rz.on(d) for d in CAMERA_SOURCES}))
    return replace(out, realism=rz)


def noise_preset_of(sensor: dict) -> str:
    """The name of the noise preset a sensor dict matches, or "custom"."""
    for name, preset in NOISE_PRESETS.items():
        if all(float(sensor.get(k, 0.0)) == v for k, v in preset.items()):
            return name
    return "custom"
