"""What the planner predicts and what ground truth says a pair of poses could verify, against
analytic geometry and real pinhole projections: the angle an edge crosses a rig's image rows
(``planner.row_angles``), an outline's two main directions (``planner.outline_axes``) and the
true boundary a pair of poses could confirm (``scoring.verifiable_visibility``), over small
perturbations of the geometry."""
from __future__ import annotations

import math

import numpy as np
import pytest

from platebench.bench.run.sensing.scoring import verifiable_visibility
from platebench.reconstruction.strategy.planner import baseline_choices, outline_axes, row_angles
from platebench.reconstruction.strategy.poses import SensorPose
from platebench.scenes.camera import Camera


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_row_angles_are_the_angles_the_projected_edges_make_with_the_image_rows(seed):
    """A rig's image rows run along its baseline. For random edges near the target, seen from a
    random pose, each baseline's angle equals the one measured on a real camera's image whose x
    axis lies along that baseline (the projected edge's direction against the image x axis)."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=3)
    d[2] = abs(d[2]) + 1.0
    d /= np.linalg.norm(d)
    target = rng.uniform(-0.01, 0.01, 3)
    pose = SensorPose(target + 0.4 * d, target, np.cross(d, [0.3, 1.0, 0.1]) / np.linalg.norm(np.cross(d, [0.3, 1.0, 0.1])))
    P = target + rng.uniform(-0.05, 0.05, (40, 3))
    T = rng.normal(size=(40, 3))
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    B = baseline_choices(pose)
    got = row_angles(pose, P, T, B)
    assert got.shape == (len(B), len(P))
    for b, row in zip(B, got):
        cam = Camera.look_at(pose.center, pose.target, 1000.0, 640, 480, up=np.cross(pose.view_dir, b))
        assert abs(cam.R[0] @ b) > 1 - 1e-9  # the image x axis is the baseline
        d_img = cam.project(P + 1e-6 * T) - cam.project(P - 1e-6 * T)
        want = np.arctan2(np.abs(d_img[:, 1]), np.abs(d_img[:, 0]))
        np.testing.assert_allclose(row, want, atol=1e-5)


def test_baseline_choices_cover_half_a_turn_across_the_centre_line():
    pose = SensorPose(np.array([0.0, 0.0, 0.4]), np.zeros(3), np.array([1.0, 0.0, 0.0]))
    B = baseline_choices(pose)
    np.testing.assert_allclose(B[0], pose.baseline_dir, atol=1e-12)
    np.testing.assert_allclose(B @ pose.view_dir, 0.0, atol=1e-12)
    ang = np.degrees(np.arctan2(B[:, 1], B[:, 0]))
    np.testing.assert_allclose(np.abs(np.diff(ang)), 180.0 / len(B), atol=1e-9)


@pytest.mark.parametrize("turn_deg", [0.0, 17.0, 44.0, -61.0])
@pytest.mark.parametrize("tilt_deg", [0.0, 1.0, 25.0])
def test_outline_axes_are_a_rectangles_sides_whatever_its_turn(turn_deg, tilt_deg):
    """A 100 x 60 mm rectangle turned ``turn_deg`` in a plane tilted ``tilt_deg``: the two axes lie
    along its sides (to 0.5 degree), perpendicular and across the plane's normal."""
    L, W, n = 0.1, 0.06, 400
    c = [(-L / 2, -W / 2), (L / 2, -W / 2), (L / 2, W / 2), (-L / 2, W / 2)]
    P2 = np.vstack([np.linspace(a, b, n // 4, endpoint=False) for a, b in zip(c, c[1:] + c[:1])])
    a, t = math.radians(turn_deg), math.radians(tilt_deg)
    Rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])
    P = np.c_[P2, np.zeros(len(P2))] @ (Rx @ Rz).T
    normal = Rx @ np.array([0.0, 0.0, 1.0])
    side = Rx @ Rz @ np.array([1.0, 0.0, 0.0])
    u, v = outline_axes(P, normal)
    assert abs(u @ v) < 1e-9 and abs(u @ normal) < 1e-9 and abs(v @ normal) < 1e-9
    off = min(math.degrees(math.acos(min(1.0, abs(x @ side)))) for x in (u, v))
    assert off < 0.5, off


def _rectangle(L=0.1, W=0.06, step=1e-3):
    c = [(-L / 2, -W / 2), (L / 2, -W / 2), (L / 2, W / 2), (-L / 2, W / 2)]
    P = np.vstack([np.linspace(a, b, int(round(math.dist(a, b) / step)), endpoint=False)
                   for a, b in zip(c, c[1:] + c[:1])])
    return np.c_[P, np.zeros(len(P))]


@pytest.mark.parametrize("turn_deg, dist_m", [(30.0, 0.4), (31.0, 0.395), (29.0, 0.405)])
def test_verifiable_boundary_is_where_the_poses_turn_about_the_edge(turn_deg, dist_m):
    """A flat 100 x 60 mm rectangle in z = 0, every point seen by both poses. Two poses turned
    ``turn_deg`` about the x axis lie out of each other's planes through the long edges (along x):
    those are verifiable. Two poses side by side along x at one height lie in one plane with
    every line along x (a long edge seen from either is the same plane): the long edges are not
    verifiable, while the short edges (along y), about which they turn, are."""
    P = _rectangle()
    long_edge = (np.abs(np.abs(P[:, 1]) - 0.03) < 1e-9) & (np.abs(P[:, 0]) < 0.045)
    short_edge = (np.abs(np.abs(P[:, 0]) - 0.05) < 1e-9) & (np.abs(P[:, 1]) < 0.025)
    masks = {"left": np.ones((2, len(P)), bool), "right": np.ones((2, len(P)), bool)}
    h = math.radians(turn_deg / 2)
    about_x = np.array([[0.0, -dist_m * math.sin(h), dist_m * math.cos(h)],
                        [0.0, dist_m * math.sin(h), dist_m * math.cos(h)]])
    v = verifiable_visibility(P, about_x, about_x, masks)
    assert v.visible[long_edge].all()
    side_by_side = np.array([[-0.15, 0.0, dist_m], [0.15, 0.0, dist_m]])
    w = verifiable_visibility(P, side_by_side, side_by_side, masks)
    assert not w.visible[long_edge].any()
    assert w.visible[short_edge].all()
    # a pose neither camera of which sees a point verifies nothing there
    hidden = {"left": masks["left"].copy(), "right": masks["right"].copy()}
    hidden["right"][1, long_edge] = False
    assert not verifiable_visibility(P, about_x, about_x, hidden).visible[long_edge].any()
    # too small a turn verifies nothing
    close = about_x * np.array([1.0, 0.3, 1.0])
    assert not verifiable_visibility(P, close, close, masks).visible.any()


@pytest.mark.parametrize("about_deg, along_deg, dist_m", [(24.0, 16.0, 0.4), (23.0, 17.0, 0.395), (25.0, 15.0, 0.405)])
def test_verifiable_asks_the_slide_angle_the_verdict_asks(about_deg, along_deg, dist_m):
    """Two poses turned ``about_deg`` about the rectangle's long edges (x) and ``along_deg`` along them:
    their rays differ by more than ``CONFIRM_ANGLE_RAD`` (25 degrees) while each lies between 20 and 27
    degrees out of the other's plane through the edge (checked here from the geometry). So the long
    edges are verifiable by the ideal verdict's rule (``CONFIRM_SLIDE_ANGLE_RAD``, the default) and
    not by a real rig's (``CONFIRM_SLIDE_ANGLE_RIG_RAD``), as ``reach_visibility`` passes it on."""
    from platebench.bench.run.sensing.scoring import reach_visibility
    from platebench.reconstruction.strategy.multiview import (
        CONFIRM_ANGLE_RAD, CONFIRM_SLIDE_ANGLE_RAD, CONFIRM_SLIDE_ANGLE_RIG_RAD)

    P = _rectangle()
    long_edge = (np.abs(np.abs(P[:, 1]) - 0.03) < 1e-9) & (np.abs(P[:, 0]) < 0.045)
    masks = {"left": np.ones((2, len(P)), bool), "right": np.ones((2, len(P)), bool)}

    def toward(a_deg, b_deg):  # turned a about x, then b about y
        a, b = math.radians(a_deg), math.radians(b_deg)
        v = np.array([0.0, -math.sin(a), math.cos(a)])
        return dist_m * np.array([v[0] * math.cos(b) + v[2] * math.sin(b), v[1], -v[0] * math.sin(b) + v[2] * math.cos(b)])
    C = np.array([toward(-about_deg / 2, -along_deg / 2), toward(about_deg / 2, along_deg / 2)])
    for p in P[long_edge]:  # the window: rays 25+ degrees apart, each pose 20-27 degrees out of the other's plane
        r = (C - p) / np.linalg.norm(C - p, axis=1, keepdims=True)
        assert r[0] @ r[1] < math.cos(CONFIRM_ANGLE_RAD)
        for i in (0, 1):
            n = np.cross(r[i], [1.0, 0.0, 0.0])
            slide = math.asin(abs(r[1 - i] @ n / np.linalg.norm(n)))
            assert CONFIRM_SLIDE_ANGLE_RAD + math.radians(0.5) < slide < CONFIRM_SLIDE_ANGLE_RIG_RAD - math.radians(0.5)
    assert verifiable_visibility(P, C, C, masks).visible[long_edge].all()
    assert not verifiable_visibility(P, C, C, masks, CONFIRM_SLIDE_ANGLE_RIG_RAD).visible[long_edge].any()
    poses = [SensorPose(c, np.zeros(3), np.array([1.0, 0.0, 0.0])) for c in C]
    for angle, want in ((CONFIRM_SLIDE_ANGLE_RAD, True), (CONFIRM_SLIDE_ANGLE_RIG_RAD, False)):
        _, v = reach_visibility(P, poses, 0.0, masks, angle)
        assert v["left"].visible[long_edge].all() == want and v["left"].visible[long_edge].any() == want
