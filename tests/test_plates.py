"""Tests of plates/: specs, exact analytic surfaces, meshes, outlines, against analytic truth.

Units: metres and radians; world frame +Z up, flat plate in z = 0 (see plates/spec.py).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh

from platebench.bench.io.codecs import decode, encode
from platebench.plates import (
    CylindricalBend,
    Dent,
    Dome,
    Flat,
    Fold,
    Plate,
    PlateSpec,
    PlateSpecError,
    SCurve,
    Twist,
    build_plate,
    reference_spec,
)
from platebench.plates.spec import FAMILIES
from platebench.plates.deformations import (
    surface_derivatives,
    surface_normal,
    surface_point,
)

L, W = 0.1165, 0.0735
DEG = math.pi / 180
RNG_SEED = 1995


def spec(deformation, thickness=0.0, length=L, width=W) -> PlateSpec:
    return PlateSpec(length, width, thickness, deformation)


EVERY_FAMILY = {
    "flat": spec(Flat()),
    "cylinder": spec(CylindricalBend(40 * DEG, "up", 0.0)),
    "cylinder_oblique_down": spec(CylindricalBend(120 * DEG, "down", 0.7)),
    "fold": spec(Fold(90 * DEG, 0.02, 0.01, "up")),
    "fold_oblique_down": spec(Fold(150 * DEG, -0.01, 0.008, "down", 2.2)),
    "twist": spec(Twist(-60 * DEG)),
    "dome": spec(Dome(0.008)),
    "bowl": spec(Dome(-0.005)),
    "dent": spec(Dent(0.002, 0.012, 0.02, -0.01)),
    "s_curve": spec(SCurve(130 * DEG, "down", 0.4)),
}
THICK = {
    "flat": spec(Flat(), 0.002),
    "cylinder_up": spec(CylindricalBend(60 * DEG, "up", 0.3), 0.002),
    "cylinder_down_350": spec(CylindricalBend(350 * DEG, "down", 0.0), 0.003),
    "fold": spec(Fold(120 * DEG, 0.0, 0.01, "down", 1.9), 0.001),
    "twist": spec(Twist(45 * DEG), 0.002),
    "dome": spec(Dome(0.006), 0.002),
    "dent": spec(Dent(0.002, 0.012, -0.05, 0.03), 0.001),
    "s_curve": spec(SCurve(90 * DEG, "up", 1.3), 0.002),
}
ISOMETRIC = ("flat", "cylinder", "cylinder_oblique_down", "fold", "fold_oblique_down", "s_curve")


@pytest.fixture(scope="module")
def plates() -> dict[str, Plate]:
    built = {f"sheet_{k}": build_plate(s) for k, s in EVERY_FAMILY.items()}
    built.update({f"thick_{k}": build_plate(s) for k, s in THICK.items()})
    built["reference"] = build_plate(reference_spec())
    built["bend180"] = build_plate(spec(CylindricalBend(180 * DEG, "up")))
    built["bend350"] = build_plate(spec(CylindricalBend(350 * DEG, "up")))
    return built


def random_uv(n: int, seed: int = RNG_SEED, length: float = L, width: float = W) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.uniform([-length / 2, -width / 2], [length / 2, width / 2], size=(n, 2))


def bending_frame(axis_rad: float):
    """Unit bending direction e and axis direction g in uv, and g in 3D."""
    e = np.array([math.cos(axis_rad), math.sin(axis_rad)])
    g = np.array([-math.sin(axis_rad), math.cos(axis_rad)])
    return e, g, np.array([g[0], g[1], 0.0])


def extreme_corners(axis_rad: float, length: float = L, width: float = W):
    """Rectangle corners with the smallest and largest bending coordinate s."""
    e, _, _ = bending_frame(axis_rad)
    corners = np.array([[x, y] for x in (-length / 2, length / 2) for y in (-width / 2, width / 2)])
    s = corners @ e
    return corners[np.argmin(s)], corners[np.argmax(s)]


def centre_line(axis_rad: float, n: int) -> np.ndarray:
    """Dense material line through the plate centre along the bending direction, inside the plate."""
    e, _, _ = bending_frame(axis_rad)
    reach = min(L / 2 / abs(e[0]) if abs(e[0]) > 1e-15 else math.inf,
                W / 2 / abs(e[1]) if abs(e[1]) > 1e-15 else math.inf)
    s = np.linspace(-reach, reach, n)
    return s[:, None] * e, 2 * reach


def polyline_length(points: np.ndarray, closed: bool = False) -> float:
    if closed:
        points = np.vstack([points, points[:1]])
    return float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())


def signed_turn(t0: np.ndarray, t1: np.ndarray, about: np.ndarray) -> float:
    """Rotation angle in [0, 2 pi) taking t0 to t1 about the unit vector `about`."""
    angle = math.atan2(float(np.dot(np.cross(t0, t1), about)), float(np.dot(t0, t1)))
    return angle % (2 * math.pi)


# ---------------------------------------------------------------- specs

def test_reference_spec_is_the_papers_plate():
    ref = reference_spec()
    assert (ref.length_m, ref.width_m, ref.thickness_m) == (0.1165, 0.0735, 0.0)
    assert ref.deformation == CylindricalBend(math.radians(10), "up", 0.0)


@pytest.mark.parametrize("name", list(EVERY_FAMILY) + [f"thick_{k}" for k in THICK])
def test_dict_round_trip_every_family(name):
    s = EVERY_FAMILY[name] if name in EVERY_FAMILY else THICK[name[len("thick_"):]]
    d = json.loads(json.dumps(encode(s)))
    assert decode(PlateSpec, d) == s
    assert d["deformation"]["family"] in FAMILIES and type(s.deformation) is FAMILIES[d["deformation"]["family"]]


def test_decode_defaults_to_flat_sheet():
    assert decode(PlateSpec, {"length_m": 0.2, "width_m": 0.1}) == PlateSpec(0.2, 0.1)


@pytest.mark.parametrize("make, words", [
    (lambda: PlateSpec(-0.1, W), ["PlateSpec.length_m", "-0.1", "allowed"]),
    (lambda: PlateSpec(L, 0.0), ["PlateSpec.width_m", "0", "allowed 0.001 to 10 m"]),
    (lambda: PlateSpec(1e300, W), ["PlateSpec.length_m", "1e+300", "allowed 0.001 to 10 m"]),
    (lambda: CylindricalBend(1e-14), ["CylindricalBend.angle_rad", "1e-14", "allowed 0 (flat) or 1e-06 to 350 deg"]),
    (lambda: PlateSpec(float("nan"), W), ["PlateSpec.length_m", "nan", "allowed"]),
    (lambda: PlateSpec(L, float("inf")), ["PlateSpec.width_m", "inf", "allowed"]),
    (lambda: PlateSpec(L, W, -0.001), ["PlateSpec.thickness_m", "-0.001", "allowed"]),
    (lambda: PlateSpec(L, "wide"), ["PlateSpec.width_m", "'wide'", "not a number"]),
    (lambda: CylindricalBend(6.3), ["CylindricalBend.angle_rad = 6.3 (360.96 deg)",
                                    "allowed 0 to 350 deg"]),
    (lambda: CylindricalBend(2 * math.pi), ["CylindricalBend.angle_rad", "360.00 deg", "350 deg"]),
    (lambda: CylindricalBend(351 * DEG), ["CylindricalBend.angle_rad", "351.00 deg", "350 deg"]),
    (lambda: CylindricalBend(-0.1), ["CylindricalBend.angle_rad", "-0.1", "0 to 350 deg"]),
    (lambda: CylindricalBend(float("nan")), ["CylindricalBend.angle_rad", "nan", "350 deg"]),
    (lambda: CylindricalBend(0.1, "left"), ["CylindricalBend.direction", "'left'", "'up' or 'down'"]),
    (lambda: CylindricalBend(0.1, "up", math.pi), ["CylindricalBend.axis_rad", "180.00 deg",
                                                   "0 to 180 deg"]),
    (lambda: Fold(0.5, 0.0, -0.01, "up"), ["Fold.band_m", "-0.01", "allowed > 0"]),
    (lambda: Fold(190 * DEG, 0.0, 0.01, "up"), ["Fold.angle_rad", "190.00 deg", "0 to 180 deg"]),
    (lambda: spec(Fold(0.5, 0.0, 0.2, "up")), ["Fold.band_m", "0.2", "0.1165"]),
    (lambda: spec(Fold(0.5, 0.0, 0.2, "up", math.pi / 2)), ["Fold.band_m", "0.2", "0.0735"]),
    (lambda: spec(Fold(0.5, 0.055, 0.01, "up")), ["Fold.position_m", "0.055", "-0.05325 to 0.05325"]),
    (lambda: Twist(100 * DEG), ["Twist.angle_rad", "100.00 deg", "-90 to 90 deg"]),
    (lambda: spec(Dome(0.03)), ["Dome.sag_m", "0.03", "allowed"]),
    (lambda: Dent(0.01, 0.01), ["Dent.depth_m", "0.01", "0.005"]),
    (lambda: Dent(0.001, 0.0), ["Dent.radius_m", "0", "> 0"]),
    (lambda: spec(Dent(0.001, 0.01, 0.07)), ["Dent.centre_u_m", "0.07", "-0.05825 to 0.05825"]),
    (lambda: spec(Fold(180 * DEG, 0.0, 0.005, "up"), 0.001), ["PlateSpec.thickness_m", "0.001",
                                                              "0.000795775", "radius"]),
    (lambda: spec(Flat(), 0.05), ["PlateSpec.thickness_m", "0.05", "0.00735"]),
    (lambda: PlateSpec(L, W, 0.0, "cylinder"), ["PlateSpec.deformation", "allowed"]),
])
def test_bad_specs_raise_with_field_value_and_range(make, words):
    with pytest.raises(PlateSpecError) as info:
        make()
    message = str(info.value)
    assert "\n" not in message
    for word in words:
        assert word in message, (word, message)


def test_plate_spec_error_is_a_value_error():
    assert issubclass(PlateSpecError, ValueError)


@pytest.mark.parametrize("d, words", [
    ({"length_m": L, "width_m": W, "deformation": {"family": "saddle"}},
     ["'saddle'", "flat, cylinder, fold, twist, dome, dent"]),
    ({"length_m": L, "width_m": W, "colour": "white"}, ["'colour'", "unknown"]),
    ({"length_m": L, "width_m": W, "deformation": {"family": "cylinder", "angle_rad": 0.1,
                                                   "radius_m": 1.0}}, ["'radius_m'", "unknown"]),
    ({"length_m": L}, ["'width_m'", "missing"]),
    ({"length_m": L, "width_m": W, "deformation": {"family": "fold", "angle_rad": 0.1}},
     ["'band_m'", "missing"]),
    ({"length_m": L, "width_m": W, "deformation": {"family": "cylinder", "angle_rad": 7.0}},
     ["CylindricalBend.angle_rad", "401.07 deg"]),
])
def test_decode_errors_name_the_problem(d, words):
    with pytest.raises(PlateSpecError) as info:
        decode(PlateSpec, d)
    for word in words:
        assert word in str(info.value), (word, str(info.value))


def test_specs_are_frozen():
    with pytest.raises(AttributeError):
        reference_spec().length_m = 1.0


# ---------------------------------------------------------------- analytic surfaces

@pytest.mark.parametrize("angle_deg", [10, 90, 180, 350])
@pytest.mark.parametrize("direction", ["up", "down"])
@pytest.mark.parametrize("axis_rad", [0.0, math.pi / 2, 0.7, 2.5])
def test_cylinder_end_tangents_differ_by_the_bend_angle(angle_deg, direction, axis_rad):
    s = spec(CylindricalBend(angle_deg * DEG, direction, axis_rad))
    e, _, g3 = bending_frame(axis_rad)
    start, end = extreme_corners(axis_rad)
    _, r_u, r_v = surface_derivatives(s, np.array([start, end]))
    tangents = e[0] * r_u + e[1] * r_v
    assert np.allclose(np.linalg.norm(tangents, axis=1), 1.0, atol=1e-14)
    about = -g3 if direction == "up" else g3
    assert abs(signed_turn(tangents[0], tangents[1], about) - angle_deg * DEG) < 1e-9


@pytest.mark.parametrize("direction", ["up", "down"])
def test_bend_direction_moves_the_ends_toward_plus_or_minus_z(direction):
    s = spec(CylindricalBend(90 * DEG, direction))
    ends = surface_point(s, np.array([[-L / 2, 0.0], [L / 2, 0.0]]))
    assert np.all(np.sign(ends[:, 2]) == (1 if direction == "up" else -1))
    centre_normal = surface_normal(s, np.zeros(2))
    assert np.allclose(centre_normal, [0, 0, 1], atol=1e-15)
    # concave side toward +Z for "up": the normals at the ends lean toward the centre
    n = surface_normal(s, np.array([[L / 2, 0.0]]))[0]
    assert (n[0] < 0) == (direction == "up")


@pytest.mark.parametrize("deformation", [
    CylindricalBend(10 * DEG), CylindricalBend(350 * DEG, "down"), CylindricalBend(180 * DEG, "up", 0.7),
    CylindricalBend(90 * DEG, "up", math.pi / 2), Fold(180 * DEG, 0.03, 0.01, "up"),
    Fold(90 * DEG, -0.01, 0.004, "down", 2.5), Fold(120 * DEG, 0.0, 0.02, "up", math.pi / 2),
])
def test_arc_length_of_centre_line_is_preserved(deformation):
    s = spec(deformation)
    uv, material_length = centre_line(deformation.axis_rad, 400_001)
    mapped = polyline_length(surface_point(s, uv))
    assert abs(mapped / material_length - 1) < 1e-9


@pytest.mark.parametrize("angle_deg", [10, 90, 180])
@pytest.mark.parametrize("axis_rad", [0.0, 1.2])
def test_fold_turns_by_its_angle_and_keeps_the_negative_side_in_place(angle_deg, axis_rad):
    fold = Fold(angle_deg * DEG, 0.01, 0.012, "up", axis_rad)
    s = spec(fold)
    e, _, g3 = bending_frame(axis_rad)
    start, end = extreme_corners(axis_rad)
    _, r_u, r_v = surface_derivatives(s, np.array([start, end]))
    tangents = e[0] * r_u + e[1] * r_v
    assert abs(signed_turn(tangents[0], tangents[1], -g3) - angle_deg * DEG) < 1e-9
    # everything with s < position - band/2 is the identity map
    uv = random_uv(2000)
    fixed = uv @ e < fold.position_m - fold.band_m / 2
    assert fixed.any() and (~fixed).any()
    assert np.allclose(surface_point(s, uv[fixed])[:, :2], uv[fixed], rtol=0, atol=1e-16)
    assert np.all(surface_point(s, uv[fixed])[:, 2] == 0)
    assert np.all(surface_point(s, uv[~fixed])[:, 2] >= 0)


def test_fold_is_c1_at_the_band_edges():
    fold = Fold(120 * DEG, 0.0, 0.01, "down", 0.0)
    s = spec(fold)
    eps = 1e-9
    for edge in (-0.005, 0.005):
        uv = np.array([[edge - eps, 0.01], [edge + eps, 0.01]])
        p = surface_point(s, uv)
        n = surface_normal(s, uv)
        assert np.linalg.norm(p[1] - p[0]) < 3 * eps
        assert np.linalg.norm(n[1] - n[0]) < 1e-6


def test_zero_angle_bends_and_flat_stay_in_the_plane():
    uv = random_uv(500)
    for deformation in (Flat(), CylindricalBend(0.0, "down", 1.0), Fold(0.0, 0.0, 0.01, "up"),
                        Twist(0.0), Dome(0.0)):
        p = surface_point(spec(deformation), uv)
        assert np.allclose(p[:, :2], uv, atol=1e-15) and np.all(p[:, 2] == 0)
        assert np.allclose(surface_normal(spec(deformation), uv), [0, 0, 1], atol=1e-15)


def test_twist_turns_the_end_sections_by_the_twist_angle():
    angle = 70 * DEG
    s = spec(Twist(angle))
    ends = surface_point(s, np.array([[-L / 2, W / 2], [L / 2, W / 2]]))
    turn = [math.atan2(p[2], p[1]) for p in ends]
    assert abs((turn[1] - turn[0]) - angle) < 1e-12
    assert np.allclose(surface_point(s, np.array([[0.03, 0.0]])), [[0.03, 0, 0]], atol=1e-17)


@pytest.mark.parametrize("sag", [0.008, -0.005])
def test_dome_corner_height_is_minus_sag(sag):
    s = spec(Dome(sag))
    corners = np.array([[x, y] for x in (-L / 2, L / 2) for y in (-W / 2, W / 2)])
    assert np.allclose(surface_point(s, corners)[:, 2], -sag, rtol=0, atol=1e-15)
    assert np.allclose(surface_point(s, np.zeros(2)), 0.0)
    # points on a sphere of radius 1/c centred on the Z axis
    c = 2 * sag / ((L * L + W * W) / 4 + sag * sag)
    p = surface_point(s, random_uv(1000))
    centre = np.array([0, 0, -1 / c])
    assert np.allclose(np.linalg.norm(p - centre, axis=1), abs(1 / c), rtol=1e-12)
    n = surface_normal(s, random_uv(1000))
    assert np.allclose(n, (p - centre) * c, atol=1e-12)


def test_dent_profile_depth_support_and_smoothness():
    dent = Dent(0.002, 0.012, 0.02, -0.01)
    s = spec(dent)
    assert surface_point(s, np.array([0.02, -0.01]))[2] == pytest.approx(-0.002, abs=1e-16)
    uv = random_uv(5000)
    r = np.linalg.norm(uv - [0.02, -0.01], axis=1)
    z = surface_point(s, uv)[:, 2]
    assert np.all(z[r >= 0.012] == 0) and np.all(z[r < 0.012] < 0) and np.all(z >= -0.002)
    assert np.allclose(surface_normal(s, uv[r >= 0.012]), [0, 0, 1])


@pytest.mark.parametrize("name", list(EVERY_FAMILY))
def test_normals_unit_orthogonal_to_tangents_and_derivatives_match_fd(name):
    s = EVERY_FAMILY[name]
    uv = random_uv(300)
    r, r_u, r_v = surface_derivatives(s, uv)
    n = surface_normal(s, uv)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-14)
    h = 1e-6
    for k, analytic in ((0, r_u), (1, r_v)):
        step = np.zeros(2)
        step[k] = h
        fd = (surface_point(s, uv + step) - surface_point(s, uv - step)) / (2 * h)
        assert np.max(np.abs(fd - analytic)) < 1e-6
        assert np.max(np.abs(np.einsum("ij,ij->i", fd, n))) < 1e-6
    assert np.allclose(surface_point(s, uv), r, atol=0)


@pytest.mark.parametrize("name", [k for k in EVERY_FAMILY if not k.startswith("fold")])
def test_centre_stays_at_origin_with_normal_plus_z(name):
    s = EVERY_FAMILY[name]
    expected_z = 0.0 if name != "dent" else surface_point(s, np.zeros(2))[2]
    assert np.allclose(surface_point(s, np.zeros(2)), [0, 0, expected_z], atol=1e-17)
    if name != "dent":
        assert np.allclose(surface_normal(s, np.zeros(2)), [0, 0, 1], atol=1e-15)


def test_single_uv_gives_single_point():
    s = reference_spec()
    assert surface_point(s, [0.01, 0.02]).shape == (3,)
    assert surface_normal(s, [0.01, 0.02]).shape == (3,)
    with pytest.raises(ValueError):
        surface_point(s, np.zeros((4, 3)))


# ---------------------------------------------------------------- meshes

def test_mesh_sizes_stay_small(plates):
    assert len(plates["reference"].mesh.vertices) < 1_000
    assert len(plates["bend350"].mesh.vertices) < 20_000
    for p in plates.values():
        assert len(p.mesh.vertices) < 200_000


def test_reference_and_180_bend_facet_error_below_one_micron(plates):
    for name in ("reference", "bend180", "bend350"):
        assert plates[name].facet_error_m() < 1e-6
    # the reference plate needs about 50 segments along its length, no more than a few times that
    ref = plates["reference"]
    assert 50 <= len(np.unique(ref.mesh_uv[:, 0])) <= 150


def test_facet_error_at_random_points_of_reference_mesh(plates):
    p = plates["reference"]
    faces = p.mesh.faces
    rng = np.random.default_rng(RNG_SEED)
    bary = rng.dirichlet([1, 1, 1], size=len(faces))
    xyz = np.einsum("fk,fkc->fc", bary, p.mesh.vertices[faces])
    uv = np.einsum("fk,fkc->fc", bary, p.mesh_uv[faces])
    assert np.max(np.linalg.norm(xyz - p.surface_point(uv), axis=1)) < 1e-6


def test_tighter_tolerance_gives_finer_mesh():
    coarse = build_plate(reference_spec(), max_facet_error_m=1e-5)
    fine = build_plate(reference_spec(), max_facet_error_m=1e-7)
    assert coarse.facet_error_m() < 1e-5 and fine.facet_error_m() < 1e-7
    assert len(fine.mesh.vertices) > len(coarse.mesh.vertices)
    with pytest.raises(ValueError):
        build_plate(reference_spec(), max_facet_error_m=0.0)


def test_every_mesh_meets_its_facet_error(plates):
    for name, p in plates.items():
        assert p.facet_error_m() < 1e-6, name


def test_mesh_vertices_lie_exactly_on_the_analytic_surface(plates):
    for name, p in plates.items():
        top = p.top_vertices
        v = np.asarray(p.mesh.vertices)
        assert np.max(np.abs(v[top] - p.surface_point(p.mesh_uv[top]))) < 1e-12, name
        if not top.all():
            t = p.spec.thickness_m
            bottom = p.surface_point(p.mesh_uv[~top]) - t * p.surface_normal(p.mesh_uv[~top])
            assert np.max(np.abs(v[~top] - bottom)) < 1e-12, name
        assert np.all(np.abs(p.mesh_uv) <= [L / 2, W / 2])


def test_sheets_are_open_and_thick_plates_watertight(plates):
    for name, p in plates.items():
        assert p.mesh.is_winding_consistent, name
        if p.spec.thickness_m > 0:
            assert p.mesh.is_watertight, name
            assert p.mesh.volume > 0, name  # outward normals
            assert p.top_faces.sum() * 2 < len(p.mesh.faces)
        else:
            assert not p.mesh.is_watertight, name
            assert p.top_vertices.all() and p.top_faces.all()


@pytest.mark.parametrize("direction, sign", [("up", 1), ("down", -1)])
def test_thick_bend_volume_matches_offset_formula(direction, sign):
    t = 0.002
    angle = 60 * DEG
    p = build_plate(spec(CylindricalBend(angle, direction), t))
    kappa = angle / L
    # bottom = top - t n: on the convex side for "up" (volume grows), concave for "down"
    exact = L * W * (t + sign * kappa * t * t / 2)
    assert p.mesh.volume == pytest.approx(exact, rel=2e-4)


def test_face_normals_agree_with_analytic_normals(plates):
    for name, p in plates.items():
        faces = p.mesh.faces
        centroid_uv = p.mesh_uv[faces].mean(axis=1)
        analytic = p.surface_normal(centroid_uv)
        dots = np.einsum("ij,ij->i", p.mesh.face_normals, analytic)
        top = p.top_faces
        assert dots[top].min() > 0.99, name
        if not top.all():
            offsets = p.vertex_offsets_m()[faces]
            bottom = ~top & (np.ptp(offsets, axis=1) == 0)
            walls = ~top & ~bottom
            assert dots[bottom].max() < -0.99, name
            assert np.abs(dots[walls]).max() < 0.1, name
            # walls face outward: along the surface image of the outline's outward uv normal
            uv = centroid_uv[walls]
            out_uv = np.where(np.isclose(np.abs(uv), [L / 2, W / 2], rtol=0, atol=1e-15),
                              np.sign(uv), 0.0)
            assert np.all(np.abs(out_uv).sum(axis=1) == 1), name
            _, r_u, r_v = surface_derivatives(p.spec, uv)
            out = out_uv[:, :1] * r_u + out_uv[:, 1:] * r_v
            out /= np.linalg.norm(out, axis=1, keepdims=True)
            assert np.einsum("ij,ij->i", p.mesh.face_normals[walls], out).min() > 0.99, name


def test_sheet_vertex_normals_are_analytic(plates):
    p = plates["sheet_dome"]
    assert np.allclose(p.mesh.vertex_normals, p.surface_normal(p.mesh_uv), atol=1e-12)


def test_plate_arrays_are_read_only(plates):
    p = plates["reference"]
    for array in (p.mesh_uv, p.boundary, p.boundary_uv, p.top_vertices, p.top_faces):
        assert not array.flags.writeable


# ---------------------------------------------------------------- boundary

def test_boundary_is_a_closed_outline_on_the_surface(plates):
    for name, p in plates.items():
        b, buv = p.boundary, p.boundary_uv
        assert b.shape == (len(buv), 3) and len(b) >= 4
        assert not np.allclose(b[0], b[-1])
        steps = np.linalg.norm(np.diff(np.vstack([b, b[:1]]), axis=0), axis=1)
        assert steps.min() > 0, name
        assert np.max(np.abs(b - p.surface_point(buv))) < 1e-12, name
        on_edge = np.isclose(np.abs(buv), [L / 2, W / 2], rtol=0, atol=1e-15).any(axis=1)
        assert on_edge.all(), name
        # counter-clockwise in uv seen from +Z, enclosing the whole plate
        x, y = buv[:, 0], buv[:, 1]
        area = 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)
        assert area == pytest.approx(L * W, rel=1e-12), name
        for corner in ([-L / 2, -W / 2], [L / 2, -W / 2], [L / 2, W / 2], [-L / 2, W / 2]):
            assert np.any(np.all(buv == corner, axis=1)), (name, corner)


def test_boundary_chord_error_below_tolerance(plates):
    for name, p in plates.items():
        mid_uv = 0.5 * (p.boundary_uv + np.roll(p.boundary_uv, -1, axis=0))
        mid = 0.5 * (p.boundary + np.roll(p.boundary, -1, axis=0))
        assert np.max(np.linalg.norm(mid - p.surface_point(mid_uv), axis=1)) < 1e-6, name


def test_boundary_perimeter_of_isometric_families(plates):
    names = [f"sheet_{k}" for k in ISOMETRIC] + ["reference", "bend180", "bend350",
                                                "thick_cylinder_up", "thick_fold"]
    for name in names:
        perimeter = polyline_length(plates[name].boundary, closed=True)
        exact = 2 * (L + W)
        assert exact * (1 - 5e-5) < perimeter <= exact * (1 + 1e-14), name


@pytest.mark.parametrize("name", ["reference", "bend180", "bend350"])
def test_bent_edge_of_mesh_boundary_keeps_its_length(name):
    p = build_plate(spec(CylindricalBend({"reference": 10, "bend180": 180, "bend350": 350}[name] * DEG)))
    edge = p.boundary_uv[:, 1] == -W / 2
    order = np.argsort(p.boundary_uv[edge, 0])
    length = polyline_length(p.boundary[edge][order])
    assert L * (1 - 5e-5) < length <= L


# ---------------------------------------------------------------- files

@pytest.mark.parametrize("name", ["reference", "thick_dent", "sheet_twist"])
def test_ply_export_round_trip(plates, tmp_path, name):
    p = plates[name]
    path = tmp_path / f"{name}.ply"
    p.export_ply(str(path))
    loaded = trimesh.load(str(path), process=False)
    assert np.array_equal(loaded.faces, p.mesh.faces)
    assert np.allclose(loaded.vertices, p.mesh.vertices, rtol=0, atol=1e-8)
    assert np.allclose(loaded.vertices, np.asarray(p.mesh.vertices, np.float32), rtol=0, atol=0)


def test_arc_spacing_keeps_its_digits_where_one_minus_x_rounds_to_one():
    """The sagitta rule s = R (1 - cos h) against the exact small-angle form h = sqrt(2 x): where
    1 - tol / R rounds to 1 the spacing is the half-angle form's, never 0."""
    import math

    from platebench.plates.meshing import _arc_spacing
    for radius_m, tol_m in ((1e9, 1e-9), (3.3e10, 2e-8), (0.1, 1e-5), (2.0, 1e-6)):
        got = _arc_spacing(radius_m, 0.0, tol_m)
        want = min(2.0 * radius_m * 2.0 * math.asin(math.sqrt(tol_m / (2.0 * radius_m))), radius_m * math.pi / 16)
        assert got > 0 and math.isclose(got, want, rel_tol=1e-6), (radius_m, tol_m, got, want)
