"""Viewpoint consistency measured in the image (``multiview.contour_planes``) and the plate's front
from the measured surface (``sides``): analytic cylinders, folds and straight edges seen by real
pinhole cameras, with the depth noise a stereo outline has, over small perturbations of the
geometry and other seeds."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from platebench.plates import CylindricalBend, PlateSpec, build_plate
from platebench.plates.spec import Dome, Fold, SCurve, Twist
from platebench.reconstruction.strategy.multiview import (
    CONFIRM_SLIDE_ANGLE_RAD,
    ViewOutline,
    confirm,
    contour_planes,
    slide_angles,
)
from platebench.reconstruction.strategy.sides import (
    SIDE_RADIUS_M,
    SPARSE_MAX_TURN_RAD,
    fit_jets,
    front_side,
    sparse_front_side,
)
from platebench.scenes.camera import Camera


def _thin_loop(P: np.ndarray, cam: Camera, rng, depth_noise_m: float) -> ViewOutline:
    """A closed outline along the 3D polyline ``P`` (N,3): out along it and back one pixel beside
    it in ``cam``'s image, every point moved along its viewing ray by N(0, depth_noise_m) (what a
    stereo outline's depth error does), all row-matched."""
    uv = cam.project(P)
    back = uv[::-1] + np.array([0.0, 1.0])
    UV = np.vstack([uv, back])
    z = cam.depth(np.vstack([P, P[::-1]])) + rng.normal(0.0, depth_noise_m, 2 * len(P))
    rays = np.column_stack([UV, np.ones(len(UV))]) @ np.linalg.inv(cam.K).T
    X = (rays * z[:, None] - cam.t) @ cam.R
    return ViewOutline("v", X, np.ones(len(X), bool), cam.center, UV, "synthetic", cam)


def _cam(eye, target=(0.0, 0.0, 0.0)):
    return Camera.look_at(eye, target, 1000.0, 640, 480, up=(0.0, 1.0, 0.0))


def _ruling(R: float, phi: float, n: int = 160, half_m: float = 0.03) -> np.ndarray:
    """Points along the ruling at angle ``phi`` of a cylinder of radius ``R`` about the y axis
    through (0, 0, -R) (its top at the origin)."""
    y = np.linspace(-half_m, half_m, n)
    return np.column_stack([np.full(n, R * math.sin(phi)), y, np.full(n, -R + R * math.cos(phi))])


@pytest.mark.parametrize("R, seed", [(0.02, 0), (0.021, 1), (0.019, 2)])
def test_contour_plane_is_the_tangent_plane_whatever_the_depth_noise(R, seed):
    """Seen from a camera, a cylinder's occluding contour is the ruling whose tangent plane holds
    the camera. The contour plane measured in the image is that tangent plane to a degree and a
    half, with 0.5 mm of depth noise on every point."""
    rng = np.random.default_rng(seed)
    eye = np.array([0.25, 0.0, 0.3])
    c = np.array([0.0, 0.0, -R])  # the axis, seen in the xz plane
    d = np.hypot(*(eye - c)[[0, 2]])
    phi = math.atan2(eye[0] - c[0], eye[2] - c[2]) - math.acos(R / d)  # the tangent ruling
    P = _ruling(R, phi)
    v = _thin_loop(P, _cam(eye), rng, 0.5e-3)
    true_n = np.array([math.sin(phi), 0.0, math.cos(phi)])  # the surface normal there
    mid = slice(20, len(P) - 20)
    ang = np.degrees(np.arccos(np.clip(np.abs(contour_planes(v)[mid] @ true_n), 0, 1)))
    assert ang.max() < 1.5, ang.max()


