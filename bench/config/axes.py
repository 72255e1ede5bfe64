"""Sample parameters as table columns and sweep axes, defined once.

``PARAMETERS`` lists every parameter column of the results table: its name (units in the
name), where it lives in a ``SampleConfig``'s form (``bench.io.codecs.bench_records``; or the
sweep pose), its unit and label for tables and plots, its type, and how its value is read back from a sample's
full configuration (what was rendered, not what the spec asked for). ``AXES`` lists the sweep
spec's axis names with the column that carries each (``bench.sweep.spec`` parses and applies
them; the report plots against the column).
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any, Callable

from platebench.bench.config.presets import noise_preset_of
from platebench.bench.config.realism import SOURCES
from platebench.bench.config.sample_config import ConfigError, SceneParams
from platebench.plates.spec import family_sweep_keys

__all__ = ["ParameterColumn", "PARAMETERS", "PARAMETER_NAMES", "AxisInfo", "AXES", "axis_column",
           "parameter_label", "parameter_columns"]


@dataclass(frozen=True)
class ParameterColumn:
    """A sample parameter in the results table."""

    name: str  # column name, unit in the name
    kind: str  # "float" | "int" | "str"
    unit: str  # "m", "deg", "px", "e-", "DN", "" ...
    label: str  # human label without unit
    read: Callable[[dict, dict], Any]  # (config dict, pose dict) -> value (None: not applicable)

    @property
    def title(self) -> str:
        return f"{self.label} ({self.unit})" if self.unit else self.label


def _deg(x):
    return None if x is None else round(math.degrees(float(x)), 9)


def _at(*path, convert=lambda v: v):
    def read(cfg: dict, pose: dict):
        node = cfg
        for key in path:
            if not isinstance(node, dict) or key not in node:
                return None
            node = node[key]
        return None if node is None else convert(node)
    return read


def _material(cfg: dict) -> dict:
    m = {"kind": "diffuse", "albedo": 0.8, "metal": "Al", "alpha": 0.2}  # scenes.scene_spec.Material defaults
    m.update(cfg.get("scene", {}).get("material") or {})
    return m


def _mat(key: str, kind: str | None = None):
    def read(cfg: dict, pose: dict):
        m = _material(cfg)
        return m.get(key) if kind is None or m.get("kind") == kind else None
    return read


def _focal(cfg: dict, pose: dict):
    """The focal length (px) of the configuration's scene table (``SceneParams.focal_px``)."""
    try:
        return SceneParams(**dict(cfg.get("scene") or {})).focal_px
    except (ConfigError, TypeError, ValueError):  # a scene that no longer parses: the focal length it states, if any
        return _at("scene", "f_px")(cfg, pose)


def _pose(key: str):
    """A rig pose angle (degrees) of the sweep pose table (absent, or no table: 0, the reference pose)."""
    def read(cfg: dict, pose: dict | None):
        return float((pose or {}).get(key, 0.0))
    return read


def _pattern(cfg: dict, pose: dict):
    p = cfg.get("scene", {}).get("pattern")
    return json.dumps(p, sort_keys=True) if p else "default"


