"""Plain-numpy description of a scene: rig, projector, lighting, materials, ground.

No Mitsuba here: reconstruction may import these types. Units: metres, radians;
radiometric quantities are relative (the camera model maps them to digital numbers).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from platebench.scenes.camera import intrinsics
from platebench.scenes.pattern import square_grid
from platebench.scenes.projector import Projector
from platebench.scenes.rig import PosedPair, StereoRig
from platebench.tolerances import tol

MATERIAL_KINDS = ("diffuse", "roughconductor")


@dataclass(frozen=True)
class RenderSettings:
    """Monte Carlo settings: samples per pixel and the base seed (integers; see ``image_seed``)."""

    spp: int = 16
    seed: int = 0

    def __post_init__(self):
        for name, lo, hi, allowed in (("spp", 1, 65536, "1 to 65536"), ("seed", 0, 2**31 - 1, "0 to 2^31-1")):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not (lo <= v <= hi):
                raise ValueError(f"{name} = {v!r} is out of range: allowed an integer {allowed}")
METALS = ("Al", "Fe")  # Mitsuba conductor presets: aluminium, iron (steel)


@dataclass(frozen=True)
class Material:
    """Plate material: white diffuse by default, or a rough metal (GGX ``alpha``)."""

    kind: str = "diffuse"
    albedo: float = 0.8
    metal: str = "Al"
    alpha: float = 0.2

    def __post_init__(self):
        if self.kind not in MATERIAL_KINDS:
            raise ValueError(f"material kind = {self.kind!r} is not allowed: choose one of {MATERIAL_KINDS}")
        if not (0.0 <= self.albedo <= 1.0):
            raise ValueError(f"material albedo = {self.albedo} is out of range: allowed 0 to 1")
        if self.metal not in METALS:
            raise ValueError(f"material metal = {self.metal!r} is not allowed: choose one of {METALS}")
        if not (0.001 <= self.alpha <= 1.0):
            raise ValueError(f"material alpha = {self.alpha} is out of range: allowed 0.001 to 1")


@dataclass(frozen=True)
class Lighting:
    """Passive: an overhead square area light. Active: the projector, plus ``ambient``.

    ``plate_radiance`` is the radiance a white (albedo 1) plate facing +Z at the
    origin receives from each light when on; lights are scaled to give it, so the
    images are well exposed whatever the distances.
    """

    area_size_m: float = 0.3
    area_height_m: float = 0.9
    plate_radiance: float = 0.85
    ambient: float = 0.0  # fraction of the passive light left on in active images
    # False: the area light hangs level at area_height_m above the rig's centre, facing down.
    # True: it rides with the sensor, on the rig's centre line behind_rig_m behind the cameras and
    # facing along their view (the same place as False for a rig looking straight down from
    # area_height_m - behind_rig_m). A tilted sensor then lights what it sees: with a fixed
    # overhead light, surfaces facing away from it are black and their edges cannot be measured.
    follows_rig: bool = False
    behind_rig_m: float = 0.5

    def __post_init__(self):
        if not (0.0 <= self.ambient <= 1.0):
            raise ValueError(f"lighting ambient = {self.ambient} is out of range: allowed 0 to 1")
        if not (self.area_size_m > 0 and self.area_height_m > 0 and self.plate_radiance > 0):
            raise ValueError("lighting sizes and plate_radiance must be > 0")
        if not (0.0 < self.behind_rig_m <= 10.0):
            raise ValueError(f"lighting behind_rig_m = {self.behind_rig_m} is out of range: allowed > 0 to 10 m")


@dataclass(frozen=True)
class SceneSpec:
    """Everything but the plate: stereo rig, projector, lighting, material, ground."""

    rig: StereoRig | PosedPair  # a conventional rig, or the pair a robot really took (rendered as it stands)
    projector: Projector
    material: Material = field(default_factory=Material)
    lighting: Lighting = field(default_factory=Lighting)
    ground_albedo: float = 0.03
    ground_z_m: float = -0.2
    max_depth: int = 3
    aperture_radius_m: float = 0.0  # 0: pinhole; > 0: thin lens (defocus blur)
    focus_distance_m: float | None = None  # thin lens focus; None: the rig's distance to the origin

    def __post_init__(self):
        if not (0.0 <= self.aperture_radius_m <= 0.05):
            raise ValueError(f"aperture_radius_m = {self.aperture_radius_m} is out of range: allowed 0 to 0.05 m")
        if self.focus_distance_m is not None and not (0.01 <= self.focus_distance_m <= 100):
            raise ValueError(f"focus_distance_m = {self.focus_distance_m} is out of range: allowed 0.01 to 100 m")

    @property
    def focus_m(self) -> float:
        """Thin-lens focus distance (m): given, or the left camera's depth of the world origin."""
        if self.focus_distance_m is not None:
            return self.focus_distance_m
        return float(max(self.rig.left.depth(np.zeros((1, 3)))[0], 0.01))

    def with_rig(self, rig: StereoRig | PosedPair) -> "SceneSpec":
        return replace(self, rig=rig)


