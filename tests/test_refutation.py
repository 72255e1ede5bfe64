"""Refutation (``reconstruction.strategy.refutation``): analytic cases on a flat 100 x 60 mm plate in
z = 0, seen by real pinhole cameras. A confirmed stretch lying on the plate's inside (as where two
poses' occluding contours cross) is refuted by the poses that see that part of the plate; the true
edges are not; nor is a point in front of or behind the measured surface."""
from __future__ import annotations

import math

import numpy as np
import pytest

from platebench.bench.io.codecs import encode
from platebench.reconstruction.strategy.multiview import ViewOutline, verify
from platebench.reconstruction.strategy.refutation import (
    REFUTE_DEPTH_M,
    REFUTE_MARGIN_PX,
    free_space_faces,
    membrane_mesh,
    refute,
    seen_inside,
    seen_outside,
)
from platebench.reconstruction.strategy.surface_model import view_membrane
from platebench.scenes.camera import Camera


def _rectangle(L=0.1, W=0.06, step=1e-3, center=(0.0, 0.0)):
    """A closed L x W rectangle in z = 0 (metres), one point per ``step``."""
    x0, y0 = center[0] - L / 2, center[1] - W / 2
    c = [(x0, y0), (x0 + L, y0), (x0 + L, y0 + W), (x0, y0 + W)]
    P = []
    for a, b in zip(c, c[1:] + c[:1]):
        k = int(round(math.dist(a, b) / step))
        P.append(np.linspace(a, b, k, endpoint=False))
    P = np.vstack(P)
    return np.c_[P, np.zeros(len(P))]


def _view(name, P, eye):
    cam = Camera.look_at(eye, (0.0, 0.0, 0.0), 1000, 640, 480)
    return ViewOutline(name, P, np.ones(len(P), bool), np.asarray(eye, float), cam.project(P), "synthetic", cam)


def _eyes(tilt_deg=35.0, distance=0.4):
    s, c = math.sin(math.radians(tilt_deg)), math.cos(math.radians(tilt_deg))
    return [(0.0, 0.0, distance), (distance * s, 0.0, distance * c), (0.0, distance * s, distance * c)]


@pytest.mark.parametrize("tilt_deg, distance, inset", [(35.0, 0.4, 0.02), (34.0, 0.405, 0.015), (36.0, 0.395, 0.025)])
def test_a_stretch_on_the_plates_inside_is_refuted_and_the_true_edges_are_not(tilt_deg, distance, inset):
    views = [_view(f"pose {k}", _rectangle(), e) for k, e in enumerate(_eyes(tilt_deg, distance))]
    # a fourth pose's outline running `inset` inside the plate all round (contours crossing on the surface)
    views.append(_view("crossing", _rectangle(L=0.1 - 2 * inset, W=0.06 - 2 * inset), (-0.2, -0.1, 0.35)))
    meshes = [membrane_mesh(view_membrane(v)) for v in views]
    confirmed = [np.ones(len(v.points), bool) for v in views]
    r = refute(views, confirmed, meshes)
    assert r[3].all()  # seen inside by all three poses that see the whole plate
    assert not any(x.any() for x in r[:3])  # every true edge point lies on the others' outlines
    # without the refutation the stray stretch is a second closed loop: not verified, and rightly so
    # (a plate has one boundary); with it, the rectangle is verified and the stretch listed as refuted
    assert not verify(views, confirmed=confirmed).verified
    v = verify(views, confirmed=confirmed, refuted=r)
    assert v.verified, v.reason
    assert encode(v)["refuted_points"] == len(views[3].points)


def test_a_point_off_the_measured_surface_or_near_the_outline_is_not_seen_inside():
    v = _view("top", _rectangle(), (0.0, 0.0, 0.4))
    mesh = membrane_mesh(view_membrane(v))
    on = np.array([[0.0, 0.0, 0.0], [0.03, 0.01, 0.0]])
    assert seen_inside(on, v, mesh).all()
    # in front of the surface (a concave plate's near edge seen against its far side), or behind it
    # (an edge the plate hides): the surface along the ray is farther than REFUTE_DEPTH_M away
    for dz in (2 * REFUTE_DEPTH_M, -2 * REFUTE_DEPTH_M):
        assert not seen_inside(on + [0.0, 0.0, dz], v, mesh).any()
    assert seen_inside(on + [0.0, 0.0, 0.5 * REFUTE_DEPTH_M], v, mesh).all()
    # within the pixel margin of the outline: could be the outline itself
    px_m = 0.4 / 1000  # metres per pixel at 0.4 m, f = 1000 px
    near_edge = np.array([[0.05 - 0.5 * REFUTE_MARGIN_PX * px_m, 0.0, 0.0]])
    assert not seen_inside(near_edge, v, mesh).any()
    # a pose without a camera refutes nothing
    blind = ViewOutline("blind", v.points, v.matched, v.camera_center, v.image_points, "synthetic")
    assert not seen_inside(on, blind, mesh).any()


