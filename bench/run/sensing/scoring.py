"""The sensing loop scored against ground truth (never read by the loop's decisions): the stage-3
reconstruction's accuracy, the merged multi-view result's accuracy, and the final poses' visibility
of the true boundary. Millimetres in the returned dicts, metres in arrays."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree
from trimesh.path.traversal import resample_path

from platebench.bench.run.score import score_in_memory
from platebench.evaluation.boundary_metrics import points_to_polyline_distance
from platebench.evaluation.metrics_row import MetricsRow
from platebench.evaluation.surface_metrics import score_surface
from platebench.reconstruction.strategy.multiview import BoundaryVerdict
from platebench.reconstruction.strategy.surface_model import SurfaceModel
from platebench.scenes.render.ground_truth import combined_visibility

TRIANGULATED_PX = 3.0  # a true boundary point lies on a pose's measured outline within this (left image)
TRUE_BOUNDARY_STEP_M = 0.5e-3  # the true boundary is sampled this finely (by arc length) for the merged scores


def stage3_accuracy(sample, rec) -> dict:
    """The stage-3 reconstruction (the paper's method) scored against ground truth (millimetres)."""
    score = score_in_memory(sample, rec)
    row = MetricsRow.from_score(score)
    return {"depth_rms_mm": row.depth_rms_mm, "points_scored": score.points.count if score.points else 0,
            "boundary_mean_mm": row.boundary_mean_mm, "surface_rms_mm": row.surface_rms_mm,
            "surface_coverage": row.coverage_frac, "paper_bound_met": row.paper_bound_met,
            "goals_met": score.goals.met if score.goals else None}


def merged_accuracy(plate, verdict: BoundaryVerdict, model: SurfaceModel, measured_surface=None) -> dict:
    """The merged multi-view result against ground truth (millimetres): the merged boundary's mean
    (symmetric) distance to the true boundary, its one-way distance, the fraction of the true
    boundary's length within 2 mm of it (the true side sampled uniformly by arc length every
    ``TRUE_BOUNDARY_STEP_M``: the plate's boundary vertices are dense on bends and up to 30 mm
    apart on flat stretches, so a mean over vertices would weigh the bends only); the measured
    surface (``measured_surface``, (S,3): the stage-3 interpolated surface and points, with the
    merged boundary) RMS distance to the true surface and its coverage (true surface within 2 mm of
    it); and the surface model's own RMS (the poses' outline membranes, which the planner uses for
    normals and ray casting: a coarse model, not a measurement)."""
    out = {"boundary_points": int(len(verdict.merged))}
    B = np.asarray(plate.boundary, float)
    if len(verdict.merged):
        est_gt = points_to_polyline_distance(verdict.merged, B)
        dense = resample_path(np.vstack([B, B[:1]]), step=TRUE_BOUNDARY_STEP_M)[:-1]  # closed: drop the repeat
        gt_est = cKDTree(verdict.merged).query(dense)[0]
        out.update(boundary_mean_mm=float(0.5 * (est_gt.mean() + gt_est.mean()) * 1e3),
                   boundary_est_to_gt_mean_mm=float(est_gt.mean() * 1e3),
                   boundary_covered_frac=float(np.mean(gt_est <= 2e-3)))
    parts = [np.asarray(p, float).reshape(-1, 3) for p in (measured_surface, verdict.merged) if p is not None]
    S = np.vstack(parts) if parts else np.zeros((0, 3))
    if len(S):
        s = score_surface(S, plate.mesh, sample_spacing_m=1e-3, coverage_radius_m=2e-3, max_distance_m=1e-3)
        out.update(surface_rms_mm=float(s.dist.rms * 1e3), surface_coverage=float(s.coverage_frac),
                   surface_points=int(len(S)))
    M = model.samples
    if len(M):
        M = M[::max(1, len(M) // 4000)]
        s = score_surface(M, plate.mesh, sample_spacing_m=2e-3, coverage_radius_m=2e-3, max_distance_m=1e-3)
        out.update(model_surface_rms_mm=float(s.dist.rms * 1e3), model_surface_coverage=float(s.coverage_frac))
    return out


def final_visibility(true_boundary: np.ndarray, measured_views) -> dict:
    """camera -> ``BoundaryVisibility`` of the true boundary (N,3) from the final poses together: a
    point counts when a pose's camera sees it (ground truth) and that pose's measured outline passes
    within ``TRIANGULATED_PX`` of it in its left image (its pair triangulated it).
    ``measured_views``: ``sensor.PassiveView``s with an outline."""
    P = np.asarray(true_boundary, float)
    masks = {"left": [], "right": []}
    for v in measured_views:
        uv = v.left_camera.project(P)
        ok = np.all(np.isfinite(uv), axis=1)
        tri = np.zeros(len(P), bool)
        tri[ok] = cKDTree(v.outline.image_points).query(uv[ok])[0] <= TRIANGULATED_PX
        for c in ("left", "right"):
            masks[c].append(np.asarray(v.gt_visibility[c].visible, bool) & tri)
    return {c: combined_visibility(P, masks[c]) for c in ("left", "right")}
