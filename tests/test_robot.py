"""The robot that moves the camera, the hand/eye solver and the realism presets: numpy only, no renders.

Against analytic truth: a known mount recovered exactly from noise-free poses; the robot's errors have
the statistics its datasheet states (ISO 9283 RP), and the orientation repeatability the joint model
predicts matches the published measurement it was not fitted to.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from platebench.bench.config import SampleConfig
from platebench.bench.config.hardware_robot import CELL, ROBOTS, TARGET, nominal_arm, robot_error_model
from platebench.bench.config.presets import with_realism
from platebench.bench.config.realism import REALISM_PRESETS, SOURCES, Realism, RealismError
from platebench.bench.io.codecs import decode, encode
from platebench.bench.run.realism import RealismSetup, calibration_flange_poses, realise
from platebench.reconstruction.calibration.hand_eye import HandEyeError, solve_hand_eye
from platebench.scenes.robot import (
    EyeInHand,
    Robot,
    RobotErrorModel,
    camera_pose,
    invert_pose,
    iso9283_repeatability,
    pose_difference,
    pose_matrix,
)
from platebench.scenes.scene_spec import reference_scene


def _random_pose(rng, spread_m=0.3):
    return pose_matrix(Rotation.random(random_state=rng).as_matrix(), rng.normal(0.0, spread_m, 3))


def _views(rng, X, T_base_target, n=8):
    F = [_random_pose(rng, 0.5) for _ in range(n)]
    P = [invert_pose(f @ X) @ T_base_target for f in F]
    return F, P


# -- hand/eye --------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", range(6))
def test_hand_eye_recovers_a_known_mount_exactly_from_noise_free_poses(seed):
    rng = np.random.default_rng(seed)
    X, T_bt = _random_pose(rng, 0.1), _random_pose(rng, 0.5)
    F, P = _views(rng, X, T_bt, n=3 + seed)  # 3 views (the minimum) and more
    r = solve_hand_eye(F, P)
    assert np.abs(r.T_flange_camera - X).max() < 1e-9
    assert np.abs(r.T_base_target - T_bt).max() < 1e-9
    assert r.rotation_rms_rad < 1e-9 and r.translation_rms_m < 1e-9


def test_hand_eye_recovers_the_cells_mount_from_its_calibration_views():
    """The cell's own hand/eye views (the robot's real, reachable commands), noise-free."""
    F = calibration_flange_poses(CELL, TARGET)
    T_wb = TARGET.pose_world(CELL)
    P = [invert_pose(f @ CELL.mount) @ T_wb for f in F]
    r = solve_hand_eye(F, P)
    dp, da = pose_difference(r.T_flange_camera, CELL.mount)
    assert dp < 1e-9 and da < 1e-9
    assert max(pose_difference(r.T_base_target, T_wb)) < 1e-9


def _noisy_error(seed, sigma_rad, sigma_m):
    rng = np.random.default_rng(seed)
    X, T_bt = _random_pose(rng, 0.1), _random_pose(rng, 0.5)
    F, P = _views(rng, X, T_bt, n=10)
    noisy = []
    for p in P:
        dR = Rotation.from_rotvec(rng.normal(0.0, sigma_rad, 3)).as_matrix()
        noisy.append(pose_matrix(dR @ p[:3, :3], p[:3, 3] + rng.normal(0.0, sigma_m, 3)))
    return pose_difference(solve_hand_eye(F, noisy).T_flange_camera, X)


def test_hand_eye_degrades_gracefully_with_noise():
    """Error grows in proportion to the noise (first order), stays of the noise's order."""
    seeds = range(12)
    e1 = np.array([_noisy_error(s, 1e-3, 1e-4) for s in seeds])
    e2 = np.array([_noisy_error(s, 2e-3, 2e-4) for s in seeds])
    ratio = np.median(e2 / e1, axis=0)
    assert np.all((1.6 < ratio) & (ratio < 2.4)), ratio
    assert np.median(e1[:, 1]) < 1.5e-3 and np.median(e1[:, 0]) < 2e-3  # rotation ~ sigma, position ~ sigma x lever


def test_hand_eye_refuses_rotations_about_one_axis():
    rng = np.random.default_rng(0)
    X, T_bt = _random_pose(rng, 0.1), _random_pose(rng, 0.5)
    F = [pose_matrix(Rotation.from_euler("z", a).as_matrix(), rng.normal(0, 0.3, 3)) for a in (0.0, 0.4, 0.9, 1.3)]
    P = [invert_pose(f @ X) @ T_bt for f in F]
    with pytest.raises(HandEyeError, match="one axis"):
        solve_hand_eye(F, P)


