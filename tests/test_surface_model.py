"""The sensing loop's surface model (``bench.run.sensing.loop.Measurements.model``) on an analytic
concave trough: a half cylinder of radius 25 mm and length 100 mm, open upwards, seen by real
pinhole cameras. Its outline (the two rims and the two end arcs) triangulated in the image spans the
opening with a lid of chords; the loop's model must not, or a camera looking into the trough would
be predicted blind to the far end arc's bottom, which it sees."""
from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

from platebench.bench.run.sensing.loop import Measurements
from platebench.reconstruction.strategy.active_views import ActivePoints
from platebench.reconstruction.strategy.multiview import ViewOutline
from platebench.reconstruction.strategy.surface_model import SurfaceModel, view_membrane
from platebench.scenes.camera import Camera

R, HALF_L = 0.025, 0.05


def _trough_outline(step=1e-3):
    """The trough's boundary, closed: rim y = -R (x up), end arc at x = +L/2, rim y = +R (x down),
    end arc at x = -L/2; the surface is y = R sin(phi), z = -R cos(phi), |phi| <= 90 deg."""
    x = np.arange(-HALF_L, HALF_L, step)
    phi = np.arange(-math.pi / 2, math.pi / 2, step / R)
    rim_a = np.c_[x, np.full(len(x), -R), np.zeros(len(x))]
    arc_a = np.c_[np.full(len(phi), HALF_L), R * np.sin(phi), -R * np.cos(phi)]
    rim_b = np.c_[-x, np.full(len(x), R), np.zeros(len(x))]
    arc_b = np.c_[np.full(len(phi), -HALF_L), -R * np.sin(phi), -R * np.cos(phi)]
    return np.vstack([rim_a, arc_a, rim_b, arc_b])


def _surface_points(dx=0.015, dphi_deg=25.0):
    """Points on the trough's surface, as the active stage's square centres would be (M,3)."""
    xs = np.arange(-HALF_L + 0.005, HALF_L, dx)
    ph = np.radians(np.arange(-75.0, 76.0, dphi_deg))
    X, P = np.meshgrid(xs, ph, indexing="ij")
    return np.c_[X.ravel(), R * np.sin(P.ravel()), -R * np.cos(P.ravel())]


def _view(name, eye):
    cam = Camera.look_at(eye, (0.0, 0.0, -R / 2), 1000, 640, 480, up=(0.0, 1.0, 0.0))
    P = _trough_outline()
    return ViewOutline(name, P, np.ones(len(P), bool), np.asarray(eye, float), cam.project(P), "synthetic", cam), cam


def _eye(tilt_deg, distance):
    """``distance`` from the trough's middle, turned ``tilt_deg`` from the vertical toward -x."""
    t = math.radians(tilt_deg)
    return np.array([-distance * math.sin(t), 0.0, distance * math.cos(t) - R / 2])


@pytest.mark.parametrize("tilt_deg, distance", [(60.0, 0.4), (59.0, 0.405), (61.0, 0.395)])
def test_the_loops_surface_model_has_no_lid_over_a_trough(tilt_deg, distance):
    """A pose above the trough measures its outline and square centres. The outline triangulated
    in the image (``view_membrane`` alone) lays a lid over the opening that blocks the way from a
    camera tilted ``tilt_deg`` toward the far end to that end arc's bottom (true surface: nothing in
    between). The loop's model (``Measurements.update``, the poses' membranes without chords) leaves
    the way open, and still blocks a segment through the trough's bottom."""
    top, cam = _view("top", _eye(0.0, distance))
    S = _surface_points()
    far_bottom = np.array([HALF_L, 0.0, -R])
    tilted = _eye(tilt_deg, distance)
    # ground truth: the segment from the tilted camera to the far bottom stays inside the cavity
    t = np.linspace(0.0, 0.97, 200)[:, None]
    seg = tilted + t * (far_bottom - tilted)
    inside = (np.abs(seg[:, 0]) < HALF_L) & (seg[:, 2] < 0)
    assert np.all(seg[inside, 1] ** 2 + seg[inside, 2] ** 2 < R ** 2)  # never through the sheet
    lid = SurfaceModel.build([view_membrane(top)])
    assert lid.blocked(tilted, far_bottom)[0]

    m = Measurements.__new__(Measurements)
    m.views, m.surfaces, m.meshes, m._merged = [], [], [], None
    m.add(SimpleNamespace(name="top", outline=top, active=ActivePoints(
        "top", S, cam.project(S), np.arange(len(S)), np.zeros(len(S)), len(S), 0, 0.015)))
    m.update()
    assert not m.model.blocked(tilted, far_bottom)[0]
    assert m.model.blocked(top.camera_center, np.array([0.0, 0.0, -2.5 * R]))[0]  # through the bottom


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_blocked_is_exact_on_stacked_sheets(seed):
    """Five square sheets stacked 4 mm apart (z = 0, 4, ... 16 mm; x, y within +-20 mm; the poses'
    membranes overlap so in a merged model), as one ``SurfaceModel``. Random segments, many crossing
    several sheets: ``blocked`` says True exactly where, by analytic geometry, the segment meets a
    sheet inside its square farther than ``BLOCK_SLACK_M`` from both ends (the first sheet met
    decides: ray casting stops there)."""
    from platebench.reconstruction.strategy.surface_model import BLOCK_SLACK_M, Membrane

    heights = np.arange(5) * 4e-3
    half = 0.02
    g = np.linspace(-half, half, 9)
    X, Y = np.meshgrid(g, g, indexing="ij")
    quads = np.array([[i * 9 + j, (i + 1) * 9 + j, (i + 1) * 9 + j + 1, i * 9 + j + 1]
                      for i in range(8) for j in range(8)])
    faces = np.vstack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    sheets = [Membrane(f"v{k}", np.c_[X.ravel(), Y.ravel(), np.full(X.size, h)], faces, np.array([0.0, 0.0, 0.4]))
              for k, h in enumerate(heights)]
    model = SurfaceModel.build(sheets)
    rng = np.random.default_rng(seed)
    n = 4000
    a = np.c_[rng.uniform(-0.03, 0.03, (n, 2)), rng.uniform(-0.01, 0.03, n)]
    b = np.c_[rng.uniform(-0.03, 0.03, (n, 2)), rng.uniform(-0.01, 0.03, n)]
    d = b - a
    dist = np.linalg.norm(d, axis=1)
    want = np.zeros(n, bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for h in heights:
            s = (h - a[:, 2]) / d[:, 2]  # fraction of the segment where it meets z = h
            p = a + s[:, None] * d
            inside = (np.abs(p[:, 0]) < half) & (np.abs(p[:, 1]) < half)
            want |= inside & (s * dist > BLOCK_SLACK_M) & (s * dist < dist - BLOCK_SLACK_M)
    # leave out segments within 1 um of a decision's edge (a sheet's border, the slack): float ties
    margin = np.zeros(n, bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for h in heights:
            s = (h - a[:, 2]) / d[:, 2]
            p = a + s[:, None] * d
            margin |= np.isfinite(s) & ((np.abs(np.abs(p[:, 0]) - half) < 1e-6) | (np.abs(np.abs(p[:, 1]) - half) < 1e-6)
                                        | (np.abs(s * dist - BLOCK_SLACK_M) < 1e-6)
                                        | (np.abs(s * dist - (dist - BLOCK_SLACK_M)) < 1e-6))
    got = model.blocked(a, b)
    assert want[~margin].sum() > n // 4 and (~want[~margin]).sum() > n // 4  # both answers well represented
    assert np.array_equal(got[~margin], want[~margin])
