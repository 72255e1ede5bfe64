"""The paper's pipeline on real renders: every square found and matched right, bad input refused."""
from __future__ import annotations

import shutil

import cv2
import numpy as np
import pytest

from platebench.bench.config import SampleConfig, SceneParams
from platebench.bench.run.render import render_sample
from platebench.evaluation.boundary_metrics import polyline_distance
from platebench.evaluation.truth import feature_at_pixels
from platebench.plates import Flat, PlateSpec
from platebench.reconstruction.paper.boundary_plane import fit_boundary_plane
from platebench.reconstruction.paper.false_boundary import (
    FeatureRays,
    false_boundary_test,
)
from platebench.reconstruction.paper.pipeline import projector_feature_rays, reconstruct
from platebench.reconstruction.paper.square_matching import (
    check_fig6,
    group_squares,
    match_squares,
)
from platebench.reconstruction.paper.squares import Square
from platebench.scenes.scene_spec import RenderSettings
from tests.conftest import run_cli

pytestmark = pytest.mark.render


def _run(sample):
    rig = sample.scene.rig
    rays = projector_feature_rays(sample.scene.projector.camera, sample.scene.projector.pattern)
    return reconstruct(sample.digital, rig, rays, sample.scene.projector.pattern)


@pytest.fixture(scope="module")
def flat_sample():
    cfg = SampleConfig(plate=PlateSpec(length_m=0.1165, width_m=0.0735, deformation=Flat()),
                       scene=SceneParams(width=480, height=360), render=RenderSettings(spp=8, seed=5))
    return render_sample(cfg)[0]


@pytest.mark.parametrize("which", ["flat", "bent10"])
def test_all_16_squares_found_and_matched_to_the_right_projected_square(which, flat_sample, small_sample):
    sample = flat_sample if which == "flat" else small_sample[0]
    r = _run(sample)
    assert r.false_boundary.detected == {"left_active": 16, "right_active": 16}
    assert r.false_boundary.expected == 16 and not r.false_boundary.false_boundary_detected
    assert len(r.points) == 16 and not r.unmatched
    # Ground-truth feature ids at the matched pixels (the method never saw them).
    gl = feature_at_pixels(sample.gt["left"].feature, r.uv_left)
    gr = feature_at_pixels(sample.gt["right"].feature, r.uv_right)
    assert np.all(gl == gr) and sorted(gl.tolist()) == list(range(16))
    assert np.all(r.feature_id == gl)
    for chk in r.fig6.values():
        assert chk.condition_1_ok and chk.condition_2_ok
    # Boundary: mean distance to the true outline well under a pixel's depth step (2 mm here).
    b = polyline_distance(r.boundary, sample.plate.boundary)
    assert b.mean_sym < 0.5e-3


def test_boundary_plane_of_flat_plate_is_the_plate(flat_sample):
    r = _run(flat_sample)
    assert abs(r.boundary_plane.normal[2]) > 0.9999
    assert abs(r.boundary_plane.offset) < 0.3e-3  # plate at z = 0


def test_tsai_and_otsu_thresholds_are_reported_for_every_image(small_sample):
    r = _run(small_sample[0])
    for name, t in r.thresholds.items():
        assert 0 < t["tsai"] < 255 and 0 < t["otsu"] < 255, name


def _sq(u, v, w=10, h=10):
    return Square(np.array([u + (w - 1) / 2, v + (h - 1) / 2]), np.zeros(2), np.full(2, np.nan), np.full((4, 2), np.nan),
                  (u, v, u + w - 1, v + h - 1), w * h)


def test_fig6_condition_2_violation_is_reported_not_silently_matched():
    # Two arrays whose squares overlap in y: a tilted surface broke the row spacing.
    squares = (_sq(0, 0), _sq(20, 2), _sq(40, 4), _sq(60, 9), _sq(80, 14))
    groups = group_squares(squares)
    chk = check_fig6(squares, [groups[0][:3], groups[0][3:]], "left_active")
    assert not chk.condition_2_ok
    assert any("overlap in y across arrays" in v for v in chk.violations)