# -- the robot's errors --------------------------------------------------------------------------
def _repeat(name: str, n: int = 3000, q=None):
    hw = ROBOTS[name]
    arm = nominal_arm(hw)
    robot = Robot.build(arm, robot_error_model(hw, accuracy=False), CELL.q_seed, None)
    T = arm.fk(CELL.q_seed if q is None else q)
    rng = np.random.default_rng(7)
    reached = [robot.execute(T, rng) for _ in range(n)]
    pos = np.array([t[:3, 3] for t in reached])
    rot = np.array([Rotation.from_matrix(t[:3, :3] @ T[:3, :3].T).as_rotvec() for t in reached])
    return hw, T, pos, rot


@pytest.mark.parametrize("name", ["puma560", "modern"])
def test_repeatability_is_the_datasheets_iso9283_rp(name):
    hw, T, pos, _ = _repeat(name)
    assert iso9283_repeatability(pos) == pytest.approx(hw.repeatability_rp_m, rel=0.05)
    assert np.linalg.norm(pos.mean(axis=0) - T[:3, 3]) < 0.1 * hw.repeatability_rp_m  # no bias: repeatability only


def test_modern_orientation_repeatability_matches_the_published_measurement():
    """Not an input: the joint sigma comes from the position RP (37 um); Slamani, Nubiola & Bonev (2012)
    measured the orientation repeatability, at worst 87 urad (ISO 9283: 3 std per axis)."""
    hw, _, _, rot = _repeat("modern")
    worst = 3.0 * rot.std(axis=0).max()
    assert worst == pytest.approx(hw.orientation_repeatability_rad, rel=0.25)


@pytest.mark.parametrize("name", ["puma560", "modern"])
def test_absolute_accuracy_is_the_published_rms_over_robots(name):
    """Over many robots (kinematic error draws), the RMS position error at the cell's working configurations
    is the published accuracy; the orientation error it implies stays within the published worst case."""
    hw = ROBOTS[name]
    arm = nominal_arm(hw)
    qs = [CELL.q_seed] + [arm.ik(T, CELL.q_seed) for T in calibration_flange_poses(CELL, TARGET)]
    model = robot_error_model(hw, q_sample=qs, repeatability=False)
    rng = np.random.default_rng(11)
    dpos, drot = [], []
    for _ in range(300):
        real = Robot.build(arm, model, CELL.q_seed, rng).real
        for q in qs:
            dp, da = pose_difference(real.fk(q), arm.fk(q))
            dpos.append(dp)
            drot.append(da)
    assert np.sqrt(np.mean(np.square(dpos))) == pytest.approx(hw.accuracy_position_m, rel=0.1)
    if hw.accuracy_orientation_rad is not None:
        assert np.sqrt(np.mean(np.square(drot))) <= hw.accuracy_orientation_rad


def test_an_exact_robot_goes_where_it_is_told_and_ik_round_trips():
    hw = ROBOTS["puma560"]
    arm = nominal_arm(hw)
    robot = Robot.build(arm, RobotErrorModel(), CELL.q_seed, np.random.default_rng(0))
    for T in calibration_flange_poses(CELL, TARGET):
        assert np.abs(robot.execute(T, np.random.default_rng(1)) - T).max() < 1e-10
        assert np.abs(arm.fk(arm.ik(T, CELL.q_seed)) - T).max() < 1e-10


@pytest.mark.parametrize("shift", [0.0, 0.005, -0.005])
def test_eye_in_hand_places_the_wanted_camera_through_the_true_mount(shift):
    """With the true mount believed and an exact robot, the camera is where it was asked for; a believed
    mount off by a known offset puts it off by exactly that offset (in the camera frame)."""
    hw = ROBOTS["puma560"]
    robot = Robot.build(nominal_arm(hw), RobotErrorModel(), CELL.q_seed, None)
    rig = reference_scene(width=512, height=480, f_px=800.0).rig
    off = pose_matrix(np.eye(3), [shift, 0.0, 0.0])
    eye = EyeInHand(robot, CELL.mount, CELL.mount @ off, rig.left)
    got = eye.move(rig.left, None)
    expected = camera_pose(rig.left) @ invert_pose(off)
    assert np.abs(camera_pose(got) - expected).max() < 1e-9


