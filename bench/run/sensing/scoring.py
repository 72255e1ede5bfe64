"""The sensing loop scored against ground truth (never read by the loop's decisions): the stage-3
reconstruction's accuracy, the merged multi-view result's accuracy, and the final poses' visibility
of the true boundary. Millimetres in the returned records (``bench.io.records``), metres in arrays."""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from platebench.bench.io.records import MergedFigures, Stage3Accuracy
from platebench.bench.run.score import score_in_memory
from platebench.evaluation.merged import SURFACE_SAMPLE_M, score_merged
from platebench.evaluation.metrics_row import MetricsRow
from platebench.reconstruction.strategy.active_views import MergedReconstruction
from platebench.reconstruction.strategy.multiview import CONFIRM_ANGLE_RAD, CONFIRM_SLIDE_ANGLE_RAD
from platebench.reconstruction.strategy.surface_model import sample_triangles
from platebench.scenes.render.ground_truth import BoundaryVisibility, combined_visibility, summarise_visibility
from platebench.tolerances import tol

TRIANGULATED_PX = 3.0  # a true boundary point lies on a pose's measured outline within this (left image)


def stage3_accuracy(sample, rec) -> Stage3Accuracy:
    """The stage-3 reconstruction (the paper's method) scored against ground truth (millimetres)."""
    score = score_in_memory(sample, rec)
    row = MetricsRow.from_score(score)
    return Stage3Accuracy(centres_depth_rms_mm=row.centres_depth_rms_mm,
                          points_scored=score.points.count if score.points else 0,
                          boundary_mean_mm=row.boundary_mean_mm, surface_rms_mm=row.surface_rms_mm,
                          coverage_frac=row.coverage_frac, paper_bound_met=row.paper_bound_met,
                          goals_met=score.goals.met if score.goals else None)


def merged_accuracy(plate, merged: MergedReconstruction, poses: int = 0) -> MergedFigures:
    """The merged multi-view reconstruction (``active_views.MergedReconstruction``) against ground
    truth, as sensing.json's record (millimetres): its surface sampled every
    ``evaluation.merged.SURFACE_SAMPLE_M``, then scored by ``evaluation.merged.score_merged`` (the
    figures' definitions). ``poses``: the measuring poses merged (recorded beside the figures)."""
    S = sample_triangles(merged.surface_vertices, merged.surface_faces, SURFACE_SAMPLE_M)
    score = score_merged(plate.mesh, plate.boundary, merged.boundary, merged.points, S)
    out = {"poses": int(poses), "boundary_points": int(len(merged.boundary)), "points": int(len(merged.points))}
    mm = 1e3
    if score.boundary is not None:
        b = score.boundary
        out.update(boundary_mean_mm=b.mean_sym_m * mm, boundary_est_to_gt_mean_mm=b.est_to_gt_mean_m * mm,
                   boundary_covered_frac=b.covered_frac)
    if score.points is not None:
        out.update(points_rms_mm=score.points.rms_m * mm, points_max_mm=score.points.max_m * mm)
    if score.surface is not None:
        s = score.surface
        out.update(surface_rms_mm=s.rms_m * mm, surface_coverage_frac=s.coverage_frac, surface_points=s.samples)
    return MergedFigures(**out)


def final_visibility(true_boundary: np.ndarray, measured_views) -> dict:
    """camera -> ``BoundaryVisibility`` of the true boundary (N,3) from the final poses together: a
    point counts when a pose's camera sees it (ground truth) and that pose's measured outline passes
    within ``TRIANGULATED_PX`` of where it really appears in its left image (``PassiveView.image_of``:
    through the camera really posed, under a real rig; its pair triangulated it).
    ``measured_views``: ``sensor.PassiveView``s with an outline."""
    P = np.asarray(true_boundary, float)
    masks = {"left": [], "right": []}
    for v in measured_views:
        uv = v.image_of(P)
        ok = np.all(np.isfinite(uv), axis=1)
        tri = np.zeros(len(P), bool)
        tri[ok] = cKDTree(v.outline.image_points).query(uv[ok])[0] <= TRIANGULATED_PX
        for c in ("left", "right"):
            masks[c].append(np.asarray(v.gt_visibility[c].visible, bool) & tri)
    return {c: combined_visibility(P, masks[c]) for c in ("left", "right")}


