"""The robots that carry the camera, and the cell they stand in. Every number says where it comes from.

Two robots (``ROBOTS``):

* ``"puma560"``: the Unimation PUMA 560 of the paper (section V-A).
* ``"modern"``: a current six-axis industrial arm, with the error figures of an ABB IRB 1600 measured
  to ISO 9283 by Slamani, Nubiola & Bonev (2012).

A robot's datasheet gives its errors as Cartesian figures; the model (``scenes.robot``) needs them as
joint and kinematic-parameter spreads. ``robot_error_model`` converts them, at the cell's
configurations, and nothing else: the conversion reproduces the stated figures (tested), it is never
tuned to any result of the bench.

What could not be sourced is said so beside the value (``UNSOURCED``). The PUMA's absolute accuracy
is taken from the one measurement of an uncalibrated PUMA that could be read for this build: Driels &
Pathre (1994) calibrated "a six degree of freedom PUMA robot" with a vision-based automatic theodolite
and checked it against a coordinate measuring machine: "an accuracy of 14 mm prior to calibration"
(abstract). The abstract names neither the statistic (RMS, mean or maximum) nor the PUMA's model; the
bench takes 14 mm as the RMS position error over the cell's configurations, as it takes the ABB arm's
published figure. Were it a maximum, the RMS would be smaller; were it a mean, somewhat larger: the
``robot_accuracy`` magnitude axis of a sweep (and ``study --realism-scale``) shows what another value does. Other
candidates (Whitney, Lozinski & Rourke 1986; Veitschegger & Wu 1988; Mooring, Roth & Driels 1991)
could not be read.

The cell (``CELL``): where the robot stands, how the camera is mounted and the hand/eye calibration
views. These are layout choices (a plausible bench top, not measurements) and carry no error: the
truth of the simulation. Units: metres and radians.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from platebench.scenes.robot import DHLink, RobotErrorModel, SerialArm, pose_matrix
from platebench.scenes.robot import kinematic_error_sigmas, joint_sigma_for_repeatability

__all__ = ["RobotHardware", "ROBOTS", "Cell", "CELL", "TargetBlock", "TARGET", "robot_error_model", "nominal_arm"]

_PI = np.pi

# PUMA 560 in standard DH parameters (a, alpha, d) as in Corke's Robotics Toolbox model mdl_puma560,
# after P. I. Corke & B. Armstrong-Helouvry, "A search for consensus among model parameters reported for
# the PUMA 560 robot", Proc. IEEE ICRA 1994, pp. 1608-1613: a2 = 431.8 mm, a3 = 20.3 mm,
# d3 = 150.05 mm, d4 = 431.8 mm; twists pi/2, 0, -pi/2, pi/2, -pi/2, 0.
PUMA560_LINKS = (
    DHLink(a=0.0, alpha=_PI / 2, d=0.0),
    DHLink(a=0.4318, alpha=0.0, d=0.0),
    DHLink(a=0.0203, alpha=-_PI / 2, d=0.15005),
    DHLink(a=0.0, alpha=_PI / 2, d=0.4318),
    DHLink(a=0.0, alpha=-_PI / 2, d=0.0),
    DHLink(a=0.0, alpha=0.0, d=0.0),
)


@dataclass(frozen=True)
class RobotHardware:
    """A robot's published error figures (SI units) and its kinematic chain.

    ``repeatability_rp_m``: ISO 9283 position repeatability RP (datasheet). ``accuracy_position_m``:
    absolute position accuracy, taken as the RMS position error of the flange over the cell's
    configurations; the model spreads it over the joint zero offsets and axis twists
    (``scenes.robot.kinematic_error_sigmas``). ``accuracy_orientation_rad`` and
    ``orientation_repeatability_rad`` are published checks of the model, not inputs (None: none
    published): the orientation errors follow from the same joint and parameter spreads."""

    name: str
    links: tuple
    repeatability_rp_m: float
    accuracy_position_m: float
    accuracy_orientation_rad: float | None
    orientation_repeatability_rad: float | None
    description: str


ROBOTS: dict[str, RobotHardware] = {
    "puma560": RobotHardware(
        name="puma560",
        links=PUMA560_LINKS,
        # Unimation's specification of the PUMA 560: repeatability +-0.1 mm (the figure quoted for the
        # 500 series by Unimation and throughout the literature; the datasheet itself was not at hand).
        repeatability_rp_m=0.1e-3,
        # M. R. Driels & U. S. Pathre, "Robot calibration using an automatic theodolite", Int. J. Adv. Manuf.
        # Technol. 9 (1994) 114-125, abstract: a six-axis PUMA, measured against a CMM (0.02 mm), had "an
        # accuracy of 14 mm prior to calibration". Taken as the RMS position error (module doc).
        accuracy_position_m=14e-3,
        accuracy_orientation_rad=None,  # no published orientation accuracy of an uncalibrated PUMA was found
        orientation_repeatability_rad=None,  # no published orientation repeatability of the PUMA 560 was found
        description="Unimation PUMA 560 (the paper's robot): repeatability 0.1 mm (Unimation); absolute "
                    "accuracy 14 mm before calibration (a PUMA measured by Driels & Pathre 1994)",
    ),
    "modern": RobotHardware(
        name="modern",
        # The chain is the PUMA's geometry (so that the cell layout is the same); only the error figures
        # are the modern arm's.
        links=PUMA560_LINKS,
        # ABB IRB 1600, measured: "unidirectional position repeatability better than 37 um" (Slamani,
        # Nubiola & Bonev 2012, Industrial Robot 39(1) 57-68, abstract; ISO 9283 RP).
        repeatability_rp_m=37e-6,
        # Same paper: "linear position accuracy is better than 650 um".
        accuracy_position_m=0.65e-3,
        # Same paper: "rotation accuracy is at worst 2.8 mrad (mainly because of the sixth robot axis)".
        accuracy_orientation_rad=2.8e-3,
        # Same paper: "unidirectional orientation repeatability is at worst 87 urad" (a check, not an input).
        orientation_repeatability_rad=87e-6,
        description="a current industrial arm: ABB IRB 1600 as measured by Slamani, Nubiola & Bonev (2012): "
                    "RP 37 um, accuracy 0.65 mm / 2.8 mrad",
    ),
}


@dataclass(frozen=True)
class Cell:
    """The work cell (layout choices, exact in the simulation).

    ``T_world_base``: the robot's base in the world (the target or plate at the world origin, +Z up).
    ``mount``: the camera's true pose on the flange, ``T_flange_camera``. ``mount_design``: the mount as
    drawn (no misalignment): what the hand/eye calibration views are commanded with before the mount is
    known. ``q_seed``: the IK seed, the configuration family the arm works in. ``calibration_views``:
    the hand/eye views, (tilt from vertical, azimuth, distance to the target centre, roll about the
    optical axis) in degrees and metres, looking at the target. ``target_yaw_rad``: the target block's
    rotation about +Z in the world (the paper measures it as the block's "rotation angle")."""

    T_world_base: np.ndarray
    mount: np.ndarray
    mount_design: np.ndarray
    q_seed: np.ndarray
    calibration_views: tuple
    target_yaw_rad: float


def _mount(misalign_deg) -> np.ndarray:
    # The camera 100 mm beyond the wrist centre along the flange's z axis and 40 mm to the side, its
    # optical axis along flange z, turned by the given small assembly misalignments (x, y, z degrees).
    R = Rotation.from_euler("xyz", misalign_deg, degrees=True).as_matrix()
    return pose_matrix(R, [0.04, 0.0, 0.10])


CELL = Cell(
    # The base 0.60 m behind and 0.15 m beside the target, its shoulder 0.25 m above the table: the wrist
    # works 0.6-0.8 m from the shoulder, well inside the PUMA's 0.86 m reach and away from its singularities.
    T_world_base=pose_matrix(np.eye(3), [-0.60, -0.15, 0.25]),
    mount=_mount([1.5, -0.8, 0.5]),  # as assembled: 1.5, -0.8 and 0.5 degrees off the drawing
    mount_design=_mount([0.0, 0.0, 0.0]),
    q_seed=np.array([0.35, -0.34, -0.03, -_PI, 2.77, 5.06]),  # the IK solution at the measuring pose
    calibration_views=(  # tilt deg, azimuth deg, distance m, roll deg: rotations about several axes (Tsai-Lenz)
        (0.0, 0.0, 0.40, 0.0), (0.0, 0.0, 0.46, 40.0), (20.0, 0.0, 0.42, -20.0), (20.0, 90.0, 0.42, 20.0),
        (20.0, 180.0, 0.42, 0.0), (20.0, 270.0, 0.42, -30.0), (25.0, 45.0, 0.38, 10.0),
        (30.0, 135.0, 0.45, -10.0), (30.0, 225.0, 0.45, 30.0), (30.0, 315.0, 0.45, -40.0),
        (12.0, 60.0, 0.38, 60.0), (12.0, 240.0, 0.38, -60.0),
    ),
    target_yaw_rad=float(np.radians(7.0)),  # a choice: the block's edges not along the image rows
)


@dataclass(frozen=True)
class TargetBlock:
    """The hand/eye target block: a checkerboard of ``squares_x`` x ``squares_y`` squares of ``square_m``
    lying flat at the world origin, turned by the cell's ``target_yaw_rad`` about +Z.

    Block frame (the frame the paper reports its accuracy test in): origin at the board's centre on its
    top face, x along the rows of squares, y across them, z up (toward the camera). The square the
    accuracy test measures is the central one (an odd count of squares puts one there).

    The paper's target (its reference [8]) is a checkerboard with three grey levels; its square size is
    not given in the paper and [8] was not at hand: 1 inch (25.4 mm) squares, 7 x 5 of them (178 x 127 mm,
    inside the 1995 camera's 0.26 x 0.24 m field at 0.40 m), are a choice."""

    squares_x: int = 7
    squares_y: int = 5
    square_m: float = 0.0254

    def corners_block(self) -> np.ndarray:
        """(N, 3) inner corners of the checkerboard in the block frame (metres), row by row."""
        xs = (np.arange(1, self.squares_x) - self.squares_x / 2.0) * self.square_m
        ys = (np.arange(1, self.squares_y) - self.squares_y / 2.0) * self.square_m
        gx, gy = np.meshgrid(xs, ys)
        return np.column_stack([gx.ravel(), gy.ravel(), np.zeros(gx.size)])

    def square_block(self) -> np.ndarray:
        """(4, 3) corners of the measured (central) square in the block frame."""
        h = self.square_m / 2.0
        return np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]])

    def pose_world(self, cell: "Cell") -> np.ndarray:
        """``T_world_block``."""
        return pose_matrix(Rotation.from_euler("z", cell.target_yaw_rad).as_matrix(), [0.0, 0.0, 0.0])

    def center_world(self, cell: "Cell") -> np.ndarray:
        return self.pose_world(cell)[:3, 3].copy()

    def charuco(self):
        """A ChArUco board with this target's squares (for measuring how well its corners are located)."""
        from platebench.scenes.render.board_renderer import BoardSpec  # noqa: PLC0415

        return BoardSpec(squares_x=self.squares_x, squares_y=self.squares_y, square_m=self.square_m,
                         marker_m=0.75 * self.square_m)


