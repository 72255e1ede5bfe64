"""The simulated robot: the plate's stereo rig and projector, moved to any pose and rendered.

``SimulatedSensor`` owns the one renderer of a sensing run (parameters are updated from pose to
pose, never a scene rebuilt) and hands back what a real sensor would give (images), with ground
truth's boundary visibility beside it for scoring only. ``passive_view`` is one measuring pose of
the loop: the passive pair rendered and its outline measured by the general outline stereo, and,
when asked, the active pair (projector beside the rig, ``active_views.projector_pose``, projecting
the verification pattern) and its checked square centres (``reconstruction.strategy.active_views``).

Under a real rig (``cfg.realism`` not ideal) every shot is a move of one drawn robot
(``bench.run.realism.RigDraw``): the images and ground truth come from the cameras really posed, and
every measurement is made with the rig the loop is told (``Shot.measured``: the commanded poses, the
estimated intrinsics and lens). World frame, metres.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from platebench.bench.config import SampleConfig, parse_grid
from platebench.bench.io.realism_records import RobotMove
from platebench.bench.run.realism import RealismSetup, draw_rig
from platebench.bench.run.render import ground_truth_at, render_images
from platebench.bench.run.sensing.records import auto_verify_grid
from platebench.plates import build_plate
from platebench.reconstruction.calibration.undistort import undistort_views
from platebench.reconstruction.paper.outline_stereo import match_outlines
from platebench.reconstruction.paper.plate_region import ReconstructionError, plate_mask
from platebench.reconstruction.strategy.active_views import ActivePoints, active_points, projector_pose
from platebench.reconstruction.strategy.multiview import ViewOutline
from platebench.reconstruction.strategy.poses import PoseError, SensorPose
from platebench.scenes.render.ground_truth import GroundTruthCaster, combined_visibility
from platebench.scenes.camera import Camera
from platebench.scenes.rig import StereoRig
from platebench.scenes.pattern import square_grid
from platebench.scenes.scene_spec import SceneSpec, scene_for_pose

PASSIVE = ("left_passive", "right_passive")
REACH_STEP_M = 0.01  # ``within_reach``: a pose out of the robot's reach comes closer by this much at a time
# ``loop.first_stages``: a stage-1 or stage-2 view whose plate runs into the image border (a real rig's
# pose error can turn the view by degrees) is taken again this fraction of its distance farther back
# along its line of sight, at most BACK_OFF_TRIES times: up to 1.1^5 = 1.61 times as far, the plate's
# image shrunk to 62 % of its size. A turned view's offset in the image does not shrink with distance;
# the room this frees holds a view turned about twice the PUMA's orientation error (42 mrad RMS, the
# kinematic model's): a stage-2 view turned about 95 mrad needed the fourth step.
BACK_OFF_FRACTION = 0.1
BACK_OFF_TRIES = 5
ACTIVE = ("left_active", "right_active")


@dataclass(frozen=True)
class Shot:
    """One render at a pose: the scene rendered (the cameras really posed: ground truth), images by
    name (radiance and digitised), ground truth's boundary visibility (camera -> ``BoundaryVisibility``;
    for scoring only), and ``told``: the rig the loop is told (commanded poses, estimated calibration;
    None: the rendered one, a rig without errors)."""

    scene: SceneSpec
    radiance: dict
    digital: dict
    gt_visibility: dict
    told: StereoRig | None = None

    @property
    def measured(self) -> SceneSpec:
        """The scene as the loop knows it: the told rig, the projector as placed."""
        return self.scene if self.told is None else self.scene.with_rig(self.told)

    def cameras_for_truth(self) -> dict:
        """``PassiveView``'s ``true_left`` and ``told_left`` for this shot (empty without rig errors)."""
        return {} if self.told is None else {"true_left": self.scene.rig.left, "told_left": self.told.left}


