"""The S-curve family (plates.spec.SCurve) against analytic truth (its two circles, its normals,
its mesh, its outline), and through a sweep, the study and the report like every other family.

Units: metres and radians; world frame +Z up, flat plate in z = 0 (see plates/spec.py).
"""
from __future__ import annotations

import json
import math
import numpy as np
import pytest
import trimesh

from platebench.bench.io.codecs import decode, encode
from platebench.plates import PlateSpec, PlateSpecError, build_plate
from platebench.plates.deformations import surface_derivatives, surface_normal, surface_point
from platebench.plates.spec import FAMILIES, SCurve, bending_extent_m, max_curvature_per_m

L, W = 0.1165, 0.0735
DEG = math.pi / 180


def frame(axis_rad: float):
    """(e, g, Z): the bending direction, the bend axis and +Z (world frame)."""
    ca, sa = math.cos(axis_rad), math.sin(axis_rad)
    return np.array([ca, sa, 0.0]), np.array([-sa, ca, 0.0]), np.array([0.0, 0.0, 1.0])


def circle_distance(P: np.ndarray, d: SCurve, length=L, width=W) -> np.ndarray:
    """Distance (m) of world points P (N,3) from the S-curve's exact profile: the half with s > 0
    lies on a circle of radius R = S / (2 angle) centred R above (up) or below (down) the axis
    through the origin, the other half on the mirror circle (module doc of plates.spec)."""
    e, g, Z = frame(d.axis_rad)
    R = bending_extent_m(length, width, d.axis_rad) / (2 * d.angle_rad)
    up = 1.0 if d.direction == "up" else -1.0
    half = np.where(P @ e < 0, -1.0, 1.0)  # p(s) = sin(k|s|)/k sign(s): the side of the middle (circles meet there)
    centre = (half * up * R)[:, None] * Z
    rel = P - (P @ g)[:, None] * g - centre  # in the (e, Z) plane of the profile
    return np.abs(np.linalg.norm(rel, axis=1) - R)


S_CURVES = [SCurve(60 * DEG, "up", 0.0), SCurve(120 * DEG, "down", math.pi / 2), SCurve(170 * DEG, "up", 0.7),
            SCurve(180 * DEG, "down", 2.4), SCurve(1 * DEG, "up", 0.0)]


@pytest.mark.parametrize("d", S_CURVES, ids=lambda d: f"{math.degrees(d.angle_rad):.0f}-{d.direction}-{d.axis_rad:.1f}")
def test_s_curve_is_two_opposite_arcs_turning_by_its_angle(d):
    """Each half lies on its circle (radius S / 2 angle, opposite sides of the plate), the
    tangent turns by the angle from the middle to either end, the ends stay parallel, the surface
    is point-symmetric about the centre, C1 at the middle, and arc length is kept."""
    spec = PlateSpec(L, W, 0.0, d)
    rng = np.random.default_rng(32)
    uv = rng.uniform([-L / 2, -W / 2], [L / 2, W / 2], (4000, 2))
    P = surface_point(spec, uv)
    assert circle_distance(P, d).max() < 1e-12 * max(1.0, 1 / d.angle_rad)
    assert np.allclose(surface_point(spec, -uv), -P, rtol=0, atol=1e-16)  # odd in (u, v)
    e, g, Z = frame(d.axis_rad)
    S = bending_extent_m(L, W, d.axis_rad)
    s = np.array([-S / 2, -1e-9, 0.0, 1e-9, S / 2])
    uv_s = np.column_stack([s * e[0], s * e[1]])
    _, r_u, r_v = surface_derivatives(spec, uv_s)
    t = e[0] * r_u + e[1] * r_v  # d r / d s
    assert np.allclose(np.linalg.norm(t, axis=1), 1.0, atol=1e-14)
    angle = np.arctan2(t @ Z, t @ e)  # tangent angle in the profile's plane
    up = 1.0 if d.direction == "up" else -1.0
    assert angle[0] == pytest.approx(up * d.angle_rad, abs=1e-9)  # both ends turned the same way ...
    assert angle[-1] == pytest.approx(up * d.angle_rad, abs=1e-9)  # ... so they are parallel
    assert np.abs(angle[1:4]).max() < 1e-7  # level and continuous through the middle (C1)
    assert np.allclose(surface_normal(spec, np.zeros(2)), Z, atol=1e-15)
    line = np.linspace(-S / 2, S / 2, 200_001)
    mapped = surface_point(spec, np.column_stack([line * e[0], line * e[1]]))
    assert np.linalg.norm(np.diff(mapped, axis=0), axis=1).sum() == pytest.approx(S, rel=1e-9)


@pytest.mark.parametrize("thickness", [0.0, 0.002])
def test_s_curve_mesh_is_exact_to_a_micron_and_keeps_its_outline_length(thickness):
    d = SCurve(150 * DEG, "up", 0.3)
    p = build_plate(PlateSpec(L, W, thickness, d))
    assert p.facet_error_m() < 1e-6
    top = np.asarray(p.mesh.vertices)[p.top_vertices]
    assert circle_distance(top, d).max() < 1e-12
    B = np.vstack([p.boundary, p.boundary[:1]])
    assert np.linalg.norm(np.diff(B, axis=0), axis=1).sum() == pytest.approx(2 * (L + W), rel=5e-5)
    # the analytic normal is the circle's: along the radius, toward the centre on the rising half
    n = surface_normal(p.spec, p.mesh_uv[p.top_vertices])
    e, g, Z = frame(d.axis_rad)
    R = bending_extent_m(L, W, d.axis_rad) / (2 * d.angle_rad)
    half = np.where(top @ e < 0, -1.0, 1.0)
    inward = (half * R)[:, None] * Z - (top - (top @ g)[:, None] * g)  # up: centre above the s > 0 half
    assert np.allclose(n, half[:, None] * inward / R, atol=1e-12)
    assert max_curvature_per_m(p.spec) == pytest.approx(2 * d.angle_rad / bending_extent_m(L, W, d.axis_rad))
    if thickness:
        assert p.mesh.is_watertight