TARGET = TargetBlock()


def nominal_arm(hw: RobotHardware, cell: Cell = CELL) -> SerialArm:
    """The arm as its controller knows it, standing where the cell puts it."""
    return SerialArm(hw.links, cell.T_world_base, hw.name)


def robot_error_model(hw: RobotHardware, cell: Cell = CELL, q_work=None, q_sample=None,
                      repeatability: bool = True, accuracy: bool = True,
                      repeatability_scale: float = 1.0, accuracy_scale: float = 1.0) -> RobotErrorModel:
    """The error model of ``hw``: the joint sigma whose ISO 9283 RP at ``q_work`` (default: the cell's
    seed configuration) is the datasheet's, and the kinematic-parameter spread whose expected RMS
    position error over ``q_sample`` (default: ``q_work`` alone) is the published accuracy figure. ``*_scale`` multiplies a term (a magnitude axis); the switches turn one off."""
    arm = nominal_arm(hw, cell)
    q_work = cell.q_seed if q_work is None else np.asarray(q_work, float)
    qs = [q_work] if q_sample is None else [np.asarray(q, float) for q in q_sample]
    sigma_q = joint_sigma_for_repeatability(arm, q_work, hw.repeatability_rp_m)
    s_len, s_ang, _ = kinematic_error_sigmas(arm, qs, hw.accuracy_position_m)
    return RobotErrorModel(joint_sigma_rad=sigma_q, sigma_length_m=s_len, sigma_angle_rad=s_ang).scaled(
        repeatability_scale, accuracy_scale, repeatability, accuracy)