PARAMETERS: tuple[ParameterColumn, ...] = (
    ParameterColumn("family", "str", "", "deformation family", _at("plate", "deformation", "family")),
    ParameterColumn("bend_deg", "float", "deg", "bend angle", _at("plate", "deformation", "angle_rad", convert=_deg)),
    ParameterColumn("direction", "str", "", "bend direction", _at("plate", "deformation", "direction")),
    ParameterColumn("axis_deg", "float", "deg", "bend axis", _at("plate", "deformation", "axis_rad", convert=_deg)),
    ParameterColumn("length_m", "float", "m", "plate length", _at("plate", "length_m")),
    ParameterColumn("width_m", "float", "m", "plate width", _at("plate", "width_m")),
    ParameterColumn("thickness_m", "float", "m", "plate thickness", _at("plate", "thickness_m")),
    ParameterColumn("material", "str", "", "material", _mat("kind")),
    ParameterColumn("albedo", "float", "", "diffuse albedo", _mat("albedo", "diffuse")),
    ParameterColumn("metal", "str", "", "metal", _mat("metal", "roughconductor")),
    ParameterColumn("roughness", "float", "", "roughness (GGX alpha)", _mat("alpha", "roughconductor")),
    ParameterColumn("distance_m", "float", "m", "sensing distance", _at("scene", "distance_m")),
    ParameterColumn("tilt_deg", "float", "deg", "rig tilt", _pose("tilt_deg")),
    ParameterColumn("azimuth_deg", "float", "deg", "rig tilt azimuth", _pose("azimuth_deg")),
    ParameterColumn("baseline_m", "float", "m", "stereo baseline", _at("scene", "baseline_m")),
    ParameterColumn("projector_kind", "str", "", "projector model", _at("scene", "projector_kind")),
    ParameterColumn("pattern", "str", "", "projected pattern", _pattern),
    ParameterColumn("width_px", "int", "px", "image width", _at("scene", "width")),
    ParameterColumn("height_px", "int", "px", "image height", _at("scene", "height")),
    ParameterColumn("f_px", "float", "px", "focal length", _focal),
    ParameterColumn("aperture_radius_m", "float", "m", "aperture radius", _at("scene", "aperture_radius_m")),
    ParameterColumn("spp", "int", "", "samples per pixel", _at("render", "spp")),
    ParameterColumn("seed", "int", "", "render seed", _at("render", "seed")),
    ParameterColumn("noise", "str", "", "sensor noise", lambda c, p: noise_preset_of(c.get("sensor", {}))),
    ParameterColumn("full_well_e", "float", "e-", "full well", _at("sensor", "full_well_e")),
    ParameterColumn("read_noise_dn", "float", "DN", "read noise", _at("sensor", "read_noise_dn")),
    ParameterColumn("bit_depth", "int", "bit", "bit depth", _at("sensor", "bit_depth")),
)
def _realism(key: str, default):
    def read(cfg: dict, pose: dict):
        return (cfg.get("realism") or {}).get(key, default)
    return read


def _source_scale(source: str):
    def read(cfg: dict, pose: dict):
        r = cfg.get("realism") or {}
        return float((r.get("scales") or {}).get(source, 1.0)) if source in (r.get("sources") or ()) else 0.0
    return read


PARAMETERS += (
    ParameterColumn("realism", "str", "", "realism preset", _realism("preset", "ideal")),
    ParameterColumn("realism_seed", "int", "", "realism draw", _realism("seed", 0)),
    *(ParameterColumn(f"realism_{s}", "float", "", f"{s} (x sourced, 0 off)", _source_scale(s)) for s in SOURCES),
)
PARAMETER_NAMES = tuple(p.name for p in PARAMETERS)
_BY_NAME = {p.name: p for p in PARAMETERS}


def parameter_columns(config: dict, pose: dict | None = None) -> dict:
    """Column name -> value of every parameter column, read from a full ``SampleConfig``'s form."""
    pose = pose or {}
    return {p.name: p.read(config, pose) for p in PARAMETERS}


def parameter_label(name: str) -> str:
    """'bend angle (deg)' for a parameter column; the name itself for anything else."""
    return _BY_NAME[name].title if name in _BY_NAME else name


@dataclass(frozen=True)
class AxisInfo:
    """A sweep spec axis: its name, the config path it sets and the results column that carries it."""

    name: str
    path: tuple[str, ...]  # into a SampleConfig's form; ("pose", key) for the pose axes; () for special axes
    columns: tuple[str, ...]  # results columns carrying its value (first one is plotted)
    help: str

    @property
    def column(self) -> str | None:
        return self.columns[0] if self.columns else None


def _axis(name, path, columns, help_):
    return AxisInfo(name, tuple(path), tuple(columns), help_)