def test_s_curve_thickness_and_angle_are_checked_against_its_own_curvature():
    with pytest.raises(PlateSpecError, match=r"SCurve.angle_rad = .* out of range: allowed 0 to 180 deg"):
        SCurve(190 * DEG)
    R = 0.05 / (2 * math.pi)  # a half circle on each half of a 50 mm plate: 8 mm
    with pytest.raises(PlateSpecError, match=r"allowed 0 to 0.00397\d* m \(half the smallest radius of curvature"):
        PlateSpec(0.05, W, 0.6 * R, SCurve(180 * DEG))
    assert PlateSpec(0.05, W, 0.45 * R, SCurve(180 * DEG)).thickness_m == pytest.approx(0.45 * R)
    assert decode(PlateSpec, encode(PlateSpec(L, W, 0.0, SCurve(0.5, "down", 1.0)))).deformation == \
        SCurve(0.5, "down", 1.0)


def test_the_s_curve_is_in_sweeps_and_the_study():
    from platebench.bench.run.sensing.study import study_cases
    from platebench.bench.sweep.spec import family_defaults, parse_spec
    assert "s_curve" in FAMILIES and family_defaults("s_curve", L, W) == {
        "family": "s_curve", "angle_rad": 10 * DEG, "direction": "up", "axis_rad": 0.0}
    spec = parse_spec({"sweep": {"name": "s"}, "base": {"scene": {"width": 160, "height": 120}},
                       "grid": {"family": ["cylinder", "s_curve"], "bend_deg": [60, 120], "axis_deg": 30}})
    got = {(c.config.plate.deformation.family, round(math.degrees(c.config.plate.deformation.angle_rad)))
           for c in spec.samples}
    assert got == {("cylinder", 60), ("cylinder", 120), ("s_curve", 60), ("s_curve", 120)}
    assert all(c.config.plate.deformation.axis_rad == pytest.approx(30 * DEG) for c in spec.samples)
    cases = study_cases(families=["s_curve"])
    assert [c.family for c in cases] == ["s_curve"] * 3 and len(study_cases()) == 61
    assert all(type(c.deformation) is SCurve for c in cases)


@pytest.mark.render
@pytest.mark.slow
def test_an_s_curve_runs_through_a_sweep_the_study_and_the_report(tmp_path):
    """The S-curve's ground truth against an independent ray cast (trimesh on the written
    plate.ply), and the family in a sweep's results, the study's family table and the report."""
    from tests.conftest import run_cli
    toml = tmp_path / "s.toml"
    toml.write_text('[sweep]\nname = "s_curve"\n[base.scene]\nwidth = 320\nheight = 240\n[base.render]\nspp = 2\n'
                    '[grid]\nfamily = "s_curve"\nbend_deg = [40, 90]\naxis_deg = 20\n')
    r = run_cli("sweep", toml, "--out", tmp_path / "ds", "--workers", "1")
    assert r.returncode == 0, r.stderr[-2000:]
    import pandas as pd
    res = pd.read_csv(tmp_path / "ds" / "results.csv")
    assert set(res["family"]) == {"s_curve"} and sorted(res["bend_deg"].round().unique()) == [40, 90]
    sample = sorted((tmp_path / "ds" / "samples").iterdir())[-1] / "sample"
    from platebench.bench.io.images import read_exr
    from platebench.bench.io.sample_files import load_calibration
    mesh = trimesh.load(sample / "plate.ply", process=False, force="mesh")
    cam = load_calibration(sample).rig.left
    vv, uu = np.mgrid[0:cam.height, 0:cam.width]
    o, dirs = cam.rays(np.column_stack([uu.ravel(), vv.ravel()]).astype(float))
    locs, idx, _ = mesh.ray.intersects_location(np.repeat(o[None], len(dirs), 0), dirs, multiple_hits=False)
    gt = read_exr(sample / "gt" / "left_depth.exr").ravel()
    both = np.isfinite(gt[idx])
    assert both.sum() > 5000 and np.abs(gt[idx][both] - cam.depth(locs)[both]).max() <= 1e-6
    cfg = json.loads((sample / "sample.json").read_text())["config"]["plate"]
    d = decode(PlateSpec, cfg).deformation
    P = read_exr(sample / "gt" / "left_points.exr").reshape(-1, 3)
    P = P[np.all(np.isfinite(P), axis=1)]
    assert type(d) is SCurve and circle_distance(P, d).max() < 2e-6  # float32 points, 1 um facets
    st = tmp_path / "st"
    r = run_cli("study", "false-boundary", "--families", "s_curve", "--limit", "1", "--width", "320", "--out", st)
    assert r.returncode == 0, r.stderr[-2000:]
    doc = json.loads((st / "study.json").read_text())
    assert list(doc["outcomes_by_family"]) == ["s_curve"] and doc["rows"][0]["case"] == "s-curve 60 up axis 0"
    assert "s_curve" in r.stdout
    r = run_cli("report", tmp_path / "ds")
    assert r.returncode == 0, r.stderr[-2000:]
    r = run_cli("report", st)
    assert r.returncode == 0, r.stderr[-2000:]
    html = (st / "report" / "index.html").read_text()
    assert "s_curve" in html and "Outcomes per family" in html
    assert "s_curve" in (tmp_path / "ds" / "report" / "index.html").read_text()
