"""The matched 3D boundary of a passive stereo pair, whichever method matched it."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class BoundaryStereo:
    """The matched 3D boundary, a closed polygon. Corner method: TL -> top -> TR -> right -> BR -> bottom
    -> BL -> left; contour-rows: the left image's region border in OpenCV's order."""

    points: np.ndarray  # (N,3) world, metres, first point not repeated
    image_points_left: np.ndarray  # (N,2) left-image pixels of each 3D point
    disparity: np.ndarray  # (N,)
    source: np.ndarray  # (N,) str: corner / side / top-bottom (corners); row / fill (contour-rows)
    corner_row_mismatch_px: np.ndarray  # (4,) |v_left - v_right| of the matched corners; (0,) for contour-rows
    method: str = "corners"  # "corners": the paper's quadrilateral stereo; "contour-rows": outline_stereo
