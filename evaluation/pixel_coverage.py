"""``coverage_frac``, the one meaning of coverage in every table, plot and file of the bench.

coverage_frac = (plate pixels of the left view with an estimate) / (plate pixels of the left view),
a fraction 0..1. The plate pixels are the ground truth's left plate mask (``gt/left_mask.png``,
(H, W) bool). What "with an estimate" means depends on the kind of output, and each kind has its
function here:

* a map (disparity or depth, left view, (H, W)): the pixel holds a valid value
  (``coverage_of_map``);
* a point cloud ((N, 3) world, metres): at least one point projects into the pixel through the
  true left camera (``coverage_of_points``: nearest pixel, OpenCV's pixel centres at whole numbers);
* a surface mesh (world, metres; the paper's ``surface.ply``, a plug-in's mesh): the pixel's true
  ray, from the left camera centre through the ground truth's world point of that pixel
  (``gt/left_points.exr``), hits the mesh (``coverage_of_mesh``; a trimesh ray cast, Embree where
  installed).

The surface-area coverage of ``evaluation.surface_metrics`` (the share of the true plate's area
within a lateral radius of the estimate) is a different figure, named ``surface_coverage_frac``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import trimesh  # annotations only: importing trimesh takes a second

__all__ = ["PixelCoverage", "coverage_of_map", "coverage_of_points", "coverage_of_mesh"]


@dataclass(frozen=True)
class PixelCoverage:
    """Plate pixels of the left view (``plate_px``) and those with an estimate (``estimated_px``)."""

    plate_px: int
    estimated_px: int

    @property
    def coverage_frac(self) -> float:
        """estimated_px / plate_px, 0..1 (NaN without plate pixels)."""
        return self.estimated_px / self.plate_px if self.plate_px else math.nan


def _mask(mask) -> np.ndarray:
    m = np.asarray(mask, bool)
    if m.ndim != 2:
        raise ValueError(f"plate mask: expected an (H, W) bool map, got shape {m.shape}")
    return m


def coverage_of_map(valid, mask) -> PixelCoverage:
    """Coverage of a left-view map: ``valid`` (H, W) bool, the pixels holding an estimate."""
    m = _mask(mask)
    v = np.asarray(valid, bool)
    if v.shape != m.shape:
        raise ValueError(f"valid map of shape {v.shape} against a plate mask of shape {m.shape}")
    return PixelCoverage(int(m.sum()), int(np.count_nonzero(v & m)))


def coverage_of_points(points_m, camera, mask) -> PixelCoverage:
    """Coverage of world points (N, 3), metres: plate pixels into which at least one point projects
    through ``camera`` (the true left camera; ``scenes.camera.Camera``), rounded to the nearest pixel
    (``evaluation.protocol.depth_from_points``)."""
    from platebench.evaluation.protocol import depth_from_points  # noqa: PLC0415
    m = _mask(mask)
    return coverage_of_map(np.isfinite(depth_from_points(points_m, camera, m.shape)), m)


def coverage_of_mesh(mesh: trimesh.Trimesh | None, eye_m, points_left_m, mask) -> PixelCoverage:
    """Coverage of a surface mesh (world frame, metres): plate pixels whose true ray hits it
    (``evaluation.protocol.mesh_hits``: the ray of a plate pixel starts at ``eye_m``, the left camera
    centre, and passes through its true world point, ``points_left_m`` (H, W, 3)). A plate pixel
    without a finite true point counts as not covered; ``mesh`` None or without faces: nothing covered."""
    from platebench.evaluation.protocol import mesh_hits  # noqa: PLC0415
    m = _mask(mask)
    pts = np.asarray(points_left_m, np.float64)
    if pts.shape != (*m.shape, 3):
        raise ValueError(f"true points of shape {pts.shape} against a plate mask of shape {m.shape}")
    v, _, _ = mesh_hits(mesh, eye_m, pts, m)
    return PixelCoverage(int(m.sum()), len(v))
