"""Sweep specifications: a TOML file that expands into many validated samples.

``platebench sweep SPEC.toml --out DATASET`` reads a spec, builds every sample's
``SampleConfig`` up front (so a bad value is refused before anything is rendered or
written), then renders, reconstructs and scores each sample (see ``bench.sweep.executors``).

The spec format (the ``[sweep]``, ``[base]``, ``[grid]`` and ``[random]`` tables, axis values,
every axis with its unit, dotted-path axes, poses, validation) is described in docs/reference.md,
"Sweep spec format". Output: see ``bench/sweep/dataset.py`` (manifest.json, results.csv/.parquet,
samples/<id>/).
"""
from __future__ import annotations

import copy
import dataclasses
import hashlib
import itertools
import json
import math
import numbers
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from platebench.bench.config import NOISE_PRESETS, ConfigError, SampleConfig, read_toml_text
from platebench.bench.config.sample_config import PlateSize
from platebench.bench.config.axes import AXES as AXIS_INFO
from platebench.bench.config.presets import with_realism
from platebench.bench.config.realism import CAMERA_SOURCES, MAX_SCALE, REALISM_PRESETS, Realism, RealismError, realism_preset
from platebench.bench.config.realism import SOURCES as _SOURCES
from platebench.bench.config.ranges import RangeError, expand_range
from platebench.bench.io.codecs import base as codec_base
from platebench.bench.io.codecs import decode, encode
from platebench.bench.run.methods import get_method, method_names
from platebench.bench.run.plugins import check_time_limit
from platebench.errors import UserValueError
from platebench.plates.spec import FAMILIES, family_sweep_keys

__all__ = ["SpecError", "SweepSpec", "SamplePlan", "load_spec", "parse_spec", "AXES",
           "family_defaults", "MAX_SAMPLES"]

MAX_SAMPLES = 100_000
_TOP_KEYS = ("sweep", "base", "grid", "random")
_SWEEP_KEYS = ("name", "description", "mode", "methods", "seed", "count", "seed_per_sample", "method_time_limit_s")
_GRID_FORMS = ("start", "stop", "step", "num", "values")
_RANDOM_FORMS = ("min", "max", "int", "values")


def _deformation_fields(family) -> tuple[str, ...]:
    """The fields ``family`` takes, read from its registered dataclass (plates.spec.FAMILIES, one source,
    asked when a spec is read: a family registered later counts); () for an unknown family."""
    cls = FAMILIES.get(family)
    return tuple(f.name for f in dataclasses.fields(cls)) if cls is not None else ()


class SpecError(ConfigError):
    """A sweep spec is invalid; the one-line message names the key, the value and the allowed range."""


def family_defaults(family: str, length_m: float, width_m: float) -> dict:
    """Deformation dict of ``family`` with its default parameters for an L x W plate (metres,
    radians; the family's own ``DeformationFamily.defaults``)."""
    if family not in FAMILIES:
        raise SpecError(f"family = {family!r} is unknown: allowed {', '.join(FAMILIES)}")
    return encode(FAMILIES[family].defaults(length_m, width_m))


# ----------------------------------------------------------------------------- axes
class _NotApplicable(Exception):
    """The axis does not apply to this sample (e.g. bend_deg on a flat plate)."""


def _num(key: str, v, integer: bool = False):
    if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(float(v)):
        raise SpecError(f"{key} = {v!r} is not a finite number")
    if integer:
        if float(v) != int(v):
            raise SpecError(f"{key} = {v!r} is not an integer")
        return int(v)
    return float(v)


def _str(key: str, v, choices=None) -> str:
    if not isinstance(v, str):
        raise SpecError(f"{key} = {v!r} is not a string" + (f": allowed {', '.join(choices)}" if choices else ""))
    if choices and v not in choices:
        raise SpecError(f"{key} = {v!r} is not allowed: allowed {', '.join(choices)}")
    return v