def verifiable_visibility(true_boundary: np.ndarray, centers: np.ndarray, eyes: np.ndarray,
                          masks: dict, slide_angle_rad: float = CONFIRM_SLIDE_ANGLE_RAD) -> BoundaryVisibility:
    """Which points of the true boundary (N,3, closed) a pair of the poses could confirm, by ground
    truth: both cameras of both poses see the point (``masks``: camera -> (P, N) bool), their
    rays differ by ``CONFIRM_ANGLE_RAD`` and each pose lies ``slide_angle_rad`` out of
    the plane through the other pose and the boundary's true tangent there
    (``multiview.confirm``'s rule, on the true edge: rays from the mid-baseline points ``centers``
    (P,3), planes and slides from the left cameras' centres ``eyes`` (P,3)). ``slide_angle_rad`` is
    the one the loop's verdict asks (``CONFIRM_SLIDE_ANGLE_RAD``; on a real rig
    ``CONFIRM_SLIDE_ANGLE_RIG_RAD``), so that "verifiable" means verifiable by the verdict's own rule. A boundary point no
    pair can confirm is one that only a narrower window of viewpoints sees (a 300-degree curl's
    tips within the robot's reach): the loop can see it, and says it cannot verify it."""
    P = np.asarray(true_boundary, float)
    C = np.asarray(centers, float)
    E = np.asarray(eyes, float)
    t = np.roll(P, -1, axis=0) - np.roll(P, 1, axis=0)
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), tol.zero_length)
    both = np.asarray(masks["left"], bool) & np.asarray(masks["right"], bool)  # (Pn, N)

    def rays(X):  # (Pn, N, 3) unit, point -> pose
        r = X[:, None, :] - P[None, :, :]
        return r / np.linalg.norm(r, axis=2, keepdims=True)
    rc, r = rays(C), rays(E)
    n = np.cross(r, t[None])  # each pose's plane through the true tangent
    n /= np.maximum(np.linalg.norm(n, axis=2, keepdims=True), tol.zero_length)
    ok = np.zeros(len(P), bool)
    sin_slide, cos_angle = np.sin(slide_angle_rad), np.cos(CONFIRM_ANGLE_RAD)
    for a in range(len(C)):
        if not both[a].any():
            continue
        pair = both[a][None, :] & both  # (Pn, N)
        slide_b = np.abs(np.einsum("pnk,nk->pn", r, n[a]))  # pose b out of a's plane
        slide_a = np.abs(np.einsum("pnk,pnk->pn", n, np.broadcast_to(r[a], r.shape)))  # a out of b's
        turned = np.einsum("pnk,nk->pn", rc, rc[a]) <= cos_angle
        ok |= (pair & turned & (slide_b >= sin_slide) & (slide_a >= sin_slide)).any(axis=0)
    return summarise_visibility(P, ok)


def reach_visibility(true_boundary: np.ndarray, poses, baseline_m: float, masks: dict,
                     slide_angle_rad: float = CONFIRM_SLIDE_ANGLE_RAD) -> tuple[dict, dict]:
    """Ground truth over reachable ``poses`` (``SensorPose``; ``masks``: camera -> (P, N) bool,
    ``SimulatedSensor.boundary_visibility_masks``): (camera -> the boundary seen by that camera of
    some pose, camera -> the boundary some pair of poses could confirm by the verdict's rule with
    ``slide_angle_rad``, ``verifiable_visibility``, the same for both cameras)."""
    P = np.asarray(true_boundary, float)
    seen = {c: combined_visibility(P, list(m)) for c, m in masks.items()}
    v = verifiable_visibility(P, np.array([p.center for p in poses]),
                              np.array([p.camera_centers(baseline_m)[0] for p in poses]), masks,
                              slide_angle_rad)
    return seen, {"left": v, "right": v}
