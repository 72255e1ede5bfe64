"""In-memory scoring: a RenderedSample's truth and a Reconstruction, without writing files."""
from __future__ import annotations

import numpy as np

from evaluation.score import ReconstructionData, SampleTruth, score_reconstruction


def truth_from_sample(sample) -> SampleTruth:
    """Ground truth of a rendered sample as evaluation's SampleTruth."""
    pattern = sample.scene.projector.pattern
    return SampleTruth(sample.plate.mesh, np.asarray(sample.plate.boundary),
                       {c: g.mask for c, g in sample.gt.items()}, {c: g.feature for c, g in sample.gt.items()},
                       sample.scene.rig, sample.scene.projector.camera,
                       np.array([f.id for f in pattern.features]),
                       np.array([f.center for f in pattern.features], float).reshape(-1, 2),
                       {c: v.to_dict() for c, v in sample.visibility.items()})


def recon_data(rec) -> ReconstructionData:
    """A pipeline Reconstruction as evaluation's ReconstructionData."""
    return ReconstructionData(rec.points, rec.uv_left, rec.uv_right, rec.feature_id, rec.boundary,
                              rec.surface_vertices, rec.false_boundary.to_dict())


def score_in_memory(sample, rec) -> dict:
    return score_reconstruction(truth_from_sample(sample), recon_data(rec))