def _table(key: str, v) -> dict:
    if not isinstance(v, dict):
        raise SpecError(f"{key} = {v!r} is not a table")
    return dict(v)


def _realism_names() -> tuple:
    return tuple(REALISM_PRESETS)


def _scale(key: str, v) -> float:
    x = _num(key, v)
    if not 0 <= x <= MAX_SCALE:
        raise SpecError(f"{key} = {v!r} is out of range: allowed 0 (off) to {MAX_SCALE:g} (x the sourced magnitude)")
    return x


def _deformation(d: dict) -> dict:
    return d["plate"]["deformation"]


def _set_deformation_field(name: str, convert=lambda x: x):
    def apply(d: dict, v, state: dict) -> None:
        dfm = _deformation(d)
        if name not in _deformation_fields(dfm.get("family")):
            raise _NotApplicable
        dfm[name] = convert(v)
    return apply


def _set_path(*path):
    def apply(d: dict, v, state: dict) -> None:
        node = d
        for p in path[:-1]:
            node = node.setdefault(p, {})
        node[path[-1]] = v
    return apply


def _apply_family(d: dict, v, state: dict) -> None:
    plate = d["plate"]
    size = decode(PlateSize, plate)
    new = family_defaults(v, size.length_m, size.width_m)
    old = _deformation(d)
    for k in ("angle_rad", "direction", "axis_rad"):
        if k in new and k in old:
            new[k] = old[k]
    plate["deformation"] = new


def _apply_material(d: dict, v, state: dict) -> None:
    if isinstance(v, str):
        d["scene"].setdefault("material", {})["kind"] = v
    else:
        d["scene"]["material"] = dict(v)


def _apply_resolution(d: dict, v, state: dict) -> None:
    d["scene"]["width"], d["scene"]["height"] = v


def _apply_noise(d: dict, v, state: dict) -> None:
    d["sensor"].update(NOISE_PRESETS[v] if isinstance(v, str) else v)


def _apply_pose(name: str):
    def apply(d: dict, v, state: dict) -> None:
        state.setdefault("pose", {})[name] = v
    return apply


def _apply_realism(d: dict, v, state: dict) -> None:
    """A realism preset: its camera (resolution, sensor) and its table; the draw (seed) is kept."""
    cfg = decode(SampleConfig, copy.deepcopy(d))
    new = encode(with_realism(cfg, realism_preset(v).with_seed(cfg.realism.seed)))
    d.clear()
    d.update(new)


def _apply_source(source: str):
    """A realism source's magnitude (x its sourced value; 0 turns it off). Robot and hand/eye sources do not
    apply to a preset without a robot, camera sources not to one without camera hardware (the axis is
    ignored for that sample)."""
    def apply(d: dict, v, state: dict) -> None:
        try:
            r = decode(Realism, copy.deepcopy(d.get("realism") or {}))
            if (r.robot is None and source in ("robot_repeatability", "robot_accuracy", "hand_eye")) or \
                    (r.camera == "ideal" and source in CAMERA_SOURCES):
                raise _NotApplicable  # the ideal preset has no robot and no camera hardware
            scales = {k: x for k, x in r.scales.items() if k != source}
            if v > 0:
                scales[source] = float(v)
            r = dataclasses.replace(r, sources=tuple(s for s in r.sources if s != source) + ((source,) if v > 0 else ()),
                        scales=scales)
        except RealismError as e:
            raise ConfigError(str(e)) from None
        new = encode(with_realism(decode(SampleConfig, copy.deepcopy(d)), r))  # the camera follows its sources
        d.clear()
        d.update(new)
    return apply


def _parse_resolution(key: str, v):
    if isinstance(v, str):
        parts = v.lower().split("x")
        if len(parts) == 2 and all(p.strip().isdigit() for p in parts):
            return int(parts[0]), int(parts[1])
    elif isinstance(v, list) and len(v) == 2:
        return _num(key, v[0], True), _num(key, v[1], True)
    raise SpecError(f"{key} = {v!r} is not a resolution: allowed \"WxH\" or [W, H] in pixels")