@pytest.mark.parametrize("R, turn_deg, seed", [(0.02, 30.0, 0), (0.021, 31.0, 1), (0.019, 29.0, 2)])
def test_coinciding_contours_confirm_nothing_and_a_true_edge_turned_about_is_confirmed(R, turn_deg, seed):
    """Two cameras in one tangent plane of a cylinder see the same ruling as their contour, so
    their outlines agree there although it is no edge; 0.5 mm of depth noise makes their 3D
    directions wander. The contour planes see both cameras in one plane: nothing is confirmed.
    The same two outlines as a true edge (a straight edge seen from poses turned ``turn_deg``
    about it) are confirmed along most of their length."""
    rng = np.random.default_rng(seed)
    phi = math.radians(60.0)
    P = _ruling(R, phi)
    n = np.array([math.sin(phi), 0.0, math.cos(phi)])
    up = np.cross(n, [0.0, 1.0, 0.0])  # in the tangent plane, across the ruling
    base = P[len(P) // 2]
    eyes = [base + 0.4 * (up * math.cos(a) + n * 0.0) + 0.4 * np.array([0.0, math.sin(a), 0.0])
            for a in (math.radians(-20.0), math.radians(20.0))]
    views = [_thin_loop(P, _cam(e, base), rng, 0.5e-3) for e in eyes]
    views = [ViewOutline(f"v{k}", v.points, v.matched, e, v.image_points, "synthetic", v.left)
             for k, (v, e) in enumerate(zip(views, eyes))]
    assert not any(c.any() for c in confirm(views))
    Q = views[0].points[20:140]
    assert np.degrees(slide_angles(contour_planes(views[0])[20:140], Q, views[1].eye)).max() < 3.0
    # a true edge: the same line, the poses turned about it (out of each other's planes)
    edge_eyes = [base + 0.4 * (up * math.cos(a) + n * math.sin(a))
                 for a in (math.radians(-turn_deg / 2), math.radians(turn_deg / 2))]
    edge_views = [_thin_loop(P, _cam(e, base), rng, 0.5e-3) for e in edge_eyes]
    edge_views = [ViewOutline(f"e{k}", v.points, v.matched, e, v.image_points, "synthetic", v.left)
                  for k, (v, e) in enumerate(zip(edge_views, edge_eyes))]
    slide = slide_angles(contour_planes(edge_views[0])[20:140], edge_views[0].points[20:140], edge_views[1].eye)
    assert np.all(slide > CONFIRM_SLIDE_ANGLE_RAD)
    # every point agrees in place, ray angle and slide; the thin loop's way back lies 0.1 mm from
    # its way out, so about half the nearest points walk the edge the other way (same-side rule)
    assert confirm(edge_views, same_side=False)[0][:len(P)].all()
    assert confirm(edge_views)[0][:len(P)].mean() > 0.3
    # the same pair, one of them seeing the edge from behind the sheet: not confirmed
    behind = [np.ones(len(edge_views[0].points), bool), np.zeros(len(edge_views[1].points), bool)]
    assert not confirm(edge_views, front=behind)[0].any()
    # where neither pose sees the plate's known front there (``front_known``), two views of the
    # sheet's back would agree on its edge: not confirmed; one pose that does is enough
    unknown = [np.zeros(len(v.points), bool) for v in edge_views]
    assert not any(c.any() for c in confirm(edge_views, front_known=unknown))
    one = [np.ones(len(edge_views[0].points), bool), np.zeros(len(edge_views[1].points), bool)]
    for a, b in zip(confirm(edge_views, front_known=one), confirm(edge_views)):
        assert np.array_equal(a, b) and b.any()


def _samples(spec: PlateSpec, step_m: float, rng) -> tuple[np.ndarray, np.ndarray]:
    """Points every ``step_m`` over the plate (u, v), jittered, with 0.2 mm of noise, and the
    exact front normals there."""
    return _samples_uv(spec, step_m, rng)[:2]


def _samples_uv(spec: PlateSpec, step_m: float, rng) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``_samples`` and the (N,2) material coordinates (u along the length, v across) of each point."""
    L, W = spec.length_m, spec.width_m
    u, v = np.meshgrid(np.arange(-L / 2 + step_m / 2, L / 2, step_m), np.arange(-W / 2 + step_m / 2, W / 2, step_m))
    uv = np.column_stack([u.ravel(), v.ravel()]) + rng.uniform(-step_m / 4, step_m / 4, (u.size, 2))
    uv = np.clip(uv, [-L / 2, -W / 2], [L / 2, W / 2])
    plate = build_plate(spec)
    P = np.asarray(plate.surface_point(uv)) + rng.normal(0.0, 0.2e-3, (len(uv), 3))
    return P, np.asarray(plate.surface_normal(uv)), uv


@pytest.mark.parametrize("deformation", [
    CylindricalBend(math.radians(300.0), "down"), CylindricalBend(math.radians(300.0), "up"),
    CylindricalBend(math.radians(240.0), "up", math.radians(61.0)), CylindricalBend(math.radians(179.0), "down",
                                                                                    math.radians(89.0)),
    Fold(math.radians(170.0), 0.015, 0.02, "up"), Fold(math.radians(169.0), 0.015, 0.02, "down"),
    Dome(0.012), Twist(math.radians(-80.0))], ids=lambda d: type(d).__name__)
@pytest.mark.parametrize("seed", [0, 1])
def test_the_front_found_from_measured_points_is_the_plates_front(deformation, seed):
    """Square centres about every 7 mm over the plate (as the poses measure them), oriented from
    the level middle and carried over the sheet: the front normals agree with the exact ones on
    at least 97 % of the points, on curls whose tips turn their backs up and folds whose flap
    faces down. Across a 170-degree fold's crease (radius 6.7 mm, points 7 mm apart) each point's
    neighbours lie on both layers and fit no plane (``PLANAR_MAX_RATIO``): nothing joins there, and
    the flap beyond stays unknown, never the wrong way."""
    rng = np.random.default_rng(seed)
    P, N = _samples(PlateSpec(0.1165, 0.0735, deformation=deformation), 7e-3, rng)
    fs = front_side(P)
    tight_crease = isinstance(deformation, Fold) and deformation.angle_rad > math.radians(150.0)
    assert fs.known.mean() > (0.5 if tight_crease else 0.97)
    agree = np.einsum("ij,ij->i", fs.normals, N) > 0
    assert agree[fs.known].mean() > 0.97, agree[fs.known].mean()
    # a camera above sees the top of the plate's middle (the oriented point nearest it; under a
    # 170-degree fold's flap the plate is not measured) from the front, the far side from behind
    mid = int(np.argmin(np.where(fs.known, np.linalg.norm(P[:, :2], axis=1), np.inf)))
    above = P[mid] + np.array([0.0, 0.0, 0.4]) * (1 if N[mid, 2] > 0 else -1)
    assert fs.side(P[mid:mid + 1], above)[0] == 1
    assert fs.side(P[mid:mid + 1], 2 * P[mid] - above)[0] == -1


def _paper_grid_centres(spec: PlateSpec, rng, poses: int = 8, pitch_m: float = 20e-3, shift_m: float = 6e-3):
    """What the paper's 4x4 grid leaves: from each of ``poses`` poses, 16 square centres
    ``pitch_m`` apart over the plate's middle, the grid shifted up to ``shift_m`` from pose to pose
    (the projector moves with the sensor), with 0.5 mm of noise: clusters, ending 20 mm and more
    inside the plate's edges."""
    g = (np.arange(4) - 1.5) * pitch_m
    u, v = np.meshgrid(g, g)
    uv = np.vstack([np.column_stack([u.ravel(), v.ravel()]) + rng.uniform(-shift_m, shift_m, 2) for _ in range(poses)])
    plate = build_plate(spec)
    return np.asarray(plate.surface_point(uv)) + rng.normal(0.0, 0.5e-3, (len(uv), 3)), plate


@pytest.mark.parametrize("deformation", [
    CylindricalBend(math.radians(10.0), "down"), CylindricalBend(math.radians(11.0), "up", math.radians(1.0)),
    CylindricalBend(math.radians(120.0), "up", math.radians(30.0)), CylindricalBend(math.radians(121.0), "down"),
    Dome(0.012), Twist(math.radians(30.0))], ids=lambda d: type(d).__name__)
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sparse_square_centres_orient_a_smooth_plate_out_to_its_edges(deformation, seed):
    """The paper's grid leaves centres too sparse and clustered for the dense orientation (ten
    nearest neighbours, 12 mm joins, sides read off tangent planes within 25 mm): it knows the
    front at less of the boundary (62-98 % here). Fitted over 20 mm, joined over 25 mm and read within 40 mm
    (``sparse_front_side``), the same centres orient the front at three quarters of the boundary
    or more (all of it but the far ends of the 120-degree bends, which drop 40 mm away from the
    middle), never the wrong way, and their normals turn little between neighbours."""
    P, plate = _paper_grid_centres(PlateSpec(0.1165, 0.0735, deformation=deformation), np.random.default_rng(seed))
    B = np.asarray(plate.boundary)
    exact = np.asarray(plate.surface_normal(plate.boundary_uv))
    fs = sparse_front_side(P)
    assert dataclasses.replace(front_side(P), jets=None).oriented_share(B) < fs.oriented_share(B)
    n = fs.normals_at(B)
    known = np.all(np.isfinite(n), axis=1)
    assert known.mean() >= 0.75 and fs.oriented_share(B) == known.mean()
    assert np.all(np.einsum("ij,ij->i", n[known], exact[known]) > 0)
    assert fs.max_turn_rad < SPARSE_MAX_TURN_RAD / 2


@pytest.mark.parametrize("deformation", [
    Fold(math.radians(170.0), 0.015, 0.02, "down"), Fold(math.radians(169.0), 0.015, 0.02, "up"),
    Fold(math.radians(120.0), 0.015, 0.02, "up"), Fold(math.radians(121.0), 0.016, 0.02, "down")],
    ids=lambda d: f"fold{math.degrees(d.angle_rad):.0f}{d.direction}")
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sparse_square_centres_across_a_crease_are_not_trusted_to_orient_it(deformation, seed):
    """Across a fold's crease the sparse centres of the paper's grid can orient the flap the wrong
    way (their joins reach across the crease); there the normals of joined neighbours turn by more
    than ``SPARSE_MAX_TURN_RAD``, which is what the sensing loop reads as "too sparse to orient this
    sheet" (``Measurements.front_checked``)."""
    P, _ = _paper_grid_centres(PlateSpec(0.1165, 0.0735, deformation=deformation), np.random.default_rng(seed))
    assert sparse_front_side(P).max_turn_rad > SPARSE_MAX_TURN_RAD


@pytest.mark.parametrize("deformation", [
    CylindricalBend(math.radians(120.0), "up", math.radians(60.0)), CylindricalBend(math.radians(121.0), "up",
                                                                                     math.radians(61.0)),
    CylindricalBend(math.radians(180.0), "up", math.radians(89.0))], ids=lambda d: f"up{math.degrees(d.angle_rad):.0f}")
@pytest.mark.parametrize("seed", [0, 1])
def test_a_row_of_centres_cut_off_near_a_steep_corner_is_oriented_with_the_plate(deformation, seed):
    """Square centres every 7 mm, but none in a 16 mm band before one end of the plate, whose last
    row stands alone (as one pose's row of squares does beside a steep corner, the squares between
    cut by the outline or stretched apart by the slope): the row is farther than ``JOIN_M`` from the
    rest, and is joined to it along the sheet (``BRIDGE_JOIN_M``), its normals the plate's front."""
    spec = PlateSpec(0.1165, 0.0735, deformation=deformation)
    P, N, uv = _samples_uv(spec, 7e-3, np.random.default_rng(seed))
    L = spec.length_m
    row = uv[:, 0] > L / 2 - 5e-3
    gap = (uv[:, 0] > L / 2 - 21e-3) & ~row
    P, N, row = P[~gap], N[~gap], row[~gap]
    fs = front_side(P)
    assert fs.known[row].mean() >= 0.8 and fs.known.mean() > 0.95
    agree = np.einsum("ij,ij->i", fs.normals, N) > 0
    assert agree[row & fs.known].all() and agree[fs.known].mean() > 0.97


def test_a_front_reads_its_fallback_only_where_it_knows_no_side():
    """``FrontSide.fallback``: the sensing loop's front is the square centres' and, where they
    tell nothing (more than ``SIDE_RADIUS_M`` away), the measured surface's."""
    spec = PlateSpec(0.1165, 0.0735, deformation=CylindricalBend(math.radians(60.0), "up"))
    P, _ = _samples(spec, 7e-3, np.random.default_rng(3))
    middle = np.abs(P[:, 0]) < 0.02
    dense = front_side(P)
    sparse = front_side(P[middle])
    both = dataclasses.replace(sparse, fallback=dense)
    ends = np.abs(P[:, 0]) > 0.02 + SIDE_RADIUS_M + 3e-3  # beyond the reach of the middle's centres
    assert np.isnan(sparse.normals_at(P[ends])).all()
    assert np.allclose(both.normals_at(P[ends]), dense.normals_at(P[ends]))
    assert np.allclose(both.normals_at(P[middle]), sparse.normals_at(P[middle]))
    assert sparse.oriented_share(P) < both.oriented_share(P) == 1.0


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("aspect, angle_deg", [(2.2, 170.0), (2.3, 169.0)])
def test_a_flap_folded_over_the_plate_never_turns_the_plates_front(aspect, angle_deg, seed):
    """A fold of 170 degrees up at aspect 2.2: seen from above, the flap (13 mm over the plate,
    facing down) hides the plate beneath it and is the larger measured part. The part that holds
    the level points on the table (the plate's middle) is oriented, front up; no point is oriented
    the wrong way (with the largest part as the middle, every oriented normal came out reversed)."""
    spec = PlateSpec(0.0735 * aspect, 0.0735, deformation=Fold(math.radians(angle_deg), 0.015, 0.02, "up"))
    P, N, _ = _samples_uv(spec, 7e-3, np.random.default_rng(seed))
    flap = P[:, 2] > 6e-3
    under = ~flap & (P[:, 0] >= P[flap, 0].min()) & (P[:, 0] <= P[flap, 0].max())  # hidden by the flap
    P, N, flap = P[~under], N[~under], flap[~under]
    assert flap.sum() > (~flap).sum()  # the flap is the larger part in view
    fs = front_side(P)
    agree = np.einsum("ij,ij->i", fs.normals, N) > 0
    assert fs.known[~flap & (P[:, 2] < 1e-3)].mean() > 0.95
    assert agree[fs.known].all()


@pytest.mark.parametrize("deformation, aspect", [
    (SCurve(math.radians(120.0), "down", math.radians(90.0)), 1.3),
    (SCurve(math.radians(121.0), "down", math.radians(89.0)), 1.8),
    (SCurve(math.radians(119.0), "down", math.radians(91.0)), 2.2),
    (CylindricalBend(math.radians(120.0), "up", math.radians(60.0)), 1.5)],
    ids=lambda d: f"{type(d).__name__}{math.degrees(d.angle_rad):.0f}" if not isinstance(d, float) else f"{d:g}")
@pytest.mark.parametrize("seed", [0, 1])
def test_a_corner_whose_squares_are_cut_by_both_edges_reads_the_front_of_the_plate_beside_it(deformation, aspect, seed):
    """Square centres every 7 mm, but none within 17 mm of one corner of the plate (as the squares
    there are cut by both edges: on the 120-degree S-curve about axis 90 the nearest measured centre
    lies 15 mm from the corner's outline, median over the verification views): the boundary within
    8 mm of that corner reads its front from the centres beside it (``SIDE_RADIUS_M``), the right way,
    where tangent planes read within 15 mm know it at under half of it."""
    area = 0.1165 * 0.0735
    spec = PlateSpec(math.sqrt(area * aspect), math.sqrt(area / aspect), deformation=deformation)
    P, N, uv = _samples_uv(spec, 7e-3, np.random.default_rng(seed))
    corner = np.array([spec.length_m / 2, -spec.width_m / 2])
    keep = np.linalg.norm(uv - corner, axis=1) > 17e-3
    fs = front_side(P[keep])
    assert fs.known.mean() > 0.95
    plate = build_plate(spec)
    near = np.linalg.norm(np.asarray(plate.boundary_uv) - corner, axis=1) <= 8e-3
    B = np.asarray(plate.boundary)[near]
    exact = np.asarray(plate.surface_normal(np.asarray(plate.boundary_uv)[near]))
    n = fs.normals_at(B)
    known = np.all(np.isfinite(n), axis=1)
    assert known.mean() >= 0.9, known.mean()
    # the right way, within 60 degrees: read up to 25 mm away on a curved sheet (the tangent-plane test
    # bounds the turn to about sqrt(2 SAME_SHEET_M / R), 26 degrees at this S-curve's 30 mm radius,
    # and the fitted normals at the edge of the missing centres add their own)
    assert np.all(np.einsum("ij,ij->i", n[known], exact[known]) > 0.5)
    planes = dataclasses.replace(fs, jets=None)  # the tangent planes alone: the reach is theirs
    assert planes.oriented_share(B) > dataclasses.replace(planes, radius_m=15e-3).oriented_share(B) + 0.4


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("aspect, angle_deg", [(2.2, 170.0), (2.3, 169.0)])
def test_the_plate_beneath_a_folded_flap_never_reads_the_flaps_side(aspect, angle_deg, seed):
    """Within ``SIDE_RADIUS_M`` of the plate beneath a 170-degree fold's flap lie the flap's centres,
    13 mm above and facing down: the plate there (not measured: the flap hides it) reads no side or
    the plate's own, never the flap's (its tangent plane passes 13 mm away, ``SAME_SHEET_M``)."""
    spec = PlateSpec(0.0735 * aspect, 0.0735, deformation=Fold(math.radians(angle_deg), 0.015, 0.02, "up"))
    P, N, _ = _samples_uv(spec, 7e-3, np.random.default_rng(seed))
    flap = P[:, 2] > 6e-3
    under = ~flap & (P[:, 0] >= P[flap, 0].min()) & (P[:, 0] <= P[flap, 0].max())
    fs = front_side(P[~under])
    n = fs.normals_at(P[under])
    known = np.all(np.isfinite(n), axis=1)
    assert np.all(n[known][:, 2] > 0.9)  # the plate's own front, up
    d = np.min(np.linalg.norm(P[under][:, None, :] - P[flap][None, :, :], axis=2), axis=1)
    assert np.mean(d < SIDE_RADIUS_M) > 0.5  # the flap's centres are within reach of most of it


@pytest.mark.parametrize("R, seed", [(0.042, 0), (0.030, 1), (0.060, 2)])
def test_a_centres_quadric_has_the_cylinders_curvature(R, seed):
    """``fit_jets`` on points every 7 mm over a cylinder of radius ``R`` (0.2 mm of noise): the
    quadric at a point away from the ends has the cylinder's curvature 1/R across its rulings (to
    15 %) and none along them, and its normal 20 mm away along the curve is the exact one to a fifth
    of the turn a tangent plane there misses by (20 mm / R rad: 27 degrees on a 42 mm radius)."""
    rng = np.random.default_rng(seed)
    phi, y = np.meshgrid(np.arange(-1.2, 1.2, 7e-3 / R), np.arange(-0.03, 0.03, 7e-3))
    phi = phi.ravel() + rng.uniform(-1e-3 / R, 1e-3 / R, phi.size)
    y = y.ravel()
    P = np.column_stack([R * np.sin(phi), y, R * np.cos(phi) - R]) + rng.normal(0.0, 0.2e-3, (phi.size, 3))
    N = np.column_stack([np.sin(phi), np.zeros_like(phi), np.cos(phi)])
    jets = fit_jets(P, N, np.ones(len(P), bool))
    i = int(np.argmin(phi ** 2 + (y / R) ** 2))  # the top, in the middle
    c = jets.coef(np.array([i]))[0]
    A = np.array([[c[3], c[4]], [c[4], c[5]]])
    k = np.linalg.eigvalsh(A)
    assert abs(k[0] + 1.0 / R) < 0.15 / R and abs(k[1]) < 0.15 / R  # curving away from the front
    target = np.array([R * np.sin(20e-3 / R), y[i], R * np.cos(20e-3 / R) - R])
    n = jets.normals_at(target[None], np.array([[i]]), np.array([[True]]), 3e-3)[0]
    exact = np.array([np.sin(20e-3 / R), 0.0, np.cos(20e-3 / R)])
    turn = np.degrees(20e-3 / R)
    assert np.degrees(np.arccos(np.clip(n @ exact, -1.0, 1.0))) < 0.2 * turn


@pytest.mark.parametrize("axis_deg, aspect", [(40.0, 1.8), (39.0, 1.8), (41.0, 1.75), (40.0, 1.85)])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_corner_beyond_every_tangent_plane_reads_its_front_off_the_quadric(axis_deg, aspect, seed):
    """A 135-degree cylinder bent down about an oblique axis: two of its corners curl down, steep,
    and here no centre lies within 21 mm of any corner (the squares there are cut by both edges and
    stretched by the slope). The sheet leaves a tangent plane by 5 mm or more that far from it, so
    the tangent planes tell the steep corners' boundary (within 8 mm of each corner) little: about
    half of the four corners' together. The centres' osculating quadrics (``jets``) tell 90 % or
    more of it, at least 0.3 more, the right way and within 25 degrees of the exact normal (the
    normals fitted beside a missing patch add their own error, on the level corners too)."""
    area = 0.1165 * 0.0735
    spec = PlateSpec(math.sqrt(area * aspect), math.sqrt(area / aspect),
                     deformation=CylindricalBend(math.radians(135.0), "down", math.radians(axis_deg)))
    P, N, uv = _samples_uv(spec, 7e-3, np.random.default_rng(seed))
    plate = build_plate(spec)
    B_uv, B_all = np.asarray(plate.boundary_uv), np.asarray(plate.boundary)
    known, planes, err = [], [], []
    for sx in (-1, 1):
        for sy in (-1, 1):
            corner = np.array([sx * spec.length_m / 2, sy * spec.width_m / 2])
            fs = front_side(P[np.linalg.norm(uv - corner, axis=1) > 21e-3])
            near = np.linalg.norm(B_uv - corner, axis=1) <= 8e-3
            n = fs.normals_at(B_all[near])
            k = np.all(np.isfinite(n), axis=1)
            exact = np.asarray(plate.surface_normal(B_uv[near]))
            known.append(k)
            planes.append(np.all(np.isfinite(dataclasses.replace(fs, jets=None).normals_at(B_all[near])), axis=1))
            err.append(np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n[k], exact[k]), -1.0, 1.0))))
    known, planes, err = np.concatenate(known), np.concatenate(planes), np.concatenate(err)
    assert known.mean() >= 0.9, known.mean()
    assert known.mean() >= planes.mean() + 0.3, (known.mean(), planes.mean())
    assert err.max() < 25.0, err.max()


