"""A stereo acquisition under a realism preset: what the robot really did, and what the method is told.

``RealismSetup.prepare(realism, rig)`` does, once per error model, what does not change between draws:
the robot's error model from its datasheet figures (``hardware_robot.robot_error_model``) and the
corner-localisation noise of the calibration views, measured on rendered target images of this
camera (``measure_corner_noise``). ``realise(setup, rig, seed)`` then draws one acquisition:

1. the robot: its real kinematics (a seeded ``KinematicErrors`` draw, absolute accuracy) and every
   move's joint error (repeatability);
2. calibration views: the robot is commanded to the cell's hand/eye views (flange poses, from the
   mount as drawn); the camera really stands where the real arm put it; the target block's corners
   are projected through the true camera and located with the measured noise;
3. estimates, each only when its source is on (else the truth, the oracle): the camera's intrinsics
   (``cv2.calibrateCamera`` on those views, through ``reconstruction.calibration.calibrate_camera``),
   the mount and the target block's pose in the world (``reconstruction.calibration.hand_eye``, from
   the COMMANDED flange poses and the target's pose in each view);
4. the stereo pair: the loop asks for the commanded conventional rig; the robot moves the camera
   there through the estimated mount, once per view (or once for a rigid head), with its errors.

``draw_rig`` does steps 1-3 once (a ``RigDraw``); its ``acquire`` does step 4 for any commanded rig, as
often as asked: the sensing loop's successive poses are successive moves of the same drawn robot, with
the same estimates (``realise`` is a draw's first pair). A pose the arm cannot reach from the cell is
taken with the cell turned about the world's vertical axis (``RigDraw.reach_yaw``: a turntable under the
plate, exact).

Returns the rig the method is told (commanded poses, estimated intrinsics), the pair that was really
taken (a ``PosedPair``: render it and cast ground truth from it) and the target pose estimate; and
what each estimate missed by (``report``), against the truth. Seeds: ``numpy.random.default_rng([seed,
k])`` with a fixed k per stream (robot, moves, corner noise), so that each source draws the same
numbers whether or not the others are on (an error budget compares like with like).
Units: metres and radians; pixels for image points.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from platebench.bench.config.hardware_robot import CELL, ROBOTS, TARGET, Cell, TargetBlock, nominal_arm, robot_error_model
from platebench.bench.config.realism import Realism
from platebench.bench.io.realism_records import DrawReport, HandEyeEstimate, IntrinsicsEstimate, ViewPoseError
from platebench.reconstruction.calibration.hand_eye import solve_hand_eye
from platebench.reconstruction.calibration.stereo import (
    BoardDetection,
    CalibrationError,
    calibrate_camera,
    distortion_is_needed,
)
from platebench.reconstruction.strategy.multiview import PoseSpread
from platebench.scenes.camera import Camera, look_at_rotation
from platebench.scenes.lens import BrownConrady
from platebench.scenes.rig import PosedPair, StereoRig
from platebench.scenes.robot import (
    EyeInHand,
    IKError,
    Robot,
    RobotErrorModel,
    camera_from_pose,
    camera_pose,
    invert_pose,
    pose_difference,
    pose_matrix,
)
from platebench.scenes.scene_spec import RenderSettings

__all__ = ["RealismSetup", "Acquisition", "RigDraw", "draw_rig", "REACH_YAWS_RAD", "realise", "realise_sample", "measure_corner_noise", "calibration_view_cameras",
           "STREAM_ROBOT", "STREAM_MOVES", "STREAM_CORNERS"]

STREAM_ROBOT, STREAM_MOVES, STREAM_CORNERS = 1, 2, 3
MIN_VIEW_CORNERS = 8  # a calibration view with fewer visible corners is not used
CORNER_MARGIN_PX = 3.0
CORNER_NOISE_VIEWS = 4  # rendered views of the target for the corner-noise measurement


@dataclass(frozen=True)
class RealismSetup:
    """What one error model needs before any draw: the realism, the cell and target, the robot's error
    model (None: no robot) and the corner-localisation noise (px per axis; 0 when nothing is estimated)."""

    realism: Realism
    cell: Cell
    target: TargetBlock
    robot_model: RobotErrorModel | None
    corner_noise_px: float

    @staticmethod
    def unit_robot_model(robot: str, cell: Cell = CELL, target: TargetBlock = TARGET) -> RobotErrorModel:
        """The error model of robot ``robot`` (a key of ``ROBOTS``) in ``cell``, both terms on at their
        datasheet magnitudes (``robot_error_model`` over the seed configuration and the hand/eye
        views' configurations): the costly part of ``prepare`` (an IK per view, the kinematic
        parameters' Jacobians), the same for every realism with that robot."""
        hw = ROBOTS[robot]
        q_views = [nominal_arm(hw, cell).ik(T, cell.q_seed) for T in calibration_flange_poses(cell, target)]
        return robot_error_model(hw, cell, q_sample=[cell.q_seed, *q_views])

    @classmethod
    def prepare(cls, realism: Realism, cfg, cell: Cell = CELL, target: TargetBlock = TARGET,
                corner_noise_px: float | None = None, spp: int = 16,
                unit_robot: RobotErrorModel | None = None) -> "RealismSetup":
        """Everything that does not change between draws. ``cfg``: the sample configuration under this
        realism (``presets.with_realism``: its camera, lens and sensor). ``corner_noise_px`` None: measured
        on rendered views of the target through that camera (only when an estimate needs it).
        ``unit_robot``: ``unit_robot_model(realism.robot, cell, target)`` when the caller has it
        (a study prepares many realisms with the same robot); scaled and switched here."""
        model = None
        if realism.robot is not None:
            unit = cls.unit_robot_model(realism.robot, cell, target) if unit_robot is None else unit_robot
            model = unit.scaled(realism.scale("robot_repeatability"), realism.scale("robot_accuracy"),
                                realism.on("robot_repeatability"), realism.on("robot_accuracy"))
        if corner_noise_px is None:
            corner_noise_px = measure_corner_noise(cfg, target, spp) if realism.estimates else 0.0
        return cls(realism, cell, target, model, float(corner_noise_px))


@dataclass(frozen=True)
class Acquisition:
    """One draw: ``told`` (the conventional rig the method is given: commanded poses, estimated K),
    ``taken`` (the pair really taken: render this), the target block's pose in the world as the method
    knows it (``T_world_block_est``) and as it is (``T_world_block``), and ``report`` (what each
    estimate missed by, and how far each view was from its command)."""

    told: StereoRig
    taken: StereoRig | PosedPair
    T_world_block_est: np.ndarray
    T_world_block: np.ndarray
    report: DrawReport = field(default_factory=DrawReport)


def _rng(seed: int, stream: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), stream])