def _parse_noise(key: str, v):
    if isinstance(v, str):
        return _str(key, v, tuple(NOISE_PRESETS))
    t = _table(key, v)
    from platebench.bench.config import _SENSOR_KEYS  # noqa: PLC0415
    bad = sorted(set(t) - _SENSOR_KEYS)
    if bad:
        raise SpecError(f"{key} has unknown key {bad[0]!r}: allowed {', '.join(sorted(_SENSOR_KEYS))} "
                        f"or a preset {', '.join(NOISE_PRESETS)}")
    return t


def _parse_material(key: str, v):
    if isinstance(v, str):
        return _str(key, v, ("diffuse", "roughconductor"))
    return _table(key, v)


@dataclass(frozen=True)
class Axis:
    """A named sweep axis: how to read a value (``parse``) and where it goes (``apply``)."""

    name: str
    parse: Callable[[str, Any], Any]
    apply: Callable[[dict, Any, dict], None]
    table_valued: bool = False

    @property
    def help(self) -> str:
        return AXIS_INFO[self.name].help if self.name in AXIS_INFO else "configuration path"


_CHOICES = {"direction": ("up", "down"), "metal": ("Al", "Fe"), "projector_kind": ("pinhole", "spot")}
_INTEGER_AXES = {"width_px", "height_px", "spp", "seed", "bit_depth", "realism_seed"}
# spec values in degrees, the configuration in radians (the shared bend axes, and any family's own in degrees)
_DEGREE_AXES = {"bend_deg", "axis_deg"} | {k.name for _, k in family_sweep_keys() if k.degrees}
_SPECIAL_AXES = {  # axes whose value is a table or sets several keys
    "family": Axis("family", lambda k, v: _str(k, v, tuple(FAMILIES)), _apply_family),
    "material": Axis("material", _parse_material, _apply_material, table_valued=True),
    "pattern": Axis("pattern", _table, _set_path("scene", "pattern"), table_valued=True),
    "resolution": Axis("resolution", _parse_resolution, _apply_resolution, table_valued=True),
    "noise": Axis("noise", _parse_noise, _apply_noise, table_valued=True),
    "realism": Axis("realism", lambda k, v: _str(k, v, _realism_names()), _apply_realism),
    **{f"realism_{s}": Axis(f"realism_{s}", lambda k, v: _scale(k, v), _apply_source(s)) for s in _SOURCES},
}


def _registry_axis(name: str) -> Axis:
    """The parser and applier of a plain axis, from its path in ``bench.config.axes.AXES``."""
    if name in _SPECIAL_AXES:
        return _SPECIAL_AXES[name]
    path = AXIS_INFO[name].path
    if name in _CHOICES:
        parse = lambda k, v, c=_CHOICES[name]: _str(k, v, c)  # noqa: E731
    else:
        parse = lambda k, v, i=name in _INTEGER_AXES: _num(k, v, i)  # noqa: E731
    if path[0] == "pose":
        apply = _apply_pose(path[1])
    elif path[:2] == ("plate", "deformation"):
        apply = _set_deformation_field(path[2], math.radians if name in _DEGREE_AXES else (lambda x: x))
    else:
        apply = _set_path(*path)
    return Axis(name, parse, apply)


_AXIS_LIST = tuple(_registry_axis(name) for name in AXIS_INFO)
AXES: dict[str, Axis] = {a.name: a for a in _AXIS_LIST}
_AXIS_ORDER = {a.name: i for i, a in enumerate(_AXIS_LIST)}
_DOTTED_ROOTS = ("plate", "scene", "render", "sensor", "realism")
POSE_LIMITS = {"tilt_deg": (0.0, 75.0), "azimuth_deg": (-360.0, 360.0)}


