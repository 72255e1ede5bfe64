"""Two-view ground truth derived from a sample's per-camera maps: both disparity maps, the
non-occlusion masks and the rectification figures of Middlebury's ``calib.txt``.

Conventions (docs/architecture.md, "Stereo"): conventional stereo (both cameras share R, the right camera is the left
one moved by the baseline B along the left camera's +x), OpenCV intrinsics, pixel centres at
integers, z-depth in metres. Middlebury's disparity convention: a pixel at column u of one view
matches column u - d (left view) or u + d (right view) of the other, with

    d = u_left - u_right = f B / Z - doffs,      doffs = cx_right - cx_left  (px),

so that Z = f B / (d + doffs) recovers the depth. Both views share the same z-depth of a point
(same R, offset along x). Unknown disparity is +inf (Middlebury's PFM convention).

Non-occlusion (Middlebury's ``mask0nocc``): a left plate pixel is non-occluded when its true
surface point is seen by the right camera too. The test is a left/right consistency check of the
ground truth: the point is projected into the right image and its own disparity d0 compared with
the right view's true disparity d1 interpolated there (bilinear over the plate pixels among the
four neighbours). When something nearer than the point covers it in the right view, d1 exceeds
d0; the point counts as occluded when d1 > d0 + ``OCCLUSION_DISPARITY_PX``, or when it projects
outside the right image. A projection that falls among no right plate pixel (a sliver at the
right silhouette) counts as seen: nothing of the plate lies in front of it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from platebench.scenes.camera import Camera
from platebench.scenes.rig import StereoRig
from platebench.tolerances import tol

__all__ = ["OCCLUSION_DISPARITY_PX", "RectifiedPair", "rectified_pair", "disparity_from_depth",
           "nonoccluded_mask", "vertical_disparity", "nearest_valid_min"]

# A right-view surface this much nearer (in disparity) than the left point hides it. Half a pixel is
# Middlebury's finest error threshold; the occluders of a bent plate are many pixels nearer.
OCCLUSION_DISPARITY_PX = 0.5


@dataclass(frozen=True)
class RectifiedPair:
    """The Middlebury view of a conventional rig: focal length (px, shared), baseline (metres),
    ``doffs`` = cx_right - cx_left (px), principal points, image size."""

    f_px: float
    baseline_m: float
    doffs_px: float
    cx_left: float
    cy_left: float
    cx_right: float
    cy_right: float
    fy_left: float
    fy_right: float
    width: int
    height: int

    @property
    def fb(self) -> float:
        """f B in px * metres: Z = fb / (d + doffs)."""
        return self.f_px * self.baseline_m


def rectified_pair(rig: StereoRig) -> RectifiedPair:
    """The pair's Middlebury parameters; refuses a rig whose cameras differ in fx, skew or size (one
    disparity then does not describe a match along a row)."""
    L, R = rig.left, rig.right
    if abs(L.K[0, 0] - R.K[0, 0]) > tol.pixel * max(1.0, L.K[0, 0]) or abs(L.K[0, 1]) > tol.pixel \
            or abs(R.K[0, 1]) > tol.pixel or (L.width, L.height) != (R.width, R.height):
        raise ValueError("stereo rig: the left and right cameras must share fx, have no skew and the same "
                         "image size for a Middlebury disparity")
    return RectifiedPair(float(L.K[0, 0]), float(rig.baseline_m), float(R.K[0, 2] - L.K[0, 2]),
                         float(L.K[0, 2]), float(L.K[1, 2]), float(R.K[0, 2]), float(R.K[1, 2]),
                         float(L.K[1, 1]), float(R.K[1, 1]), L.width, L.height)


NDISP_MULTIPLE = 16  # Middlebury's ndisp is rounded up to a multiple of this (what OpenCV's matchers take)


def ndisp_for(disparity) -> int:
    """Middlebury's ``ndisp`` of a true disparity map (px, non-finite unknown): a conservative bound on
    the disparity levels, max(d) rounded up plus one, then up to a multiple of ``NDISP_MULTIPLE``; it
    is also the SDK's maxdisp, the clip of the estimates (``disparity_metrics.middlebury_metrics``)."""
    d = np.asarray(disparity, np.float64)
    known = d[np.isfinite(d)]
    vmax = math.ceil(known.max()) if known.size else 0
    return NDISP_MULTIPLE * math.ceil((max(vmax, 0) + 1) / NDISP_MULTIPLE)


