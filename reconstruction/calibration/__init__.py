"""Calibration from images (paper IV-A): stereo cameras (ChArUco) and the structured light's rays."""
from platebench.reconstruction.calibration.stereo import *  # noqa: F401,F403
from platebench.reconstruction.calibration.stereo import __all__ as _stereo
from platebench.reconstruction.calibration.structured_light import *  # noqa: F401,F403
from platebench.reconstruction.calibration.structured_light import __all__ as _sl

__all__ = [*_stereo, *_sl]