def _dotted_axis(name: str) -> Axis:
    parts = name.split(".")
    if parts[0] not in _DOTTED_ROOTS or len(parts) < 2 or not all(parts):
        raise SpecError(f"unknown axis {name!r}: allowed {', '.join(AXES)}, or a dotted configuration path "
                        f"starting with {', '.join(_DOTTED_ROOTS)} (e.g. \"scene.distance_m\")")
    return Axis(name, lambda k, v: v, _set_path(*parts), table_valued=True)


def _axis(name: str) -> Axis:
    return AXES.get(name) or _dotted_axis(name)


# ----------------------------------------------------------------------------- values of an axis
def _is_range(spec, axis: Axis, forms, needs) -> bool:
    """Is a table written for an axis a range/choice form (rather than a table-valued value)?"""
    if not isinstance(spec, dict):
        return False
    if not axis.table_valued:
        return True
    return set(spec) <= set(forms) and ("values" in spec or needs <= set(spec))


def _grid_values(key: str, axis: Axis, spec) -> list:
    if _is_range(spec, axis, _GRID_FORMS, {"start", "stop"}):
        bad = sorted(set(spec) - set(_GRID_FORMS))
        if bad:
            raise SpecError(f"{key} has unknown key {bad[0]!r}: allowed a list, {{start, stop, step}}, "
                            "{start, stop, num} or {values = [...]}")
        if "values" in spec:
            if len(spec) != 1:
                raise SpecError(f"{key}: 'values' cannot be combined with {', '.join(sorted(set(spec) - {'values'}))}")
            vals = spec["values"]
            return _grid_values(key, axis, vals if isinstance(vals, list) else [vals])
        if "start" not in spec or "stop" not in spec or ("step" in spec) == ("num" in spec):
            raise SpecError(f"{key} = {spec!r}: a range needs start, stop and exactly one of step or num")
        ints = "step" in spec and all(isinstance(spec[k], int) and not isinstance(spec[k], bool)
                                      for k in ("start", "stop", "step"))
        try:  # counted before it is expanded: {start = 0, stop = 1e12, step = 1e-3} is refused, not made
            raw = expand_range(key, spec["start"], spec["stop"], spec.get("step"), spec.get("num"),
                               max_count=MAX_SAMPLES, integers=ints)
        except RangeError as e:
            raise SpecError(str(e)) from None
        return [axis.parse(key, x) for x in raw]
    if isinstance(spec, list) and not (axis.name == "resolution" and _is_pair(spec)):
        values = spec
    else:
        values = [spec]
    if not values:
        raise SpecError(f"{key} is empty: give at least one value")
    return [axis.parse(f"{key}[{i}]" if len(values) > 1 else key, v) for i, v in enumerate(values)]


def _is_pair(v) -> bool:
    return isinstance(v, list) and len(v) == 2 and all(isinstance(x, int) and not isinstance(x, bool) for x in v)


@dataclass(frozen=True)
class _RandomAxis:
    key: str
    axis: Axis
    choices: tuple | None = None
    lo: float | None = None
    hi: float | None = None
    integer: bool = False

    def draw(self, rng: np.random.Generator):
        if self.choices is not None:
            return copy.deepcopy(self.choices[int(rng.integers(len(self.choices)))])
        if self.integer:
            return self.axis.parse(self.key, int(rng.integers(int(self.lo), int(self.hi) + 1)))
        return self.axis.parse(self.key, float(rng.uniform(self.lo, self.hi)))


