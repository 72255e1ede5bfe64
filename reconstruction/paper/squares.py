"""Projected squares in an active image (paper V-C): threshold, blobs, contours, corners, centres.

Each square is found as a bright connected blob (Tsai's moment-preserving threshold),
followed along its contour (OpenCV border following), its four corners located on
the contour (``approxPolyDP``) and refined to sub-pixel (``cornerSubPix``). Three
centres are reported; the **intensity-weighted centroid** over the blob grown by
2 px is the one matched and triangulated: it integrates every pixel's partial
coverage, so it is unbiased to a few hundredths of a pixel, whereas the binary-mask
centroid is quantised by the threshold (a prototype measured ~0.1 mm depth bias from
it) and the corner-diagonal centre inherits corner-detector error on blurred corners.

Each blob is processed inside its own bounding box (no full-image mask per square).
Pixel coordinates: OpenCV, pixel centres at integers.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from platebench.reconstruction.paper.plate_region import (
    ReconstructionError,
    check_image,
    order_corners,
)
from platebench.reconstruction.paper.threshold import tsai_moment_threshold
from platebench.tolerances import tol

GROW_PX = 2
MIN_AREA_PX = 12


@dataclass(frozen=True)
class Square:
    """One detected square in one image (pixel coordinates)."""

    centroid: np.ndarray  # (2,) intensity-weighted centroid: the matching point
    mask_centroid: np.ndarray  # (2,) centroid of the thresholded blob
    corner_center: np.ndarray  # (2,) intersection of the diagonals of the refined corners (NaN if none)
    corners: np.ndarray  # (4,2) TL, TR, BR, BL, sub-pixel (NaN if the blob is not a quadrilateral)
    bbox: tuple[int, int, int, int]  # u0, v0, u1, v1 inclusive
    area_px: int

    @property
    def v_extent(self) -> tuple[float, float]:
        return float(self.bbox[1]), float(self.bbox[3])

    @property
    def u_extent(self) -> tuple[float, float]:
        return float(self.bbox[0]), float(self.bbox[2])


@dataclass(frozen=True)
class SquareDetection:
    """All squares found in one active image, with the threshold used."""

    squares: tuple[Square, ...]
    threshold: float
    background_level: float
    rejected_outside: int  # blobs dropped because they are not inside the plate region


def _diagonal_intersection(c: np.ndarray) -> np.ndarray:
    p, r = c[0], c[2] - c[0]
    q, s = c[1], c[3] - c[1]
    den = r[0] * s[1] - r[1] * s[0]
    if abs(den) < tol.zero_length:  # parallel diagonals (pixel units; any tiny floor works)
        return np.full(2, np.nan)
    t = ((q - p)[0] * s[1] - (q - p)[1] * s[0]) / den
    return p + t * r


def extract_squares(image: np.ndarray, region_mask: np.ndarray | None = None, name: str = "image") -> SquareDetection:
    """Detect the projected squares, keeping those whose centroid lies in ``region_mask``."""
    f = check_image(image, name)
    t = tsai_moment_threshold(f, mask=None)
    binary = (f > t.threshold).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    H, W = f.shape
    f32 = f.astype(np.float32)
    squares, outside = [], 0
    for i in range(1, n):
        x, y, w, h, area = stats[i]
        if area < MIN_AREA_PX:
            continue
        u0, v0 = max(x - GROW_PX - 1, 0), max(y - GROW_PX - 1, 0)
        u1, v1 = min(x + w + GROW_PX, W - 1), min(y + h + GROW_PX, H - 1)
        blob = (labels[v0:v1 + 1, u0:u1 + 1] == i).astype(np.uint8)
        grown = cv2.dilate(blob, np.ones((2 * GROW_PX + 1,) * 2, np.uint8))
        patch = f[v0:v1 + 1, u0:u1 + 1]
        wgt = np.clip(patch - t.z0, 0.0, None) * grown
        vv, uu = np.mgrid[v0:v1 + 1, u0:u1 + 1]
        centroid = np.array([(uu * wgt).sum(), (vv * wgt).sum()]) / wgt.sum()
        mask_centroid = np.array([uu[blob > 0].mean(), vv[blob > 0].mean()])
        if region_mask is not None:
            cu, cv_ = int(round(centroid[0])), int(round(centroid[1]))
            if not region_mask[cv_, cu]:
                outside += 1
                continue
        corners = np.full((4, 2), np.nan)
        contours, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        if contours:
            c = max(contours, key=cv2.contourArea)
            approx = cv2.approxPolyDP(c, 0.1 * cv2.arcLength(c, True) / 4, True)
            if len(approx) == 4:
                pts = order_corners(approx[:, 0, :].astype(np.float32) + np.array([u0, v0], np.float32))
                crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 0.01)
                win = max(2, min(5, int(min(w, h) // 4)))
                corners = cv2.cornerSubPix(f32, pts.reshape(-1, 1, 2).astype(np.float32), (win, win), (-1, -1),
                                           crit).reshape(4, 2).astype(float)
        squares.append(Square(centroid, mask_centroid, _diagonal_intersection(corners), corners,
                              (int(x), int(y), int(x + w - 1), int(y + h - 1)), int(area)))
    if not squares:
        raise ReconstructionError(f"{name}: no squares found inside the plate region")
    return SquareDetection(tuple(squares), t.threshold, t.z0, outside)