@pytest.mark.parametrize("bend_deg, aspect", [(160.0, 3.0), (159.0, 2.9), (161.0, 3.1), (150.0, 2.5)])
@pytest.mark.parametrize("seed", [0, 1])
def test_the_steep_ends_of_a_long_curl_read_their_front_off_quadrics_25_to_35_mm_away(bend_deg, aspect, seed):
    """A strip of aspect 3 curled 160 degrees down: its ends drop steeply and no centre lies within
    24 mm of them along the plate (the projected squares there are foreshortened). No tangent plane
    reaches the ends' boundary (``SIDE_RADIUS_M``); quadrics read up to ``JET_REACH_M`` tell its
    front at three quarters of it or more, within 20 degrees of the exact normal."""
    area = 0.1165 * 0.0735
    spec = PlateSpec(math.sqrt(area * aspect), math.sqrt(area / aspect),
                     deformation=CylindricalBend(math.radians(bend_deg), "down", 0.0))
    P, N, uv = _samples_uv(spec, 7e-3, np.random.default_rng(seed))
    plate = build_plate(spec)
    B_uv = np.asarray(plate.boundary_uv)
    fs = front_side(P[np.abs(uv[:, 0]) < spec.length_m / 2 - 24e-3])
    ends = np.abs(B_uv[:, 0]) > spec.length_m / 2 - 3e-3
    B, exact = np.asarray(plate.boundary)[ends], np.asarray(plate.surface_normal(B_uv[ends]))
    assert dataclasses.replace(fs, jets=None).oriented_share(B) == 0.0
    n = fs.normals_at(B)
    known = np.all(np.isfinite(n), axis=1)
    assert known.mean() >= 0.75, known.mean()
    err = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n[known], exact[known]), -1.0, 1.0)))
    assert err.max() < 20.0, err.max()
