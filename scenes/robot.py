"""The robot that carries the camera: commanded poses and the poses it really reaches (plain numpy).

Frames and units. Metres and radians. A pose is a 4x4 homogeneous matrix ``T_a_b`` that maps
coordinates in frame b to frame a (``x_a = T_a_b @ x_b``). Frames: ``world`` (the bench's world:
+Z up, the plate or target at the origin), ``base`` (the robot's base, standard Denavit-Hartenberg
frame 0; ``T_world_base`` is the cell layout, known exactly), ``flange`` (DH frame 6, the wrist),
``camera`` (OpenCV camera frame; a ``scenes.camera.Camera`` holds ``T_camera_world = [R | t]``).

The arm is a 6-R serial chain in standard DH parameters, each link
``A_i = Rz(theta_i + theta0_i) Tz(d_i) Tx(a_i) Rx(alpha_i) Ry(beta_i)`` (``beta`` is Hayati's
extra rotation, zero in the nominal model, so that a misalignment of parallel axes, which DH
cannot express, can be drawn as an error).

What a commanded pose becomes (``Robot.execute``):

* the controller solves the inverse kinematics of its NOMINAL model for the commanded flange pose
  (``SerialArm.ik``, a Levenberg-Marquardt solve from the cell's seed configuration);
* repeatability: each move lands the joints at ``q + dq`` with ``dq ~ N(0, sigma_q^2)`` per joint,
  new on every move (encoder quantisation, servo error, backlash);
* absolute accuracy: the real arm's parameters differ from the nominal ones by a fixed, seeded draw
  (``KinematicErrors``: link lengths and offsets, twists, joint zero offsets), so the same joint angles
  place the flange elsewhere, by an error that changes smoothly with the configuration.

The executed flange pose is the REAL arm's forward kinematics at ``q + dq``. Nobody downstream sees
it: the loop knows the commanded pose only. ``EyeInHand`` adds the camera on the flange: the true
mount and the believed (estimated) mount, and turns "put the camera here" into a flange command
through the believed mount, returning the camera that is really there.

Repeatability is quoted in datasheets as ISO 9283's RP = mean + 3 std of the distances of the
attained positions from their barycentre; ``iso9283_repeatability`` computes it, and
``joint_sigma_for_repeatability`` turns a datasheet RP into the joint-angle sigma that gives it at a
stated configuration (the model's one free number, taken from the source).
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from platebench.scenes.camera import Camera
from platebench.scenes.rig import PosedPair, StereoRig
from platebench.tolerances import tol

__all__ = ["DHLink", "SerialArm", "KinematicErrors", "RobotErrorModel", "Robot", "EyeInHand",
           "pose_matrix", "invert_pose", "camera_pose", "camera_from_pose", "pose_difference",
           "iso9283_repeatability", "joint_sigma_for_repeatability", "kinematic_error_sigmas", "IKError"]

N_JOINTS = 6


class IKError(ValueError):
    """A commanded pose the arm cannot reach (or not near its seed configuration)."""


# -- poses ---------------------------------------------------------------------------------
def pose_matrix(R, p) -> np.ndarray:
    """4x4 pose from a 3x3 rotation and a translation (metres)."""
    T = np.eye(4)
    T[:3, :3] = np.asarray(R, float)
    T[:3, 3] = np.ravel(np.asarray(p, float))
    return T


def invert_pose(T) -> np.ndarray:
    """Inverse of a rigid 4x4 pose."""
    T = np.asarray(T, float)
    R = T[:3, :3]
    return pose_matrix(R.T, -R.T @ T[:3, 3])


def camera_pose(cam: Camera) -> np.ndarray:
    """``T_world_camera`` of a camera (its centre and axes in the world)."""
    return pose_matrix(cam.R.T, cam.center)


def camera_from_pose(T_world_camera, template: Camera) -> Camera:
    """``template`` (its intrinsics, image size and lens) placed at ``T_world_camera``."""
    T = invert_pose(T_world_camera)
    return replace(template, R=T[:3, :3], t=T[:3, 3])


def pose_difference(T_a, T_b) -> tuple[float, float]:
    """(position distance in metres, rotation angle in radians) between two poses."""
    dp = float(np.linalg.norm(np.asarray(T_a)[:3, 3] - np.asarray(T_b)[:3, 3]))
    dR = np.asarray(T_a)[:3, :3] @ np.asarray(T_b)[:3, :3].T
    return dp, float(Rotation.from_matrix(dR).magnitude())


def _rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_y(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


# -- the arm -------------------------------------------------------------------------------
@dataclass(frozen=True)
class DHLink:
    """One revolute link in standard DH parameters (metres, radians) plus Hayati's ``beta``."""

    a: float
    alpha: float
    d: float
    theta0: float = 0.0  # joint zero offset: the link turns by q + theta0
    beta: float = 0.0

    def transform(self, q: float) -> np.ndarray:
        th = q + self.theta0
        T = np.eye(4)
        Rz = _rot_z(th)
        T[:3, :3] = Rz @ _rot_x(self.alpha) @ _rot_y(self.beta)
        T[:3, 3] = np.array([self.a * np.cos(th), self.a * np.sin(th), self.d])
        return T