@dataclass(frozen=True)
class PassiveView:
    """A measuring pose's result: its outline (None when passive stereo failed, with ``error``), its
    checked square centres (None when no active pair was taken; empty when none passed), its left
    camera, and ground truth's visibility from both cameras (scoring only)."""

    name: str
    pose: SensorPose
    outline: ViewOutline | None
    left_camera: Camera  # the pinhole the outline's pixels are measured in (undistorted; the told camera)
    gt_visibility: dict
    error: str | None = None
    active: ActivePoints | None = None
    # under a real rig: the left camera really posed, with its true lens, and the one the loop was told
    # (commanded pose, estimated lens); None when the rendered camera is the told one
    true_left: Camera | None = None
    told_left: Camera | None = None

    def image_of(self, points_world: np.ndarray) -> np.ndarray:
        """(N,2) pixels, in the measured (undistorted) left image, where the world points (N,3)
        really appear: projected through the camera really posed and its true lens, then undistorted
        with the told lens into ``left_camera``'s pixels, as the images were. Without rig errors,
        ``left_camera.project``. NaN behind the camera. Scoring only (ground truth)."""
        if self.true_left is None or self.told_left is None:
            return self.left_camera.project(points_world)
        return self.left_camera.pixels(self.told_left.normalised(self.true_left.project(points_world)))


def plate_masks(digital: dict) -> dict:
    """camera -> ``PlateMask`` of its passive image."""
    return {c: plate_mask(digital[f"{c}_passive"], f"{c}_passive") for c in ("left", "right")}


def measure_outline(name: str, scene: SceneSpec, digital: dict, masks: dict | None = None) -> ViewOutline:
    """The plate's outline in the world frame from a passive pair (general outline stereo); a
    distorted rig's images are undistorted first (``masks``, if given, are of undistorted images)."""
    digital, rig = undistort_views({k: digital[k] for k in PASSIVE}, scene.rig)
    scene = replace(scene, rig=rig)
    m = masks or plate_masks(digital)
    st = match_outlines(digital["left_passive"], digital["right_passive"], m["left"], m["right"], scene.rig)
    return ViewOutline.from_stereo(name, st, scene.rig.center, scene.rig.left)


def _same_rig(a, b) -> bool:
    """True when two commanded rigs place both cameras identically."""
    return all(np.array_equal(x.R, y.R) and np.array_equal(x.t, y.t) for x, y in ((a.left, b.left), (a.right, b.right)))