def _random_axis(key: str, axis: Axis, spec) -> _RandomAxis:
    if _is_range(spec, axis, _RANDOM_FORMS, {"min", "max"}):
        bad = sorted(set(spec) - set(_RANDOM_FORMS))
        if bad:
            raise SpecError(f"{key} has unknown key {bad[0]!r}: allowed a list, {{min, max}}, "
                            "{min, max, int = true} or {values = [...]}")
        if "values" in spec:
            if len(spec) != 1:
                raise SpecError(f"{key}: 'values' cannot be combined with {', '.join(sorted(set(spec) - {'values'}))}")
            vals = spec["values"]
            return _RandomAxis(key, axis, tuple(_grid_values(key, axis, vals if isinstance(vals, list) else [vals])))
        if "min" not in spec or "max" not in spec:
            raise SpecError(f"{key} = {spec!r}: a random range needs min and max")
        integer = spec.get("int", False)
        if not isinstance(integer, bool):
            raise SpecError(f"{key}.int = {integer!r} is not allowed: allowed true or false")
        lo, hi = _num(f"{key}.min", spec["min"], integer), _num(f"{key}.max", spec["max"], integer)
        if hi < lo:
            raise SpecError(f"{key}: max = {spec['max']!r} is below min = {spec['min']!r}: allowed max >= min")
        axis.parse(f"{key}.min", lo)
        return _RandomAxis(key, axis, None, lo, hi, integer)
    return _RandomAxis(key, axis, tuple(_grid_values(key, axis, spec)))


# ----------------------------------------------------------------------------- the spec
@dataclass(frozen=True)
class SamplePlan:
    """One expanded sample: id, axis values as written, its validated configuration and pose."""

    index: int
    sample_id: str
    params: dict  # axis name -> value (as in the spec; human units where the name says so)
    config: SampleConfig
    pose: dict | None  # {"tilt_deg", "azimuth_deg"} or None (the reference pose)
    config_sha256: str

    @property
    def config_dict(self) -> dict:
        return encode(self.config)


@dataclass(frozen=True)
class SweepSpec:
    """A parsed, validated sweep spec and its expansion (``samples``)."""

    name: str
    mode: str
    methods: tuple
    seed: int
    count: int | None
    seed_per_sample: bool
    base: dict  # canonical SampleConfig dict
    axes: tuple  # ((key, definition as written), ...)
    samples: tuple  # SamplePlan, ...
    doc: dict  # the parsed TOML
    text: str = ""
    description: str = ""
    ignored: dict = field(default_factory=dict)  # axis -> number of samples it did not apply to
    duplicates: int = 0
    method_time_limit_s: float | None = None  # sweep.method_time_limit_s (None: plugins.METHOD_TIME_LIMIT_S)

    @property
    def sha256(self) -> str:
        """Identity of the expansion: the sample ids, configurations, poses and methods."""
        h = hashlib.sha256()
        h.update(json.dumps(list(self.methods)).encode())
        for s in self.samples:
            h.update(f"{s.sample_id}:{s.config_sha256}\n".encode())
        return h.hexdigest()


@codec_base.encode.register(SweepSpec)
def _(x: SweepSpec) -> dict:
    """The spec as the dataset manifest (dataset.json's ``spec``) holds it; registered beside the type, as
    ``bench.io`` does not import ``bench.sweep``."""
    return {"name": x.name, "description": x.description, "mode": x.mode,
            "methods": list(x.methods), "seed": x.seed, "count": x.count,
            "seed_per_sample": x.seed_per_sample, "method_time_limit_s": x.method_time_limit_s,
            "base": x.base,
            "axes": {k: v for k, v in x.axes}, "n_samples": len(x.samples),
            "ignored_axes": x.ignored, "duplicates_dropped": x.duplicates, "sha256": x.sha256}


def config_sha256(config_dict: dict, pose: dict | None, methods) -> str:
    doc = {"config": config_dict, "pose": pose, "methods": list(methods)}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def _check_pose(where: str, pose: dict) -> None:
    for k, (lo, hi) in POSE_LIMITS.items():
        if k in pose and not lo <= pose[k] <= hi:
            raise SpecError(f"{where}{k} = {pose[k]!r} is out of range: allowed {lo:g} to {hi:g} deg")
    if pose:
        from platebench.bench.sweep.tasks import pose_supported  # noqa: PLC0415
        why = pose_supported()
        if why:
            raise SpecError(f"{where}{next(iter(pose))}: pose axes are not available in this build ({why})")


