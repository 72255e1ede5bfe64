"""The sensing loop under a real rig (``sense --realism``): every pose taken by the robot with its errors,
the loop measuring through the commanded poses and the estimated hand/eye and calibration."""
from __future__ import annotations

import json

import numpy as np
import pytest

from platebench.bench.config import SampleConfig
from platebench.bench.config.hardware_robot import CELL, ROBOTS, nominal_arm
from platebench.bench.config.presets import with_realism
from platebench.bench.run.realism import RealismSetup, draw_rig, realise
from platebench.scenes.robot import IKError, camera_pose, kinematic_error_sigmas, pose_difference
from platebench.scenes.scene_spec import scene_for_pose
from tests.conftest import run_cli

CFG95 = with_realism(SampleConfig(), "1995")
PUMA = ROBOTS[CFG95.realism.robot]
# the arm's absolute error (RMS over configurations): its published position accuracy and the orientation
# error the kinematic model implies for it (``scenes.robot.kinematic_error_sigmas``)
ARM_POSITION_RMS_M = PUMA.accuracy_position_m
ARM_ROTATION_RMS_RAD = kinematic_error_sigmas(nominal_arm(PUMA), [CELL.q_seed], PUMA.accuracy_position_m)[2]


def _far_side_rig(tilt_deg: float, distance_m: float = 0.45):
    """The 1995 rig looking at the plate from the side away from the robot's base (azimuth 0)."""
    t = np.radians(tilt_deg)
    centre = distance_m * np.array([np.sin(t), 0.0, np.cos(t)])
    return scene_for_pose(centre, np.zeros(3), np.array([0.0, 1.0, 0.0]), CFG95.scene.build()).rig


def test_one_draw_takes_successive_pairs_with_the_same_robot_and_estimates():
    """``realise`` is one draw's first pair; the draw's later pairs keep its robot and estimates and
    draw a new repeatability error for every move."""
    rig = CFG95.scene.build().rig
    setup = RealismSetup.prepare(CFG95.realism, CFG95, corner_noise_px=0.15)
    d = draw_rig(setup, rig.left, 7)
    first, again = d.acquire(rig), d.acquire(rig)
    ref = realise(setup, rig, 7)
    # the same draw again (OpenCV's calibration may differ in the last bits between calls)
    assert np.allclose(first.taken.left.t, ref.taken.left.t, atol=1e-9)
    assert np.allclose(first.told.left.K, ref.told.left.K)
    assert np.array_equal(again.told.left.K, first.told.left.K)  # the same estimates
    step, _ = pose_difference(camera_pose(first.taken.left), camera_pose(again.taken.left))
    assert 1e-6 < step < 1e-3  # a new move to the same command: the PUMA's repeatability (0.1 mm RP), not more


@pytest.mark.parametrize("tilt_deg", [40.0, 55.0])
def test_a_pose_beyond_the_arms_reach_is_taken_with_the_cell_turned(tilt_deg):
    rig = _far_side_rig(tilt_deg)
    d = draw_rig(RealismSetup.prepare(CFG95.realism, CFG95, corner_noise_px=0.15), rig.left, 2)
    with pytest.raises(IKError):  # from the cell as it stands, the arm cannot reach the far side
        for cam in (rig.left, rig.right):
            d.robot.joints_for(d.eye().command_for(cam))
    yaw = d.reach_yaw(rig)
    assert yaw is not None and yaw != 0.0
    acq = d.acquire(rig, yaw)
    for c in ("left", "right"):  # the pair really taken is near the command: within the arm's own error
        dp, da = pose_difference(camera_pose(acq.taken.cameras[c]), camera_pose(rig.cameras[c]))
        assert 1e-5 < dp < 3 * ARM_POSITION_RMS_M and 1e-5 < da < 3 * ARM_ROTATION_RMS_RAD, (dp, da)
        assert acq.report.views[c].position_error_m == pytest.approx(dp)


