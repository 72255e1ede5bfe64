"""Scoring glue: ground truth and reconstructions, from memory or from files, into ``evaluation``.

``evaluation.score`` takes plain arrays (``SampleTruth``, ``ReconstructionData``); this module is
the one place that assembles them, from a ``RenderedSample`` in memory or from a sample
directory (``bench.io.sample_files``), and from a pipeline ``Reconstruction`` or a
reconstruction directory (``bench.io.recon_files``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from platebench.bench.io.images import DatasetError
from platebench.bench.io.recon_files import load_reconstruction
from platebench.bench.io.sample_files import (
    load_calibration,
    load_ground_truth,
    load_pattern,
    load_true_cameras,
)
from platebench.evaluation.score import (
    ReconstructionData,
    SampleTruth,
    Score,
    score_reconstruction,
)

__all__ = ["truth_from_sample", "truth_from_files", "recon_data", "score_in_memory", "score_files",
           "score_any"]


def _feature_table(pattern) -> tuple[np.ndarray, np.ndarray]:
    """(ids (N,), centres (N, 2) projector px) of a pattern's features."""
    return (np.array([f.id for f in pattern.features], int),
            np.array([f.center for f in pattern.features], float).reshape(-1, 2))


def truth_from_sample(sample) -> SampleTruth:
    """Ground truth of a ``RenderedSample`` in memory."""
    ids, centres = _feature_table(sample.scene.projector.pattern)
    return SampleTruth(sample.plate.mesh, np.asarray(sample.plate.boundary),
                       {c: g.mask for c, g in sample.gt.items()}, {c: g.feature for c, g in sample.gt.items()},
                       sample.scene.rig, sample.scene.projector.camera, ids, centres,
                       {c: v.to_dict() for c, v in sample.visibility.items()})


def truth_from_files(sample_dir: Path) -> tuple[SampleTruth, dict]:
    """Ground truth of a written sample, and its sample.json."""
    gt = load_ground_truth(sample_dir)
    calib = load_calibration(sample_dir)
    ids, centres = _feature_table(load_pattern(sample_dir))
    rig = load_true_cameras(sample_dir) or calib.rig  # the cameras really posed (realism), else calib.json's
    truth = SampleTruth(gt.mesh, gt.boundary, gt.mask, gt.feature, rig, calib.projector_camera, ids, centres,
                        gt.visibility)
    return truth, gt.meta


def recon_data(rec) -> ReconstructionData:
    """A pipeline ``Reconstruction`` as evaluation's ``ReconstructionData``."""
    return ReconstructionData(rec.points, rec.uv_left, rec.uv_right, rec.feature_id, rec.boundary,
                              rec.surface_vertices, rec.false_boundary.to_dict(),
                              rec.cut.points, rec.cut.uv_left, rec.cut.uv_right)


def score_in_memory(sample, rec) -> Score:
    """Score a pipeline ``Reconstruction`` against a ``RenderedSample``'s truth."""
    return score_reconstruction(truth_from_sample(sample), recon_data(rec))


def score_files(sample_dir: Path, recon_dir: Path) -> Score:
    """Score a reconstruction directory against a sample directory (refused if it was made from
    other images: recon.json records the checksums of the images it read)."""
    truth, meta = truth_from_files(sample_dir)
    rec = load_reconstruction(recon_dir)
    want = meta.get("images", {})
    for name, digest in rec.meta.get("input_checksums", {}).items():
        if want.get(name) != digest:
            raise DatasetError(f"{recon_dir} was not made from {sample_dir}: image {name} differs "
                               "(reconstruct this sample first)")
    data = ReconstructionData(rec.points, rec.uv_left, rec.uv_right, rec.feature_id, rec.boundary,
                              None if rec.surface is None else np.asarray(rec.surface.vertices),
                              rec.meta.get("false_boundary", {}), rec.cut_points, rec.cut_uv_left, rec.cut_uv_right)
    return score_reconstruction(truth, data)


def score_any(sample, reconstruction) -> Score:
    """``score_in_memory`` or ``score_files``, by what is passed (objects or directories)."""
    if isinstance(sample, (str, Path)) and isinstance(reconstruction, (str, Path)):
        return score_files(Path(sample), Path(reconstruction))
    if not isinstance(sample, (str, Path)) and not isinstance(reconstruction, (str, Path)):
        return score_in_memory(sample, reconstruction)
    raise TypeError("score(sample, reconstruction): pass both in memory (RenderedSample, Reconstruction) "
                    "or both as directories")