def test_missing_square_is_flagged_and_its_array_left_unmatched():
    left = tuple(_sq(20 * k, 0) for k in range(4)) + tuple(_sq(20 * k, 40) for k in range(4))
    right = tuple(_sq(20 * k - 5, 0) for k in (0, 1, 3)) + tuple(_sq(20 * k - 5, 40) for k in range(4))
    gl, gr = group_squares(left), group_squares(right)
    chk = check_fig6(right, gr, "right_active")
    assert not chk.condition_1_ok and any("a square is missing" in v for v in chk.violations)
    m = match_squares(left, right, gl, gr, row_tolerance_px=10)
    assert len(m.pairs) == 4  # only the complete array is matched
    assert any("x order is ambiguous" in n for n in m.unmatched)


def test_counting_test_flags_fewer_squares_than_rays_inside_the_boundary():
    boundary = np.array([[-0.05, -0.03, 0.0], [0.05, -0.03, 0.0], [0.05, 0.03, 0.0], [-0.05, 0.03, 0.0]])
    plane = fit_boundary_plane(boundary, toward=np.array([0, 0, 1.0]))
    xs = np.array([-0.06, -0.02, 0.0, 0.02, 0.04])  # the first ray lands outside the boundary
    targets = np.column_stack([xs, np.zeros(5), np.zeros(5)])
    o = np.array([0.0, 0.0, 0.4])
    d = (targets - o) / np.linalg.norm(targets - o, axis=1, keepdims=True)
    rays = FeatureRays(np.repeat(o[None], 5, 0), d, np.arange(5))
    ok = false_boundary_test({"left_active": 4, "right_active": 4}, rays, plane, boundary)
    assert ok.expected == 4 and ok.expected_ids == (1, 2, 3, 4) and not ok.false_boundary_detected
    bad = false_boundary_test({"left_active": 4, "right_active": 3}, rays, plane, boundary)
    assert bad.false_boundary_detected


# -- the CLI on bad input -------------------------------------------------------
@pytest.fixture()
def inputs_only(small_sample_dir, tmp_path):
    """A copy holding only what reconstruction may read (no ground truth at all)."""
    d = tmp_path / "sample"
    (d / "images").mkdir(parents=True)
    for name in ("calib.json", "pattern.json", "pattern.png"):
        shutil.copy(small_sample_dir / name, d / name)
    for p in (small_sample_dir / "images").glob("*.png"):
        shutil.copy(p, d / "images" / p.name)
    return d


def test_reconstruct_needs_no_ground_truth(inputs_only, tmp_path):
    p = run_cli("reconstruct", inputs_only, "--out", tmp_path / "r")
    assert p.returncode == 0, p.stderr
    assert {x.name for x in (tmp_path / "r").iterdir()} == {"points.ply", "points.csv", "boundary.npy",
                                                             "surface.ply", "recon.json", ".platebench-output.json"}


@pytest.mark.parametrize("damage, message", [
    ("missing", "left_active.png: file is missing"),
    ("size", "right_passive.png: size 100x80 differs from calib.json's 480x360"),
    ("blank", "left_passive.png: image is blank"),
    ("saturated", "left_active.png: image is saturated"),
    ("noplate", "right_passive.png: no plate found"),
    ("nosquares", "left_active.png: no squares found inside the plate region"),
])
def test_bad_input_is_one_line_error_and_leaves_nothing(inputs_only, tmp_path, damage, message):
    img = inputs_only / "images"
    if damage == "missing":
        (img / "left_active.png").unlink()
    elif damage == "size":
        cv2.imwrite(str(img / "right_passive.png"), np.zeros((80, 100), np.uint8))
    elif damage == "blank":
        cv2.imwrite(str(img / "left_passive.png"), np.full((360, 480), 17, np.uint8))
    elif damage == "saturated":
        cv2.imwrite(str(img / "left_active.png"), np.full((360, 480), 255, np.uint8))
    elif damage == "noplate":
        a = np.zeros((360, 480), np.uint8)
        a[5, 5] = 200
        cv2.imwrite(str(img / "right_passive.png"), a)
    elif damage == "nosquares":
        a = np.zeros((360, 480), np.uint8)
        a[2:6, 2:6] = 200  # a bright blob outside the plate only
        cv2.imwrite(str(img / "left_active.png"), a)
    out = tmp_path / "r"
    p = run_cli("reconstruct", inputs_only, "--out", out)
    assert p.returncode == 2, p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and message in p.stderr
    assert not out.exists() and not any(x.name.startswith(".tmp") for x in tmp_path.iterdir())
