"""The structured-light projector: a pinhole with its own K, pose and pattern.

Two Mitsuba light models sit behind this one type (``kind``):

* ``"pinhole"`` (default): Mitsuba's ``projector`` emitter. Same pixel-to-direction
  mapping as the perspective camera, so its OpenCV K is
  ``[[f, 0, W/2 - 0.5], [0, f, H/2 - 0.5], [0, 0, 1]]`` with pixel centres at
  integers (``W/2`` in Mitsuba's texel-edge coordinates). Proven by test.
* ``"spot"``: Mitsuba's ``spot`` emitter with a texture. The texture spans
  +-cutoff on both axes, so ``fx = W / (2 tan cutoff)``, ``fy = H / (2 tan cutoff)``
  (non-square texels when W != H); the cone clips the texture's corners, and
  the beam falls off linearly between ``beam_width`` and ``cutoff``.
  The 180-degree rotation relative to the camera is absorbed in
  ``scenes.render.mitsuba_convert``. Proven by the same test.

Units: metres, radians; frames as in ``scenes.camera``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.scenes.camera import Camera, intrinsics, look_at_rotation
from platebench.scenes.pattern import Pattern
from platebench.scenes.rig import DEFAULT_UP

PROJECTOR_KINDS = ("pinhole", "spot")


@dataclass(frozen=True)
class Projector:
    """A projector: pinhole ``camera`` model (K, R, t, pattern size) plus its ``pattern``."""

    camera: Camera
    pattern: Pattern
    kind: str = "pinhole"
    cutoff_rad: float | None = None  # spot only

    def __post_init__(self):
        if self.kind not in PROJECTOR_KINDS:
            raise ValueError(f"projector kind = {self.kind!r} is not allowed: choose one of {PROJECTOR_KINDS}")
        if (self.camera.width, self.camera.height) != (self.pattern.width, self.pattern.height):
            raise ValueError("projector camera size must equal the pattern size")
        if self.kind == "spot" and not (self.cutoff_rad and 0 < self.cutoff_rad < np.pi / 2):
            raise ValueError(f"spot cutoff_rad = {self.cutoff_rad} is out of range: allowed (0, pi/2)")

    @classmethod
    def look_at(cls, eye, target, pattern: Pattern, f_px: float | None = None, kind: str = "pinhole",
                cutoff_rad: float | None = None, up=DEFAULT_UP) -> "Projector":
        """Place a projector at ``eye`` aiming its centre ray at ``target``."""
        R = look_at_rotation(eye, target, up)
        t = -R @ np.asarray(eye, float)
        w, h = pattern.width, pattern.height
        if kind == "spot":
            if cutoff_rad is None:
                raise ValueError("a spot projector needs cutoff_rad")
            tc = np.tan(cutoff_rad)
            K = intrinsics(w / (2 * tc), w, h, fy_px=h / (2 * tc))
        else:
            if f_px is None:
                raise ValueError("a pinhole projector needs f_px")
            K = intrinsics(f_px, w, h)
        return cls(Camera(K, R, t, w, h), pattern, kind, cutoff_rad)

    def with_pattern(self, pattern: Pattern) -> "Projector":
        if (pattern.width, pattern.height) != (self.pattern.width, self.pattern.height):
            raise ValueError("a replacement pattern must keep the projector's size")
        return Projector(self.camera, pattern, self.kind, self.cutoff_rad)