def test_sense_under_the_1995_rig_measures_through_the_commanded_poses(tmp_path):
    out = tmp_path / "s95"
    p = run_cli("sense", "--realism", "1995", "--realism-seed", "3", "--width", "320", "--height", "300", "--spp", "2",
                "--bend-deg", "60", "--out", out)
    assert p.returncode == 0, p.stderr
    doc = json.loads((out / "sensing.json").read_text())
    acq = doc["acquisition"]
    assert acq["realism"]["preset"] == "1995" and acq["realism"]["seed"] == 3
    assert doc["config"]["realism"]["seed"] == 3
    he = acq["estimates"]["hand_eye"]
    moves = acq["moves"]
    assert len(moves) >= len(doc["final"]["poses"]) + 1  # stage 1, stage 2 (stage 3 where it stands), the views
    pos = np.array([[m[f"{c}_position_error_m"] for c in ("left", "right")] for m in moves])
    rot = np.array([[m[f"{c}_rotation_error_rad"] for c in ("left", "right")] for m in moves])
    # The cameras really stand where the estimated mount and the robot's errors put them: off by the mount
    # estimate's error and the arm's absolute error at each configuration (centimetres and tens of milliradians
    # for the PUMA), never where they were commanded, and each move lands differently (a new repeatability
    # draw, another arm configuration).
    assert 0.2 * he["mount_position_error_m"] < np.median(pos) < he["mount_position_error_m"] + 2 * ARM_POSITION_RMS_M
    assert 0.2 * he["mount_rotation_error_rad"] < np.median(rot) < he["mount_rotation_error_rad"] + 2 * ARM_ROTATION_RMS_RAD
    assert pos.min() > 1e-5 and np.ptp(pos) > 1e-5
    # stage 3's sample: its calibration is what the loop was told (the commanded stage-2 pose, estimated K), its
    # ground truth comes from the cameras really posed, apart by the move recorded for stage 2
    from platebench.bench.io.sample_files import load_calibration, load_true_cameras
    told, taken = load_calibration(out / "stage3" / "sample").rig, load_true_cameras(out / "stage3" / "sample")
    pose2 = doc["steps"][1]["pose"]
    commanded = scene_for_pose(np.array(pose2["center_m"]), np.array(pose2["target_m"]), np.array(pose2["baseline_dir"]),
                               CFG95.scene.build()).rig
    assert np.allclose(told.left.center, commanded.left.center, atol=1e-9)
    assert not np.allclose(told.left.K, with_realism(SampleConfig(), "1995").scene.build().rig.left.K)
    stage2 = next(m for m in moves if m["view"] == "stage 2")
    dp, _ = pose_difference(camera_pose(taken.left), camera_pose(told.left))
    assert dp == pytest.approx(stage2["left_position_error_m"], rel=1e-6)
    assert doc["final"]["outcome"] != "silent"
    # the PUMA's poses stand centimetres off: no pair confirms an edge, and the loop stops its cures after
    # FRUITLESS_CURES of them instead of spending the budget, saying why
    from platebench.reconstruction.strategy.budget import FRUITLESS_CURES, MAX_CURE_VIEWS
    stop = [st for st in doc["steps"] if st.get("decision") == "stop"]
    assert not doc["final"]["boundary_verified"] and len(stop) == 1
    assert doc["cures"] == FRUITLESS_CURES < MAX_CURE_VIEWS and "confirmed no outline point" in stop[0]["reason"]
    assert "realism     1995 (draw 3)" in p.stdout and "moves" in p.stdout
    # the loop knows how far its poses disagree from its own hand/eye residuals (not the truth), and moved
    # each pose's outline onto the others' (``registration``): by millimetres, as the moves were off
    spread = acq["pose_spread"]
    assert spread["translation_rms_mm"] == pytest.approx(he["residual_translation_rms_m"] * 1e3, abs=1e-3)
    reg = acq["registration"]
    mv = np.load(out / "multiview.npz")
    assert sorted(reg) == sorted(mv["view_names"].tolist())
    shift = np.linalg.norm(np.array(list(reg.values())), axis=1)
    assert 0.05 < np.median(shift) < 3 * np.median(pos) * 1e3 + 1.0, shift
    assert "registered" in p.stdout