@dataclass(frozen=True)
class SerialArm:
    """A 6-R arm: its links and where its base stands in the world (``T_world_base``)."""

    links: tuple
    T_world_base: np.ndarray = field(default_factory=lambda: np.eye(4))
    name: str = "arm"

    def __post_init__(self):
        if len(self.links) != N_JOINTS:
            raise ValueError(f"SerialArm needs {N_JOINTS} links, got {len(self.links)}")
        object.__setattr__(self, "T_world_base", np.asarray(self.T_world_base, float))

    def fk(self, q) -> np.ndarray:
        """``T_world_flange`` at joint angles ``q`` (6,) radians."""
        T = self.T_world_base.copy()
        for link, qi in zip(self.links, np.asarray(q, float)):
            T = T @ link.transform(qi)
        return T

    def ik(self, T_world_flange, q_seed, max_error_m: float = tol.ik_position_m) -> np.ndarray:
        """Joint angles that put the flange at ``T_world_flange``, solved from ``q_seed`` (the
        configuration family: elbow, wrist) by Levenberg-Marquardt on the position and rotation
        residuals. Raises IKError when the pose is out of reach (residual above ``max_error_m``)."""
        target = np.asarray(T_world_flange, float)
        Rt = target[:3, :3]

        def residual(q):
            T = self.fk(q)
            dr = Rotation.from_matrix(T[:3, :3] @ Rt.T).as_rotvec()
            return np.concatenate([T[:3, 3] - target[:3, 3], dr])

        sol = least_squares(residual, np.asarray(q_seed, float), method="lm", xtol=tol.ik_solver_eps,
                            ftol=tol.ik_solver_eps, gtol=tol.ik_solver_eps, max_nfev=400)
        err = np.abs(residual(sol.x))
        if not (np.all(err[:3] < max_error_m) and np.all(err[3:] < max_error_m)):
            raise IKError(f"{self.name}: commanded pose out of reach from the seed configuration "
                          f"(residual {np.max(err[:3]) * 1e3:.3g} mm, {np.max(err[3:]) * 1e3:.3g} mrad)")
        return sol.x

    def jacobian(self, q, step: float = tol.fd_step) -> np.ndarray:
        """(6, 6) Jacobian of (flange position, flange rotation vector) in the world by central
        differences (metres and radians per radian)."""
        q = np.asarray(q, float)
        T0 = self.fk(q)
        J = np.zeros((6, N_JOINTS))
        for i in range(N_JOINTS):
            dq = np.zeros(N_JOINTS)
            dq[i] = step
            Tp, Tm = self.fk(q + dq), self.fk(q - dq)
            J[:3, i] = (Tp[:3, 3] - Tm[:3, 3]) / (2 * step)
            J[3:, i] = (Rotation.from_matrix(Tp[:3, :3] @ T0[:3, :3].T).as_rotvec()
                        - Rotation.from_matrix(Tm[:3, :3] @ T0[:3, :3].T).as_rotvec()) / (2 * step)
        return J

    def with_errors(self, errors: "KinematicErrors") -> "SerialArm":
        """The real arm: nominal parameters plus ``errors``."""
        links = tuple(DHLink(lk.a + errors.a[i], lk.alpha + errors.alpha[i], lk.d + errors.d[i],
                             lk.theta0 + errors.theta0[i], lk.beta + errors.beta[i])
                      for i, lk in enumerate(self.links))
        return replace(self, links=links, name=f"{self.name} (real)")


@dataclass(frozen=True)
class KinematicErrors:
    """Deviations of the real arm's parameters from the nominal ones, per joint (6,): lengths
    ``a``, ``d`` (metres), angles ``alpha``, ``theta0``, ``beta`` (radians)."""

    a: np.ndarray
    d: np.ndarray
    alpha: np.ndarray
    theta0: np.ndarray
    beta: np.ndarray

    @classmethod
    def zero(cls) -> "KinematicErrors":
        z = np.zeros(N_JOINTS)
        return cls(z, z, z, z, z)

    @classmethod
    def draw(cls, rng: np.random.Generator, sigma_length_m: float, sigma_angle_rad: float) -> "KinematicErrors":
        """Independent zero-mean normal deviations: every length by ``sigma_length_m``, every angle
        by ``sigma_angle_rad``."""
        def n(s):
            return rng.normal(0.0, s, N_JOINTS) if s > 0 else np.zeros(N_JOINTS)
        return cls(n(sigma_length_m), n(sigma_length_m), n(sigma_angle_rad), n(sigma_angle_rad),
                   n(sigma_angle_rad))


