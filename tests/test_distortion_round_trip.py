"""A distorted lens end to end: render through it, calibrate from board renders through it,
undistort with the estimated calibration, and the reference experiment's depth error returns.

Small renders (640 x 480, f = 1000 px: the reference field of view; spp 8). The lens is the
1995 camera's (Zhang 1998's measured k1, k2: 12 px of barrel at the image corners here), with
the 1995 camera's non-square pixels (fy = 1.25 fx). Measured here (seed 0): ideal camera with
its true calibration 0.046 mm depth RMS; the distorted camera with its estimated calibration
(free distortion chosen from the images, the pipeline undistorting the images) 0.058-0.073 mm;
the same images with a pinhole estimate 1.8 mm.
"""
from __future__ import annotations

from dataclasses import replace

import pytest

pytestmark = pytest.mark.render

LENS = {"k1": -0.228601, "k2": 0.190353}


@pytest.fixture(scope="module")
def configs():
    from platebench.bench.config import SampleConfig, SceneParams
    from platebench.scenes.scene_spec import RenderSettings
    ideal = SampleConfig(scene=SceneParams(width=640, height=480), render=RenderSettings(spp=8, seed=0))
    lens = replace(ideal, scene=replace(ideal.scene, distortion=dict(LENS), fy_px=1.25 * ideal.scene.focal_px))
    return ideal, lens


def _depth(sample, rig, rays):
    from platebench.bench.run.score import recon_data, truth_from_sample
    from platebench.evaluation.score import score_reconstruction
    from platebench.reconstruction.paper.pipeline import reconstruct
    score = score_reconstruction(truth_from_sample(sample), recon_data(
        reconstruct(sample.digital, rig, rays, sample.scene.projector.pattern)))
    return score


def test_distortion_round_trip_returns_the_ideal_depth_error(configs, tmp_path):
    from platebench.bench.run.calibration import compare_reconstruction, load_estimated_calibration, run_calibration
    from platebench.bench.run.render import render_sample
    from platebench.evaluation.metrics_row import MetricsRow
    from platebench.reconstruction.paper.pipeline import projector_feature_rays
    from platebench.bench.io.atomic import write_json
    ideal_cfg, lens_cfg = configs
    ideal, renderer = render_sample(ideal_cfg)
    proj = ideal.scene.projector
    ideal_rms = MetricsRow.from_score(_depth(ideal, ideal.scene.rig,
                                             projector_feature_rays(proj.camera, proj.pattern))).centres_depth_rms_mm

    result, renderer = run_calibration(lens_cfg, target_z_m=(-0.02, 0.02))
    assert result.distortion_model == "free_distortion"  # chosen from the images
    est = result.report.cameras["free_distortion"]["left"]
    assert abs(est.dist_k1_k2_p1_p2_k3[0] - LENS["k1"]) < 0.02
    assert abs(est.fy_px / est.fx_px - 1.25) < 2e-3
    assert result.rig_estimate.left.distortion is not None

    cmp = compare_reconstruction(lens_cfg, result, renderer)
    rows = {k: MetricsRow.from_score(s) for k, s in cmp.items()}
    for k, s in cmp.items():
        assert s.points.count == 16 and s.matching.correct_match_count == 16, (k, rows[k])
    assert rows["true"].centres_depth_rms_mm < 2.0 * ideal_rms, (rows["true"], ideal_rms)  # the oracle undistorts exactly
    assert rows["estimated"].centres_depth_rms_mm < 2.0 * ideal_rms, (rows["estimated"], ideal_rms)

    # the calibration.json the CLI writes hands the lens to `reconstruct --calibration`
    path = tmp_path / "calibration.json"
    write_json(path, result.report.to_dict())
    rig, rays = load_estimated_calibration(path)
    assert rig.left.distortion == result.rig_estimate.left.distortion

    # without undistortion the same images miss by millimetres: the lens matters
    distorted, _ = render_sample(lens_cfg, renderer)
    pinhole = _depth(distorted, result.stereo["fixed_distortion"].to_rig(), result.rays)
    assert pinhole.points is None or MetricsRow.from_score(pinhole).centres_depth_rms_mm > 10 * ideal_rms
