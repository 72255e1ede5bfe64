"""OpenCV's calibration solvers on one thread, so that the same detections give the same bytes.

``cv2.calibrateCamera`` (and ``cv2.stereoCalibrate``) run parts of their Levenberg-Marquardt steps on
OpenCV's thread pool, and the partial sums meet in whatever order the threads finish: twelve
calibrations of one set of detections, on 2 threads, returned twelve lenses that differ in their last
bits. Under a real rig those bits reach every told pose, and a sensing loop's decisions (a pixel more
or less on an outline) then differ from run to run. ``opencv_serial`` sets OpenCV's thread count to
1 for the solver and puts back the caller's count after it (nothing else changes; the solve is a few
milliseconds).
"""
from __future__ import annotations

from contextlib import contextmanager

import cv2

__all__ = ["opencv_serial"]


@contextmanager
def opencv_serial():
    """Run the enclosed OpenCV calls on one thread; the previous thread count is restored after."""
    before = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(before)