# -- error model and a physical robot ------------------------------------------------------
@dataclass(frozen=True)
class RobotErrorModel:
    """The error terms of one kind of robot (SI units).

    ``joint_sigma_rad``: repeatability, per joint, drawn anew on every move (0: perfect).
    ``sigma_length_m``/``sigma_angle_rad``: the spread of the real arm's kinematic parameters about
    the nominal ones (absolute accuracy), drawn once per robot (0: the nominal model is exact).
    ``repeatability``/``accuracy``: switches, so that each term can be turned off alone.
    """

    joint_sigma_rad: float = 0.0
    sigma_length_m: float = 0.0
    sigma_angle_rad: float = 0.0
    repeatability: bool = True
    accuracy: bool = True

    def __post_init__(self):
        for name in ("joint_sigma_rad", "sigma_length_m", "sigma_angle_rad"):
            v = getattr(self, name)
            if not (np.isfinite(v) and 0.0 <= v <= 0.1):
                raise ValueError(f"{name} = {v!r} is out of range: allowed 0 to 0.1")

    def scaled(self, repeatability_scale: float = 1.0, accuracy_scale: float = 1.0,
               repeatability: bool = True, accuracy: bool = True) -> "RobotErrorModel":
        """The same robot with its repeatability term (``joint_sigma_rad``) and its accuracy terms
        (``sigma_length_m``, ``sigma_angle_rad``) multiplied by the scales, and the switches set."""
        return RobotErrorModel(joint_sigma_rad=self.joint_sigma_rad * repeatability_scale,
                               sigma_length_m=self.sigma_length_m * accuracy_scale,
                               sigma_angle_rad=self.sigma_angle_rad * accuracy_scale,
                               repeatability=repeatability, accuracy=accuracy)

    @property
    def exact(self) -> bool:
        """True when the robot goes exactly where it is told."""
        return not (self.repeatability and self.joint_sigma_rad > 0) and \
            not (self.accuracy and (self.sigma_length_m > 0 or self.sigma_angle_rad > 0))


@dataclass(frozen=True)
class Robot:
    """One physical robot: the nominal arm its controller believes in, its real arm (nominal plus a
    seeded ``KinematicErrors`` draw), its error model and the seed configuration of its IK."""

    nominal: SerialArm
    real: SerialArm
    errors: RobotErrorModel
    q_seed: np.ndarray

    @classmethod
    def build(cls, nominal: SerialArm, errors: RobotErrorModel, q_seed, rng: np.random.Generator | None) -> "Robot":
        """A robot whose real arm is drawn from ``errors`` with ``rng`` (None or accuracy off: the
        nominal arm itself)."""
        if rng is None or not errors.accuracy or (errors.sigma_length_m == 0 and errors.sigma_angle_rad == 0):
            real = nominal
        else:
            real = nominal.with_errors(KinematicErrors.draw(rng, errors.sigma_length_m, errors.sigma_angle_rad))
        return cls(nominal, real, errors, np.asarray(q_seed, float))

    def joints_for(self, T_world_flange) -> np.ndarray:
        """The controller's joint angles for a commanded flange pose (its nominal model)."""
        return self.nominal.ik(T_world_flange, self.q_seed)

    def execute(self, T_world_flange_cmd, rng: np.random.Generator | None) -> np.ndarray:
        """The flange pose the robot really reaches when commanded to ``T_world_flange_cmd``."""
        q = self.joints_for(T_world_flange_cmd)
        if self.errors.repeatability and self.errors.joint_sigma_rad > 0 and rng is not None:
            q = q + rng.normal(0.0, self.errors.joint_sigma_rad, N_JOINTS)
        return self.real.fk(q)


