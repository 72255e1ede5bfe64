"""Codecs of the bench's own configuration records (`bench.config`) (see `bench.io.codecs`). The sensing
loop's records register theirs in ``bench.io.sensing_records``; a type of a higher layer registers its
form beside it (``bench.run.sensing.study.StudyResult``, ``bench.sweep.spec.SweepSpec``), as ``bench.io``
does not import ``bench.run`` or ``bench.sweep``.

The forms are the files' layouts: a sample's configuration as sample.json's ``config`` and a sample
TOML file hold it (``SampleConfig``: plate, scene, render, sensor, realism; metres, radians, pixels),
a sweep sample's rig pose (degrees), the realism table, and the studies' settings as study.json and
cut_study.json hold them. Readers raise the configuration's own errors (``ConfigError``,
``RealismError``), one line naming the key."""
from __future__ import annotations

from dataclasses import replace

from platebench.bench.config.realism import Realism, RealismError, realism_preset
from platebench.bench.config.sample_config import (
    _RENDER_KEYS,
    _SCENE_KEYS,
    _SENSOR_KEYS,
    _TOP_KEYS,
    ConfigError,
    PlateSize,
    RigPose,
    SampleConfig,
    SceneParams,
    _check_keys,
    check_types,
)
from platebench.bench.config.study import CutSquaresSettings, StudySettings
from platebench.bench.io.codecs.base import decode, decoder, encode
from platebench.plates import PlateSpec, reference_spec
from platebench.scenes.scene_spec import RenderSettings
from platebench.scenes.sensor_model import SensorModel


# ----------------------------------------------------------------------------- bench.config
@encode.register(SceneParams)
def _(x: SceneParams) -> dict:
    d = {k: getattr(x, k) for k in ("distance_m", "width", "height", "f_px", "baseline_m",
                                    "projector_kind", "ambient", "material", "pattern",
                                    "aperture_radius_m", "focus_distance_m")}
    # Recorded only when set, so that records of square-pixel, distortion-free scenes keep their layout.
    if x.fy_px is not None:
        d["fy_px"] = x.fy_px
    if x.distortion:
        d["distortion"] = dict(x.distortion)
    return d


@decoder(PlateSize)
def _(d) -> PlateSize:
    """A sample configuration's plate table: its ``length_m`` and ``width_m``."""
    return PlateSize(d["length_m"], d["width_m"])


@encode.register(RigPose)
def _(x: RigPose) -> dict:
    return {"tilt_deg": x.tilt_deg, "azimuth_deg": x.azimuth_deg}


@decoder(RigPose)
def _(d) -> RigPose:
    """A sweep sample's pose table (``{"tilt_deg", "azimuth_deg"}``, either absent: 0; None: the
    reference pose)."""
    d = d or {}
    return RigPose(float(d.get("tilt_deg", 0.0)), float(d.get("azimuth_deg", 0.0)))


@encode.register(Realism)
def _(x: Realism) -> dict:
    return {"preset": x.name, "camera": x.camera, "robot": x.robot, "rigid_head": x.rigid_head,
            "sources": list(x.sources), "scales": dict(x.scales), "seed": x.seed}


@decoder(Realism)
def _(d: dict) -> Realism:
    """A realism table (the encoder's keys; ``preset`` alone gives that preset, other keys change it);
    RealismError naming the key for a form it cannot read."""
    if not isinstance(d, dict):
        raise RealismError(f"realism = {d!r} is not a table")
    allowed = {"preset", "camera", "robot", "rigid_head", "sources", "scales", "seed"}
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise RealismError(f"unknown key realism.{unknown[0]}: allowed keys are {', '.join(sorted(allowed))}")
    base = realism_preset(d.get("preset", "ideal"))
    changes = {k: d[k] for k in ("camera", "robot", "rigid_head", "seed") if k in d}
    if "sources" in d:
        if not isinstance(d["sources"], (list, tuple)):
            raise RealismError(f"realism.sources = {d['sources']!r} is not a list of sources")
        changes["sources"] = tuple(d["sources"])
    if "scales" in d:
        if not isinstance(d["scales"], dict):
            raise RealismError(f"realism.scales = {d['scales']!r} is not a table of source = factor")
        changes["scales"] = {**base.scales, **d["scales"]}
    return replace(base, **changes)


@encode.register(SampleConfig)
def _(x: SampleConfig) -> dict:
    d = {"plate": encode(x.plate), "scene": encode(x.scene),
         "render": {"spp": x.render.spp, "seed": x.render.seed, "variant": x.variant},
         "sensor": encode(x.sensor)}
    if encode(x.realism) != encode(Realism()):  # the ideal bench's records hold no realism table
        d["realism"] = encode(x.realism)
    return d


@decoder(SampleConfig)
def _(d: dict) -> SampleConfig:
    """A configuration table (a sample TOML file, sample.json's ``config``; every table optional:
    the reference experiment's); ConfigError naming the key for a form it cannot read."""
    if not isinstance(d, dict):
        raise ConfigError(f"configuration = {d!r} is not a table")
    _check_keys("config", d, _TOP_KEYS)
    check_types(d)
    try:
        plate = decode(PlateSpec, d["plate"]) if "plate" in d else reference_spec()
        scene_d = dict(d.get("scene", {}))
        _check_keys("scene", scene_d, _SCENE_KEYS)
        scene = SceneParams(**scene_d)
        render_d = dict(d.get("render", {}))
        _check_keys("render", render_d, _RENDER_KEYS)
        variant = render_d.pop("variant", None)
        render = RenderSettings(**render_d)
        sensor_d = dict(d.get("sensor", {}))
        _check_keys("sensor", sensor_d, _SENSOR_KEYS)
        sensor = SensorModel(**sensor_d)
        realism = decode(Realism, d["realism"]) if "realism" in d else Realism()
    except RealismError as e:
        raise ConfigError(str(e)) from None
    except ConfigError:
        raise
    except (ValueError, TypeError) as e:
        raise ConfigError(str(e).splitlines()[0]) from None
    return SampleConfig(plate, scene, render, sensor, variant, realism)


@encode.register(StudySettings)
def _(x: StudySettings) -> dict:
    """study.json's settings (the false-boundary study's)."""
    return {"bends_deg": list(x.bends_deg), "axes_deg": list(x.axes_deg), "aspect": x.aspect,
            "families": list(x.families), "grid": x.grid or "paper's 4x4 (sense's default)",
            "verify_grid": x.verify_grid or "stage 3's", "width_px": x.width_px,
            "height_px": x.height_px, "spp": x.spp, "seed": x.seed,
            "perturb_axis_deg": x.perturb_axis_deg, "perturb_distance_mm": x.perturb_distance_mm,
            "plates": x.plates, "workers": x.workers}


@encode.register(CutSquaresSettings)
def _(x: CutSquaresSettings) -> dict:
    """cut_study.json's settings."""
    return {"bends_deg": list(x.bends_deg), "axes_deg": list(x.axes_deg),
            "distances_m": list(x.distances_m), "width_px": x.width_px, "spp": x.spp,
            "seed": x.seed, "grid": x.grid or "paper's 4x4"}