def test_realism_flags_of_sense_and_study_refuse_bad_values(tmp_path):
    cases = [(("sense", "--realism", "1996"), "invalid choice: '1996'"),
             (("sense", "--realism", "1995", "--realism-seed", "-1"), "--realism-seed = -1 is out of range"),
             (("sense", "--realism", "1995", "--camera", "1995"), "--camera and --realism both choose the camera"),
             (("study", "false-boundary", "--realism", "1996"), "invalid choice: '1996'"),
             (("study", "false-boundary", "--realism", "1995", "--width", "100"), "--width = 100 is out of range"),
             (("study", "cut-squares", "--realism", "1995"), "--realism = 1995 for the cut-squares study"),
             (("study", "false-boundary", "--realism-scale", "robot_accuracy=2"),
              "--realism-scale robot_accuracy=2 without an error source"),
             (("study", "false-boundary", "--realism", "1995", "--realism-scale", "robot_accuracy=x"),
              "--realism-scale robot_accuracy = 'x' is not a number"),
             (("study", "false-boundary", "--realism", "1995", "--realism-scale", "lens=2"),
              "--realism-scale source 'lens' is not on in realism 1995"),
             (("study", "false-boundary", "--realism", "1995", "--realism-scale", "noise=2,noise=3"),
              "--realism-scale source 'noise' is given twice"),
             (("study", "cut-squares", "--realism-scale", "robot_accuracy=2"),
              "--realism-scale robot_accuracy=2 for the cut-squares study")]
    for args, words in cases:
        p = run_cli(*args, "--out", tmp_path / "o")
        assert p.returncode == 2 and words in p.stderr.strip().splitlines()[-1], (args, p.stderr)
        assert "Traceback" not in p.stderr
    assert not (tmp_path / "o").exists()


def test_ground_truth_finds_a_point_where_the_camera_really_posed_shows_it_in_the_measured_image():
    """``PassiveView.image_of``: a world point through the camera really posed and its true lens,
    then undistorted with the told lens into the told pinhole's pixels, checked against OpenCV's
    ``projectPoints`` and ``undistortPoints`` (a camera 3 mm and 0.5 degree off the told one,
    different lenses and focal lengths)."""
    import cv2
    from scipy.spatial.transform import Rotation

    from platebench.bench.run.sensing.sensor import PassiveView
    from platebench.scenes.camera import Camera, intrinsics
    from platebench.scenes.lens import BrownConrady

    from dataclasses import replace as dc_replace
    told = dc_replace(Camera.look_at([0.01, -0.02, 0.4], [0.0, 0.0, 0.0], 800.0, 640, 480),
                      distortion=BrownConrady(k1=-0.08, k2=0.05, p1=0.001))
    turn = Rotation.from_rotvec(np.radians(0.5) * np.array([0.6, 0.8, 0.0])).as_matrix()
    true = Camera(intrinsics(812.0, 640, 480), turn @ told.R, turn @ told.t + [0.003, -0.001, 0.002], 640, 480,
                  BrownConrady(k1=-0.11, k2=0.09, p2=-0.002))
    P = np.random.default_rng(4).uniform([-0.06, -0.04, -0.02], [0.06, 0.04, 0.02], (200, 3))
    v = PassiveView("test", None, None, told.pinhole, {}, true_left=true, told_left=told)
    raw, _ = cv2.projectPoints(P, cv2.Rodrigues(true.R)[0], true.t, true.K, true.distortion.as_opencv())
    want = cv2.undistortPoints(raw, told.K, told.distortion.as_opencv(), P=told.K,
                               criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)).reshape(-1, 2)
    assert np.max(np.linalg.norm(v.image_of(P) - want, axis=1)) < 1e-6
    # far from the told camera's own projection (the pose error), which it equals without rig errors
    assert np.median(np.linalg.norm(v.image_of(P) - told.pinhole.project(P), axis=1)) > 5.0
    plain = PassiveView("test", None, None, told.pinhole, {})
    assert np.array_equal(plain.image_of(P), told.pinhole.project(P))


