"""Scoring glue: ground truth and reconstructions, from memory or from files, into ``evaluation``.

``evaluation.score`` takes plain arrays (``SampleTruth``, ``ReconstructionData``); this module is
the one place that assembles them, from a ``RenderedSample`` in memory or from a sample
directory (``bench.io.sample_files``), and from a pipeline ``Reconstruction`` or a
reconstruction directory (``bench.io.recon_files``).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from platebench.bench.io.codecs import decode
from platebench.bench.io.images import DatasetError
from platebench.bench.io.recon_files import load_reconstruction
from platebench.bench.io.sample_files import (
    load_calibration,
    load_ground_truth,
    load_pattern,
    load_true_cameras,
    read_json,
)
from platebench.bench.io.verify import verify_reconstruction
from platebench.evaluation.score import (
    BoundaryTruth,
    ReconstructionData,
    SampleTruth,
    Score,
    score_reconstruction,
)

__all__ = ["truth_from_sample", "truth_from_files", "recon_data", "score_in_memory", "score_files",
           "score_any", "check_made_from"]


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
                       {c: BoundaryTruth.of(v) for c, v in sample.visibility.items()}, sample.gt["left"].points)


def truth_from_files(sample_dir: Path) -> tuple[SampleTruth, dict]:
    """Ground truth of a written sample, and its sample.json. The sample's files are verified first
    (``bench.io.verify.verify_sample``): one changed, swapped or replaced by a link is refused."""
    from platebench.bench.io.verify import sample_checksums, verify_sample  # noqa: PLC0415
    verify_sample(sample_dir, sample_checksums(Path(sample_dir)), then="refusing to score against it")
    gt = load_ground_truth(sample_dir)
    calib = load_calibration(sample_dir)
    ids, centres = _feature_table(load_pattern(sample_dir))
    rig = load_true_cameras(sample_dir) or calib.rig  # the cameras really posed (realism), else calib.json's
    truth = SampleTruth(gt.mesh, gt.boundary, gt.mask, gt.feature, rig, calib.projector_camera, ids, centres,
                        {c: decode(BoundaryTruth, v) for c, v in gt.visibility.items()}, gt.points["left"])
    return truth, gt.meta


def recon_data(rec) -> ReconstructionData:
    """A pipeline ``Reconstruction`` as evaluation's ``ReconstructionData``."""
    return ReconstructionData(rec.points, rec.uv_left, rec.uv_right, rec.feature_id, rec.boundary,
                              rec.surface_vertices, rec.false_boundary,
                              rec.cut.points, rec.cut.uv_left, rec.cut.uv_right, rec.surface_faces)


def score_in_memory(sample, rec) -> Score:
    """Score a pipeline ``Reconstruction`` against a ``RenderedSample``'s truth."""
    return score_reconstruction(truth_from_sample(sample), recon_data(rec))


def check_made_from(sample_dir: Path, recon_dir: Path, recon_meta: dict | None = None,
                    sample_meta: dict | None = None) -> None:
    """Refuse (one-line ``DatasetError``) a reconstruction that was not made from this sample: every image
    checksum its recon.json records (``input_checksums``, written by ``platebench reconstruct``) must be
    the sample.json's checksum of that image. ``recon_meta`` / ``sample_meta``: the recon.json and
    sample.json documents when the caller has read them (read from the directories otherwise; a
    reconstruction without recon.json records nothing to compare). Every reader that scores a
    reconstruction against a sample (``score_files``, ``platebench compare``) checks the pair here."""
    if recon_meta is None:
        path = Path(recon_dir) / "recon.json"
        recon_meta = read_json(path) if path.is_file() else {}
    recorded = recon_meta.get("input_checksums") or {}
    if not recorded:
        return
    if not isinstance(recorded, dict):
        raise DatasetError(f"{Path(recon_dir) / 'recon.json'}: input_checksums is not a table of image checksums")
    if sample_meta is None:
        sample_meta = read_json(Path(sample_dir) / "sample.json")
    want = sample_meta.get("images") or {}
    for name, digest in sorted(recorded.items()):
        if not isinstance(want, dict) or want.get(name) != digest:
            raise DatasetError(f"{recon_dir} was not made from {sample_dir}: image {name} differs "
                               "(reconstruct this sample first)")


def score_files(sample_dir: Path, recon_dir: Path) -> Score:
    """Score a reconstruction directory against a sample directory (refused if a file of either differs
    from its recorded checksum, or if the reconstruction was made from other images: ``check_made_from``)."""
    truth, meta = truth_from_files(sample_dir)
    verify_reconstruction(Path(recon_dir))
    rec = load_reconstruction(recon_dir)
    check_made_from(sample_dir, recon_dir, rec.meta, meta)
    data = ReconstructionData(rec.points, rec.uv_left, rec.uv_right, rec.feature_id, rec.boundary,
                              None if rec.surface is None else np.asarray(rec.surface.vertices),
                              rec.false_boundary, rec.cut_points, rec.cut_uv_left, rec.cut_uv_right,
                              None if rec.surface is None else np.asarray(rec.surface.faces))
    return score_reconstruction(truth, data)


def score_any(sample, reconstruction) -> Score:
    """``score_in_memory`` or ``score_files``, by what is passed (objects or directories)."""
    if isinstance(sample, (str, Path)) and isinstance(reconstruction, (str, Path)):
        return score_files(Path(sample), Path(reconstruction))
    if not isinstance(sample, (str, Path)) and not isinstance(reconstruction, (str, Path)):
        return score_in_memory(sample, reconstruction)
    raise TypeError("score(sample, reconstruction): pass both in memory (RenderedSample, Reconstruction) "
                    "or both as directories")
