"""Calibration from images (paper IV-A): the stereo cameras (ChArUco, ``stereo``), the hand/eye
transform (``hand_eye``) and the undistortion of a calibrated pair's images (``undistort``). The
structured light's rays are calibrated with the paper's own square detection:
``reconstruction.paper.structured_light``."""
from platebench.reconstruction.calibration.stereo import *  # noqa: F401,F403
from platebench.reconstruction.calibration.stereo import __all__ as _stereo

__all__ = [*_stereo]