def calibration_view_cameras(cell: Cell, target: TargetBlock, K, width: int, height: int) -> list[Camera]:
    """The cell's hand/eye views as cameras looking at the target block's centre (the design)."""
    out = []
    for tilt, az, dist, roll in cell.calibration_views:
        t, a = np.radians(tilt), np.radians(az)
        eye = target.center_world(cell) + dist * np.array([np.sin(t) * np.cos(a), np.sin(t) * np.sin(a), np.cos(t)])
        R = look_at_rotation(eye, target.center_world(cell), (-1.0, 0.0, 0.0) if tilt < 89 else (0.0, 0.0, 1.0))
        c, s = np.cos(np.radians(roll)), np.sin(np.radians(roll))
        R = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]]) @ R  # roll about the optical axis
        out.append(Camera(K, R, -R @ eye, width, height))
    return out


def calibration_flange_poses(cell: Cell, target: TargetBlock) -> list[np.ndarray]:
    """The flange commands of the hand/eye views (through the mount as drawn)."""
    cams = calibration_view_cameras(cell, target, np.diag([1.0, 1.0, 1.0]), 16, 16)
    return [camera_pose(c) @ invert_pose(cell.mount_design) for c in cams]


def _observe(cam: Camera, pts_world: np.ndarray, noise_px: float, rng) -> tuple[np.ndarray, np.ndarray]:
    """(indices, (M,2) pixels) of the target corners a camera sees, located with Gaussian noise."""
    uv = cam.project(pts_world)
    ok = np.isfinite(uv[:, 0]) & cam.in_image(uv, CORNER_MARGIN_PX)
    noise = rng.normal(0.0, noise_px, uv.shape) if noise_px > 0 else np.zeros_like(uv)
    return np.nonzero(ok)[0], (uv + noise)[ok]


def realise(setup: RealismSetup, rig: StereoRig, seed: int) -> Acquisition:
    """One draw of the acquisition of the commanded conventional ``rig`` (see the module doc)."""
    return draw_rig(setup, rig.left, seed).acquire(rig)