def _validate(d: dict, state: dict, cache: dict | None = None) -> SampleConfig:
    cfg = decode(SampleConfig, copy.deepcopy(d))
    pose = state.get("pose")
    key = json.dumps([d["scene"], pose], sort_keys=True, default=str)
    if cache is not None and key in cache:
        return cfg
    try:
        scene = cfg.scene.build()
    except ValueError as e:
        raise ConfigError(str(e).splitlines()[0]) from None
    if pose:
        from platebench.bench.sweep.tasks import posed_scene  # noqa: PLC0415
        try:
            posed_scene(scene, cfg.scene.distance_m, pose)
        except ValueError as e:
            raise ConfigError(f"pose {pose}: {str(e).splitlines()[0]}") from None
    if cache is not None:
        cache[key] = True
    return cfg


def _apply_all(base: dict, items: list, until: int | None = None):
    d = copy.deepcopy(base)
    state: dict = {}
    ignored = []
    order = sorted(range(len(items)), key=lambda i: (_AXIS_ORDER.get(items[i][1].name, len(_AXIS_ORDER)), i))
    for i in order[:until]:
        key, axis, value = items[i]
        try:
            axis.apply(d, copy.deepcopy(value), state)
        except _NotApplicable:
            ignored.append(key)
    return d, state, ignored, [items[i] for i in order]


def _build_sample(base: dict, items: list, section: str, label: str, cache: dict) -> tuple:
    """Apply ``items`` [(key, Axis, value)] to ``base`` and validate. On failure, validate after
    each axis in turn so that the bad value is blamed on the axis that brought it."""
    d, state, ignored, ordered = _apply_all(base, items)
    try:
        if "pose" in state:
            _check_pose(f"{section}.", state["pose"])
        return _validate(d, state, cache), d, state, ignored
    except ConfigError:
        pass
    for n in range(1, len(ordered) + 1):
        key, axis, value = ordered[n - 1]
        d, state, _, _ = _apply_all(base, ordered, n)
        try:
            if "pose" in state:
                _check_pose(f"{section}.", state["pose"])
            _validate(d, state)
        except SpecError as e:
            raise SpecError(f"{e} (sample {label})") from None
        except ConfigError as e:
            shown = json.dumps(value) if not isinstance(value, str) else repr(value)
            raise SpecError(f"{section}.{key} = {shown} (sample {label}): {e}") from None
    _validate(d, state)  # raises
    raise AssertionError("unreachable")


def _check_table_keys(where: str, d: dict, allowed) -> None:
    bad = sorted(set(d) - set(allowed))
    if bad:
        raise SpecError(f"unknown key {where}{bad[0]}: allowed keys are {', '.join(allowed)}")


def _sweep_table(doc: dict) -> tuple[dict, str, str, str]:
    """Check the spec's tables; (the [sweep] table, name, description, mode 'grid' or 'random')."""
    if not isinstance(doc, dict):
        raise SpecError("a sweep spec must be a TOML table")
    _check_table_keys("", doc, _TOP_KEYS)
    sweep = doc.get("sweep", {})
    if not isinstance(sweep, dict):
        raise SpecError("sweep must be a table")
    _check_table_keys("sweep.", sweep, _SWEEP_KEYS)
    for t in ("base", "grid", "random"):
        if t in doc and not isinstance(doc[t], dict):
            raise SpecError(f"{t} must be a table")
    name = sweep.get("name", "sweep")
    if not isinstance(name, str):
        raise SpecError(f"sweep.name = {name!r} is not a string")
    description = sweep.get("description", "")
    mode = sweep.get("mode")
    if mode is None:
        if "grid" in doc and "random" in doc:
            raise SpecError("both [grid] and [random] are given: keep one, or set sweep.mode")
        mode = "random" if "random" in doc else "grid"
    _str("sweep.mode", mode, ("grid", "random"))
    other = "random" if mode == "grid" else "grid"
    if other in doc:
        raise SpecError(f"[{other}] is given but sweep.mode = {mode!r}: remove it")
    return sweep, name, description if isinstance(description, str) else str(description), mode