def disparity_from_depth(depth_m, pair: RectifiedPair) -> np.ndarray:
    """(H, W) float64 disparity f B / Z - doffs (px) of a z-depth map (metres); +inf where the depth is
    unknown (non-finite or <= 0). The same formula serves both views (they share z-depth)."""
    z = np.asarray(depth_m, np.float64)
    ok = np.isfinite(z) & (z > 0)
    out = np.full(z.shape, np.inf)
    out[ok] = pair.fb / z[ok] - pair.doffs_px
    return out


def nearest_valid_min(img: np.ndarray, valid: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Smallest ``img`` value among the ``valid`` pixels at floor/ceil of each (N, 2) pixel coordinate
    (one row or column when the coordinate is a whole number); NaN where none is valid or uv is outside."""
    H, W = img.shape
    uv = np.asarray(uv, float).reshape(-1, 2)
    out = np.full(len(uv), np.inf)
    inside = np.all(np.isfinite(uv), axis=1)
    u, v = np.where(inside, uv[:, 0], -10.0), np.where(inside, uv[:, 1], -10.0)
    for uu in (np.floor(u), np.ceil(u)):
        for vv in (np.floor(v), np.ceil(v)):
            ok = (uu >= 0) & (uu < W) & (vv >= 0) & (vv < H)
            ui, vi = uu[ok].astype(int), vv[ok].astype(int)
            val = np.where(valid[vi, ui], img[vi, ui], np.inf)
            out[ok] = np.minimum(out[ok], val)
    out[~np.isfinite(out)] = np.nan
    return out


def nonoccluded_mask(points_left, mask_left, disparity_left, right: Camera, disparity_right, mask_right,
                     threshold_px: float = OCCLUSION_DISPARITY_PX) -> np.ndarray:
    """(H, W) bool: left plate pixels whose true surface point the right camera sees (module doc).

    Args:
        points_left: (H, W, 3) world points of the left view (metres), NaN off the plate.
        mask_left: (H, W) bool plate mask of the left view.
        disparity_left: (H, W) true left disparity (px), +inf unknown.
        right: the right camera.
        disparity_right: (H, W) true right disparity (px), +inf unknown.
        mask_right: (H, W) bool plate mask of the right view.
    """
    mask_left = np.asarray(mask_left, bool)
    mask_right = np.asarray(mask_right, bool)
    d0 = np.asarray(disparity_left, np.float64)
    d1 = np.asarray(disparity_right, np.float64)
    known = mask_left & np.isfinite(d0) & np.all(np.isfinite(points_left), axis=-1)
    vv, uu = np.nonzero(known)
    P = np.asarray(points_left, np.float64)[vv, uu]
    uv_r = right.project(P)
    in_view = right.in_image(uv_r)
    d1_at = nearest_valid_min(d1, mask_right & np.isfinite(d1), uv_r)
    hidden = np.isfinite(d1_at) & (d1_at > d0[vv, uu] + threshold_px)
    out = np.zeros(mask_left.shape, bool)
    out[vv, uu] = in_view & ~hidden
    return out


def vertical_disparity(disparity_left, pair: RectifiedPair) -> np.ndarray:
    """|v_right - v_left| (px) of every left pixel with a known disparity, from the rig alone.

    A point seen at row v of the left view at depth Z = f B / (d + doffs) has camera y = (v - cy_l) Z /
    fy_l (shared by both views), hence row fy_r y / Z + cy_r in the right view. Zero for a rig whose
    cameras share fy and cy (every sample of the bench); Middlebury's dyavg/dymax summarise it.
    """
    d = np.asarray(disparity_left, np.float64)
    vv = np.nonzero(np.isfinite(d))[0].astype(np.float64)
    v_r = pair.fy_right * (vv - pair.cy_left) / pair.fy_left + pair.cy_right
    return np.abs(v_r - vv)
