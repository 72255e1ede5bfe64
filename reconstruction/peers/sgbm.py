"""Peer method: OpenCV semi-global block matching (``cv2.StereoSGBM``) on the passive pair.

The pair is already rectified (conventional geometry, ``d = u_left - u_right = f B / Z``).
The disparity search range comes from a depth range: ``minDisparity = floor(f B / Z_max)``,
``numDisparities`` = the span up to ``ceil(f B / Z_min)`` rounded up to a multiple of 16.
By default the depth range is +-``depth_margin`` (15 %) around the depth of the world
origin in the left camera (the rig looks at the plate there): a prior on the scene, not
ground truth. Smoothness penalties are the usual ``P1 = 8 cn bs^2``, ``P2 = 32 cn bs^2``
(OpenCV's defaults are P1 = P2 = 0, i.e. no smoothness at all). OpenCV's output is int16
in 1/16 px with ``(minDisparity - 1) * 16`` for "no match"; here it becomes float px with
NaN where there is none.

On a texture-free plate SGBM has nothing to match but Monte Carlo noise and the plate's
outline: the paper's motivation for structured light (section I).
Pure function of the images and the calibration.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

import cv2
import numpy as np

from platebench.reconstruction.methods import Disparity, MethodInputs, register_method
from platebench.reconstruction.peers.graycode import DenseResult, as_disparity, dense_result
from platebench.scenes.rig import StereoRig

__all__ = ["disparity_range", "default_depth_range", "sgbm", "sgbm_active", "sgbm_passive",
           "BLOCK_SIZE", "MIN_IMAGE_PX"]

BLOCK_SIZE = 5  # StereoSGBM's matched block, px (odd)
# the smallest image the registered SGBM methods accept, px: numDisparities is at least 16, plus one block
MIN_IMAGE_PX = 16 + BLOCK_SIZE


def default_depth_range(rig: StereoRig, depth_margin: float = 0.15) -> tuple[float, float]:
    """(Z_min, Z_max) in metres: +-``depth_margin`` around the world origin's depth in the left camera."""
    z0 = float(rig.left.depth(np.zeros((1, 3)))[0])
    if not z0 > 0:
        raise ValueError("the world origin is behind the left camera: pass depth_range_m explicitly")
    if not 0 < depth_margin < 1:
        raise ValueError(f"depth_margin = {depth_margin} is out of range: allowed (0, 1)")
    return z0 * (1 - depth_margin), z0 * (1 + depth_margin)


def disparity_range(rig: StereoRig, depth_range_m: tuple[float, float]) -> tuple[int, int]:
    """(minDisparity, numDisparities) covering depths Z_min..Z_max (metres)."""
    z_min, z_max = (float(z) for z in depth_range_m)
    if not (0 < z_min < z_max):
        raise ValueError(f"depth_range_m = {depth_range_m} is out of range: need 0 < Z_min < Z_max")
    fb = rig.left.f_px * rig.baseline_m
    d_lo = int(math.floor(fb / z_max))
    d_hi = int(math.ceil(fb / z_min))
    num = int(math.ceil(max(d_hi - d_lo, 1) / 16.0) * 16)
    return d_lo, num


def _to_8bit(img) -> np.ndarray:
    a = np.asarray(img)
    if a.dtype == np.uint8:
        return np.ascontiguousarray(a)
    if a.dtype == np.uint16:
        return np.ascontiguousarray((a >> 8).astype(np.uint8))
    raise TypeError(f"SGBM needs 8- or 16-bit camera images, got {a.dtype} (float images are not camera output)")


def sgbm(left, right, rig: StereoRig, depth_range_m: tuple[float, float] | None = None,
         block_size: int = BLOCK_SIZE, uniqueness_ratio: int = 10, speckle_window: int = 100, speckle_range: int = 2,
         disp12_max_diff: int = 1, mode: int = cv2.STEREO_SGBM_MODE_SGBM) -> DenseResult:
    """SGBM on the passive left/right images -> left disparity (float px, NaN where none)."""
    t0 = time.perf_counter()
    L, R = _to_8bit(left), _to_8bit(right)
    if L.shape != R.shape or L.ndim != 2:
        raise ValueError(f"left/right must be two (H, W) images of one size, got {L.shape} and {R.shape}")
    if block_size < 1 or block_size % 2 == 0:
        raise ValueError(f"block_size = {block_size} is out of range: allowed an odd number >= 1")
    rng = depth_range_m if depth_range_m is not None else default_depth_range(rig)
    d_min, n_disp = disparity_range(rig, rng)
    cn = 1
    matcher = cv2.StereoSGBM.create(minDisparity=d_min, numDisparities=n_disp, blockSize=block_size,
                                    P1=8 * cn * block_size ** 2, P2=32 * cn * block_size ** 2,
                                    disp12MaxDiff=disp12_max_diff, uniquenessRatio=uniqueness_ratio,
                                    speckleWindowSize=speckle_window, speckleRange=speckle_range, mode=mode)
    raw = matcher.compute(L, R)
    t_match = time.perf_counter() - t0
    d = raw.astype(np.float64) / 16.0
    d[raw < d_min * 16] = np.nan
    notes = (f"StereoSGBM minDisparity {d_min}, numDisparities {n_disp} (depth {rng[0]:.4f}-{rng[1]:.4f} m), "
             f"blockSize {block_size}, P1 {8 * cn * block_size ** 2}, P2 {32 * cn * block_size ** 2}",)
    res = dense_result("sgbm", d, rig, 1, {"match_s": t_match}, notes)
    return replace(res, timings={"match_s": t_match, "total_s": time.perf_counter() - t0})


# ----------------------------------------------------------------------------- registered methods
@register_method("sgbm", "OpenCV StereoSGBM on the active pair (the projected grid; sgbm-passive: the passive pair)",
                 "disparity", ("left_active", "right_active"), min_image_px=MIN_IMAGE_PX, default=True)
def sgbm_active(inputs: MethodInputs) -> Disparity:
    """SGBM on the active pair: the projected grid gives it texture inside the plate."""
    return as_disparity(sgbm(inputs.images["left_active"], inputs.images["right_active"], inputs.rig,
                             depth_range_m=inputs.depth_range_m))


@register_method("sgbm-passive", "OpenCV StereoSGBM on the passive pair (nothing to match inside a plain plate)",
                 "disparity", ("left_passive", "right_passive"), min_image_px=MIN_IMAGE_PX)
def sgbm_passive(inputs: MethodInputs) -> Disparity:
    """SGBM on the passive pair."""
    return as_disparity(sgbm(inputs.images["left_passive"], inputs.images["right_passive"], inputs.rig,
                             depth_range_m=inputs.depth_range_m))
