"""A written sample's ground truth for scoring dense maps, point clouds and meshes
(``evaluation.field_scores.FieldTruth``): read once from the sample's files, both views' maps
turned into disparities and the non-occlusion mask (``evaluation.stereo_truth``); the left
disparity is the sample's own ``gt/disp0GT.pfm`` (float32, the file a user is given), checked
against the depth map's. The coverage is measured through the left camera really posed (``gt/cameras.json`` under a
real rig, else ``calib.json``'s): a cloud's points project through it, a mesh's true rays start at
its centre and pass through ``gt/left_points.exr``.

The plate mesh (``plate.ply``) keeps the layout of ``plates.Plate``: its first faces are the top
surface; with a thickness the bottom twins and the side walls (two faces per outline segment)
follow. ``top_faces`` recovers that split from the face count, the outline's length
(``boundary.npy``) and the thickness in ``sample.json``.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from platebench.bench.files import require_dir
from platebench.bench.io.images import DatasetError
from platebench.bench.io.sample_files import load_calibration, load_ground_truth, load_true_cameras
from platebench.evaluation.field_scores import FieldTruth

__all__ = ["load_field_truth", "top_faces"]


def top_faces(n_faces: int, n_vertices: int, n_boundary: int, thickness_m: float) -> np.ndarray:
    """(F,) bool: the top-surface faces of a ``plates.Plate`` mesh (module doc)."""
    if thickness_m <= 0:
        return np.ones(n_faces, bool)
    n_top = (n_faces - 2 * n_boundary) // 2
    if n_top <= 0 or 2 * n_top + 2 * n_boundary != n_faces or n_vertices % 2:
        raise DatasetError(f"plate.ply: {n_faces} faces and {n_vertices} vertices do not fit a plate of thickness "
                           f"{thickness_m} m with a {n_boundary}-point outline")
    return np.arange(n_faces) < n_top


def load_field_truth(sample_dir: Path) -> FieldTruth:
    """The ground truth every output kind is scored against (left view; world frame, metres). The sample's
    files are verified first (``bench.io.verify.verify_sample``): one changed, swapped or replaced by a
    link is refused (``DatasetError``)."""
    from platebench.bench.io.verify import sample_checksums, verify_sample  # noqa: PLC0415
    sample_dir = require_dir(Path(sample_dir), "sample directory", DatasetError)
    verify_sample(sample_dir, sample_checksums(sample_dir), then="refusing to score against it")
    gt = load_ground_truth(sample_dir)
    rig = load_calibration(sample_dir).rig
    posed = load_true_cameras(sample_dir)  # the cameras really posed (realism): the true rays start there
    thickness = float(gt.meta.get("config", {}).get("plate", {}).get("thickness_m", 0.0) or 0.0)
    top = top_faces(len(gt.mesh.faces), len(gt.mesh.vertices), len(gt.boundary), thickness)
    try:
        return FieldTruth.from_maps(rig, gt.depth["left"], gt.mask["left"], gt.points["left"], gt.depth["right"],
                                    gt.mask["right"], gt.mesh, top, disparity_left=gt.disparity,
                                    true_left=None if posed is None else posed.left)
    except ValueError as e:
        raise DatasetError(f"{sample_dir}: {e}") from None