@dataclass(frozen=True)
class RigDraw:
    """One draw of a real rig before any stereo pair (steps 1-3 of the module doc): the robot as drawn
    (None: no robot), the estimates the method is told (``K_est``, ``lens_est``: None, a pinhole;
    ``mount_est``, ``T_block_est``), the truth beside them, and ``report`` (what each estimate missed
    by). ``acquire(rig)`` takes one stereo pair with it (step 4); successive pairs continue the same
    draw: the same robot and estimates, each move a new repeatability draw from ``moves`` (a stream
    that advances: a sensing run's poses are its successive moves). ``camera``: the true camera
    (intrinsics, image size, lens; its pose is ignored)."""

    realism: Realism
    cell: Cell
    camera: Camera
    robot: Robot | None
    K_est: np.ndarray
    lens_est: BrownConrady | None
    mount_est: np.ndarray
    T_block_est: np.ndarray
    T_world_block: np.ndarray
    moves: np.random.Generator
    report: DrawReport
    exact: bool = False  # the robot goes where it is told and the method is told the truth

    def told(self, rig: StereoRig) -> StereoRig:
        """The conventional ``rig`` as the method is told it: its commanded poses, the estimated
        intrinsics and lens (CalibrationError when the estimated lens is unusable)."""
        if self.exact:
            return rig
        try:
            return StereoRig(replace(rig.left, K=self.K_est, distortion=self.lens_est),
                             replace(rig.right, K=self.K_est, distortion=self.lens_est), rig.baseline_m)
        except ValueError as e:  # e.g. an estimated lens that folds over inside the image: the draw cannot be measured
            raise CalibrationError(f"draw {self.realism.seed}: the estimated calibration is unusable: "
                                   f"{str(e).splitlines()[0]}") from None

    @property
    def moves_camera(self) -> bool:
        """True when the cameras really posed are not the commanded ones (a robot, or an estimated mount)."""
        return not self.exact and (self.robot is not None or self.realism.on("hand_eye"))

    @property
    def pose_spread(self) -> PoseSpread | None:
        """How far this rig's poses disagree as its own hand/eye calibration measured it (the RMS
        residuals of its relative motions, ``multiview.PoseSpread``); None when no hand/eye calibration
        was made (``exact``, or the mount told as it is)."""
        he = self.report.hand_eye
        if self.exact or he is None:
            return None
        return PoseSpread(he.residual_translation_rms_m, he.residual_rotation_rms_rad)

    def eye(self) -> EyeInHand:
        """The camera on the flange: its true mount and the mount the method believes in."""
        return EyeInHand(self.robot or _exact_robot(self.realism, self.cell), self.cell.mount, self.mount_est,
                         self.camera)

    def acquire(self, rig: StereoRig, yaw_rad: float = 0.0) -> Acquisition:
        """The pair really taken for the commanded conventional ``rig`` (step 4 of the module doc): the
        rig the method is told, the pair that was taken, and how far each view was from its command.
        ``yaw_rad``: the cell turned about the world's vertical axis through the origin (``reach_yaw``)."""
        told = self.told(rig)
        if not self.moves_camera:
            return Acquisition(told, rig, self.T_block_est, self.T_world_block, self.report)
        head = None
        if self.realism.rigid_head:
            head = invert_pose(camera_pose(rig.left)) @ camera_pose(rig.right)  # the head's true left -> right pose
        if yaw_rad == 0.0:
            taken = self.eye().executed_pair(rig, self.moves, head)
        else:
            turn = _turn(yaw_rad)  # the cell turned: command the rig as the turned cell sees it, turn back what it took
            back = invert_pose(turn)
            turned = self.eye().executed_pair(PosedPair(_moved(back, rig.left), _moved(back, rig.right)), self.moves,
                                              head)
            taken = PosedPair(_moved(turn, turned.left), _moved(turn, turned.right))
        report = self.report.with_views({c: ViewPoseError(*pose_difference(camera_pose(taken.cameras[c]),
                                                                          camera_pose(rig.cameras[c])))
                                         for c in ("left", "right")})
        return Acquisition(told, taken, self.T_block_est, self.T_world_block, report)

    def reach_yaw(self, rig: StereoRig, yaws_rad=None) -> float | None:
        """The first of ``yaws_rad`` (default ``REACH_YAWS_RAD``: no turn first, then ever larger turns)
        by which the cell turned about the world's vertical axis lets the arm reach both views of ``rig``
        (its controller's IK, from its seed configuration); None when none does. 0 without a robot."""
        if self.robot is None or not self.moves_camera:
            return 0.0
        eye = self.eye()
        for yaw in REACH_YAWS_RAD if yaws_rad is None else yaws_rad:
            turn_back = _turn(-yaw)
            try:
                for cam in (rig.left, rig.right):
                    self.robot.joints_for(eye.command_for(_moved(turn_back, cam)))
            except IKError:
                continue
            return float(yaw)
        return None