def _methods(sweep: dict, methods) -> tuple[tuple[str, ...], str]:
    """(the methods, each known or loadable, without repeats; where they came from) from --methods
    (``methods`` not None) or sweep.methods."""
    if methods is None:
        methods, where = sweep.get("methods", ["paper"]), "sweep.methods"
    else:
        where = "--methods"
    if isinstance(methods, str):
        methods = [methods]
    if not isinstance(methods, (list, tuple)) or not methods:
        raise SpecError(f"{where} = {methods!r}: give a non-empty list from {', '.join(method_names())}")
    for m in methods:
        try:
            get_method(m)
        except UserValueError as e:
            raise SpecError(f"{where}: {e}") from None
    return tuple(dict.fromkeys(methods)), where


def _seeding(sweep: dict, mode: str) -> tuple[int, bool, int | None]:
    """(sweep.seed, sweep.seed_per_sample, sweep.count: random mode only), checked."""
    seed = _num("sweep.seed", sweep.get("seed", 0), True)
    if not 0 <= seed < 2**63:
        raise SpecError(f"sweep.seed = {seed} is out of range: allowed 0 to 2^63-1")
    seed_per_sample = sweep.get("seed_per_sample", False)
    if not isinstance(seed_per_sample, bool):
        raise SpecError(f"sweep.seed_per_sample = {seed_per_sample!r} is not allowed: allowed true or false")
    count = sweep.get("count")
    if mode == "random":
        if count is None:
            raise SpecError("sweep.count is missing: random mode needs the number of samples")
        count = _num("sweep.count", count, True)
        if not 1 <= count <= MAX_SAMPLES:
            raise SpecError(f"sweep.count = {count} is out of range: allowed 1 to {MAX_SAMPLES}")
    elif count is not None:
        raise SpecError("sweep.count applies to random mode only: a grid's size is the product of its axes")
    return seed, seed_per_sample, count


def _base(doc: dict) -> dict:
    """The [base] table as a full, valid sample config dict."""
    try:
        base_cfg = decode(SampleConfig, copy.deepcopy(doc.get("base", {})))
        base_cfg.scene.build()
    except ValueError as e:
        msg = str(e).splitlines()[0]
        raise SpecError(f"base: {msg}" if not msg.startswith("unknown key config.") else
                        "unknown key base." + msg[len("unknown key config."):]) from None
    return encode(base_cfg)


def _plans(mode: str, axes_doc: dict, seed: int, count: int | None) -> tuple[list, list[tuple[dict, list]]]:
    """(the axes [(key, Axis)], one (params, [(key, Axis, value)]) per planned sample): the grid's
    product, or ``count`` draws of the random axes (draw i from the generator seeded [seed, i])."""
    if not axes_doc:
        raise SpecError(f"[{mode}] is empty: give at least one axis, e.g. bend_deg = [0, 20, 40]"
                        if mode == "grid" else "[random] is empty: give at least one axis to draw")
    axes = [(k, _axis(k)) for k in axes_doc]
    plans: list[tuple[dict, list]] = []
    if mode == "grid":
        value_lists = [_grid_values(f"{mode}.{k}", a, axes_doc[k]) for k, a in axes]
        total = math.prod(len(v) for v in value_lists)
        if total > MAX_SAMPLES:
            raise SpecError(f"[grid] expands to {total} samples: allowed at most {MAX_SAMPLES}")
        for combo in itertools.product(*value_lists):
            items = [(k, a, v) for (k, a), v in zip(axes, combo)]
            plans.append(({k: v for (k, _), v in zip(axes, combo)}, items))
        return axes, plans
    draws = [(k, a, _random_axis(f"{mode}.{k}", a, axes_doc[k])) for k, a in sorted(axes, key=lambda x: x[0])]
    order = {k: j for j, (k, _) in enumerate(axes)}
    for i in range(count):
        rng = np.random.default_rng([seed, i])
        items = sorted(((k, a, r.draw(rng)) for k, a, r in draws), key=lambda it: order[it[0]])
        plans.append(({k: v for k, _, v in items}, items))
    return axes, plans


