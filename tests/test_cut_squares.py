"""Squares cut in either image (by the plate's outline, or by the threshold where part of a square
is lit at grazing incidence) are found from the images alone; their centres are set apart from the
points, the surface and the scores, kept in cut_points.csv, and reported by the counting test and
``evaluate``. Ground truth (the true centre of the feature lighting each centre's pixel) judges it."""
from __future__ import annotations

import json

import numpy as np
import pytest

from platebench.bench.config import SampleConfig, SceneParams, with_overrides
from platebench.reconstruction.paper.squares import CUT_CONTACT_PX, DIM_MAX_FRAC, extract_squares
from platebench.scenes.scene_spec import RenderSettings
from tests.conftest import run_cli

PAPER_DEPTH_MM, PAPER_XY_MM = 2.0, 1.0


def test_a_square_cut_by_the_outline_or_the_threshold_is_named_from_the_image():
    """Synthetic active image: a whole square, one running past the plate region's edge, one whose
    right part is lit too dim for the threshold, and one near (not at) the edge."""
    img = np.zeros((100, 120), np.uint8)
    img[20:40, 20:40] = 200  # whole
    img[20:40, 100:110] = 200  # runs to the region's edge at u = 110
    img[60:80, 60:72] = 200
    img[60:80, 72:80] = 40  # the same square's dim part (below the threshold, above a quarter of its contrast)
    img[60:80, 88:105] = 200  # whole, 5 px inside the edge
    region = np.ones(img.shape, bool)
    region[:, 110:] = False
    by_u = {s.bbox[0]: s for s in extract_squares(img, region).squares}
    assert by_u[20].cut is None and by_u[88].cut is None
    assert by_u[100].cut == "outline" and by_u[100].outline_contact_px >= 20 >= CUT_CONTACT_PX
    assert by_u[60].cut == "threshold" and by_u[60].dim_px >= DIM_MAX_FRAC * by_u[60].area_px
    assert by_u[88].outline_contact_px == 0 and by_u[88].dim_px == 0


def _oblique(bend_deg, direction, axis_deg, distance_m, seed=0):
    from platebench.bench.run.render import render_sample
    base = SampleConfig(scene=SceneParams(width=640, height=480), render=RenderSettings(spp=2, seed=seed))
    cfg = with_overrides(base, bend_deg=bend_deg, bend_direction=direction, bend_axis_deg=axis_deg,
                         distance_m=distance_m)
    return render_sample(cfg)[0]


def _point_errors_mm(sample, points, uv_left):
    """(depth, max per-axis x/y) errors (mm) of each point against the true centre of the feature
    lighting its left pixel (NaN where no feature does)."""
    from platebench.bench.run.score import truth_from_sample
    from platebench.evaluation.truth import feature_at_pixels, true_feature_points
    t = truth_from_sample(sample)
    true = true_feature_points(t.mesh, t.projector, t.feature_centers)
    index = {int(i): k for k, i in enumerate(t.feature_ids)}
    out = np.full((len(points), 2), np.nan)
    for k, g in enumerate(feature_at_pixels(t.feature_maps["left"], uv_left)):
        if int(g) in index:
            e = t.rig.left.R @ (points[k] - true[index[int(g)]])
            out[k] = abs(e[2]) * 1e3, max(abs(e[0]), abs(e[1])) * 1e3
    return out


