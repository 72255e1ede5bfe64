"""Structured-light calibration (paper IV-A, last paragraph): the projector lights a
white target plane placed at two or more known depths; at each depth the square
centres (intensity-weighted centroids, ``reconstruction.paper.squares``) are found in both
images, matched to their projector features, triangulated, and each feature's ray is
the least-squares 3D line (SVD) through its centres at the different depths.

Matching criterion (the paper asks for "certain criterion ... to match these
intersection points to their corresponding structured light rays"): with the target
plane roughly perpendicular to the projector and cameras whose image axes are within
45 degrees of roll of the projector's (not mirrored), the pattern's rows stay image
rows and the order is kept. Squares are sorted into horizontal arrays (``group_squares``:
y-overlapping x-neighbours, arrays by y), squares within an array by x; the k-th array
is pattern row k and the j-th square in it is column j. Every feature must be seen at
every depth (else ``CalibrationError`` names the image and the counts).

Frames and units: world frame (+Z up), metres, OpenCV camera frames (x_cam = R x_world
+ t), pixel centres at integer coordinates. ``R, T`` of a stereo pair map the left
camera frame to the right one: ``x_right = R @ x_left + T``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.reconstruction.calibration.stereo import (
    CalibrationError,
    StereoCalibration,
)
from platebench.reconstruction.paper.false_boundary import FeatureRays
from platebench.reconstruction.paper.square_matching import group_squares
from platebench.reconstruction.paper.squares import extract_squares
from platebench.scenes.pattern import Pattern
from platebench.scenes.rig import StereoRig

__all__ = ["PlaneObservation", "StructuredLightCalibration", "label_squares", "fit_line", "nearest_point_to_lines", "calibrate_structured_light"]


@dataclass(frozen=True)
class PlaneObservation:
    """Square centres of one target depth: pixels in both images and triangulated world points,
    one row per pattern feature (in the pattern's feature order)."""

    uv_left: np.ndarray
    uv_right: np.ndarray
    points: np.ndarray
    plane_normal: np.ndarray
    plane_offset_m: float
    flatness_rms_m: float


@dataclass(frozen=True)
class StructuredLightCalibration:
    """Fitted feature rays and how well the data fit them."""

    rays: FeatureRays
    residual_rms_m: np.ndarray  # (F,) RMS distance of each ray's centres to its fitted line (0 for 2 depths)
    planes: tuple[PlaneObservation, ...]
    projector_center: np.ndarray  # least-squares common point of the rays (world, metres)
    center_miss_m: np.ndarray  # (F,) distance of each ray to that point


def label_squares(squares, pattern: Pattern, name: str = "image") -> np.ndarray:
    """(F,2) centroid of each pattern feature's square, in the pattern's feature order.

    The criterion of the module docstring: arrays sorted by y are pattern rows, squares
    sorted by x are columns; every row must hold exactly the pattern's columns.
    """
    rows = 1 + max(f.row for f in pattern.features)
    cols = 1 + max(f.col for f in pattern.features)
    groups = group_squares(squares)
    counts = [len(g) for g in groups]
    if len(groups) != rows or any(c != cols for c in counts):
        raise CalibrationError(f"{name}: expected {rows} rows of {cols} squares on the target plane, found rows "
                               f"of {counts} squares: move the target so that every square lands on it")
    grid = np.array([[squares[k].centroid for k in g] for g in groups])  # (rows, cols, 2)
    return np.array([grid[f.row, f.col] for f in pattern.features], float)


def fit_line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Least-squares 3D line through (K,3) points (SVD): centroid, unit direction, RMS distance."""
    p = np.asarray(points, float)
    c = p.mean(axis=0)
    _, s, Vt = np.linalg.svd(p - c, full_matrices=False)
    d = Vt[0]
    r = p - c
    dist = r - np.outer(r @ d, d)
    return c, d, float(np.sqrt(np.mean(np.sum(dist ** 2, axis=1))))


def _fit_plane(p: np.ndarray) -> tuple[np.ndarray, float, float]:
    c = p.mean(axis=0)
    n = np.linalg.svd(p - c)[2][2]
    if n[2] < 0:
        n = -n
    res = (p - c) @ n
    return n, float(n @ c), float(np.sqrt(np.mean(res ** 2)))


def nearest_point_to_lines(origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Least-squares point closest to a set of 3D lines."""
    A = np.zeros((3, 3))
    b = np.zeros(3)
    for o, d in zip(origins, directions):
        P = np.eye(3) - np.outer(d, d)
        A += P
        b += P @ o
    return np.linalg.solve(A, b)


def calibrate_structured_light(active_pairs, stereo, pattern: Pattern) -> StructuredLightCalibration:
    """Feature rays from active image pairs of a white target plane at >= 2 depths.

    ``active_pairs``: [(left_image, right_image), ...], one pair per depth. ``stereo``: a
    ``StereoCalibration`` (estimated; centres triangulated with its registration's model)
    or a ``StereoRig`` (true). Rays are in the world frame of that calibration; each ray's
    origin is its point nearest the rays' common point
    (the estimated projector centre) and its direction points away from the projector.
    """
    if len(active_pairs) < 2:
        raise CalibrationError(f"structured-light calibration needs the target at >= 2 depths, "
                               f"got {len(active_pairs)}")
    if not pattern.features:
        raise CalibrationError("the pattern has no numbered features to calibrate")
    if isinstance(stereo, StereoRig):
        stereo = StereoCalibration.from_rig(stereo)
    planes = []
    for k, (left, right) in enumerate(active_pairs):
        uv = {}
        for cam, img in (("left", left), ("right", right)):
            name = f"target {k} {cam}"
            uv[cam] = label_squares(extract_squares(np.asarray(img), None, name).squares, pattern, name)
        pts = stereo.triangulate(uv["left"], uv["right"])
        n, off, flat = _fit_plane(pts)
        planes.append(PlaneObservation(uv["left"], uv["right"], pts, n, off, flat))
    P = np.stack([p.points for p in planes], axis=1)  # (F, depths, 3)
    cents, dirs, res = [], [], []
    for pts in P:
        c, d, r = fit_line(pts)
        cents.append(c)
        dirs.append(d)
        res.append(r)
    cents, dirs = np.array(cents), np.array(dirs)
    C = nearest_point_to_lines(cents, dirs)
    t = np.einsum("ij,ij->i", C - cents, dirs)
    origins = cents + dirs * t[:, None]
    # Point away from the projector: toward the centres seen on the targets.
    sign = np.sign(np.einsum("ij,ij->i", cents - origins, dirs))
    sign[sign == 0] = 1.0
    dirs = dirs * sign[:, None]
    miss = np.linalg.norm(origins - C, axis=1)
    ids = np.array([f.id for f in pattern.features], int)
    return StructuredLightCalibration(FeatureRays(origins, dirs, ids), np.array(res), tuple(planes), C, miss)