def _samples(base: dict, plans, mode: str, methods: tuple, seed_per_sample: bool):
    """(samples [(params, SampleConfig, pose, digest)], keys ignored {key: count}, duplicates dropped)."""
    width = max(4, len(str(len(plans) - 1)))
    samples, seen, ignored, cache = [], set(), {}, {}
    duplicates = 0
    base_seed = base["render"]["seed"]
    for i, (params, items) in enumerate(plans):
        if seed_per_sample and "seed" not in params:
            items = items + [("seed", AXES["seed"], (base_seed + i) % 2**31)]
        cfg, _, state, ign = _build_sample(base, items, mode, f"{i:0{width}d}", cache)
        for k in ign:
            ignored[k] = ignored.get(k, 0) + 1
        pose = state.get("pose")
        digest = config_sha256(encode(cfg), pose, methods)
        if digest in seen:
            duplicates += 1
            continue
        seen.add(digest)
        samples.append((params, cfg, pose, digest))
    return samples, ignored, duplicates


def parse_spec(doc: dict, text: str = "", methods: tuple | None = None) -> SweepSpec:
    """Validate a parsed spec and expand it into samples (raises SpecError, nothing is written)."""
    sweep, name, description, mode = _sweep_table(doc)
    methods, where = _methods(sweep, methods)
    seed, seed_per_sample, count = _seeding(sweep, mode)
    base = _base(doc)
    axes_doc = doc.get(mode, {})
    axes, plans = _plans(mode, axes_doc, seed, count)
    samples, ignored, duplicates = _samples(base, plans, mode, methods, seed_per_sample)
    posed = [p for _, _, p, _ in samples if p and any(float(v) != 0.0 for k, v in p.items() if k == "tilt_deg")]
    rerender = [m for m in methods if get_method(m).rerenders_from_config]
    if posed and rerender:
        raise SpecError(f"{where}: {', '.join(rerender)} cannot run on samples with a pose axis (tilt_deg): "
                        "they re-create the scene from sample.json, which holds no pose; drop one or the other")
    width = max(4, len(str(len(samples) - 1)))
    plans_out = tuple(SamplePlan(j, f"{j:0{width}d}", p, c, pose, dg) for j, (p, c, pose, dg) in enumerate(samples))
    return SweepSpec(name, mode, methods, seed, count, seed_per_sample, base, tuple((k, axes_doc[k]) for k, _ in axes),
                     plans_out, doc, text, description, ignored, duplicates, _time_limit(sweep))


def _time_limit(sweep: dict) -> float | None:
    """sweep.method_time_limit_s, checked (None when not given)."""
    if "method_time_limit_s" not in sweep:
        return None
    try:
        return check_time_limit(sweep["method_time_limit_s"], "sweep.method_time_limit_s")
    except UserValueError as e:
        raise SpecError(str(e)) from None


def load_spec(path: Path, methods: tuple | None = None) -> SweepSpec:
    """Read, validate and expand a TOML sweep spec (raises SpecError with a one-line message)."""
    path = Path(path)
    try:
        doc, text = read_toml_text(path, "sweep spec")
    except ConfigError as e:
        raise SpecError(str(e)) from None
    try:
        return parse_spec(doc, text, methods)
    except SpecError as e:
        raise SpecError(f"{path}: {e}") from None
