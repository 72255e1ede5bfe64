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

A blob is not always a whole square, and the centroid of a part is not the square's centre:

* **cut by the outline**: the plate's outline (the passive image's plate region, in this camera)
  runs through the square, so its light ends where the plate does; the square's light (the blob
  and the dimmer lit pixels joined to it) then touches the outside of the region along the cut
  (``outline_contact_px``: its pixels within one pixel of it; a whole square keeps the unlit plate
  between its edge and the outline);
* **cut by the threshold**: part of the square is lit at grazing incidence and falls below the
  moment-preserving threshold (the two-level model does not hold across it), so the lit square
  runs on past the blob as dimmer pixels (``dim_px``: pixels of the smoothed image above a
  quarter of the threshold's contrast joined to the blob within ``DIM_RING_PX`` beyond the
  centroid's window, away from other blobs).

``Square.cut`` names either, from the image alone. How well the flags find the centres outside
the paper's bound: docs/findings/design-record.md.
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
CUT_CONTACT_PX = 3  # a square whose light has this many pixels next to the plate region's outside: cut by the outline
DIM_RING_PX = 4  # a square's light is looked for this far beyond the centroid's window (GROW_PX) ...
DIM_LEVEL = 0.25  # ... above this share of the threshold's contrast (background level + 0.25 (t - z0)) ...
DIM_SMOOTH_PX = 1.0  # ... in the image smoothed by a Gaussian of this sigma (pixel noise is not light) ...
DIM_AWAY_PX = 3  # ... and this far from any other blob (its own blur is not this one's light)
DIM_MAX_FRAC = 0.10  # a square whose light runs past its window by this share of its area or more: cut by the threshold


@dataclass(frozen=True)
class Square:
    """One detected square in one image (pixel coordinates)."""

    centroid: np.ndarray  # (2,) intensity-weighted centroid: the matching point
    mask_centroid: np.ndarray  # (2,) centroid of the thresholded blob
    corner_center: np.ndarray  # (2,) intersection of the diagonals of the refined corners (NaN if none)
    corners: np.ndarray  # (4,2) TL, TR, BR, BL, sub-pixel (NaN if the blob is not a quadrilateral)
    bbox: tuple[int, int, int, int]  # u0, v0, u1, v1 inclusive
    area_px: int
    outline_contact_px: int = 0  # blob pixels within 1 px of the outside of the plate region (module doc)
    dim_px: int = 0  # lit pixels below the threshold just beyond the blob (module doc)

    @property
    def cut(self) -> str | None:
        """Why the blob is not a whole square: "outline" (the plate's outline cuts it), "threshold"
        (part of it too dim for the threshold), or None (whole)."""
        if self.outline_contact_px >= CUT_CONTACT_PX:
            return "outline"
        if self.dim_px >= DIM_MAX_FRAC * self.area_px:
            return "threshold"
        return None

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


def _cut_measures(f: np.ndarray, smooth: np.ndarray, labels: np.ndarray, i: int, bbox, region_mask,
                  threshold: float, z0: float) -> tuple[int, int]:
    """(outline contact, dim pixels) of blob ``i`` of ``labels`` (module doc): the square's light is
    the blob and the pixels of ``smooth`` (the image smoothed by ``DIM_SMOOTH_PX``, so that pixel
    noise does not pass for light) above ``DIM_LEVEL`` of the threshold's contrast joined to it
    within ``DIM_RING_PX`` beyond the centroid's window, away from other blobs; contact counts its
    pixels within one pixel of the outside of ``region_mask`` (None: 0), dim those beyond the
    centroid's window."""
    H, W = f.shape
    x, y, w, h = bbox
    pad = GROW_PX + DIM_RING_PX + DIM_AWAY_PX + 1
    u0, v0, u1, v1 = max(x - pad, 0), max(y - pad, 0), min(x + w - 1 + pad, W - 1), min(y + h - 1 + pad, H - 1)
    lab = labels[v0:v1 + 1, u0:u1 + 1]
    blob = lab == i

    def grow(m, r):
        return cv2.dilate(m.astype(np.uint8), np.ones((2 * r + 1,) * 2, np.uint8)) > 0
    near = grow(blob, GROW_PX + DIM_RING_PX) & ~grow((lab > 0) & ~blob, DIM_AWAY_PX)
    lit = blob | (near & (smooth[v0:v1 + 1, u0:u1 + 1] > z0 + DIM_LEVEL * (threshold - z0)))
    _, parts = cv2.connectedComponents(lit.astype(np.uint8), connectivity=8)
    light = np.isin(parts, np.unique(parts[blob]))
    dim = int(np.count_nonzero(light & ~grow(blob, GROW_PX)))
    contact = 0
    if region_mask is not None:
        contact = int(np.count_nonzero(light & grow(~region_mask[v0:v1 + 1, u0:u1 + 1], 1)))
    return contact, dim


def extract_squares(image: np.ndarray, region_mask: np.ndarray | None = None, name: str = "image") -> SquareDetection:
    """Detect the projected squares, keeping those whose centroid lies in ``region_mask``; each
    says whether it is cut (``Square.cut``: by the outline of ``region_mask``, or by the threshold)."""
    f = check_image(image, name)
    t = tsai_moment_threshold(f, mask=None)
    binary = (f > t.threshold).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    H, W = f.shape
    f32 = f.astype(np.float32)
    smooth = cv2.GaussianBlur(f32, (0, 0), DIM_SMOOTH_PX)
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
        contact, dim = _cut_measures(f, smooth, labels, i, (x, y, w, h), region_mask, t.threshold, t.z0)
        squares.append(Square(centroid, mask_centroid, _diagonal_intersection(corners), corners,
                              (int(x), int(y), int(x + w - 1), int(y + h - 1)), int(area), contact, dim))
    if not squares:
        raise ReconstructionError(f"{name}: no squares found inside the plate region")
    return SquareDetection(tuple(squares), t.threshold, t.z0, outside)
