"""``evaluation.score`` on a hand-built truth (no render): a flat plate at a known depth, four
projected features, and a reconstruction displaced by known amounts. Every figure of the typed
``Score`` and of its ``MetricsRow`` is known in closed form."""
from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from platebench.bench.io.codecs import decode, encode
from platebench.evaluation.metrics_row import MetricsRow, metric_label
from platebench.evaluation.score import BoundaryTruth, ReconstructionData, SampleTruth, Score, score_reconstruction
from platebench.reconstruction.paper.false_boundary import FalseBoundaryTest
from platebench.scenes.camera import Camera
from platebench.scenes.rig import StereoRig

W, H, F = 320, 240, 400.0
SIDE = 0.10  # plate side, m; the plate lies in z = 0, centred
Z_CAM = 0.40


def _truth() -> tuple[SampleTruth, np.ndarray]:
    rig = StereoRig.conventional(center=(0.0, 0.0, Z_CAM), target=(0.0, 0.0, 0.0), baseline_m=0.05, f_px=F,
                                 width=W, height=H)
    projector = Camera.look_at((0.0, 0.0, Z_CAM), (0.0, 0.0, 0.0), F, W, H, up=(-1.0, 0.0, 0.0))
    mesh = trimesh.Trimesh(vertices=[[-SIDE / 2, -SIDE / 2, 0], [SIDE / 2, -SIDE / 2, 0], [SIDE / 2, SIDE / 2, 0],
                                     [-SIDE / 2, SIDE / 2, 0]], faces=[[0, 1, 2], [0, 2, 3]], process=False)
    t = np.linspace(0, 1, 50, endpoint=False)
    c = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * SIDE / 2
    boundary = np.vstack([np.column_stack([c[k, 0] + (c[(k + 1) % 4, 0] - c[k, 0]) * t,
                                           c[k, 1] + (c[(k + 1) % 4, 1] - c[k, 1]) * t, np.zeros_like(t)])
                          for k in range(4)])
    true_pts = np.array([[-0.02, -0.02, 0.0], [0.02, -0.02, 0.0], [0.02, 0.02, 0.0], [-0.02, 0.02, 0.0]])
    centres = projector.project(true_pts)
    ids = np.array([10, 11, 12, 13])
    fmaps, masks = {}, {}
    vv, uu = np.mgrid[0:H, 0:W]
    for name, cam in rig.cameras.items():
        fmap = np.full((H, W), -1, np.int32)
        for i, p in zip(ids, cam.project(true_pts)):
            fmap[(uu - p[0]) ** 2 + (vv - p[1]) ** 2 <= 9] = i
        fmaps[name] = fmap
        corners = cam.project(c3 := np.column_stack([c, np.zeros(4)]))
        del c3
        inside = np.ones((H, W), bool)
        for k in range(4):  # convex polygon test (counter-clockwise in the image or not: use signs)
            a, b = corners[k], corners[(k + 1) % 4]
            inside &= ((b[0] - a[0]) * (vv - a[1]) - (b[1] - a[1]) * (uu - a[0])) * \
                       ((b[0] - a[0]) * (corners[(k + 2) % 4][1] - a[1]) - (b[1] - a[1]) * (corners[(k + 2) % 4][0] - a[0])) > 0
        masks[name] = inside
    vis = {cam: BoundaryTruth(false_boundary=False, visible_fraction=1.0) for cam in ("left", "right")}
    return SampleTruth(mesh, boundary, masks, fmaps, rig, projector, ids, centres, vis), true_pts


def _recon(truth: SampleTruth, true_pts, depth_mm=0.0, ex_mm=0.0, ey_mm=0.0, boundary_up_mm=0.0,
           surface_up_mm=0.0, detected=False) -> ReconstructionData:
    R = truth.rig.left.R
    offset_cam = np.array([ex_mm, ey_mm, depth_mm]) * 1e-3
    pts = true_pts + offset_cam @ R  # camera-frame offset in the world frame
    uv_l = truth.rig.left.project(true_pts)
    uv_r = truth.rig.right.project(true_pts)
    b = truth.boundary + [0.0, 0.0, boundary_up_mm * 1e-3]
    g = np.linspace(-SIDE / 2, SIDE / 2, 101)  # 1 mm vertex spacing (coverage radius 2 mm)
    gx, gy = np.meshgrid(g, g)
    surf = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, surface_up_mm * 1e-3)])
    fb = FalseBoundaryTest({"left_active": 4, "right_active": 4}, 4, (), counting_test=detected)
    return ReconstructionData(pts, uv_l, uv_r, truth.feature_ids, b, surf, fb)


@pytest.fixture(scope="module")
def truth():
    return _truth()


def test_depth_offset_is_the_depth_error_and_nothing_else(truth):
    t, p = truth
    s = score_reconstruction(t, _recon(t, p, depth_mm=0.1))
    assert s.points.count == 4
    assert s.points.stats.depth.rms == pytest.approx(1e-4, rel=1e-9)
    assert s.points.stats.xy_radial.rms == pytest.approx(0.0, abs=1e-12)
    # the points lie 0.1 mm off the plate along the (vertical) optical axis
    assert s.points.to_surface_rms_m == pytest.approx(1e-4, rel=1e-6)
    assert s.matching.matched_count == s.matching.correct_match_count == 4
    assert s.matching.expected_count_gt == 4 and s.matching.expected_count_method == 4
    assert s.paper_bound.met and s.paper_bound.all_points
    assert not s.goals.met  # 0.1 mm > the 0.03 mm depth-RMS goal
    assert s.false_boundary.agrees and not s.false_boundary.ground_truth_any