@pytest.mark.render
@pytest.mark.parametrize("bend_deg, direction, axis_deg, distance_m, reason", [
    (40.0, "up", 30.0, 0.5, "outline"), (40.0, "up", 31.0, 0.495, "outline"), (60.0, "down", 29.0, 0.505, "outline"),
    (120.0, "down", 45.0, 0.4, "threshold"), (120.0, "down", 44.0, 0.405, "threshold"),
])
def test_no_kept_centre_of_an_oblique_bend_breaks_the_papers_bound(bend_deg, direction, axis_deg, distance_m, reason):
    """Oblique bends at 640 x 480 whose outline (0.5 m: the grid's outer rows run off the plate's
    long edges) or shading (a convex 120-degree bend: its end squares lit at grazing incidence)
    cuts squares. Kept with the others (the paper's pipeline as it was), some centres break the
    paper's bound; set apart, every kept centre meets it, and the counting test and the
    reconstruction say how many were cut and why."""
    from platebench.reconstruction.paper.pipeline import PipelineOptions, projector_feature_rays, reconstruct
    s = _oblique(bend_deg, direction, axis_deg, distance_m)
    sc = s.scene
    rays = projector_feature_rays(sc.projector.camera, sc.projector.pattern)
    rec = reconstruct(s.digital, sc.rig, rays, sc.projector.pattern)
    kept = _point_errors_mm(s, rec.points, rec.uv_left)
    assert len(rec.points) >= 2 and np.all(np.isfinite(kept))
    assert kept[:, 0].max() <= PAPER_DEPTH_MM and kept[:, 1].max() <= PAPER_XY_MM, kept
    assert len(rec.cut) >= 2 and any(reason in r for r in rec.cut.reasons), rec.cut.reasons
    assert sum(rec.false_boundary.cut.values()) >= len(rec.cut) // 2 + 1
    old = reconstruct(s.digital, sc.rig, rays, sc.projector.pattern, PipelineOptions(keep_cut_squares=True))
    assert len(old.points) == len(rec.points) + len(rec.cut) and len(old.cut) == 0
    before = _point_errors_mm(s, old.points, old.uv_left)
    assert np.any(~((before[:, 0] <= PAPER_DEPTH_MM) & (before[:, 1] <= PAPER_XY_MM)))  # NaN: on no feature at all


@pytest.mark.render
def test_cut_centres_are_kept_apart_in_files_and_reported_by_evaluate(tmp_path):
    s, r = tmp_path / "s", tmp_path / "r"
    p = run_cli("render", "--out", s, "--bend-deg", "40", "--bend-direction", "up", "--bend-axis-deg", "30",
                "--distance-m", "0.5", "--width", "640", "--height", "480", "--spp", "2")
    assert p.returncode == 0, p.stderr[-2000:]
    p = run_cli("reconstruct", s, "--out", r)
    assert p.returncode == 0, p.stderr[-2000:]
    assert "cut squares" in p.stdout
    meta = json.loads((r / "recon.json").read_text())
    n_cut = meta["cut_squares"]["count"]
    assert n_cut >= 2 and meta["n_points"] + n_cut == 16
    assert all("outline" in x for x in meta["cut_squares"]["reasons"])
    assert sum(meta["false_boundary"]["cut_squares"].values()) >= n_cut
    lines = [ln for ln in (r / "cut_points.csv").read_text().splitlines()[1:] if ln.strip()]
    assert len(lines) == n_cut
    p = run_cli("evaluate", s, r)
    assert p.returncode == 0, p.stderr[-2000:]
    assert f"cut squares      {n_cut} centres set apart" in p.stdout
    score = json.loads((r / "score.json").read_text())
    assert score["points"]["count"] == meta["n_points"] and score["cut_points"]["count"] == n_cut
    assert score["points"]["depth_max_mm"] <= PAPER_DEPTH_MM and score["points"]["x_max_mm"] <= PAPER_XY_MM
    assert score["points"]["y_max_mm"] <= PAPER_XY_MM
    assert max(score["cut_points"]["x_max_mm"], score["cut_points"]["y_max_mm"]) > PAPER_XY_MM
    assert score["paper_bound"]["all_points"] is False  # 16 expected, fewer kept: said, not hidden


@pytest.mark.render
def test_the_cut_squares_study_counts_centres_outside_the_bound_kept_and_set_apart(tmp_path):
    """``study cut-squares`` on two oblique plates at 0.5 m: with the cut squares kept, centres break
    the paper's bound; with them set apart (the default), none of the kept does, and every one that
    broke it is among those set apart."""
    out = tmp_path / "cs"
    p = run_cli("study", "cut-squares", "--bend", "40", "--axes", "31", "--distances", "0.495", "--width", "640",
                "--spp", "2", "--out", out)
    assert p.returncode == 0, p.stderr[-2000:]
    doc = json.loads((out / "cut_study.json").read_text())
    t = doc["totals"]
    assert t["plates"] == 2 and t["errors"] == 0 and t["centres"] == t["kept"] + t["cut"]
    assert t["outside_before"] >= 2 and t["outside_kept"] == 0 and t["outside_cut"] == t["outside_before"]
    assert "totals: 2 plates" in p.stdout
    p = run_cli("study", "cut-squares", "--distances", "5", "--out", tmp_path / "bad")
    assert p.returncode == 2 and "--distances value 5 is out of range: allowed 0.2 to 2" in p.stderr, p.stderr
