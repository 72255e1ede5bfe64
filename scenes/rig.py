"""Stereo rigs: the conventional (parallel) geometry the paper assumes, and a pair as really posed.

``StereoRig`` (paper section III): both cameras share R; the right camera's centre is the left
one's moved by the baseline along the left camera's +x axis. Hence ``t_right = t_left - (B, 0, 0)``
and the disparity of a world point is ``d = u_left - u_right = f B / Z``. It is what a method is
told (the commanded geometry) and what the ideal bench renders.

``PosedPair``: two cameras at any poses, e.g. the one camera a robot moved to the left and right
views with its errors (``scenes.robot``). The renderer and the ground-truth caster need only each
camera's own K, R, t, so they render a posed pair exactly as it stands, while a method keeps the
commanded ``StereoRig``.
Units: metres; frames as in ``scenes.camera``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.scenes.camera import Camera, intrinsics, look_at_rotation
from platebench.tolerances import tol

# World -X appears up in the image, so image x (and the baseline) runs along world +Y:
# across the reference plate's bend, as the paper's exploring strategy asks.
DEFAULT_UP = (-1.0, 0.0, 0.0)


class _CameraPair:
    """What any pair of cameras offers: the two by name and the mid-point of their centres."""

    left: Camera
    right: Camera

    @property
    def center(self) -> np.ndarray:
        """Mid-point of the two optical centres, the mid-baseline point (world, metres)."""
        return 0.5 * (self.left.center + self.right.center)

    @property
    def cameras(self) -> dict[str, Camera]:
        return {"left": self.left, "right": self.right}


@dataclass(frozen=True)
class StereoRig(_CameraPair):
    """A conventional stereo pair: ``left``, ``right`` and the baseline in metres."""

    left: Camera
    right: Camera
    baseline_m: float

    def __post_init__(self):
        if not (np.isfinite(self.baseline_m) and self.baseline_m > 0):
            raise ValueError(f"baseline_m = {self.baseline_m} is out of range: allowed > 0")
        if not np.allclose(self.left.R, self.right.R, atol=tol.stereo_pose_m):
            raise ValueError("conventional stereo needs both cameras to share R")
        expected = self.left.t - np.array([self.baseline_m, 0.0, 0.0])
        if not np.allclose(self.right.t, expected, atol=tol.stereo_pose_m):
            raise ValueError("right camera must be the left one moved by the baseline along its +x")

    @classmethod
    def conventional(cls, center, target, baseline_m, f_px, width, height,
                     up=DEFAULT_UP, K=None, distortion=None) -> "StereoRig":
        """Place the rig with its mid-baseline point at ``center`` looking at ``target``.

        The default ``up`` (world -X appears up in the image) puts the image x axis,
        and so the baseline, along world +Y: across the reference plate's bend.
        ``K`` (3x3) replaces the square-pixel, centred ``intrinsics(f_px, ...)`` (e.g. non-square
        pixels); ``distortion`` (``scenes.lens.BrownConrady``) is the lens of both cameras (the
        paper's pair is one camera moved by the robot).
        """
        R = look_at_rotation(center, target, up)
        K = intrinsics(f_px, width, height) if K is None else np.asarray(K, float)
        c = np.asarray(center, float)
        c_left = c - 0.5 * baseline_m * R[0]
        left = Camera(K, R, -R @ c_left, width, height, distortion)
        right = Camera(K, R, left.t - np.array([baseline_m, 0.0, 0.0]), width, height, distortion)
        return cls(left, right, float(baseline_m))

    def disparity(self, depth_m):
        """Disparity in pixels for a z-depth in metres: f B / Z."""
        return self.left.f_px * self.baseline_m / np.asarray(depth_m, float)


@dataclass(frozen=True)
class PosedPair(_CameraPair):
    """Two cameras at arbitrary poses (no parallel constraint): what a robot really took.

    Same read interface as ``StereoRig`` for what renders and ground truth need: ``left``,
    ``right``, ``cameras``, ``center`` and ``baseline_m`` (the distance between the optical centres).
    """

    left: Camera
    right: Camera

    @property
    def baseline_m(self) -> float:
        """Distance between the two optical centres (metres)."""
        return float(np.linalg.norm(self.right.center - self.left.center))

    @classmethod
    def of(cls, rig: "StereoRig | PosedPair") -> "PosedPair":
        """The pair of any rig (a conventional rig as a posed pair)."""
        return cls(rig.left, rig.right)