class SimulatedSensor:
    """The rig of ``cfg``'s scene on a robot; the passive light rides with it (``follows_rig``).
    Stage 3 projects ``cfg``'s pattern; the measuring poses after it (``passive_view``) project
    ``verify_grid`` ('ROWSxCOLS@SQUARE_PX', ``parse_grid``; "auto": ``records.auto_verify_grid`` of
    the image width; None: ``cfg``'s pattern too), from the same projector."""

    def __init__(self, cfg: SampleConfig, progress=None, verify_grid: str | None = None,
                 corner_noise_px: float | None = None):
        self.cfg = cfg
        built = cfg.scene.build()
        self.base = replace(built, lighting=replace(built.lighting, follows_rig=True))
        # a real rig (``cfg.realism`` not ideal): one draw of the robot and the estimates for the whole run
        self.rig_draw = None if cfg.realism.is_ideal else draw_rig(
            RealismSetup.prepare(cfg.realism, cfg, corner_noise_px=corner_noise_px), built.rig.left, cfg.realism.seed)
        self.moves: list[RobotMove] = []  # each acquisition of a real rig: commanded vs really posed (``_acquire``)
        self._last = None  # (commanded rig, Acquisition) of the last move: a shot at the same pose reuses it
        proj = self.base.projector
        if verify_grid == "auto":
            verify_grid = auto_verify_grid(self.base.rig.left.width)
        grid = None if verify_grid is None else square_grid(proj.pattern.width, proj.pattern.height,
                                                             **parse_grid(verify_grid))
        same = grid is None or grid.description == proj.pattern.description
        self.verify_base = self.base if same else replace(self.base, projector=proj.with_pattern(grid))
        self.plate = build_plate(cfg.plate)
        # the camera the loop plans with: the estimated one under a real rig
        self.camera = self.base.rig.left if self.rig_draw is None else self.rig_draw.told(self.base.rig).left
        self.projector_camera = self.base.projector.camera
        self.baseline_m = self.base.rig.baseline_m
        self.renderer = None
        self._progress = progress or (lambda name: None)

    @property
    def patterns(self) -> dict:
        """The projected patterns' descriptions: stage 3's and the measuring poses' after it."""
        return {"stage3": self.base.projector.pattern.description,
                "verification": self.verify_base.projector.pattern.description}

    def scene_at(self, pose: SensorPose, projector: SensorPose | None = None, verify: bool = False) -> SceneSpec:
        """The scene with the rig at ``pose`` and the projector at ``projector`` (default: between
        the cameras), projecting the verification pattern if ``verify``, else the sample's."""
        return scene_for_pose(pose.center, pose.target, pose.baseline_dir, self.verify_base if verify else self.base,
                              projector_center=None if projector is None else projector.center,
                              projector_target=None if projector is None else projector.target)

    def within_reach(self, pose: SensorPose, nearest_m: float) -> SensorPose:
        """``pose``, or under a real rig whose robot cannot reach it, the same line of sight brought
        closer to its target (steps of ``REACH_STEP_M``, no closer than ``nearest_m``) until the robot
        reaches it from some turn of the cell (``RigDraw.reach_yaw``); its reason says so. ``pose`` when
        none does (``shoot`` then refuses it)."""
        if self.rig_draw is None:
            return pose
        d0 = pose.distance_m
        for d in np.arange(d0, nearest_m - REACH_STEP_M / 2, -REACH_STEP_M):
            p = pose.at_distance(d)
            if self.reaches(p):
                return p if d == d0 else replace(p, reason=f"{pose.reason}; brought to {d * 1e3:.0f} mm, the farthest "
                                                 f"the robot ({self.cfg.realism.robot}) reaches ({d0 * 1e3:.0f} mm asked)")
        return pose

    def reaches(self, pose: SensorPose) -> bool:
        """Whether the rig can be put at ``pose``: always on the ideal bench; under a real rig, when the
        robot reaches it from some turn of the cell (``RigDraw.reach_yaw``)."""
        return self.rig_draw is None or self.rig_draw.reach_yaw(self.scene_at(pose).rig) is not None

    def shoot(self, pose: SensorPose, names, projector: SensorPose | None = None, label: str = "",
              verify: bool = False) -> Shot:
        """Render the images ``names`` with the rig at ``pose`` (and the projector at ``projector``,
        projecting the verification pattern if ``verify``)."""
        self._progress(f"{label}: render" if label else "render")
        scene = self.scene_at(pose, projector, verify)
        told = None
        if self.rig_draw is not None:
            acq = self._acquire(scene.rig, label)
            scene, told = scene.with_rig(acq.taken), acq.told
        rad, dig, vis, self.renderer = render_images(self.cfg, self.renderer, scene, self.plate, names)
        return Shot(scene, rad, dig, vis, told)

    def _acquire(self, rig, label: str):
        """The robot moved to the commanded ``rig`` (``realism.RigDraw.acquire``), the cell turned when
        the arm cannot reach it otherwise (``RigDraw.reach_yaw``; ``PoseError`` when no turn lets it).
        A shot at the same commanded rig as the last one is taken where the robot already stands (at
        each view the camera takes its passive and active images before it moves on)."""
        if self._last is not None and _same_rig(self._last[0], rig):
            return self._last[1]
        yaw = self.rig_draw.reach_yaw(rig)
        if yaw is None:
            raise PoseError(f"{label or 'pose'}: the robot ({self.cfg.realism.robot}) cannot reach this pose "
                            "from any turn of the cell")
        acq = self.rig_draw.acquire(rig, yaw)
        self._last = (rig, acq)
        self.moves.append(RobotMove(label, float(np.degrees(yaw)), acq.report.views))
        return acq

    def dense_ground_truth(self) -> tuple[dict, dict]:
        """Dense ground truth and boundary visibility at the last shot's scene (scoring only)."""
        return ground_truth_at(self.renderer)

    def passive_view(self, name: str, pose: SensorPose, rays_for=None) -> PassiveView:
        """Render the passive pair at ``pose`` and measure its outline; with ``rays_for`` (scene ->
        ``FeatureRays``, the projector's calibration) also the active pair, with the projector
        beside the rig (``active_views.projector_pose``) projecting the verification pattern, and its square centres
        (``active_views.active_points``)."""
        return self._measure_view(name, pose, self._shoot_view(name, pose, rays_for is not None), rays_for)

    def passive_views(self, views, rays_for=None) -> list[PassiveView]:
        """``passive_view`` of each ``(name, pose)`` of ``views``, in order, rendered as one batch: the
        images of every view back to back, then their measurements (the same views and measurements
        as one ``passive_view`` after another).

        The renders do not overlap the measurements in a second thread: Dr.Jit 1.5.0 (the locked
        version) can deadlock when two Python threads use it, one holding the GIL while it waits for
        Dr.Jit's lock and the other holding that lock while its log callback asks for the GIL (fixed
        upstream by Dr.Jit commit 553c0ad, after 1.5.0), and Python's garbage collector can free
        Dr.Jit objects in the measuring thread at any moment. An overlap would save little: a view's
        render is short beside its measurement (docs/findings/design-record.md)."""
        active = rays_for is not None
        shots = [self._shoot_view(name, pose, active) for name, pose in views]
        return [self._measure_view(name, pose, shot, rays_for) for (name, pose), shot in zip(views, shots)]

    def _shoot_view(self, name: str, pose: SensorPose, active: bool) -> Shot | PoseError:
        """The view's shot; under a real rig, the ``PoseError`` of a pose its robot cannot reach."""
        try:
            return self.shoot(pose, PASSIVE + (ACTIVE if active else ()),
                              projector=projector_pose(pose) if active else None, label=name, verify=True)
        except PoseError as e:
            if self.rig_draw is None:
                raise
            return e

    def _measure_view(self, name: str, pose: SensorPose, shot: Shot | PoseError, rays_for) -> PassiveView:
        """The outline (and, with ``rays_for``, the checked square centres) measured from ``shot``
        (a pose the robot could not reach: no outline, the reason as the error)."""
        if isinstance(shot, PoseError):
            return PassiveView(name, pose, None, self.camera, {}, f"not taken: {shot}")
        # a distorted camera's images are measured undistorted, with its pinhole (reconstruction.calibration.undistort);
        # under a real rig, with the estimated lens, at the commanded poses (``Shot.measured``)
        digital, rig = undistort_views(shot.digital, shot.measured.rig)
        scene = replace(shot.measured, rig=rig)
        try:
            masks = plate_masks(digital)
            o = measure_outline(name, scene, digital, masks)
        except ReconstructionError as err:
            return PassiveView(name, pose, None, rig.left, shot.gt_visibility, f"passive stereo failed: {err}",
                               **shot.cameras_for_truth())
        active = None
        if rays_for is not None:
            try:
                active = active_points(name, digital, {c: m.mask for c, m in masks.items()}, rig,
                                       rays_for(shot.measured), shot.scene.projector.pattern)
            except ReconstructionError:  # no square inside the outline: recorded as 0 points (ViewRecord.active)
                active = ActivePoints.empty(name)
        return PassiveView(name, pose, o, rig.left, shot.gt_visibility, active=active, **shot.cameras_for_truth())

    def boundary_visibility_masks(self, poses) -> dict:
        """camera -> (P, N) bool: which true boundary points that camera of each of ``poses`` sees
        (ground truth, scoring only). Updates the renderer's scene parameters pose by pose; renders
        nothing."""
        masks = {"left": [], "right": []}
        for p in poses:
            self.renderer.set_scene(self.scene_at(p))
            caster = GroundTruthCaster(self.renderer)
            for c in ("left", "right"):
                masks[c].append(np.asarray(caster.boundary_visibility(c).visible, bool))
        n = len(self.plate.boundary)
        return {c: np.array(m, bool).reshape(len(poses), n) for c, m in masks.items()}

    def boundary_visible_from(self, poses) -> dict:
        """camera -> ``BoundaryVisibility`` of the true boundary from any of ``poses`` (that camera of
        at least one pose sees the point; ground truth, scoring only)."""
        masks = self.boundary_visibility_masks(poses)
        P = np.asarray(self.plate.boundary, float)
        return {c: combined_visibility(P, list(m)) for c, m in masks.items()}
