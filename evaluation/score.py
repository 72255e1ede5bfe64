"""Score a reconstruction against a sample's exact ground truth.

Inputs are plain arrays and geometry types (bench/ reads the files). Every JSON key
carries its unit. Sections:

* ``points``: 3D error of each triangulated square centre against the true centre
  (projector ray through the feature centre, cut with the plate mesh). The true
  identity of a reconstructed point is the ground-truth feature lighting its left
  pixel; errors are split into depth (along the left optical axis) and x/y, as in the
  paper; plus the distance of each point to the true surface.
* ``matching``: detected / matched / visible / expected counts and the correct-match
  rate (left and right pixels lit by the same feature).
* ``boundary_3d`` (mm) and ``boundary_image`` (px, left image, against the GT mask).
* ``surface``: interpolated surface against the plate mesh (RMS, max, coverage).
* ``false_boundary``: ground truth (a true-boundary point hidden from a camera) vs
  the counting test's verdict.
* ``paper_bound`` (depth <= 2 mm, x/y <= 1 mm, paper V-D) and ``goals`` (depth RMS <=
  0.03 mm, x/y RMS <= 0.05 mm, boundary mean <= 0.2 mm).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from evaluation.boundary_metrics import contour_pixels_distance, polyline_distance
from evaluation.point_metrics import point_to_surface_distance, score_points
from evaluation.surface_metrics import score_surface
from evaluation.truth import feature_at_pixels, feature_visibility, true_feature_points
from scenes.camera import Camera
from scenes.rig import StereoRig

PAPER_DEPTH_MM, PAPER_XY_MM = 2.0, 1.0
GOAL_DEPTH_RMS_MM, GOAL_XY_RMS_MM, GOAL_BOUNDARY_MEAN_MM = 0.03, 0.05, 0.2


class ScoreError(ValueError):
    """Sample and reconstruction cannot be scored together."""


@dataclass(frozen=True)
class SampleTruth:
    mesh: trimesh.Trimesh
    boundary: np.ndarray
    masks: dict
    feature_maps: dict
    rig: StereoRig
    projector: Camera
    feature_ids: np.ndarray
    feature_centers: np.ndarray
    visibility: dict  # camera -> {"false_boundary": bool, "visible_fraction": float, ...}


@dataclass(frozen=True)
class ReconstructionData:
    points: np.ndarray
    uv_left: np.ndarray
    uv_right: np.ndarray
    feature_id: np.ndarray
    boundary: np.ndarray
    surface_vertices: np.ndarray | None
    false_boundary: dict  # recon.json's false_boundary section


def score_reconstruction(truth: SampleTruth, rec: ReconstructionData) -> dict:
    """All metrics of one reconstruction, as a JSON-ready dict (units in the keys)."""
    for name, arr in (("points", rec.points), ("boundary", rec.boundary)):
        if arr.size and not np.all(np.isfinite(arr)):
            raise ScoreError(f"reconstruction {name} hold NaN or inf")
    true_pts = true_feature_points(truth.mesh, truth.projector, truth.feature_centers)
    vis = feature_visibility(truth.feature_maps, true_pts, truth.feature_ids)
    id_index = {int(i): k for k, i in enumerate(truth.feature_ids)}
    gid_l = feature_at_pixels(truth.feature_maps["left"], rec.uv_left)
    gid_r = feature_at_pixels(truth.feature_maps["right"], rec.uv_right)
    correct = (gid_l == gid_r) & (gid_l >= 0)
    out: dict = {}
    # -- points ---------------------------------------------------------------
    known = np.array([g in id_index and np.all(np.isfinite(true_pts[id_index[g]])) for g in gid_l], bool)
    if known.any():
        est = rec.points[known]
        tru = true_pts[[id_index[g] for g in gid_l[known]]]
        ps = score_points(est, tru, truth.rig.left.R).to_dict()
        d_surf = point_to_surface_distance(rec.points, truth.mesh)  # exact; trimesh's is off in metres
        ps["to_surface_rms_mm"] = float(np.sqrt(np.mean(d_surf ** 2)) * 1e3)
        ps["to_surface_max_mm"] = float(d_surf.max() * 1e3)
        out["points"] = ps
    else:
        out["points"] = {"count": 0}
    out["matching"] = {
        "matched_count": int(len(rec.points)),
        "correct_match_count": int(correct.sum()),
        "correct_match_rate_frac": float(correct.mean()) if len(correct) else 0.0,
        "label_correct_rate_frac": float(np.mean(rec.feature_id == gid_l)) if len(gid_l) else 0.0,
        "detected_count": {k: int(v) for k, v in rec.false_boundary.get("detected", {}).items()},
        "visible_count": {cam: len(ids) for cam, ids in vis.seen.items()},
        "visible_in_both_count": len(vis.visible_in_both()),
        "expected_count_gt": len(vis.on_plate),
        "expected_count_method": int(rec.false_boundary.get("expected", -1)),
    }
    # -- boundary ---------------------------------------------------------------
    if len(rec.boundary) >= 3:
        out["boundary_3d"] = polyline_distance(rec.boundary, truth.boundary).to_dict()
        uv = truth.rig.left.project(rec.boundary)
        out["boundary_image"] = contour_pixels_distance(truth.masks["left"], uv).to_dict()
    # -- surface ----------------------------------------------------------------
    if rec.surface_vertices is not None and len(rec.surface_vertices):
        out["surface"] = score_surface(rec.surface_vertices, truth.mesh, sample_spacing_m=1e-3).to_dict()
    # -- false boundary ---------------------------------------------------------
    gt_fb = {cam: bool(v["false_boundary"]) for cam, v in truth.visibility.items()}
    detected = bool(rec.false_boundary.get("false_boundary_detected", False))
    out["false_boundary"] = {"ground_truth": gt_fb, "ground_truth_any": any(gt_fb.values()),
                             "detected": detected, "agrees": detected == any(gt_fb.values())}
    # -- bounds and goals --------------------------------------------------------
    p = out["points"]
    n_expected = out["matching"]["expected_count_gt"]
    if p.get("count", 0):
        out["paper_bound"] = {"depth_max_mm": p["depth_max_mm"], "xy_max_mm": max(p["x_max_mm"], p["y_max_mm"]),
                              "all_points": p["count"] == n_expected,
                              "met": bool(p["depth_max_mm"] <= PAPER_DEPTH_MM and
                                          max(p["x_max_mm"], p["y_max_mm"]) <= PAPER_XY_MM and
                                          p["count"] == n_expected)}
        xy_rms = float(np.sqrt((p["x_rms_mm"] ** 2 + p["y_rms_mm"] ** 2) / 2))
        out["goals"] = {"depth_rms_mm": p["depth_rms_mm"], "depth_rms_goal_mm": GOAL_DEPTH_RMS_MM,
                        "xy_rms_mm": xy_rms, "xy_rms_goal_mm": GOAL_XY_RMS_MM,
                        "boundary_mean_mm": out.get("boundary_3d", {}).get("mean_sym_mm", float("nan")),
                        "boundary_mean_goal_mm": GOAL_BOUNDARY_MEAN_MM}
        out["goals"]["met"] = bool(p["depth_rms_mm"] <= GOAL_DEPTH_RMS_MM and xy_rms <= GOAL_XY_RMS_MM and
                                   out["goals"]["boundary_mean_mm"] <= GOAL_BOUNDARY_MEAN_MM)
    return out


def format_table(score: dict) -> str:
    """A readable summary of a score dict."""
    lines = []
    p, m = score.get("points", {}), score["matching"]
    if p.get("count"):
        lines.append(f"{'points':16s} {p['count']} matched; depth RMS {p['depth_rms_mm']:.4f} mm, max "
                     f"{p['depth_max_mm']:.4f} mm; x/y RMS {p['x_rms_mm']:.4f}/{p['y_rms_mm']:.4f} mm; "
                     f"3D RMS {p['err3d_rms_mm']:.4f} mm")
    lines.append(f"{'matching':16s} correct {m['correct_match_count']}/{m['matched_count']}; visible L/R "
                 f"{m['visible_count'].get('left')}/{m['visible_count'].get('right')}; expected (truth) "
                 f"{m['expected_count_gt']}, expected (method) {m['expected_count_method']}")
    if "boundary_3d" in score:
        b = score["boundary_3d"]
        lines.append(f"{'boundary 3D':16s} mean {b['mean_sym_mm']:.4f} mm, RMS {b['rms_sym_mm']:.4f} mm, "
                     f"Hausdorff {b['hausdorff_mm']:.4f} mm")
        bi = score["boundary_image"]
        lines.append(f"{'boundary image':16s} mean {bi['mean_sym_px']:.3f} px, Hausdorff {bi['hausdorff_px']:.3f} px")
    if "surface" in score:
        s = score["surface"]
        keys = {k: v for k, v in s.items() if k.endswith(("rms_mm", "max_mm", "_frac")) and v is not None}
        lines.append(f"{'surface':16s} " + ", ".join(f"{k} {v:.4g}" for k, v in keys.items()))
    fb = score["false_boundary"]
    lines.append(f"{'false boundary':16s} truth {fb['ground_truth_any']}, detected {fb['detected']}, "
                 f"{'agree' if fb['agrees'] else 'DISAGREE'}")
    if "paper_bound" in score:
        pb, g = score["paper_bound"], score["goals"]
        lines.append(f"{'paper bound':16s} depth <= 2 mm, x/y <= 1 mm, all points: {'MET' if pb['met'] else 'NOT MET'} "
                     f"(depth max {pb['depth_max_mm']:.4f}, x/y max {pb['xy_max_mm']:.4f})")
        lines.append(f"{'goal':16s} depth RMS {g['depth_rms_mm']:.4f} <= {g['depth_rms_goal_mm']}, x/y RMS "
                     f"{g['xy_rms_mm']:.4f} <= {g['xy_rms_goal_mm']}, boundary mean {g['boundary_mean_mm']:.4f} <= "
                     f"{g['boundary_mean_goal_mm']}: {'MET' if g['met'] else 'NOT MET'}")
    return "\n".join(lines)