AXES: dict[str, AxisInfo] = {a.name: a for a in (
    # the realism first: an axis of resolution or noise then changes what the preset's camera set
    _axis("realism", (), ("realism",), "realism preset: ideal, 1995, modern (camera, robot, estimates)"),
    _axis("realism_seed", ("realism", "seed"), ("realism_seed",), "the draw of the realism's error sources"),
    *(_axis(f"realism_{s}", (), (f"realism_{s}",), f"{SOURCES[s]}: magnitude x sourced (0 off)") for s in SOURCES),
    _axis("length_m", ("plate", "length_m"), ("length_m",), "plate length, m"),
    _axis("width_m", ("plate", "width_m"), ("width_m",), "plate width, m"),
    _axis("thickness_m", ("plate", "thickness_m"), ("thickness_m",), "plate thickness, m"),
    _axis("family", ("plate", "deformation", "family"), ("family",), "deformation family"),
    _axis("bend_deg", ("plate", "deformation", "angle_rad"), ("bend_deg",), "bend angle, deg"),
    _axis("direction", ("plate", "deformation", "direction"), ("direction",), "bend direction"),
    _axis("axis_deg", ("plate", "deformation", "axis_rad"), ("axis_deg",), "bend-axis direction, deg"),
    # each family's own axes, in its order (plates.spec: DeformationFamily.sweep_keys)
    *(_axis(k.name, ("plate", "deformation", k.field), (), f"{k.help} ({family})") for family, k in family_sweep_keys()),
    _axis("material", ("scene", "material"), ("material",), "material kind or table"),
    _axis("albedo", ("scene", "material", "albedo"), ("albedo",), "diffuse albedo"),
    _axis("metal", ("scene", "material", "metal"), ("metal",), "conductor preset"),
    _axis("roughness", ("scene", "material", "alpha"), ("roughness",), "GGX alpha"),
    _axis("distance_m", ("scene", "distance_m"), ("distance_m",), "sensing distance, m"),
    _axis("tilt_deg", ("pose", "tilt_deg"), ("tilt_deg",), "pose: tilt from vertical, deg"),
    _axis("azimuth_deg", ("pose", "azimuth_deg"), ("azimuth_deg",), "pose: tilt direction from +X, deg"),
    _axis("baseline_m", ("scene", "baseline_m"), ("baseline_m",), "stereo baseline, m"),
    _axis("projector_kind", ("scene", "projector_kind"), ("projector_kind",), "projector model"),
    _axis("ambient", ("scene", "ambient"), (), "ambient fraction in active images"),
    _axis("pattern", ("scene", "pattern"), ("pattern",), "square grid table"),
    _axis("resolution", ("scene",), ("width_px", "height_px"), "\"WxH\" or [W, H]"),
    _axis("width_px", ("scene", "width"), ("width_px",), "camera width, px"),
    _axis("height_px", ("scene", "height"), ("height_px",), "camera height, px"),
    _axis("f_px", ("scene", "f_px"), ("f_px",), "focal length, px"),
    _axis("aperture_radius_m", ("scene", "aperture_radius_m"), ("aperture_radius_m",), "thin-lens aperture radius, m"),
    _axis("focus_distance_m", ("scene", "focus_distance_m"), (), "thin-lens focus distance, m"),
    _axis("spp", ("render", "spp"), ("spp",), "samples per pixel"),
    _axis("seed", ("render", "seed"), ("seed",), "render seed"),
    _axis("noise", ("sensor",), ("noise",), "noise preset or sensor table"),
    _axis("full_well_e", ("sensor", "full_well_e"), ("full_well_e",), "shot noise, e- at full scale"),
    _axis("read_noise_dn", ("sensor", "read_noise_dn"), ("read_noise_dn",), "read noise, DN"),
    _axis("bit_depth", ("sensor", "bit_depth"), ("bit_depth",), "8 or 16"),
    _axis("gamma", ("sensor", "gamma"), (), "response exponent"),
)}
_PATH_AXES = {a.path: a for a in AXES.values() if a.path}


def axis_column(spec_axis: str) -> str | None:
    """The results column carrying a spec axis (also for dotted configuration paths such as
    "scene.material.alpha" or "plate.deformation.angle_rad"); None if no column carries it."""
    if spec_axis in AXES:
        return AXES[spec_axis].column
    a = _PATH_AXES.get(tuple(spec_axis.split(".")))
    return a.column if a else None