def test_lateral_errors_per_axis_and_radial_are_different_figures(truth):
    """x/y offsets (0.03, 0.04) mm: radial RMS 0.05 mm; per-axis RMS sqrt((0.03^2 + 0.04^2)/2) mm.
    The goal (0.05 mm) is checked against the per-axis figure and the paper's bound against the
    larger per-axis maximum; the names say which is which (one used to be sqrt(2) off)."""
    t, p = truth
    s = score_reconstruction(t, _recon(t, p, ex_mm=0.03, ey_mm=0.04))
    row = MetricsRow.from_score(s)
    assert row.xy_radial_rms_mm == pytest.approx(0.05, rel=1e-9)
    assert row.xy_per_axis_rms_mm == pytest.approx(math.sqrt((0.03 ** 2 + 0.04 ** 2) / 2), rel=1e-9)
    assert s.goals.xy_per_axis_rms_mm == pytest.approx(row.xy_per_axis_rms_mm)
    assert s.paper_bound.xy_per_axis_max_mm == pytest.approx(0.04, rel=1e-9)
    d = encode(s)
    assert d["points"]["xy_radial_rms_mm"] == pytest.approx(0.05)
    assert "xy_rms_mm" not in d["points"] and "xy_rms_mm" not in d["goals"]
    assert "radial" in metric_label("xy_radial_rms_mm") and "per axis" in metric_label("xy_per_axis_rms_mm")


def test_boundary_and_surface_offsets(truth):
    t, p = truth
    s = score_reconstruction(t, _recon(t, p, boundary_up_mm=0.3, surface_up_mm=0.2))
    assert s.boundary_3d.mean_sym == pytest.approx(3e-4, rel=1e-6)
    assert s.boundary_3d.hausdorff == pytest.approx(3e-4, rel=1e-6)
    assert s.surface.dist.rms == pytest.approx(2e-4, rel=1e-6)
    assert s.surface.surface_coverage_frac > 0.95
    row = MetricsRow.from_score(s)
    assert row.boundary_mean_mm == pytest.approx(0.3, rel=1e-6) and row.surface_rms_mm == pytest.approx(0.2, rel=1e-6)
    assert not s.goals.met  # boundary mean 0.3 mm > 0.2 mm goal


def test_a_wrong_flag_disagrees_and_a_missing_point_breaks_the_bound(truth):
    t, p = truth
    s = score_reconstruction(t, _recon(t, p, detected=True))
    assert s.false_boundary.detected and not s.false_boundary.agrees
    rec = _recon(t, p)
    three = ReconstructionData(rec.points[:3], rec.uv_left[:3], rec.uv_right[:3], rec.feature_id[:3], rec.boundary,
                               rec.surface_vertices, rec.false_boundary)
    s = score_reconstruction(t, three)
    assert s.points.count == 3 and not s.paper_bound.all_points and not s.paper_bound.met
    assert MetricsRow.from_score(s).paper_bound_met is False


def test_metrics_row_columns_and_units():
    row = MetricsRow(depth_rms_mm=float("nan"), matched_count=4.0, extra={"mb_all_bad_1_0_pct": 3.5})
    cols = row.columns()
    assert cols["depth_rms_mm"] is None and cols["matched_count"] == 4 and cols["mb_all_bad_1_0_pct"] == 3.5
    with pytest.raises(ValueError, match="depth_rms_mm"):
        MetricsRow(extra={"depth_rms_mm": 1.0})


def test_metric_labels_carry_the_unit_once():
    assert metric_label("depth_rms_mm") == "depth RMS over the plate's pixels (mm)"
    assert metric_label("centres_depth_rms_mm") == "depth RMS at the square centres (mm)"
    assert metric_label("eth_all_a50_px") == "ETH3D A50 error, all pixels with known truth (px)"
    assert metric_label("mb_all_bad_1_0_pct") == "Middlebury bad 1.0 px, all pixels with known truth (%)"
    assert metric_label("depth_bad_0_1_mm_pct") == "estimated plate pixels with depth error > 0.1 mm (%)"
    assert metric_label("method_lit_px") == "the method's own figure 'lit_px'"


@pytest.mark.parametrize("offsets", [dict(depth_mm=0.1, ex_mm=0.03, ey_mm=0.04, boundary_up_mm=0.3, surface_up_mm=0.2),
                                     dict(depth_mm=0.07, ex_mm=-0.02, boundary_up_mm=0.1, detected=True)])
def test_score_json_reads_back_as_the_same_score(truth, offsets):
    """score.json (``encode(score)``) read back with ``decode(Score, d)`` writes the same file, and its
    MetricsRow (what the report and the results table show) is the one of the score it came from."""
    t, p = truth
    s = score_reconstruction(t, _recon(t, p, **offsets))
    d = encode(s)
    back = decode(Score, d)
    assert encode(back) == d
    assert MetricsRow.from_score(back) == MetricsRow.from_score(s)
    assert back.paper_bound.met == s.paper_bound.met and back.goals.met == s.goals.met
    assert back.false_boundary.agrees == s.false_boundary.agrees
    empty = decode(Score, {"points": {"count": 0}, "matching": d["matching"], "false_boundary": d["false_boundary"]})
    assert empty.points is None and empty.surface is None and empty.paper_bound is None