# -- realism presets -----------------------------------------------------------------------------
def test_every_source_is_off_in_ideal_and_the_ideal_config_is_the_benchs():
    ideal = REALISM_PRESETS["ideal"]
    assert ideal.sources == () and ideal.is_ideal and ideal.robot is None
    assert not any(ideal.on(s) for s in SOURCES)
    assert encode(with_realism(SampleConfig(), "ideal")) == encode(SampleConfig())
    cfg = with_realism(SampleConfig(), ideal)
    rig = cfg.scene.build().rig
    acq = realise(RealismSetup.prepare(ideal, cfg), rig, 5)
    assert acq.taken is rig and acq.told is rig


@pytest.mark.parametrize("name", ["1995", "modern"])
def test_each_source_switches_alone(name):
    rz = REALISM_PRESETS[name]
    assert set(rz.sources) == set(SOURCES)
    for s in SOURCES:
        assert rz.only(s).sources == (s,) and rz.without(s).sources == tuple(x for x in SOURCES if x != s)
    assert not rz.scaled("robot_accuracy", 0.0).on("robot_accuracy")
    assert decode(Realism, encode(rz.with_seed(9))) == rz.with_seed(9)
    with pytest.raises(RealismError, match="allowed"):
        rz.with_sources(["lens_flare"])


def test_estimates_from_noise_free_views_of_an_exact_robot_are_the_truth():
    """hand_eye and calibration on, the robot exact, the corners located exactly: the pair taken is the
    commanded one and the method is told the truth (the frames of the whole chain agree)."""
    rz = REALISM_PRESETS["1995"].with_sources(["hand_eye", "calibration"])
    cfg = with_realism(SampleConfig(), rz)
    rig = cfg.scene.build().rig
    acq = realise(RealismSetup.prepare(rz, cfg, corner_noise_px=0.0), rig, 3)
    for c in ("left", "right"):  # calibrateCamera works on float32 points: 1 um, 1 urad
        assert max(pose_difference(camera_pose(acq.taken.cameras[c]), camera_pose(rig.cameras[c]))) < 1e-6
    assert np.abs(acq.told.left.K - rig.left.K).max() < 1e-3  # px, of 931
    assert max(pose_difference(acq.T_world_block_est, acq.T_world_block)) < 1e-6


def test_robot_errors_move_the_views_by_their_sourced_order():
    """Repeatability alone: each view within a few RP of its command, the pair no longer parallel."""
    rz = REALISM_PRESETS["1995"].only("robot_repeatability")
    cfg = with_realism(SampleConfig(), rz)
    rig = cfg.scene.build().rig
    setup = RealismSetup.prepare(rz, cfg)
    d = [realise(setup, rig, k).report.views["left"].position_error_m for k in range(20)]
    rp = ROBOTS["puma560"].repeatability_rp_m
    assert 0.05 * rp < np.median(d) < rp
    acq = realise(setup, rig, 0)
    assert not np.allclose(acq.taken.left.R, acq.taken.right.R, atol=1e-9)
    assert acq.told is not acq.taken and np.allclose(acq.told.left.R, rig.left.R)


def test_realism_sweep_axes_set_the_preset_each_source_and_the_draw():
    from platebench.bench.config.axes import parameter_columns
    from platebench.bench.sweep.spec import parse_spec

    spec = parse_spec({"sweep": {"name": "r", "methods": ["paper"]}, "base": {"scene": {"width": 320, "height": 240}},
                       "grid": {"realism": ["ideal", "1995"], "realism_robot_accuracy": [0, 3], "realism_seed": [2]}})
    by = {(p.params["realism"], p.params["realism_robot_accuracy"]): p.config for p in spec.samples}
    assert len(spec.samples) == 3  # the robot axis does not apply to ideal: its two samples are one
    ideal, off, big = by[("ideal", 0.0)], by[("1995", 0.0)], by[("1995", 3.0)]
    assert ideal.realism.is_ideal and ideal.scene.width == 320 and ideal.realism.seed == 2
    assert off.scene.width == 512 and not off.realism.on("robot_accuracy") and off.realism.on("robot_repeatability")
    assert big.realism.scale("robot_accuracy") == 3.0 and big.realism.seed == 2
    cols = parameter_columns(encode(big))
    assert cols["realism"] == "1995" and cols["realism_seed"] == 2 and cols["realism_robot_accuracy"] == 3.0
    assert parameter_columns(encode(SampleConfig()))["realism"] == "ideal"
