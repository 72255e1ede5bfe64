"""Plate boundary extraction in a passive image (paper V-C): threshold, region, contour, corners.

Steps, each a function: Tsai's moment-preserving threshold -> the largest bright
connected region, grown by hysteresis down to ``HYSTERESIS`` of the Tsai contrast (a bent
plate's steep parts, lit at a grazing angle, fall below Tsai's threshold while still far
above the dark background; without this the boundary shrinks by millimetres at 150 degrees)
and holes filled -> contour following (OpenCV's border following,
``findContours`` with every contour pixel kept) -> the outline's corners
(``approxPolyDP`` to a quadrilateral). Pixel coordinates follow OpenCV: pixel
centres at integers, u right, v down.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from platebench.errors import UserValueError
from platebench.reconstruction.paper.threshold import tsai_moment_threshold

HYSTERESIS = 0.1  # low threshold = z0 + HYSTERESIS (z1 - z0)


class ReconstructionError(UserValueError):
    """The images do not allow the requested reconstruction step (message says which and why)."""


class PlateAtBorderError(ReconstructionError):
    """The plate's region runs into the image border: part of it may lie outside the image, so its
    outline is not the plate's (a sensing loop can move the cameras back and take the view again)."""


@dataclass(frozen=True)
class PlateRegion:
    """The plate as seen in one passive image."""

    mask: np.ndarray  # (H,W) bool
    contour: np.ndarray  # (N,2) float pixel coordinates, outline of the mask (contour following)
    corners: np.ndarray  # (4,2) approximate corners, ordered TL, TR, BR, BL (image orientation)
    threshold: float  # low (hysteresis) threshold used for the region and its edges, image units
    tsai_threshold: float  # Tsai's moment-preserving threshold, image units
    background_level: float  # Tsai's z0
    plate_level: float  # Tsai's z1


def check_image(image: np.ndarray, name: str) -> np.ndarray:
    """Validate a camera image: 2-D, not blank, not saturated. Returns float64."""
    return validated_image(image, name).astype(np.float64)


def validated_image(image: np.ndarray, name: str) -> np.ndarray:
    """``check_image``'s checks, returning the image as it is (no float copy)."""
    img = np.asarray(image)
    if img.ndim != 2:
        raise ReconstructionError(f"{name}: expected a grey image, got shape {img.shape}")
    if np.issubdtype(img.dtype, np.integer):
        full = np.iinfo(img.dtype).max
        saturated = np.count_nonzero(img >= full) / img.size
        if saturated > 0.5:
            raise ReconstructionError(f"{name}: image is saturated ({saturated * 100:.0f} % of pixels at {full})")
    lo, hi = float(img.min()), float(img.max())
    if hi - lo <= 0:
        raise ReconstructionError(f"{name}: image is blank (every pixel = {hi:g})")
    return img


def order_corners(pts: np.ndarray) -> np.ndarray:
    """Order 4 points as top-left, top-right, bottom-right, bottom-left (image axes)."""
    pts = np.asarray(pts, float).reshape(4, 2)
    c = pts.mean(axis=0)
    ang = np.arctan2(pts[:, 1] - c[1], pts[:, 0] - c[0])
    pts = pts[np.argsort(ang)]  # from -pi: TL, TR, BR, BL for a roughly axis-aligned quad
    start = np.argmin(pts.sum(axis=1))
    return np.roll(pts, -start, axis=0)


@dataclass(frozen=True)
class PlateMask:
    """The plate's region in one passive image, before any corner is looked for.

    ``contour``: (N,2) float pixel coordinates of the region's outer border pixels (OpenCV
    border following, every pixel kept, in OpenCV's order); thresholds in image units."""

    mask: np.ndarray  # (H,W) bool, holes filled
    contour: np.ndarray  # (N,2) float
    threshold: float  # low (hysteresis) threshold
    tsai_threshold: float
    background_level: float  # Tsai's z0
    plate_level: float  # Tsai's z1


def plate_mask(image: np.ndarray, name: str = "image") -> PlateMask:
    """The bright plate region on the dark background: Tsai threshold, largest region, hysteresis
    growth down to ``HYSTERESIS`` of the contrast, holes filled. Refuses a region touching the border."""
    f = validated_image(image, name)
    if f.dtype.kind not in "ui":
        f = f.astype(np.float64)
    t = tsai_moment_threshold(f)
    binary = (f > t.threshold).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    if n < 2:
        raise ReconstructionError(f"{name}: no plate found (nothing above the threshold {t.threshold:.3g})")
    biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    if stats[biggest, cv2.CC_STAT_AREA] < 100:
        raise ReconstructionError(f"{name}: no plate found (largest bright region is "
                                  f"{stats[biggest, cv2.CC_STAT_AREA]} px)")
    low = t.z0 + HYSTERESIS * (t.z1 - t.z0)
    _, low_labels = cv2.connectedComponents((f > low).astype(np.uint8), connectivity=8)
    seed = np.zeros(int(low_labels.max()) + 1, np.uint8)  # the low-threshold regions the plate's region touches
    seed[low_labels[labels == biggest]] = 1
    seed[0] = 0
    region = seed[low_labels]
    contours, _ = cv2.findContours(region, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    outer = max(contours, key=cv2.contourArea)
    filled = np.zeros_like(region)
    cv2.drawContours(filled, [outer], -1, 1, thickness=cv2.FILLED)
    touches = (filled[0].any() or filled[-1].any() or filled[:, 0].any() or filled[:, -1].any())
    if touches:
        raise PlateAtBorderError(f"{name}: the plate touches the image border (move the cameras back)")
    return PlateMask(filled.astype(bool), outer[:, 0, :].astype(float), float(low), t.threshold, t.z0, t.z1)


def quadrilateral_corners(region: PlateMask) -> np.ndarray | None:
    """The outline's four corners (TL, TR, BR, BL) by ``approxPolyDP``, or None when the outline
    is not a quadrilateral at any of the tried tolerances (1 to 8 % of the perimeter)."""
    outer = region.contour.astype(np.int32).reshape(-1, 1, 2)
    peri = cv2.arcLength(outer, True)
    for frac in (0.01, 0.02, 0.03, 0.05, 0.08):
        a = cv2.approxPolyDP(outer, frac * peri, True)
        if len(a) == 4:
            return order_corners(a[:, 0, :])
    return None


def extract_plate_region(image: np.ndarray, name: str = "image") -> PlateRegion:
    """Find the plate (the bright region on the dark background) in a passive image, with the four
    corners the paper's boundary stereo needs (``plate_mask`` alone for any outline)."""
    m = plate_mask(image, name)
    corners = quadrilateral_corners(m)
    if corners is None:
        raise ReconstructionError(f"{name}: plate outline is not a quadrilateral (corners not found)")
    return PlateRegion(m.mask, m.contour, corners, m.threshold, m.tsai_threshold, m.background_level,
                       m.plate_level)
