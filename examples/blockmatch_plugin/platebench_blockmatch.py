"""An example PlateBench plug-in: OpenCV's block matcher (``cv2.StereoBM``) on the active pair.

A plug-in is one function of a sample's inputs (``MethodInputs``: the four camera images, the
calibration and the projected pattern; never the ground truth) returning one output kind of
``platebench.reconstruction.methods``: ``Disparity``, ``Depth``, ``Points`` or ``Mesh``. PlateBench
scores it against the exact ground truth with the metrics of that kind and puts every figure in
the results table. This module offers two, registered as entry points in ``pyproject.toml``:

* ``block_match``: the left disparity map (scored with Middlebury/ETH3D metrics);
* ``block_match_points``: the same matches triangulated into world points (scored by their
  distance to the true surface, outliers and coverage).

The pair is rectified (both cameras share R; the right one is moved by the baseline along x), so
a match at disparity d lies at depth Z = f B / d. The search range assumes the plate lies within
+-15 % of the depth of the world origin in the left camera (the rig looks at it): a prior on the
scene, not ground truth. The projected square grid gives the block matcher something to match;
the plain passive pair has almost no texture.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

from platebench.reconstruction.methods import Disparity, MethodInputs, Points

BLOCK_SIZE = 11  # odd, >= 5 (StereoBM)
DEPTH_MARGIN = 0.15


def _to_8bit(img: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(img if img.dtype == np.uint8 else (img >> 8).astype(np.uint8))


def _disparity(inputs: MethodInputs) -> tuple[np.ndarray, int]:
    rig = inputs.rig
    fb = rig.left.K[0, 0] * rig.baseline_m
    z0 = float(rig.left.depth(np.zeros((1, 3)))[0])  # depth of the world origin (the plate's centre)
    d_lo = int(math.floor(fb / (z0 * (1 + DEPTH_MARGIN))))
    n_disp = 16 * math.ceil((math.ceil(fb / (z0 * (1 - DEPTH_MARGIN))) - d_lo) / 16)
    left, right = _to_8bit(inputs.images["left_active"]), _to_8bit(inputs.images["right_active"])
    bm = cv2.StereoBM.create(numDisparities=n_disp, blockSize=BLOCK_SIZE)
    bm.setMinDisparity(d_lo)
    bm.setUniquenessRatio(10)
    bm.setTextureThreshold(10)
    raw = bm.compute(left, right)  # int16, 1/16 px; (d_lo - 1) * 16 where nothing matched
    disp = raw.astype(np.float64) / 16.0
    return np.where(raw >= d_lo * 16, disp, np.inf), n_disp


def block_match(inputs: MethodInputs) -> Disparity:
    """OpenCV StereoBM on the projected-grid pair: left disparity (px)."""
    disp, n_disp = _disparity(inputs)
    return Disparity(disp, metrics={"search_range_px": float(n_disp),
                                    "matched_px_count": float(np.isfinite(disp).sum())})


def block_match_points(inputs: MethodInputs) -> Points:
    """OpenCV StereoBM on the projected-grid pair, triangulated: world points (metres)."""
    disp, _ = _disparity(inputs)
    rig = inputs.rig
    K = rig.left.K
    v, u = np.nonzero(np.isfinite(disp))
    z = K[0, 0] * rig.baseline_m / disp[v, u]
    y = (v - K[1, 2]) * z / K[1, 1]
    x = (u - K[0, 2]) * z / K[0, 0]
    cam = np.column_stack([x, y, z])
    world = (cam - rig.left.t) @ rig.left.R  # x_cam = R x_world + t
    return Points(world, metrics={"points_count": float(len(world))})