def test_refute_needs_one_membrane_per_view():
    v = _view("top", _rectangle(), (0.0, 0.0, 0.4))
    with pytest.raises(ValueError, match="1 membrane meshes for 2 views"):
        refute([v, v], [np.ones(len(v.points), bool)] * 2, [membrane_mesh(view_membrane(v))])


@pytest.mark.parametrize("tilt_deg, distance", [(35.0, 0.4), (34.0, 0.405), (36.0, 0.395)])
def test_points_beside_the_plate_are_seen_outside_and_points_on_or_above_it_are_not(tilt_deg, distance):
    """Every point of the plate in view projects inside a pose's outline. Points 30 mm beside the
    plate project outside it (the pose saw background there); points on the plate, 20 mm above or
    below its middle (seen against it), and points within the pixel margin of the outline do not;
    nor do points out of the frame or behind the camera, about which the pose saw nothing."""
    views = [_view(f"pose {k}", _rectangle(), e) for k, e in enumerate(_eyes(tilt_deg, distance))]
    on = np.array([[0.0, 0.0, 0.0], [0.03, 0.01, 0.0], [-0.04, -0.02, 0.0]])
    beside = np.array([[0.08, 0.0, 0.0], [0.0, 0.06, 0.0], [-0.08, -0.05, 0.0]])
    px_m = distance / 1000  # metres per pixel at the plate, f = 1000 px
    near_edge = np.array([[0.05 + 0.5 * REFUTE_MARGIN_PX * px_m, 0.0, 0.0]])
    for v in views:
        assert not seen_outside(on, v).any()
        middle = np.array([[0.0, 0.0, 0.0], [0.01, 0.005, 0.0]])
        assert not seen_outside(middle + [0.0, 0.0, 0.02], v).any()
        assert not seen_outside(middle - [0.0, 0.0, 0.02], v).any()
        assert seen_outside(beside, v).all()
        assert not seen_outside(near_edge, v).any()
        assert not seen_outside(np.array([[5.0, 0.0, 0.0], [0.0, 0.0, 2.0]]), v).any()  # out of frame, behind
    blind = ViewOutline("blind", views[0].points, views[0].matched, views[0].camera_center, views[0].image_points,
                        "synthetic")
    assert not seen_outside(beside, blind).any()


@pytest.mark.parametrize("lift_m", [0.025, 0.03])
def test_the_merged_surface_drops_the_faces_of_a_stretch_measured_off_the_plate(lift_m):
    """A fourth pose's surface: the plate, with its outline's corner stretch measured ``lift_m``
    too far along its own rays (a mismatched stretch, which then lies beyond the plate's edge:
    beside it in the other poses' images). The three other poses saw background there: the faces
    touching it are dropped, the rest kept; the three true surfaces keep every face."""
    views = [_view(f"pose {k}", _rectangle(), e) for k, e in enumerate(_eyes())]
    bad = _rectangle()
    lift = (bad[:, 0] > 0.035) & (bad[:, 1] > 0.015)
    eye = np.array([-0.1, -0.1, 0.38])
    ray = bad[lift] - eye
    bad[lift] += lift_m * ray / np.linalg.norm(ray, axis=1, keepdims=True)  # along the pose's own rays
    views.append(_view("mismatched", bad, eye))
    membranes = [view_membrane(v) for v in views]
    keep = free_space_faces(membranes, views)
    assert all(k.all() for k in keep[:3])
    faces = np.asarray(membranes[3].faces)
    lifted = np.nonzero(np.linalg.norm(membranes[3].vertices[:, None] - bad[lift][None], axis=2).min(axis=1) < 1e-9)[0]
    touching = np.isin(faces, lifted).any(axis=1)
    assert touching.any() and not keep[3][touching].any()
    assert keep[3][~touching].all()
