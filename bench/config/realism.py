"""Realism presets: which error sources of a real rig are on, and how large (``ideal``, ``1995``, ``modern``).

A ``Realism`` composes the camera hardware (``bench.config.hardware_camera.CAMERA_HARDWARE``: sensor,
lens, digitiser; "ideal" keeps the bench's ideal camera), the robot that carries the camera
(``bench.config.hardware_robot.ROBOTS``), how the stereo pair is taken (one camera moved between the
two views, the paper's set-up, or a rigid two-camera head) and the set of error SOURCES that are on.
Each source can be turned on or off alone and scaled (1 = as sourced), so that an error budget can run
each source alone, all together and all but one:

=====================  ==========================================================================
distortion             the lens's Brown-Conrady distortion (scale: its coefficients)
pixel_aspect           non-square pixels, fy != fx (scale: of fy / fx - 1)
defocus                the thin lens at its f-number (scale: of the aperture radius)
line_jitter            the analogue grabber's per-row shift (scale: of its std)
noise                  the camera's shot and read noise, its bit depth kept (scale: of the noise std)
robot_repeatability    each move of the robot lands with a new random joint error (datasheet RP)
robot_accuracy         the robot's real kinematics differ from its controller's (absolute accuracy)
hand_eye               the camera's mount on the flange and the target's pose are estimated from
                       target views at noisy robot poses (Park-Martin), not known
calibration            the camera's intrinsics are estimated from the same target views
                       (``cv2.calibrateCamera``), not known
=====================  ==========================================================================

With a source off, its part is exact: the oracle. ``ideal`` has every source off and no robot: it
renders the commanded rig itself and reproduces the bench's noise-free figures exactly. ``seed`` is
the draw: the robot's kinematic errors, every move's error, the calibration views' corner noise.

The parameters behind each source live with their sources' citations: ``hardware_robot`` (robots,
cell), ``presets`` (cameras). Nothing here is tuned to a result.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from platebench.errors import UserValueError

__all__ = ["SOURCES", "Realism", "REALISM_PRESETS", "realism_preset", "RealismError"]


class RealismError(UserValueError):
    """A realism preset, source or scale that does not exist or is out of range."""


CAMERA_SOURCES = ("distortion", "pixel_aspect", "defocus", "line_jitter", "noise")  # hardware_camera's defects
SOURCES: dict[str, str] = {
    "distortion": "lens distortion (Brown-Conrady), undistorted by the calibration the method is told",
    "pixel_aspect": "non-square pixels of the digitiser (fy != fx)",
    "defocus": "defocus of the lens at its f-number",
    "line_jitter": "frame grabber line jitter (a per-row horizontal shift)",
    "noise": "camera shot and read noise",
    "robot_repeatability": "robot repeatability (a new joint error every move)",
    "robot_accuracy": "robot absolute accuracy (real kinematics differ from the controller's)",
    "hand_eye": "hand/eye mount and target pose estimated from target views (Park-Martin)",
    "calibration": "camera intrinsics estimated from the target views (calibrateCamera)",
}
ROBOT_SOURCES = ("robot_repeatability", "robot_accuracy")
MAX_SCALE = 100.0


@dataclass(frozen=True)
class Realism:
    """One error model of the rig (see the module doc). ``sources``: the sources that are on;
    ``scales``: ``{source: factor}`` for sources not at their sourced magnitude; ``seed``: the draw."""

    name: str = "ideal"
    camera: str = "ideal"
    robot: str | None = None
    rigid_head: bool = False
    sources: tuple = ()
    scales: dict = field(default_factory=dict)
    seed: int = 0

    def __post_init__(self):
        bad = [s for s in self.sources if s not in SOURCES]
        if bad:
            raise RealismError(f"realism source {bad[0]!r} is not known: allowed {', '.join(SOURCES)}")
        object.__setattr__(self, "sources", tuple(s for s in SOURCES if s in self.sources))
        for s, f in self.scales.items():
            if s not in SOURCES:
                raise RealismError(f"realism scale of {s!r}: not a source; allowed {', '.join(SOURCES)}")
            if isinstance(f, bool) or not isinstance(f, (int, float)) or not math.isfinite(f) or not 0 <= f <= MAX_SCALE:
                raise RealismError(f"realism scale of {s} = {f!r} is out of range: allowed 0 to {MAX_SCALE:g}")
        object.__setattr__(self, "scales", {s: float(self.scales[s]) for s in SOURCES if s in self.scales})
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2 ** 31:
            raise RealismError(f"realism seed = {self.seed!r} is out of range: allowed an integer 0 to 2^31-1")
        if self.robot is None and any(s in self.sources for s in ROBOT_SOURCES + ("hand_eye",)):
            raise RealismError(f"realism {self.name!r}: robot and hand/eye sources need a robot")

    # -- queries --------------------------------------------------------------------
    def on(self, source: str) -> bool:
        """True when ``source`` is on (and not scaled to zero)."""
        return source in self.sources and self.scale(source) > 0

    def scale(self, source: str) -> float:
        return self.scales.get(source, 1.0)

    @property
    def moves_camera(self) -> bool:
        """True when the rendered cameras are not the commanded ones (a robot or an estimated mount)."""
        return self.robot is not None and any(self.on(s) for s in ROBOT_SOURCES + ("hand_eye",))

    @property
    def estimates(self) -> bool:
        """True when anything the method is told is an estimate (mount, target pose, intrinsics)."""
        return self.on("hand_eye") or self.on("calibration")

    @property
    def is_ideal(self) -> bool:
        """No source on: the commanded rig is rendered and the method is told the truth."""
        return not any(self.on(s) for s in SOURCES)

    # -- variants (an error budget) ---------------------------------------------------
    def with_sources(self, sources, label: str | None = None) -> "Realism":
        """This preset with exactly ``sources`` on (any of SOURCES)."""
        return replace(self, sources=tuple(sources), name=label or self.name)

    def only(self, source: str) -> "Realism":
        return self.with_sources([source], f"{self.name}: {source} only")

    def without(self, source: str) -> "Realism":
        return self.with_sources([s for s in self.sources if s != source], f"{self.name}: all but {source}")

    def scaled(self, source: str, factor: float) -> "Realism":
        return replace(self, scales={**self.scales, source: factor})

    def with_seed(self, seed: int) -> "Realism":
        return replace(self, seed=int(seed))


REALISM_PRESETS: dict[str, Realism] = {
    # Every source off: the commanded rig, the true calibration, a noise-free camera.
    "ideal": Realism(),
    # The paper's rig (section V-A): the PULNiX TM-540, its lens and grabber (hardware_camera "1995") moved by a
    # PUMA 560 between the left and the right view; mount and intrinsics estimated from target views.
    "1995": Realism(name="1995", camera="1995", robot="puma560", rigid_head=False, sources=tuple(SOURCES)),
    # A current rig: a modern camera (hardware_camera "modern") on a rigid two-camera head carried by a modern arm; the head's
    # stereo geometry is fixed, so robot errors move the whole pair but not one view against the other.
    "modern": Realism(name="modern", camera="modern", robot="modern", rigid_head=True, sources=tuple(SOURCES)),
}


def realism_preset(name: str) -> Realism:
    """The preset ``name`` (one-line RealismError naming the allowed ones otherwise)."""
    if name not in REALISM_PRESETS:
        raise RealismError(f"--realism = {name!r} is not known: choose one of {', '.join(REALISM_PRESETS)}")
    return REALISM_PRESETS[name]
