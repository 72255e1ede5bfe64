"""Named presets: camera (resolution + sensor model) and sensor noise levels.

The "1995" camera is a PULNiX TM-540-like CCD (512 x 480, 8-bit, noisy), the paper's; "modern"
a current machine-vision camera; "ideal" is noise-free. Noise presets set the shot noise
(electrons at full scale) and the read noise (DN) of the sensor model.
"""
from __future__ import annotations

from dataclasses import replace

from platebench.bench.config.realism import Realism, RealismError, realism_preset
from platebench.bench.config.sample_config import ConfigError, SampleConfig
from platebench.scenes.sensor_model import SensorModel

__all__ = ["CAMERA_PRESETS", "NOISE_PRESETS", "with_camera_preset", "noise_preset_of", "with_realism",
           "realism_sensor"]

NOISE_PRESETS = {
    "none": {"full_well_e": 0.0, "read_noise_dn": 0.0},
    "low": {"full_well_e": 20000.0, "read_noise_dn": 0.5},
    "medium": {"full_well_e": 5000.0, "read_noise_dn": 1.0},
    "high": {"full_well_e": 1000.0, "read_noise_dn": 2.0},
}



CAMERA_PRESETS = {
    "ideal": ({}, SensorModel()),
    "1995": ({"width": 512, "height": 480},
             SensorModel(bit_depth=8, full_well_e=4000.0, read_noise_dn=1.5, gamma=1.0)),
    "modern": ({"width": 2048, "height": 1536},
               SensorModel(bit_depth=16, full_well_e=20000.0, read_noise_dn=3.0, gamma=1.0)),
}


def with_camera_preset(cfg: SampleConfig, name: str) -> SampleConfig:
    """``cfg`` with a camera preset's resolution (field of view kept) and sensor model."""
    if name not in CAMERA_PRESETS:
        raise ConfigError(f"--camera = {name!r} is not known: choose one of {', '.join(CAMERA_PRESETS)}")
    scene_over, sensor = CAMERA_PRESETS[name]
    return replace(cfg, scene=replace(cfg.scene, **scene_over), sensor=sensor)



def realism_sensor(realism: Realism) -> SensorModel:
    """The sensor of a realism's camera preset with its noise on (scaled by the ``sensor`` scale: read
    noise times the scale, shot noise as from a full well divided by its square), or noise-free at the same
    bit depth when the ``sensor`` source is off."""
    sensor = CAMERA_PRESETS[realism.camera][1]
    if not realism.on("sensor"):
        return replace(sensor, full_well_e=0.0, read_noise_dn=0.0)
    k = realism.scale("sensor")
    return replace(sensor, read_noise_dn=sensor.read_noise_dn * k,
                   full_well_e=sensor.full_well_e / (k * k) if sensor.full_well_e > 0 else 0.0)


def with_realism(cfg: SampleConfig, realism: "Realism | str") -> SampleConfig:
    """``cfg`` under a realism preset (a name or a ``Realism``): its camera preset's resolution (field
    of view kept) and its sensor (``realism_sensor``), and the realism recorded in the config."""
    try:
        rz = realism_preset(realism) if isinstance(realism, str) else realism
    except RealismError as e:
        raise ConfigError(str(e)) from None
    if rz.camera not in CAMERA_PRESETS:
        raise ConfigError(f"realism camera = {rz.camera!r} is not known: choose one of {', '.join(CAMERA_PRESETS)}")
    scene_over, _ = CAMERA_PRESETS[rz.camera]
    return replace(cfg, scene=replace(cfg.scene, **scene_over), sensor=realism_sensor(rz), realism=rz)


def noise_preset_of(sensor: dict) -> str:
    """The name of the noise preset a sensor dict matches, or "custom"."""
    for name, preset in NOISE_PRESETS.items():
        if all(float(sensor.get(k, 0.0)) == v for k, v in preset.items()):
            return name
    return "custom"
