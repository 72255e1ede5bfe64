"""The paper's accuracy test as a study (``platebench study accuracy``) and realism in rendered samples:
real renders, few draws."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from platebench.bench.config import SampleConfig
from platebench.bench.config.presets import with_realism
from platebench.bench.config.realism import REALISM_PRESETS, SOURCES
from platebench.bench.run.accuracy import AccuracySettings, budget_configs, run_accuracy_study
from tests.conftest import run_cli

pytestmark = pytest.mark.render


def test_budget_rows_are_none_each_alone_all_but_each_and_all():
    confs = budget_configs(REALISM_PRESETS["1995"])
    kinds = [c.kind for c in confs]
    n = len(SOURCES)
    assert kinds == ["none"] + ["alone"] * n + ["all_but"] * n + ["all"]
    assert [c.realism.sources for c in confs if c.kind == "alone"] == [(s,) for s in SOURCES]
    assert [c.label for c in budget_configs(REALISM_PRESETS["ideal"])] == ["no source"]


def test_a_small_accuracy_study_runs_end_to_end(tmp_path):
    out = tmp_path / "acc"
    p = run_cli("study", "accuracy", "--realism", "1995", "--draws", "2", "--spp", "4", "--out", out)
    assert p.returncode == 0, p.stderr
    doc = json.loads((out / "accuracy.json").read_text())
    rows = doc["rows"]
    assert len(rows) == 2 * (2 * len(SOURCES) + 2) and all(r["status"] == "ok" for r in rows)
    assert {r["seed"] for r in rows} == {0, 1} and all(r["realism"].startswith("1995") for r in rows)
    s = doc["summary"]["block"]["all sources"]
    assert s["draws"] == 2 and 0 < s["depth"]["worst_median_mm"] < 10 and 0 < s["xy"]["worst_median_mm"] < 10
    assert doc["paper"] == {**doc["paper"], "depth_mm": 2.0, "xy_mm": 1.0}
    with open(out / "accuracy.csv") as f:
        table = list(csv.DictReader(f))
    assert len(table) == len(rows) and {"realism", "seed", "worst_depth_mm", "worst_xy_mm"} <= set(table[0])
    assert (out / "accuracy.png").stat().st_size > 10_000
    assert "paper (V-D): depth <= 2 mm" in p.stdout and "added to the no-source floor alone (depth" in p.stdout


@pytest.mark.parametrize("seed0", [0, 5])
def test_plate_centres_moved_past_their_neighbours_by_the_arm_are_still_identified(seed0):
    """The PUMA's absolute error alone (no hand/eye estimate to cancel it) moves the plate's measured
    centres in the world by about a centimetre, more than half the squares' 16 mm+ spacing, so nearness
    in space cannot say which true centre each is. Read in the left image, every one of the 16 is
    identified in every draw that measures the plate (a draw whose view runs the plate into the image
    border fails, with that reason)."""
    from platebench.evaluation.truth import true_feature_points
    from platebench.plates import build_plate

    cfg = with_realism(SampleConfig(), "1995")
    proj = cfg.scene.build().projector
    P = true_feature_points(build_plate(cfg.plate).mesh, proj.camera,
                            np.array([f.center for f in proj.pattern.features], float).reshape(-1, 2))
    gaps = np.linalg.norm(P[:, None] - P[None], axis=2)
    spacing_m = gaps[~np.eye(len(P), dtype=bool)].min()
    study = run_accuracy_study(AccuracySettings(REALISM_PRESETS["1995"].only("robot_accuracy"), draws=3,
                                                targets=("plate",), spp=2, seed0=seed0, budget=False))
    ok = [r for r in study.rows if r.ok]
    assert len(ok) >= 2 and all(r.points == 16 for r in ok)
    assert all("image border" in r.error for r in study.rows if not r.ok)
    assert max(r.worst_xy_mm for r in ok) > 0.5 * spacing_m * 1e3


def test_the_ideal_study_measures_the_methods_floor_in_the_true_block_frame():
    """Every source off: the corners are triangulated by the true rig and the block's true pose, so the errors
    are the corner method's alone: well inside the paper's bound, and the plate's centres at the bench's
    noise-free level."""
    study = run_accuracy_study(AccuracySettings(REALISM_PRESETS["ideal"], draws=2, targets=("block", "plate"), spp=4))
    assert {r.config for r in study.rows} == {"no source"}
    block, plate = study.summary["block"]["no source"], study.summary["plate"]["no source"]
    assert block.depth.max_mm < 1.0 and block.xy.max_mm < 0.2
    assert plate.depth.rms_mm < 0.03 and plate.xy.max_mm < 0.05
    assert all(r.acquisition.exact and r.acquisition.to_dict() == {"exact": True} for r in study.rows)
    # the study's file form reads back as the study
    from platebench.bench.io.accuracy_records import AccuracyStudy
    assert AccuracyStudy.from_dict(json.loads(json.dumps(study.to_dict()))) == study


def test_render_under_realism_renders_the_pair_really_taken_and_tells_the_commanded_rig(tmp_path):
    out = tmp_path / "s95"
    p = run_cli("render", "--realism", "1995", "--realism-seed", "4", "--spp", "2", "--out", out)
    assert p.returncode == 0, p.stderr
    from platebench.bench.io.images import read_pfm
    from platebench.bench.io.sample_files import load_calibration, load_ground_truth, load_true_cameras

    told, taken = load_calibration(out).rig, load_true_cameras(out)
    commanded = with_realism(SampleConfig(), "1995").scene.build().rig
    assert np.allclose(told.left.R, commanded.left.R) and np.allclose(told.left.t, commanded.left.t)
    assert not np.allclose(told.left.K, commanded.left.K)  # the estimated intrinsics
    assert not np.allclose(taken.left.t, commanded.left.t, atol=1e-5)  # the robot put the camera elsewhere
    meta = json.loads((out / "sample.json").read_text())
    assert meta["config"]["realism"]["preset"] == "1995" and meta["config"]["realism"]["seed"] == 4
    assert set(meta["acquisition"]) >= {"views", "hand_eye", "calibration"}
    # the disparity truth is the images' own: left ground-truth points seen by the true right camera
    gt = load_ground_truth(out)
    disp = read_pfm(out / "gt" / "disp0GT.pfm")
    vv, uu = np.nonzero(gt.mask["left"])
    k = np.linspace(0, len(vv) - 1, 50).astype(int)
    ur = taken.right.project(gt.points["left"][vv[k], uu[k]].astype(np.float64))[:, 0]
    assert np.allclose(disp[vv[k], uu[k]], uu[k] - ur, atol=1e-3)


def test_posed_pair_disparity_of_a_conventional_rig_is_f_b_over_z(small_sample):
    from platebench.bench.io.sample_files import pair_disparity

    sample, _ = small_sample
    rig, g = sample.scene.rig, sample.gt["left"]
    d = pair_disparity(g, rig)
    assert np.allclose(d[g.mask], rig.disparity(g.depth64[g.mask]), atol=2e-3)  # float32 points
    assert np.all(np.isinf(d[~g.mask]))


def _square_image(corners_px: np.ndarray, size=(160, 200), over: int = 8) -> np.ndarray:
    """(H,W) uint8: a bright convex quadrilateral with corners ``corners_px`` (pixel centres at
    integers) on a dark ground, each pixel its exact coverage to 1/over^2 (area sampled)."""
    import cv2
    H, W = size
    big = np.zeros((H * over, W * over), np.uint8)
    pts = np.round((corners_px + 0.5) * over - 0.5).astype(np.int32)
    cv2.fillConvexPoly(big, pts.reshape(-1, 1, 2), 1)
    cover = big.reshape(H, over, W, over).mean(axis=(1, 3))
    return np.round(30 + 190 * cover).astype(np.uint8)


@pytest.mark.parametrize("turn_deg, shift", [(7.0, (0.31, 0.62)), (8.0, (0.8, 0.15)), (-11.0, (0.5, 0.5))])
def test_block_corners_by_edges_are_sub_pixel_and_by_pixels_lie_on_the_pixel_grid(turn_deg, shift):
    """A 60-pixel square turned ``turn_deg`` at a fractional offset, drawn with exact pixel
    coverage: the edge lines find its corners within 0.25 px; the paper's method (the polygon of the
    binary outline) puts each corner on an outline pixel, on the integer grid, within 1.5 px."""
    from platebench.bench.run.accuracy import block_corners
    a = np.radians(turn_deg)
    R = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    true = (np.array([[-30.0, -30.0], [30.0, -30.0], [30.0, 30.0], [-30.0, 30.0]]) @ R.T
            + np.array([100.0, 80.0]) + np.array(shift))  # TL, TR, BR, BL
    img = _square_image(true)
    edges = block_corners(img, "square", "edges")
    pixels = block_corners(img, "square", "pixels")
    assert np.max(np.linalg.norm(edges - true, axis=1)) < 0.25  # the drawing itself is exact to 1/16 px
    assert np.array_equal(pixels, np.round(pixels))
    assert np.max(np.linalg.norm(pixels - true, axis=1)) < 1.5
    with pytest.raises(ValueError, match="edges, pixels"):
        block_corners(img, "square", "subpixel")


def test_the_paper_corner_method_runs_in_the_study_and_is_recorded(tmp_path):
    """``--corners pixels``: the block's corners on the pixel grid; with every source off the worst
    corner stays within the grid's half pixel in each image (1 px is 0.43 mm across, 0.34 mm down at
    0.40 m); the settings record the method."""
    study = run_accuracy_study(AccuracySettings(REALISM_PRESETS["ideal"], draws=2, targets=("block",), spp=4,
                                                corners="pixels"))
    block = study.summary["block"]["no source"]
    assert block.xy.max_mm < 0.5 and block.depth.max_mm < 3.0
    assert study.to_dict()["settings"]["corners"] == "pixels"
    from platebench.bench.io.accuracy_records import AccuracySettings as Settings
    assert Settings.from_dict({**study.settings.to_dict(), "corners": "pixels"}).corners == "pixels"


def test_realism_scale_scales_a_source_and_refuses_what_is_not_one(tmp_path):
    """``--realism-scale robot_accuracy=4``: the arm's kinematic spread is four times the sourced one
    (the robot model, not a label); a source the preset does not have, a value that is no number or out
    of range: one-line errors, exit 2, nothing written."""
    from platebench.bench.config.study import with_scales
    from platebench.bench.config import SampleConfig
    from platebench.bench.config.presets import with_realism
    from platebench.bench.run.realism import RealismSetup

    base = REALISM_PRESETS["1995"]
    scaled = with_scales(base, "robot_accuracy=4, noise=0.5")
    assert scaled.scales == {"noise": 0.5, "robot_accuracy": 4.0}
    models = [RealismSetup.prepare(r, with_realism(SampleConfig(), r), corner_noise_px=0.15).robot_model
              for r in (base, scaled)]
    assert models[1].sigma_length_m == pytest.approx(4 * models[0].sigma_length_m)
    assert models[1].sigma_angle_rad == pytest.approx(4 * models[0].sigma_angle_rad)
    assert models[1].joint_sigma_rad == pytest.approx(models[0].joint_sigma_rad)
    # a study builds the robot's unit model once and scales it per budget row: the same model as built anew
    unit = RealismSetup.unit_robot_model(base.robot)
    no_rp = next(c.realism for c in budget_configs(base) if c.kind == "all_but"
                 and "robot_repeatability" not in c.realism.sources)
    for r, m in ((base, models[0]), (scaled, models[1]), (no_rp, None)):
        m = m or RealismSetup.prepare(r, with_realism(SampleConfig(), r), corner_noise_px=0.15).robot_model
        assert RealismSetup.prepare(r, with_realism(SampleConfig(), r), corner_noise_px=0.15,
                                    unit_robot=unit).robot_model == m
    assert not no_rp.on("robot_repeatability") and unit.repeatability and unit.accuracy
    for bad, words in (("robot_accuracy=x", "is not a number"), ("dust=2", "is not on in realism 1995"),
                       ("robot_accuracy=-1", "out of range: allowed 0 to"), ("robot_accuracy", "is not SOURCE=F")):
        p = run_cli("study", "accuracy", "--out", tmp_path / "a", "--realism-scale", bad)
        assert p.returncode == 2 and words in p.stderr and len(p.stderr.strip().splitlines()) == 1, p.stderr
        assert not (tmp_path / "a").exists()


def test_a_measured_point_is_identified_in_the_image_and_one_stands_for_each_true_point():
    """``evaluation.accuracy.identify_in_image``: the nearest true point within the fraction of the true points'
    spacing; of two on one true point the nearer stands for it; one too far is no one."""
    from platebench.evaluation.accuracy import identify_in_image, nearest_order

    true_uv = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    m = identify_in_image([[0.5, 0.0], [1.0, 0.2], [10.0, 2.9], [5.0, 5.0]], true_uv, 0.3)
    assert m.spacing_px == 10.0
    assert m.ok.tolist() == [True, False, True, False] and m.index[m.ok].tolist() == [0, 1]
    assert nearest_order(true_uv, true_uv[[2, 0, 1]] + 0.1) == [2, 0, 1]


def test_a_trials_figures_and_a_budget_rows_statistics_follow_their_definitions():
    """``evaluation.accuracy``: a trial's worst and RMS per measure; over trials the median worst value and its
    quantiles, the pooled RMS, 95th percentile and maximum, and the share within the paper's bound."""
    from platebench.evaluation.accuracy import PAPER_DEPTH_MM, score_trial, summarise_trials

    e = np.array([[0.1, -0.3, 1.5], [0.2, 0.05, -2.5], [-0.4, 0.1, 0.5]]) * 1e-3
    t = score_trial(e)
    assert t.points == 3 and t.worst_depth_m == pytest.approx(2.5e-3) and t.worst_xy_m == pytest.approx(0.4e-3)
    assert t.rms_depth_m == pytest.approx(np.sqrt(np.mean(e[:, 2] ** 2)))
    assert t.rms_xy_m == pytest.approx(np.sqrt(np.mean(e[:, :2] ** 2)))
    assert t.mean_depth_m == pytest.approx(np.mean(e[:, 2]))
    trials = [e * 1e3, e * 0.5e3]
    s = summarise_trials([2.5, 1.25], [0.4, 0.2], trials)
    pooled = np.abs(np.concatenate(trials))
    assert s.depth.worst_median == pytest.approx(1.875) and s.depth.within_bound_frac == 0.5
    assert s.depth.worst_quantiles["q95"] == pytest.approx(np.quantile([2.5, 1.25], 0.95))
    assert s.depth.rms == pytest.approx(np.sqrt(np.mean(pooled[:, 2] ** 2))) and s.depth.max == 2.5
    assert s.depth.p95 == pytest.approx(np.quantile(pooled[:, 2], 0.95))
    assert s.xy.max == 0.4 and s.xy.mean_signed is None and s.xy.within_bound_frac == 1.0
    assert s.depth.mean_signed == pytest.approx(np.mean(np.concatenate(trials)[:, 2]))
    assert PAPER_DEPTH_MM == 2.0
