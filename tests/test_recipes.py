"""The extension recipes of docs/extending.md, each run with its toy module of tests/recipes/: a
deformation family (``toy_family``), a metric (``toy_metric``) and a cure rule (``toy_cure``). Each
toy registers itself on import, in one module, and nothing else of the bench names it; each test
takes it out of its registry afterwards, so the rest of the suite sees the built-ins only.

One tiny sweep (one sample, 160 x 120, spp 1, in this process) is the only render."""
from __future__ import annotations

import contextlib
import importlib
import math
import sys
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import pytest

from platebench.bench.config import SampleConfig
from platebench.bench.io.config_files import load_config
from platebench.bench.io.codecs import decode, encode
from platebench.bench.sweep.spec import load_spec, parse_spec
from platebench.evaluation.metrics_row import METRIC_NAMES, METRICS, Metric, is_metric, metric_label, metric_unit, \
    register_metric
from platebench.plates import PlateSpec, PlateSpecError, build_plate
from platebench.plates.deformations import surface_normal, surface_point
from platebench.plates.plate import MAX_FACET_ERROR_M
from platebench.plates.spec import FAMILIES, DeformationFamily, Flat, register_family
from platebench.reconstruction.strategy.bending import bending_curve
from platebench.reconstruction.strategy.cures import CURE_PARAMETERS, CURE_RULES, CureContext, CureParameters, \
    cure_rules, register_cure_rule
from platebench.reconstruction.strategy.planner import cure_views
from platebench.reconstruction.strategy.poses import Reach, SensorPose
from platebench.scenes.camera import Camera, intrinsics

L, W = 0.1165, 0.0735
TINY = {"scene": {"width": 160, "height": 120}, "render": {"spp": 1, "seed": 1}}


@contextlib.contextmanager
def registered(module: str, registry: dict, key: str):
    """Import the toy ``module`` (it registers ``key`` in ``registry``), then take it out again."""
    assert key not in registry
    sys.modules.pop(module, None)
    try:
        mod = importlib.import_module(module)
        assert key in registry
        yield mod
    finally:
        registry.pop(key, None)
        sys.modules.pop(module, None)


# ----------------------------------------------------------------------------- a deformation family
@pytest.fixture
def ripple():
    with registered("tests.recipes.toy_family", FAMILIES, "toy_ripple") as mod:
        yield mod.Ripple


def test_a_family_module_is_known_to_plate_specs_configs_and_sweep_specs(ripple, tmp_path):
    d = {"length_m": L, "width_m": W, "deformation": {"family": "toy_ripple", "amplitude_m": 0.001,
                                                      "wavelength_m": 0.05}}
    spec = decode(PlateSpec, d)
    assert type(spec.deformation) is ripple and decode(PlateSpec, encode(spec)) == spec
    assert list(FAMILIES)[-1] == "toy_ripple"  # after the built-ins, in the tables' order
    (tmp_path / "sample.toml").write_text(f'[plate]\nlength_m = {L}\nwidth_m = {W}\n[plate.deformation]\n'
                                          'family = "toy_ripple"\namplitude_m = 0.001\nwavelength_m = 0.05\n')
    assert load_config(tmp_path / "sample.toml").plate.deformation == spec.deformation
    (tmp_path / "sweep.toml").write_text('[grid]\nfamily = ["cylinder", "toy_ripple"]\n')
    for sweep in (load_spec(tmp_path / "sweep.toml"), parse_spec({"grid": {"family": ["cylinder", "toy_ripple"]}})):
        got = [s.config.plate.deformation for s in sweep.samples]
        assert [g.family for g in got] == ["cylinder", "toy_ripple"]
        size = sweep.samples[1].config.plate
        assert got[1] == ripple.defaults(size.length_m, size.width_m)
    with pytest.raises(PlateSpecError, match="wavelength_m"):
        decode(PlateSpec, {**d, "deformation": {**d["deformation"], "wavelength_m": 0.0}})


@pytest.mark.parametrize("thickness_m", [0.0, 0.001])
def test_a_family_module_meshes_on_its_own_exact_surface(ripple, thickness_m):
    a, wavelength = 0.001, 0.05
    spec = PlateSpec(L, W, thickness_m, ripple(a, wavelength))
    k = 2 * math.pi / wavelength
    uv = np.random.default_rng(0).uniform(-0.5, 0.5, (200, 2)) * [L, W]
    u = uv[:, 0]
    assert np.allclose(surface_point(spec, uv), np.column_stack([u, uv[:, 1], a * np.sin(k * u)]), rtol=0, atol=1e-15)
    n = np.column_stack([-a * k * np.cos(k * u), np.zeros_like(u), np.ones_like(u)])
    assert np.allclose(surface_normal(spec, uv), n / np.linalg.norm(n, axis=1, keepdims=True), rtol=0, atol=1e-12)
    plate = build_plate(spec)
    top = plate.top_vertices
    assert np.array_equal(np.asarray(plate.mesh.vertices)[top], surface_point(spec, plate.mesh_uv[top]))
    assert plate.facet_error_m() < MAX_FACET_ERROR_M
    assert plate.mesh.is_watertight == (thickness_m > 0)


def _family(name: str, kind: str, with_surface: bool = True):
    """A family class keyed ``name`` with layout ``kind``, with or without its ``surface``."""
    class Toy(DeformationFamily):
        family: ClassVar[str] = name
        label: ClassVar[str] = name
        layout: ClassVar[str] = kind
        max_curvature_per_m = Flat.max_curvature_per_m
        defaults = classmethod(lambda cls, length_m, width_m: cls())
        if with_surface:
            surface = Flat.surface
    return dataclass(frozen=True)(Toy)


