"""Numerical tolerances, defined once (cf. trimesh's ``constants.tol``).

Geometry is in metres, angles in radians. Each tolerance says what it guards; code imports
``tol`` and names the field instead of writing a bare literal. Relative tolerances are
multiplied by the scale of the quantity they compare (a length, a pixel count, ...).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["tol", "Tolerances", "is_rotation", "ceil_count", "floor_count"]


@dataclass(frozen=True)
class Tolerances:
    """Named tolerances; the module-level ``tol`` is the one instance."""

    rotation: float = 1e-9          # |R R^T - I| entries and det(R) = +1 of a proper rotation
    zero_length: float = 1e-12      # a vector or segment this short (m or px) has no direction
    unit_norm: float = 1e-9         # |v| below this: "no direction" for a (near) unit vector, or a length
                                    # below this fraction of its scale (a ruling, a baseline) is none
    parallel: float = 1e-12         # |d . n| below this: a ray parallel to a plane (or a line to an edge)
    relative: float = 1e-12         # relative slack for comparing derived floats to their exact value
    step_count: float = 1e-9        # ceil(x - step_count): a count of steps not raised by rounding
    angle_rad: float = 1e-9         # slack of an angle compared with a limit it may equal (radians)
    pixel: float = 1e-9             # pixel-coordinate equality (principal point, K entries)
    disparity_file_px: float = 1e-3  # a sample's disp0GT.pfm (float32) and its float32 depth map's disparity agree
    stereo_pose_m: float = 1e-12    # both cameras of a conventional rig share R, t differs by B only
    benchmark_block_frac: float = 2e-3  # a benchmark image rendered on another variant: each block mean
                                    # (bench.benchmark.verify.BLOCKS) within this fraction of the full scale
                                    # of the recorded one (0.5 DN of 255: edge pixels that differ by up to
                                    # 0.05 of full scale between cuda and llvm, a few hundred in a block)
    rebuilt_px: float = 1e-6        # K entries (px) of a rig re-created from sample.json against calib.json's
    rebuilt_pose: float = 1e-9      # R entries and t (m) of a re-created rig against calib.json's
    fit_converged: float = 1e-9     # fixed-point iterations (corner intersections) stop here (px)
    fit_moving_px: float = 1e-2     # a fixed point still moving this much (px) when the iterations end is none
    plane_fit_converged: float = 1e-13  # the L1 boundary plane's iterations stop when its normal turns less
                                        # (rad) and its offset moves less (fraction of the boundary's size)
    subpixel_eps_px: float = 1e-5   # OpenCV cornerSubPix stops when a corner moves less (px)
    solver_eps: float = 1e-12       # OpenCV's iterative calibration stops when its error changes less
    ik_position_m: float = 1e-9     # a robot's inverse kinematics must put the flange this close (m, and rad)
    ik_solver_eps: float = 1e-15    # its Levenberg-Marquardt steps stop when they change x, f or g less
    fd_step: float = 1e-7           # central-difference step of a Jacobian (m for lengths, rad for angles)
    inside_outline: float = 1e-6    # a grid node this close to the outline (fraction of the grid step) is inside
    sup_refine: float = 1e-4        # a boundary distance's supremum is refined to this fraction of the spacing
    tiny: float = 1e-30             # floor of a denominator that may be zero (a degenerate triangle, no noise)
    occlusion_slack_m: float = 1e-5  # a boundary point is occluded only by surface > 10 um in front of it
    flat_height_m: float = 1e-5     # a fitted height field this flat (over the plate) has no bend
    lens_inverse_residual: float = 1e-12  # the ground truth's inverse distortion (normalised units): a larger
                                          # residual after its Newton steps is an error, never a silent map
    rank_tie_pct: float = 1e-9      # two methods' primary figures (mean bad-2mm, percent) this close are tied
                                    # on the leaderboard (the tie-breakers decide)
    plate_window_px: float = 4.0    # ground truth casts the plate's projected vertex box widened by this (px):
                                    # a lens bends a triangle's short edges by far less

tol = Tolerances()


def is_rotation(R, atol: float = tol.rotation) -> bool:
    """True if ``R`` is a proper 3x3 rotation: R R^T = I and det(R) = +1 within ``atol``."""
    R = np.asarray(R, dtype=float)
    return (R.shape == (3, 3) and bool(np.all(np.isfinite(R))) and np.allclose(R @ R.T, np.eye(3), atol=atol)
            and abs(np.linalg.det(R) - 1.0) <= 10 * atol + 1e-15)


def ceil_count(x: float) -> int:
    """ceil(x) for a count of steps, not raised by a rounding error of ``tol.step_count``."""
    return int(np.ceil(x - tol.step_count))


def floor_count(x: float) -> int:
    """floor(x) for a count of steps, not lowered by a rounding error of ``tol.step_count``."""
    return int(np.floor(x + tol.step_count))