@dataclass(frozen=True)
class ReferenceSetup:
    """The reference experiment's set-up: the cameras' height above the plate (m), their image size
    (px), focal length (px) and baseline (m), the projector's image size (px) and focal length (px)."""

    distance_m: float
    width: int
    height: int
    f_px: float
    baseline_m: float
    projector_width: int
    projector_height: int
    projector_f_px: float


# Reference experiment (paper V-A; docs/architecture.md): cameras 0.40 m above the plate looking
# straight down, 1280 x 960 px, f = 2000 px, baseline 0.10 m, projector between them.
REFERENCE = ReferenceSetup(distance_m=0.40, width=1280, height=960, f_px=2000.0, baseline_m=0.10,
                           projector_width=1024, projector_height=768, projector_f_px=1600.0)


def default_pattern(width=1024, height=768):
    """4 x 4 squares of 10 mm at 0.4 m (40 px at f = 1600), x gap 6 mm, row gap 20 mm."""
    return square_grid(width, height, rows=4, cols=4, square_px=40, gap_x_px=24, gap_y_px=80)


def up_for_baseline(view_dir, baseline_dir) -> np.ndarray:
    """The look-at ``up`` that puts the image x axis (hence the baseline) along ``baseline_dir``.

    With OpenCV look-at axes x = forward x up, choosing up = baseline x forward gives
    x = baseline (for a baseline perpendicular to the viewing direction).
    """
    f = np.asarray(view_dir, float)
    f = f / np.linalg.norm(f)
    b = np.asarray(baseline_dir, float)
    b = b - f * (b @ f)
    nb = np.linalg.norm(b)
    if nb < tol.unit_norm:
        raise ValueError("baseline direction is parallel to the viewing direction")
    return np.cross(b / nb, f)


def scene_for_pose(center, target, baseline_dir, base: SceneSpec, baseline_m: float | None = None,
                   projector_center=None, projector_target=None) -> SceneSpec:
    """``base`` with the rig re-placed: mid-baseline at ``center`` looking at ``target``, baseline
    along ``baseline_dir``; the projector sits between the cameras aimed at ``target``, or at
    ``projector_center`` aimed at ``projector_target`` (default ``target``), its image x axis
    along the baseline. K, lens distortion and pattern of both are kept. World frame, metres."""
    center = np.asarray(center, float)
    target = np.asarray(target, float)
    pc = center if projector_center is None else np.asarray(projector_center, float)
    pt = target if projector_target is None else np.asarray(projector_target, float)
    up = up_for_baseline(target - center, baseline_dir)
    p_up = up_for_baseline(pt - pc, baseline_dir)
    left = base.rig.left
    rig = StereoRig.conventional(center, target, baseline_m or base.rig.baseline_m, left.f_px,
                                 left.width, left.height, up=up, K=left.K, distortion=left.distortion)
    p = base.projector
    if p.kind == "spot":
        proj = Projector.look_at(pc, pt, p.pattern, kind="spot", cutoff_rad=p.cutoff_rad, up=p_up)
    else:
        proj = Projector.look_at(pc, pt, p.pattern, f_px=p.camera.f_px, kind=p.kind, up=p_up)
    return replace(base, rig=rig, projector=proj)


def reference_scene(distance_m: float = REFERENCE.distance_m, width: int = REFERENCE.width,
                    height: int = REFERENCE.height, f_px: float = REFERENCE.f_px,
                    baseline_m: float = REFERENCE.baseline_m, target=(0.0, 0.0, 0.0),
                    projector_kind: str = "pinhole", pattern=None, material: Material | None = None,
                    lighting: Lighting | None = None, fy_px: float | None = None,
                    distortion=None) -> SceneSpec:
    """The paper's reference set-up, optionally changed; the rig looks straight down at ``target``.
    ``fy_px``: the vertical focal length in pixels (non-square pixels; default ``f_px``);
    ``distortion``: both cameras' lens (``scenes.lens.BrownConrady``; default none)."""
    if not (0.05 <= distance_m <= 5.0):
        raise ValueError(f"distance_m = {distance_m} is out of range: allowed 0.05 to 5 m")
    target = np.asarray(target, float)
    center = target + np.array([0.0, 0.0, distance_m])
    K = None if fy_px is None else intrinsics(f_px, width, height, fy_px=fy_px)
    rig = StereoRig.conventional(center, target, baseline_m, f_px, width, height, K=K, distortion=distortion)
    pattern = pattern or default_pattern(REFERENCE.projector_width, REFERENCE.projector_height)
    if projector_kind == "spot":
        # Same footprint as the pinhole: tan(cutoff) = (W/2) / f, texture stretched to +-cutoff.
        cutoff = float(np.arctan(pattern.width / 2.0 / REFERENCE.projector_f_px))
        proj = Projector.look_at(center, target, pattern, kind="spot", cutoff_rad=cutoff)
    else:
        proj = Projector.look_at(center, target, pattern, f_px=REFERENCE.projector_f_px, kind=projector_kind)
    return SceneSpec(rig, proj, material or Material(), lighting or Lighting())
