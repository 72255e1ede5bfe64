"""Hand/eye calibration of a camera on a robot's flange (the paper's IV-A, its reference [8]):
``AX = XB`` solved in closed form by Park & Martin (1994).

Data: the flange poses the robot was commanded to, ``T_base_flange_i`` (4x4, metres), and the pose of
a fixed target in the camera at each of them, ``T_camera_target_i`` (from the target's image, e.g.
``cv2.solvePnP`` or ``cv2.calibrateCamera``'s extrinsics). The unknown is the mount
``X = T_flange_camera``. The target does not move, so for views i, j
``F_i X P_i = F_j X P_j``, i.e. ``A X = X B`` with ``A = F_j^-1 F_i`` and ``B = P_j P_i^-1``.

Why this solver. OpenCV's ``calibrateHandEye`` is the library choice, but the pinned
opencv-contrib-python-headless 5.0.0.93 does not expose it to Python (fixed upstream, not released);
pinning a 4.x release would change the OpenCV under every other part of the bench. The paper's own
method (Chen & Zheng 1993, its [8]) needs the camera's optical axis found by moving it along the robot's
x and z axes over a three-grey-level checkerboard and a two-plane calibration: a procedure tied to
that target and robot, not a general solver. Park & Martin's closed form is standard, short, and exact
on noise-free data:

* rotation: with ``alpha_k = log(R_A)``, ``beta_k = log(R_B)`` (rotation vectors), ``alpha_k = R_X
  beta_k``; ``R_X`` is the orthogonal Procrustes solution over all motions (their
  ``(M^T M)^(-1/2) M^T``, computed as ``scipy.spatial.transform.Rotation.align_vectors``);
* translation: ``(R_A - I) t_X = R_X t_B - t_A``, stacked over all motions, least squares.

All pairs of views are used as motions. At least two motions with non-parallel rotation axes are
needed (else the rotation about the common axis is unobservable): ``HandEyeError`` otherwise.
The target's pose in the robot's base frame comes with it: ``T_base_target = F_i X P_i``, averaged
over the views (rotation mean by ``Rotation.mean``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from platebench.errors import UserValueError

__all__ = ["HandEyeError", "HandEyeResult", "solve_hand_eye", "MIN_AXIS_ANGLE_RAD"]

MIN_AXIS_ANGLE_RAD = np.radians(5.0)  # motions whose rotation axes differ less than this are "parallel"
MIN_ROTATION_RAD = np.radians(2.0)  # a motion turning less than this carries no axis


class HandEyeError(UserValueError):
    """The views do not determine the hand/eye transform (too few, or rotations about one axis only)."""


@dataclass(frozen=True)
class HandEyeResult:
    """``T_flange_camera`` (the mount X) and ``T_base_target`` (the fixed target in the robot's base
    frame), 4x4, metres; residuals of ``A X = X B`` over the motions used: RMS rotation (radians) and
    translation (metres); the number of motions."""

    T_flange_camera: np.ndarray
    T_base_target: np.ndarray
    rotation_rms_rad: float
    translation_rms_m: float
    motions: int


def _inv(T):
    R = T[:3, :3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ T[:3, 3]
    return out


def solve_hand_eye(T_base_flange, T_camera_target) -> HandEyeResult:
    """Solve ``A X = X B`` (Park & Martin 1994) from N >= 3 views: ``T_base_flange`` (N, 4, 4) commanded
    flange poses and ``T_camera_target`` (N, 4, 4) target poses seen by the camera."""
    F = np.asarray(T_base_flange, float)
    P = np.asarray(T_camera_target, float)
    if F.ndim != 3 or F.shape[1:] != (4, 4) or P.shape != F.shape:
        raise HandEyeError(f"hand/eye needs matching (N, 4, 4) pose stacks, got {F.shape} and {P.shape}")
    n = len(F)
    if n < 3:
        raise HandEyeError(f"hand/eye needs >= 3 views, got {n}")
    A, B = [], []
    for i in range(n):
        for j in range(i + 1, n):
            A.append(_inv(F[j]) @ F[i])
            B.append(P[j] @ _inv(P[i]))
    alpha = Rotation.from_matrix(np.array([a[:3, :3] for a in A])).as_rotvec()
    beta = Rotation.from_matrix(np.array([b[:3, :3] for b in B])).as_rotvec()
    turning = np.linalg.norm(alpha, axis=1) > MIN_ROTATION_RAD
    axes = alpha[turning] / np.linalg.norm(alpha[turning], axis=1)[:, None]
    if len(axes) < 2 or np.max(np.linalg.norm(np.cross(axes[0], axes), axis=1)) < np.sin(MIN_AXIS_ANGLE_RAD):
        raise HandEyeError("hand/eye views rotate about one axis only (or not at all): the mount's rotation "
                           "about it is not determined; add views turned about another axis")
    R_X, _ = Rotation.align_vectors(alpha[turning], beta[turning])
    R_X = R_X.as_matrix()
    M = np.concatenate([a[:3, :3] - np.eye(3) for a in A])
    rhs = np.concatenate([R_X @ b[:3, 3] - a[:3, 3] for a, b in zip(A, B)])
    t_X = np.linalg.lstsq(M, rhs, rcond=None)[0]
    X = np.eye(4)
    X[:3, :3], X[:3, 3] = R_X, t_X
    rot_res = Rotation.from_matrix(np.array([a[:3, :3] @ R_X @ b[:3, :3].T @ R_X.T for a, b in zip(A, B)]))
    trans_res = M @ t_X - rhs
    targets = np.array([F[i] @ X @ P[i] for i in range(n)])
    T_bt = np.eye(4)
    T_bt[:3, :3] = Rotation.from_matrix(targets[:, :3, :3]).mean().as_matrix()
    T_bt[:3, 3] = targets[:, :3, 3].mean(axis=0)
    return HandEyeResult(X, T_bt, float(np.sqrt(np.mean(rot_res.magnitude() ** 2))),
                         float(np.sqrt(np.mean(trans_res ** 2) * 3)), len(A))
