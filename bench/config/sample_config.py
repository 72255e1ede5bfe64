"""Sample configuration: a plate and a scene from a TOML file and/or CLI flags.

TOML layout (all SI: metres, radians; every key optional, defaults = the paper's
reference experiment)::

    [plate]            # a PlateSpec's form (bench/io/codecs/plates.py), e.g.
    length_m = 0.1165
    width_m = 0.0735
    thickness_m = 0.0
    [plate.deformation]
    family = "cylinder"
    angle_rad = 0.17453
    direction = "up"

    [scene]
    distance_m = 0.40
    width = 1280
    height = 960
    f_px = 2000.0
    baseline_m = 0.10
    projector_kind = "pinhole"   # or "spot"
    ambient = 0.0
    fy_px = 2500.0               # vertical focal length (px): non-square pixels; default f_px
    [scene.material]             # kind = "diffuse" | "roughconductor", albedo, metal, alpha
    [scene.pattern]              # rows, cols, square_px, gap_x_px, gap_y_px
    [scene.distortion]           # Brown-Conrady lens distortion, OpenCV's k1, k2, p1, p2, k3

    [render]
    spp = 16
    seed = 0

    [realism]                    # optional; see bench/config/realism.py
    preset = "1995"              # ideal (default), 1995, modern: robot, hand/eye, calibration errors
    seed = 3                     # the draw of the error sources
    sources = ["robot_repeatability", "hand_eye"]   # optional: only these on
    scales = { robot_accuracy = 2.0 }               # optional: a source's magnitude (1 = as sourced)

Unknown keys are refused with the key named. The realism table records the error model a sample was
rendered with; the camera part of a preset (resolution, sensor) is applied to [scene] and [sensor] by
``bench.config.presets.with_realism`` (``--realism``), so those tables say what was rendered.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from platebench.bench.config.realism import Realism
from platebench.bench.files import CONFIG_MAX_BYTES, read_capped
from platebench.errors import UserValueError
from platebench.plates import CylindricalBend, PlateSpec, reference_spec
from platebench.plates.spec import MIN_BEND_DEG
from platebench.scenes.camera import Camera, intrinsics
from platebench.scenes.lens import BrownConrady
from platebench.scenes.pattern import square_grid
from platebench.scenes.render.passes import WAVEFRONT_LIMIT, fits_wavefront
from platebench.scenes.scene_spec import (
    REFERENCE,
    Lighting,
    Material,
    RenderSettings,
    SceneSpec,
    reference_scene,
)
from platebench.scenes.sensor_model import SensorModel

__all__ = ["ConfigError", "SceneParams", "PlateSize", "RigPose", "SampleConfig", "RenderSettings", "SensorModel", "parse_grid",
           "with_overrides", "read_toml", "read_toml_text", "check_types", "check_value_type", "check_render_size",
           "WAVEFRONT_LIMIT", "TOML_MAX_DEPTH"]

# tables and arrays nested deeper than this in a TOML file are refused (no configuration nests beyond 4)
TOML_MAX_DEPTH = 64


class ConfigError(UserValueError):
    """A configuration key or value is not allowed."""


def check_render_size(width: int, height: int, spp: int, what: str = "render.spp") -> None:
    """Refuse (ConfigError, one line) a render that Mitsuba's JIT variants cannot trace: every render runs
    by the pass plan of ``scenes.render.passes`` (``pass_plan``), whose passes stay within Mitsuba's
    ``WAVEFRONT_LIMIT`` samples whenever one sample per pixel does; any spp renders at such a size."""
    width, height, spp = int(width), int(height), int(spp)
    if fits_wavefront(width, height):
        return
    raise ConfigError(f"{what} = {spp} cannot be rendered at {width} x {height} px: one sample per pixel is "
                      f"{width * height} samples, over Mitsuba's {WAVEFRONT_LIMIT + 1:.3g} per pass")


IMAGE_SIZE_PX = (16, 8192)  # allowed image width and height (px), each
_SCENE_KEYS = {"distance_m", "width", "height", "f_px", "baseline_m", "projector_kind", "ambient",
               "material", "pattern", "aperture_radius_m", "focus_distance_m", "fy_px", "distortion"}
_DISTORTION_KEYS = {"k1", "k2", "p1", "p2", "k3"}
_PATTERN_KEYS = {"rows", "cols", "square_px", "gap_x_px", "gap_y_px"}
_MATERIAL_KEYS = {"kind", "albedo", "metal", "alpha"}
_RENDER_KEYS = {"spp", "seed", "variant"}
_SENSOR_KEYS = {"bit_depth", "radiance_full_scale", "gamma", "full_well_e", "read_noise_dn", "line_jitter_px"}
_TOP_KEYS = {"plate", "scene", "render", "sensor", "realism"}


# Types of every scalar key (what TOML gives): "int" (an integer, not 160.5, not "160", not a bool),
# "float" (a finite number, not a string), "str", "table", "float?" (a number or absent). Ranges are
# checked by the classes; the type check comes first so that the message says what is wrong.
_TYPES = {
    "scene": {"distance_m": "float", "width": "int", "height": "int", "f_px": "float?", "baseline_m": "float",
              "projector_kind": "str", "ambient": "float", "material": "table", "pattern": "table",
              "aperture_radius_m": "float", "focus_distance_m": "float?", "fy_px": "float?",
              "distortion": "table"},
    "scene.pattern": dict.fromkeys(_PATTERN_KEYS, "int"),
    "scene.distortion": dict.fromkeys(_DISTORTION_KEYS, "float"),
    "scene.material": {"kind": "str", "albedo": "float", "metal": "str", "alpha": "float"},
    "render": {"spp": "int", "seed": "int", "variant": "str?"},
    "sensor": {"bit_depth": "int", "radiance_full_scale": "float", "gamma": "float", "full_well_e": "float",
               "read_noise_dn": "float", "line_jitter_px": "float"},
    "plate": {"length_m": "float", "width_m": "float", "thickness_m": "float", "deformation": "table"},
}
_ALLOWED = {"scene.width": "an integer 16 to 8192", "scene.height": "an integer 16 to 8192",
            "render.spp": "an integer 1 to 65536", "render.seed": "an integer 0 to 2^31-1",
            "sensor.bit_depth": "8 or 16"}
_TEXT_KEYS = {"family", "direction"}  # the only text values of plate.deformation


def _type_error(key: str, v, kind: str) -> ConfigError:
    what = {"int": "an integer", "float": "a finite number", "str": "a string", "table": "a table"}[kind.rstrip("?")]
    allowed = _ALLOWED.get(key, what)
    shown = repr(v) if not isinstance(v, float) else f"{v!r}"
    return ConfigError(f"{key} = {shown} is not {what}"
                       + (f" ({type(v).__name__})" if isinstance(v, (str, bool)) else "") + f": allowed {allowed}")


def check_value_type(key: str, v, kind: str) -> None:
    """Refuse ``v`` for ``key`` unless it has the type ``kind`` (see ``_TYPES``); one-line ConfigError."""
    if kind.endswith("?"):
        if v is None:
            return
        kind = kind[:-1]
    if kind == "int":
        ok = isinstance(v, int) and not isinstance(v, bool)
    elif kind == "float":
        ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
    elif kind == "str":
        ok = isinstance(v, str)
    else:
        ok = isinstance(v, dict)
    if not ok:
        raise _type_error(key, v, kind)


def check_types(d: dict, prefix: str = "") -> None:
    """Check the type of every known key of a configuration dict (before any class sees it)."""
    if not isinstance(d, dict):
        raise ConfigError(f"{prefix or 'configuration'} = {d!r} is not a table")
    for table, types in _TYPES.items():
        node = d
        for part in table.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        if node is None:
            continue
        if not isinstance(node, dict):
            raise ConfigError(f"{prefix}{table} = {node!r} is not a table")
        for k, v in node.items():
            if k in types:
                check_value_type(f"{prefix}{table}.{k}", v, types[k])
    dfm = (d.get("plate") or {}).get("deformation") if isinstance(d.get("plate"), dict) else None
    if isinstance(dfm, dict):
        for k, v in dfm.items():
            check_value_type(f"{prefix}plate.deformation.{k}", v, "str" if k in _TEXT_KEYS else "float")


def _check_keys(where: str, d: dict, allowed: set) -> None:
    unknown = sorted(set(d) - allowed)
    if unknown:
        raise ConfigError(f"unknown key {where}.{unknown[0]}: allowed keys are {', '.join(sorted(allowed))}")


@dataclass(frozen=True)
class SceneParams:
    """The scalar knobs of a scene (what sample.json records); ``build()`` makes the SceneSpec."""

    distance_m: float = REFERENCE.distance_m
    width: int = REFERENCE.width
    height: int = REFERENCE.height
    f_px: float | None = None  # None: 2000 px scaled with the width (same field of view)
    baseline_m: float = REFERENCE.baseline_m
    projector_kind: str = "pinhole"
    ambient: float = 0.0
    material: dict = field(default_factory=dict)
    pattern: dict = field(default_factory=dict)
    aperture_radius_m: float = 0.0  # thin-lens aperture radius; 0: pinhole (no defocus)
    focus_distance_m: float | None = None  # None: focused on the plate centre
    fy_px: float | None = None  # vertical focal length (px); None: fy = fx (square pixels)
    distortion: dict = field(default_factory=dict)  # OpenCV k1, k2, p1, p2, k3 (absent: 0); {}: no distortion

    def __post_init__(self):
        checks = (("distance_m", 0.05, 5.0), ("width", *IMAGE_SIZE_PX), ("height", *IMAGE_SIZE_PX),
                  ("f_px", 10.0, 1e5), ("baseline_m", 1e-3, 2.0), ("ambient", 0.0, 1.0), ("fy_px", 10.0, 1e5))
        for name, lo, hi in checks:
            v = getattr(self, name)
            if name in ("f_px", "fy_px") and v is None:
                continue
            if not isinstance(v, (int, float)) or not math.isfinite(v) or not (lo <= v <= hi):
                raise ConfigError(f"scene.{name} = {v!r} is out of range: allowed {lo} to {hi}")
        if self.projector_kind not in ("pinhole", "spot"):
            raise ConfigError(f"scene.projector_kind = {self.projector_kind!r}: allowed 'pinhole' or 'spot'")
        _check_keys("scene.material", self.material, _MATERIAL_KEYS)
        _check_keys("scene.pattern", self.pattern, _PATTERN_KEYS)
        _check_keys("scene.distortion", self.distortion, _DISTORTION_KEYS)
        try:  # the lens must map this image one-to-one (checked by the camera model)
            lens = self.lens
            if lens is not None:
                fy = self.focal_px if self.fy_px is None else float(self.fy_px)
                Camera(intrinsics(self.focal_px, int(self.width), int(self.height), fy_px=fy), np.eye(3),
                       np.zeros(3), int(self.width), int(self.height), lens)
        except ValueError as e:
            raise ConfigError(f"scene.distortion: {e}") from None

    def build(self) -> SceneSpec:
        try:
            material = Material(**self.material)
            pattern = None
            if self.pattern:
                pattern = square_grid(REFERENCE.projector_width, REFERENCE.projector_height, **self.pattern)
            scene = reference_scene(distance_m=self.distance_m, width=int(self.width), height=int(self.height),
                                    f_px=self.focal_px, baseline_m=self.baseline_m,
                                    projector_kind=self.projector_kind, pattern=pattern, material=material,
                                    lighting=Lighting(ambient=self.ambient), fy_px=self.fy_px,
                                    distortion=self.lens)
            return replace(scene, aperture_radius_m=self.aperture_radius_m, focus_distance_m=self.focus_distance_m)
        except ValueError as e:
            raise ConfigError(str(e)) from None

    @property
    def focal_px(self) -> float:
        """Focal length in pixels; by default the reference 2000 px scaled with the image width."""
        return float(self.f_px) if self.f_px is not None else REFERENCE.f_px * self.width / REFERENCE.width

    @property
    def lens(self) -> BrownConrady | None:
        """The lens distortion of both cameras (None: an ideal pinhole)."""
        return BrownConrady(**{k: float(v) for k, v in self.distortion.items()}) if self.distortion else None


@dataclass(frozen=True)
class PlateSize:
    """A plate's length and width (m), as a sample's configuration table holds them while a sweep's
    axes change it (its deformation may not fit the new size yet)."""

    length_m: float
    width_m: float


@dataclass(frozen=True)
class RigPose:
    """A sweep's pose of the rig (``scenes.scene_spec.scene_for_pose``): its viewing direction
    tilted ``tilt_deg`` from vertical toward azimuth ``azimuth_deg`` (from +X around +Z), degrees;
    0, 0: the reference rig looking straight down."""

    tilt_deg: float = 0.0
    azimuth_deg: float = 0.0


@dataclass(frozen=True)
class SampleConfig:
    """Everything that defines one sample."""

    plate: PlateSpec = field(default_factory=reference_spec)
    scene: SceneParams = field(default_factory=SceneParams)
    render: RenderSettings = field(default_factory=RenderSettings)
    sensor: SensorModel = field(default_factory=SensorModel)
    variant: str | None = None
    realism: Realism = field(default_factory=Realism)  # error sources of a real rig; ideal: none

    def __post_init__(self):
        check_render_size(self.scene.width, self.scene.height, self.render.spp)


# Camera presets: resolution and what the sensor gives. "1995" is a PULNiX TM-540-like CCD
# (512 x 480, 8-bit, noisy); "modern" a current machine-vision camera; "ideal" is noise-free.




def read_toml(path: Path, what: str = "TOML") -> dict:
    """A TOML file as a dict; one-line errors naming the file (missing, a directory, a FIFO or a
    device, larger than ``CONFIG_MAX_BYTES``, unreadable: the OSError; not UTF-8; bad syntax:
    ConfigError)."""
    return read_toml_text(path, what)[0]


def read_toml_text(path: Path, what: str = "TOML") -> tuple[dict, str]:
    """(the parsed TOML file, its text), read once (``read_toml``)."""
    path = Path(path)
    data = read_capped(path, CONFIG_MAX_BYTES, f"{what} file (TOML)", ConfigError, missing=f"{what} file is missing")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(f"{path}: not UTF-8 text (byte 0x{data[e.start]:02x} at offset {e.start}): allowed a "
                          f"UTF-8 {what} file (TOML)") from None
    too_deep = f"{path}: tables and arrays nested deeper than {TOML_MAX_DEPTH} levels: allowed at most {TOML_MAX_DEPTH}"
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: invalid TOML ({str(e).splitlines()[0]})") from None
    except RecursionError:  # the parser recurses once per level of nesting
        raise ConfigError(too_deep) from None
    if _depth(doc) > TOML_MAX_DEPTH:
        raise ConfigError(too_deep)
    return doc, text


def _depth(doc) -> int:
    """How deep tables and arrays nest in ``doc`` (a parsed TOML document: 1), counted without recursion."""
    deepest, stack = 0, [(doc, 1)]
    while stack:
        node, level = stack.pop()
        deepest = max(deepest, level)
        children = node.values() if isinstance(node, dict) else node
        stack.extend((c, level + 1) for c in children if isinstance(c, (dict, list)))
    return deepest


def parse_grid(text: str) -> dict:
    """'ROWSxCOLS@SQUARE_PX' (e.g. '6x12@12') -> square_grid keywords: ROWS arrays of COLS squares
    of SQUARE_PX projector pixels, x gap SQUARE_PX/2, row gap 4 x SQUARE_PX (the Fig. 6 spacing)."""
    import re  # noqa: PLC0415
    m = re.fullmatch(r"\s*(\d+)\s*x\s*(\d+)\s*@\s*(\d+)\s*", text or "")
    if not m:
        raise ConfigError(f"--grid = {text!r} is not ROWSxCOLS@SQUARE_PX (e.g. 4x4@40, the paper's; 6x12@12)")
    rows, cols, sq = (int(g) for g in m.groups())
    for name, v, lo, hi in (("ROWS", rows, 1, 40), ("COLS", cols, 1, 80), ("SQUARE_PX", sq, 4, 200)):
        if not lo <= v <= hi:
            raise ConfigError(f"--grid {name} = {v} is out of range: allowed {lo} to {hi}")
    return {"rows": rows, "cols": cols, "square_px": sq, "gap_x_px": max(1, sq // 2), "gap_y_px": 4 * sq}


def with_overrides(cfg: SampleConfig, bend_deg=None, width=None, height=None, spp=None, seed=None,
                   variant=None, distance_m=None, bend_direction=None, bend_axis_deg=None,
                   grid=None) -> SampleConfig:
    """Apply CLI flags on top of a configuration (angles in degrees, as the flags say).

    ``bend_direction`` 'down' (convex) or 'up' (concave); ``bend_axis_deg`` the bend axis's angle
    from the plate's width direction, 0 to 180 (0: bent along its length; 90: across its width);
    ``grid`` 'ROWSxCOLS@SQUARE_PX' (see ``parse_grid``)."""
    plate = cfg.plate
    if bend_deg is not None or bend_direction is not None or bend_axis_deg is not None:
        if bend_deg is not None and (not math.isfinite(bend_deg) or not (0.0 <= bend_deg <= 350.0)):
            raise ConfigError(f"--bend-deg = {bend_deg} is out of range: allowed 0 to 350 degrees")
        if bend_deg is not None and 0.0 < bend_deg < MIN_BEND_DEG:
            raise ConfigError(f"--bend-deg = {bend_deg:g} is out of range: allowed 0 (flat) or {MIN_BEND_DEG:g} to "
                              "350 degrees")
        if bend_direction is not None and bend_direction not in ("up", "down"):
            raise ConfigError(f"--bend-direction = {bend_direction!r}: allowed 'down' (convex) or 'up' (concave)")
        if bend_axis_deg is not None and (not math.isfinite(bend_axis_deg) or not (0.0 <= bend_axis_deg < 180.0)):
            raise ConfigError(f"--bend-axis-deg = {bend_axis_deg} is out of range: allowed 0 to 180 (exclusive) degrees")
        dfm = plate.deformation
        if not isinstance(dfm, CylindricalBend):
            dfm = CylindricalBend(angle_rad=math.radians(10.0))
        changes = {k: v for k, v in (("angle_rad", None if bend_deg is None else math.radians(bend_deg)),
                                      ("direction", bend_direction),
                                      ("axis_rad", None if bend_axis_deg is None else math.radians(bend_axis_deg)))
                   if v is not None}
        try:
            plate = replace(plate, deformation=replace(dfm, **changes))
        except ValueError as e:
            raise ConfigError(str(e)) from None
    scene_over = {k: v for k, v in (("width", width), ("height", height), ("distance_m", distance_m))
                  if v is not None}
    if grid is not None:
        scene_over["pattern"] = parse_grid(grid)
    scene = replace(cfg.scene, **scene_over) if scene_over else cfg.scene
    try:
        render = RenderSettings(spp=spp if spp is not None else cfg.render.spp,
                                seed=seed if seed is not None else cfg.render.seed)
    except ValueError as e:
        raise ConfigError(str(e)) from None
    return SampleConfig(plate, scene, render, cfg.sensor, variant or cfg.variant, cfg.realism)