# Turns of the cell about the world's vertical axis tried by ``RigDraw.reach_yaw``: none, then +-30 deg
# steps to a half turn (a turntable under the plate; exact in the simulation).
REACH_YAWS_RAD = tuple(np.radians([0.0, 30.0, -30.0, 60.0, -60.0, 90.0, -90.0, 120.0, -120.0, 150.0, -150.0, 180.0]))


def _turn(yaw_rad: float) -> np.ndarray:
    """4x4: a turn by ``yaw_rad`` about the world's vertical axis through the origin."""
    return pose_matrix(Rotation.from_rotvec([0.0, 0.0, float(yaw_rad)]).as_matrix(), np.zeros(3))


def _moved(T, cam: Camera) -> Camera:
    """``cam`` moved rigidly by the world transform ``T`` (4x4)."""
    return camera_from_pose(np.asarray(T) @ camera_pose(cam), cam)


def draw_rig(setup: RealismSetup, camera: Camera, seed: int) -> RigDraw:
    """Steps 1-3 of the module doc for the true ``camera`` (intrinsics, image size, lens): the robot,
    the calibration views and the estimates, draw ``seed``."""
    rz = setup.realism
    cell, target = setup.cell, setup.target
    T_world_block = target.pose_world(cell)
    K_true, W, H = camera.K, camera.width, camera.height
    moves = setup.robot_model is not None and not setup.robot_model.exact
    move_rng = _rng(seed, STREAM_MOVES)
    if not moves and not rz.estimates:  # the robot goes where it is told, the method is told the truth
        return RigDraw(rz, cell, camera, None, K_true, camera.distortion, cell.mount, T_world_block, T_world_block,
                       move_rng, DrawReport(exact=True), exact=True)
    calibration = hand_eye = None
    robot = None
    if moves:
        hw = ROBOTS[rz.robot]
        robot = Robot.build(nominal_arm(hw, cell), setup.robot_model, cell.q_seed, _rng(seed, STREAM_ROBOT))
    mount_est, T_block_est, K_est, lens_est = cell.mount, T_world_block, K_true, camera.distortion
    if rz.estimates:
        corners_block = target.corners_block()
        corners_world = corners_block @ T_world_block[:3, :3].T + T_world_block[:3, 3]
        noise = _rng(seed, STREAM_CORNERS)
        eye_cal = EyeInHand(robot, cell.mount, cell.mount, camera) if robot is not None else None
        flanges, dets = [], []
        for F in calibration_flange_poses(cell, target):
            cam = eye_cal.move_flange(F, move_rng) if eye_cal is not None else camera_from_pose(F @ cell.mount, camera)
            idx, uv = _observe(cam, corners_world, setup.corner_noise_px, noise)
            flanges.append(F)
            dets.append(BoardDetection(idx, uv, corners_block[idx]) if len(idx) >= MIN_VIEW_CORNERS else None)
        used = [i for i, d in enumerate(dets) if d is not None]
        if rz.on("calibration"):
            fixed = calibrate_camera(dets, (W, H), fix_distortion=True)
            free = calibrate_camera(dets, (W, H), fix_distortion=False)
            cal = free if distortion_is_needed({"camera": fixed}, {"camera": free}) else fixed
            K_est = cal.K
            lens_est = None if cal.fix_distortion else BrownConrady.from_opencv(cal.dist)
            poses = [pose_matrix(cv2.Rodrigues(r)[0], t) for r, t in zip(cal.rvecs, cal.tvecs)]
            used = list(cal.views)
            calibration = IntrinsicsEstimate(fx_error_px=float(K_est[0, 0] - K_true[0, 0]),
                                             fy_error_px=float(K_est[1, 1] - K_true[1, 1]),
                                             cx_error_px=float(K_est[0, 2] - K_true[0, 2]),
                                             cy_error_px=float(K_est[1, 2] - K_true[1, 2]),
                                             reprojection_rms_px=cal.rms_px, views=len(used),
                                             distortion_estimated=not cal.fix_distortion,
                                             distortion_k1_k2_p1_p2_k3=tuple(cal.dist.tolist()))
        else:
            poses = []
            for i in used:
                ok, rv, tv = cv2.solvePnP(dets[i].object_points, dets[i].image_points, K_true, _opencv_dist(camera),
                                          flags=cv2.SOLVEPNP_ITERATIVE)
                poses.append(pose_matrix(cv2.Rodrigues(rv)[0], tv))
        if rz.on("hand_eye"):
            he = solve_hand_eye([flanges[i] for i in used], poses)
            mount_est, T_block_est = he.T_flange_camera, he.T_base_target
            dp, da = pose_difference(mount_est, cell.mount)
            bp, ba = pose_difference(T_block_est, T_world_block)
            hand_eye = HandEyeEstimate(mount_position_error_m=dp, mount_rotation_error_rad=da,
                                       target_position_error_m=bp, target_rotation_error_rad=ba,
                                       residual_rotation_rms_rad=he.rotation_rms_rad,
                                       residual_translation_rms_m=he.translation_rms_m, views=len(used))
    report = DrawReport(exact=False, calibration=calibration, hand_eye=hand_eye,
                        corner_noise_px=setup.corner_noise_px if rz.estimates else None)
    return RigDraw(rz, cell, camera, robot, K_est, lens_est, mount_est, T_block_est, T_world_block, move_rng, report)