@pytest.mark.parametrize("seed", [0, 3])
def test_a_measured_outline_lies_where_the_truth_really_appears_under_the_1995_rig(seed):
    """Under a real rig, the stage-2 outline measured at 320 x 240 passes within a pixel of every true
    boundary point the left camera sees, as ``image_of`` places it (what ``final_visibility`` asks)."""
    from dataclasses import replace

    from scipy.spatial import cKDTree

    from platebench.bench.config import RenderSettings, SceneParams
    from platebench.bench.run.sensing.sensor import SimulatedSensor
    from platebench.reconstruction.strategy.poses import SensorPose

    cfg = with_realism(SampleConfig(scene=SceneParams(width=320, height=240), render=RenderSettings(spp=2)), "1995")
    sensor = SimulatedSensor(replace(cfg, realism=replace(cfg.realism, seed=seed)), verify_grid=None)
    rig = sensor.base.rig
    b = rig.right.center - rig.left.center
    view = sensor.passive_view("test", SensorPose(rig.center, np.zeros(3), b / np.linalg.norm(b)))
    assert view.true_left is not None and view.told_left is not None
    seen = np.asarray(view.gt_visibility["left"].visible, bool)
    d = cKDTree(view.outline.image_points).query(view.image_of(sensor.plate.boundary[seen]))[0]
    assert seen.mean() > 0.99 and np.percentile(d, 95) < 1.0, np.percentile(d, [50, 95])


def test_a_studys_realism_scale_reaches_every_plates_draw():
    """``study false-boundary --realism 1995 --realism-scale robot_accuracy=0.5``: the study's rig and each
    plate's draw carry the scale, and the robot drawn for a plate has half the kinematic spread of the
    preset's (the arm's accuracy halved), its repeatability unchanged."""
    import argparse

    from platebench.bench.cli.study import study_base
    from platebench.bench.run.sensing.study import study_cases, with_realism_seeds
    from platebench.scenes.scene_spec import RenderSettings

    args = argparse.Namespace(realism="1995", realism_scale="robot_accuracy=0.5", grid=None, width=320)
    base, extra = study_base(args, RenderSettings(spp=1))
    assert base.realism.scales == {"robot_accuracy": 0.5} and extra["corner_noise_px"] > 0
    case = with_realism_seeds(study_cases()[:1], 0)[0]
    cfg = case.config(base)
    assert cfg.realism.scales == {"robot_accuracy": 0.5} and cfg.realism.seed == case.realism_seed
    half = RealismSetup.prepare(cfg.realism, cfg, corner_noise_px=0.15).robot_model
    full = RealismSetup.prepare(CFG95.realism, CFG95, corner_noise_px=0.15).robot_model
    assert half.sigma_angle_rad == pytest.approx(0.5 * full.sigma_angle_rad, rel=1e-12)
    assert half.joint_sigma_rad == pytest.approx(full.joint_sigma_rad, rel=1e-12)
    # the study's settings record the scale and read it back; a study at the sourced magnitudes writes none
    from platebench.bench.io.codecs import decode, encode
    from platebench.bench.io.sensing_records import StudyRealism
    rz = StudyRealism("1995", base.realism.sources, "seeds", 0.15, tuple(base.realism.scales.items()))
    assert encode(rz)["realism_scales"] == {"robot_accuracy": 0.5}
    assert decode(StudyRealism, json.loads(json.dumps(encode(rz)))) == rz
    assert "realism_scales" not in encode(StudyRealism("1995", base.realism.sources, "seeds", 0.15))
