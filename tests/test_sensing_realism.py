"""The sensing loop under a real rig (``sense --realism``): every pose taken by the robot with its errors,
the loop measuring through the commanded poses and the estimated hand/eye and calibration."""
from __future__ import annotations

import json

import numpy as np
import pytest

from platebench.bench.config import SampleConfig
from platebench.bench.config.presets import with_realism
from platebench.bench.run.realism import RealismSetup, draw_rig, realise
from platebench.scenes.robot import IKError, camera_pose, pose_difference
from platebench.scenes.scene_spec import scene_for_pose
from tests.conftest import run_cli

CFG95 = with_realism(SampleConfig(), "1995")


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
    for c in ("left", "right"):  # the pair really taken is near the command, as an unturned pose's
        dp, da = pose_difference(camera_pose(acq.taken.cameras[c]), camera_pose(rig.cameras[c]))
        assert 1e-5 < dp < 0.01 and 1e-5 < da < 0.02, (dp, da)
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
    # The cameras really stand where the estimated mount and the robot's errors put them: of the order of the
    # mount estimate's error (millimetres and milliradians for this preset), never where they were commanded,
    # and each move lands differently (a new repeatability draw, another arm configuration).
    assert 0.2 * he["mount_position_error_m"] < np.median(pos) < he["mount_position_error_m"] + 3e-3
    assert 0.2 * he["mount_rotation_error_rad"] < np.median(rot) < he["mount_rotation_error_rad"] + 3e-3
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
    assert "realism     1995 (draw 3)" in p.stdout and "moves" in p.stdout


def test_realism_flags_of_sense_and_study_refuse_bad_values(tmp_path):
    cases = [(("sense", "--realism", "1996"), "invalid choice: '1996'"),
             (("sense", "--realism", "1995", "--realism-seed", "-1"), "--realism-seed = -1 is out of range"),
             (("sense", "--realism", "1995", "--camera", "1995"), "--camera and --realism both choose the camera"),
             (("study", "false-boundary", "--realism", "1996"), "invalid choice: '1996'"),
             (("study", "false-boundary", "--realism", "1995", "--width", "100"), "--width = 100 is out of range"),
             (("study", "cut-squares", "--realism", "1995"), "--realism = 1995 for the cut-squares study")]
    for args, words in cases:
        p = run_cli(*args, "--out", tmp_path / "o")
        assert p.returncode == 2 and words in p.stderr.strip().splitlines()[-1], (args, p.stderr)
        assert "Traceback" not in p.stderr
    assert not (tmp_path / "o").exists()