def realise_sample(cfg, rig: StereoRig) -> Acquisition:
    """One acquisition of ``rig`` under a sample configuration's realism (its draw: ``cfg.realism.seed``;
    its camera: ``cfg``'s; the corner noise measured with it)."""
    return realise(RealismSetup.prepare(cfg.realism, cfg), rig, cfg.realism.seed)


def _opencv_dist(cam: Camera) -> np.ndarray:
    return np.zeros(5) if cam.distortion is None else cam.distortion.as_opencv()


def _exact_robot(rz: Realism, cell: Cell) -> Robot:
    """A robot that goes exactly where it is told (robot sources off, the mount still estimated)."""
    hw = ROBOTS[rz.robot]
    return Robot.build(nominal_arm(hw, cell), RobotErrorModel(), cell.q_seed, None)


# -- corner-localisation noise, measured on renders ----------------------------------------
def measure_corner_noise(cfg, target: TargetBlock = TARGET, spp: int = 16, seed: int = 0) -> float:
    """RMS per-axis error (px) of corners located (``detect_charuco``) on rendered images of a ChArUco board
    with the target's square size, seen by ``cfg``'s left camera (its lens, aperture and sensor, line
    jitter included) in a few of the bench's calibration poses (``board_renderer.calibration_poses``),
    against their exact projections through that camera."""
    from platebench.reconstruction.calibration.stereo import detect_charuco  # noqa: PLC0415
    from platebench.scenes.render.board_renderer import BoardRenderer, calibration_poses  # noqa: PLC0415

    scene = cfg.scene.build()
    rig, camera = scene.rig, scene.rig.left
    spec = target.charuco()
    centre = camera.center + camera.R[2] * float(camera.depth(np.zeros((1, 3)))[0])
    picks = [p for p in calibration_poses(rig, spec, target=centre)
             if p.name in ("flat", "tilt+x", "diag++", "roll45")][:CORNER_NOISE_VIEWS]
    br = BoardRenderer(rig, spec, cfg.variant, cfg.sensor, scene.aperture_radius_m,
                       scene.focus_m if scene.aperture_radius_m > 0 else None)
    board = spec.board()
    errs = []
    for i, pose in enumerate(picks):
        br.set_pose(pose)
        img = cfg.sensor.digitize(br.render("left", RenderSettings(spp, seed), i), seed=seed * 101 + i)
        det = detect_charuco(img, board)
        if det is None:
            continue
        errs.append(det.image_points - camera.project(pose.to_world(det.object_points)))
    if not errs:
        raise ValueError("corner noise: no board corners found in the rendered views")
    e = np.concatenate(errs)
    return float(np.sqrt(np.mean(e ** 2)))