# -- the camera on the flange ----------------------------------------------------------------
@dataclass(frozen=True)
class EyeInHand:
    """A camera on the robot's flange (``camera``: its true intrinsics, image size and lens; its pose is
    ignored): its true mount ``T_flange_camera`` and the mount the loop believes in (an estimate, or
    the truth).

    ``move(wanted)`` commands the flange so that, by the believed mount, the camera would be at
    ``wanted``; it returns the camera the robot really put there. The loop keeps using ``wanted``.
    """

    robot: Robot
    mount_true: np.ndarray
    mount_believed: np.ndarray
    camera: Camera

    def command_for(self, wanted: Camera) -> np.ndarray:
        """The flange command that puts the camera at ``wanted`` by the believed mount."""
        return camera_pose(wanted) @ invert_pose(self.mount_believed)

    def camera_at(self, T_world_flange) -> Camera:
        """The true camera when the flange is really at ``T_world_flange``."""
        return camera_from_pose(np.asarray(T_world_flange) @ self.mount_true, self.camera)

    def move(self, wanted: Camera, rng: np.random.Generator | None) -> Camera:
        """The camera the robot really places when asked for ``wanted`` (a new move: new
        repeatability draw)."""
        return self.camera_at(self.robot.execute(self.command_for(wanted), rng))

    def move_flange(self, T_world_flange_cmd, rng: np.random.Generator | None) -> Camera:
        """The true camera after a flange command (calibration views are commanded as flange poses)."""
        return self.camera_at(self.robot.execute(T_world_flange_cmd, rng))

    def executed_pair(self, rig: StereoRig, rng: np.random.Generator | None, rigid_head: np.ndarray | None = None
                      ) -> PosedPair:
        """The stereo pair the robot really takes for the commanded conventional ``rig``.

        ``rigid_head`` None: ONE camera moved to the left view and then to the right view (two
        moves, the paper's set-up). Otherwise a rigid two-camera head: the true ``T_left_right``
        of the head; one move places the left camera and the right one rides with it."""
        left = self.move(rig.left, rng)
        if rigid_head is None:
            right = self.move(rig.right, rng)
        else:
            right = camera_from_pose(camera_pose(left) @ np.asarray(rigid_head, float), self.camera)
        return PosedPair(left, right)


# -- repeatability as datasheets state it -----------------------------------------------------
def iso9283_repeatability(positions) -> float:
    """ISO 9283 position repeatability RP (metres) of attained positions (N, 3): the mean distance
    from their barycentre plus three standard deviations of those distances."""
    p = np.asarray(positions, float)
    dist = np.linalg.norm(p - p.mean(axis=0), axis=1)
    return float(dist.mean() + 3.0 * dist.std(ddof=1))


def joint_sigma_for_repeatability(arm: SerialArm, q, rp_m: float, draws: int = 200_000, seed: int = 0) -> float:
    """The per-joint angle sigma (radians, equal for every joint) whose first-order effect gives the
    position repeatability ``rp_m`` (ISO 9283 RP) at configuration ``q``. RP scales linearly with the
    sigma, so it is measured once for a unit sigma on ``draws`` seeded samples and scaled."""
    J = arm.jacobian(q)[:3]
    dq = np.random.default_rng(seed).normal(0.0, 1.0, (draws, N_JOINTS))
    return float(rp_m / iso9283_repeatability(dq @ J.T))


_LENGTHS = ("a", "d")
_ANGLES = ("alpha", "theta0", "beta")


def _parameter_jacobians(arm: SerialArm, q, step: float = tol.fd_step) -> tuple[np.ndarray, np.ndarray]:
    """(6, 12) and (6, 18): flange (position, rotation vector) per unit change of every length and every
    angle parameter of ``arm`` at ``q`` (central differences)."""
    T0 = arm.fk(q)
    out = {}
    for group in (_LENGTHS, _ANGLES):
        cols = []
        for i in range(N_JOINTS):
            for name in group:
                poses = []
                for sgn in (1.0, -1.0):
                    links = list(arm.links)
                    links[i] = replace(links[i], **{name: getattr(links[i], name) + sgn * step})
                    poses.append(replace(arm, links=tuple(links)).fk(q))
                Tp, Tm = poses
                col = np.concatenate([(Tp[:3, 3] - Tm[:3, 3]),
                                      Rotation.from_matrix(Tp[:3, :3] @ T0[:3, :3].T).as_rotvec()
                                      - Rotation.from_matrix(Tm[:3, :3] @ T0[:3, :3].T).as_rotvec()]) / (2 * step)
                cols.append(col)
        out[group] = np.column_stack(cols)
    return out[_LENGTHS], out[_ANGLES]


def kinematic_error_sigmas(arm: SerialArm, qs, position_rms_m: float) -> tuple[float, float, float]:
    """(sigma_length_m, sigma_angle_rad, orientation_rms_rad): the spread of independent normal errors of
    every angle parameter (joint zero offsets, twists, Hayati's beta; lengths exact) whose expected RMS
    flange position error over the configurations ``qs`` is ``position_rms_m`` (first order), and the
    RMS orientation error that spread gives (to compare with a published orientation accuracy)."""
    pos_a = rot_a = 0.0
    for q in qs:
        _, JA = _parameter_jacobians(arm, q)
        pos_a += np.sum(JA[:3] ** 2)
        rot_a += np.sum(JA[3:] ** 2)
    n = len(qs)
    s_ang = float(position_rms_m / np.sqrt(pos_a / n)) if position_rms_m > 0 else 0.0
    return 0.0, s_ang, float(s_ang * np.sqrt(rot_a / n))