def test_a_family_without_its_surface_or_its_ruling_cannot_register():
    with pytest.raises(TypeError, match="surface"):
        register_family(_family("toy_no_surface", "grid", with_surface=False))
    with pytest.raises(TypeError, match="ruling"):  # a ruled layout needs the family's own ruling: no default
        register_family(_family("toy_no_ruling", "strips"))
    with pytest.raises(ValueError, match="registered already"):
        register_family(_family("cylinder", "grid"))
    unregistered = _family("toy_unregistered", "grid")
    assert not {"toy_no_surface", "toy_no_ruling", "toy_unregistered"} & set(FAMILIES)
    with pytest.raises(PlateSpecError, match="not a deformation"):
        PlateSpec(L, W, 0.0, unregistered())
    with pytest.raises(PlateSpecError, match="toy_unregistered"):
        decode(PlateSpec, {"length_m": L, "width_m": W, "deformation": {"family": "toy_unregistered"}})


# ----------------------------------------------------------------------------- a metric
@pytest.fixture(scope="module")
def swept(tmp_path_factory):
    """A one-sample sweep of the paper's pipeline, run in this process with the toy metric registered:
    its results table (rows, column names)."""
    from platebench.bench.sweep.dataset import read_results
    from platebench.bench.sweep.executors import LocalExecutor, run_sweep
    with registered("tests.recipes.toy_metric", METRICS, "toy_matched_frac"):
        out = tmp_path_factory.mktemp("recipes") / "ds"
        spec = parse_spec({"sweep": {"name": "recipes"}, "base": TINY, "grid": {"bend_deg": [10]}})
        summary = run_sweep(spec, out, LocalExecutor(0), progress=False)
    assert summary.ok == 1, summary
    table = read_results(out)
    return table.to_pylist(), list(table.column_names)


def test_a_metric_module_is_a_column_of_a_sweeps_results_table(swept):
    rows, names = swept
    (row,) = rows
    assert row["status"] == "ok" and row["expected_count_gt"]
    assert row["toy_matched_frac"] == pytest.approx(row["matched_count"] / row["expected_count_gt"], rel=1e-12)
    assert [n for n in names if n in METRIC_NAMES] == list(METRIC_NAMES)  # the shared columns, in their order
    assert names.index("toy_matched_frac") > names.index(METRIC_NAMES[-1])  # the registered ones after them


def test_a_registered_metric_is_labelled_and_checked():
    with registered("tests.recipes.toy_metric", METRICS, "toy_matched_frac"):
        assert is_metric("toy_matched_frac") and metric_unit("toy_matched_frac") == "fraction"
        assert metric_label("toy_matched_frac") == "share of the expected square centres matched (fraction)"
        for name in ("toy_matched_frac", "depth_rms_mm", "depth_mean_mm", ""):  # registered, shared, of a family
            with pytest.raises(ValueError, match="not allowed"):
                register_metric(Metric(name, "x", "mm", lambda score: 1.0))
        with pytest.raises(TypeError):
            register_metric(Metric("toy_other_mm", "x", "mm", lambda score: 1.0, kind="text"))
    assert not is_metric("toy_matched_frac")


# ----------------------------------------------------------------------------- a cure rule
def _arc(theta_deg: float, direction: str, n: int = 600) -> np.ndarray:
    th = math.radians(theta_deg)
    R = L / th
    phi = np.linspace(-th / 2, th / 2, n)
    s = 1.0 if direction == "up" else -1.0
    return np.column_stack([R * np.sin(phi), np.zeros(n), s * R * (1 - np.cos(phi))])


@pytest.fixture
def step_back():
    with registered("tests.recipes.toy_cure", CURE_RULES, "toy step back") as mod:
        yield mod


def _plan(**kw):
    profile = _arc(160.0, "down")
    ctx = CureContext(bending_curve(profile, np.array([0.0, 0.0, 1.0])),
                      SensorPose(np.array([0.05, 0.0, 0.35]), np.zeros(3), np.array([0.0, 1.0, 0.0])), 2, 16)
    cam = Camera(intrinsics(1000, 640, 480), np.eye(3), np.zeros(3), 640, 480)
    return cure_views(ctx, Reach(), profile[::20], cam, 0.1, **kw)


def test_a_cure_rule_module_is_iterated_by_the_planner_and_proposes_its_view(step_back):
    assert cure_rules()[-1] is step_back.TOY_CURE  # the list the planner and the sensing loop iterate
    views, _ = _plan()
    assert [v.name for v in views] == ["cure 1", "cure 2", "toy step back"]  # the paper's first
    toy = views[-1]
    assert toy.method == "toy step back" and toy.purpose == "cure"
    assert toy.pose.distance_m == pytest.approx(math.hypot(0.05, 0.35) * step_back.STEP_BACK, rel=1e-12)
    (only,), _ = _plan(rules=(step_back.TOY_CURE,))
    assert only.name == "toy step back"


def test_the_cure_thresholds_live_in_one_parameters_record():
    assert (CURE_PARAMETERS.min_view_turn_deg, CURE_PARAMETERS.min_baseline_turn_deg) == (2.0, 10.0)
    views, note = _plan(params=CureParameters(min_view_turn_deg=180.0, min_baseline_turn_deg=180.0))
    assert [v.name for v in views] == ["cure 2"] and note.startswith("cure 1 would not move the sensor")
    with pytest.raises(ValueError, match="registered already"):
        register_cure_rule(CURE_RULES["cure 1"])


def test_the_built_in_families_are_the_registered_ones():
    from platebench.plates.spec import Deformation
    built_in = [cls.family for cls in Deformation.__args__]
    assert list(FAMILIES)[:len(built_in)] == built_in  # every built-in family, in the order tables show them
    assert isinstance(SampleConfig().plate.deformation, tuple(FAMILIES.values()))
