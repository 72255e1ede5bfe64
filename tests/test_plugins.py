"""Plug-in methods: found by entry point (group ``platebench.methods``) or ``module:function``, run by
``compare`` and by sweeps like the built-ins, locally and on a real 2-worker Dask cluster, with every
metric they produce in results.parquet.

The example plug-in (``examples/blockmatch_plugin``, OpenCV block matching) is installed for real
with pip into a folder put on PYTHONPATH of the sweep and of the Dask workers: they know only the
method's name and resolve it themselves.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from platebench.bench.run import methods as methods_mod
from platebench.bench.run.methods import get_method
from platebench.bench.run.plugins import PluginError
from platebench.errors import UserValueError
from platebench.reconstruction.methods import METHODS

REPO = Path(__file__).resolve().parents[1]
EXAMPLE = REPO / "examples" / "blockmatch_plugin"
SMALL = {"scene": {"width": 160, "height": 120}, "render": {"spp": 2, "seed": 2}}

PLUGIN_SOURCE = '''
"""Test plug-ins (written outside the package)."""
import numpy as np
from platebench.reconstruction.methods import Depth, Points


def flat_guess(inputs):
    """A plane at the depth of the world origin: the plug-in interface in six lines."""
    rig = inputs.rig
    z0 = float(rig.left.depth(np.zeros((1, 3)))[0])
    H, W = inputs.images["left_passive"].shape
    return Depth(np.full((H, W), z0), metrics={"guess_depth_mm": z0 * 1e3})


def centre_point(inputs):
    return Points(np.zeros((1, 3)))


def wrong(inputs):
    return np.zeros((2, 2))
'''


@pytest.fixture
def registry():
    """Plug-ins registered during a test are forgotten after it."""
    before = dict(METHODS)
    yield METHODS
    METHODS.clear()
    METHODS.update(before)


@pytest.fixture
def plugin_module(tmp_path, monkeypatch):
    (tmp_path / "my_plugins.py").write_text(PLUGIN_SOURCE)
    monkeypatch.syspath_prepend(str(tmp_path))
    return "my_plugins"


def _fake_install(site: Path, name: str, value: str) -> None:
    """A distribution's metadata with one entry point (what pip leaves in site-packages)."""
    d = site / "fake_plugin-1.0.dist-info"
    d.mkdir(parents=True)
    (d / "METADATA").write_text("Metadata-Version: 2.1\nName: fake-plugin\nVersion: 1.0\n")
    (d / "entry_points.txt").write_text(f"[platebench.methods]\n{name} = {value}\n")


# ----------------------------------------------------------------------------- resolution (no render)
def test_module_function_and_entry_point_resolution(registry, plugin_module, tmp_path, monkeypatch):
    m = get_method(f"{plugin_module}:flat_guess")
    assert m.description.startswith("A plane at the depth") and not m.rerenders_from_config
    assert get_method(f"{plugin_module}:flat_guess") is m  # resolved once, then registered
    _fake_install(tmp_path, "flat-guess", f"{plugin_module}:flat_guess")
    assert "flat-guess" in methods_mod.method_names()
    assert get_method("flat-guess").name == "flat-guess"
    with pytest.raises(UserValueError, match=r"method 'nonsense' is not known: allowed paper, .*flat-guess"):
        get_method("nonsense")
    with pytest.raises(PluginError, match="cannot import module 'no_such_module' .not found on the Python path"):
        get_method("no_such_module:f")
    with pytest.raises(PluginError, match=r"write a plug-in as module:function"):
        get_method("my plugins:f")
    # an attribute is looked for where the module is imported: in the plug-in's process, on its first call
    missing = get_method(f"{plugin_module}:missing")
    assert missing.description == f"plug-in {plugin_module}:missing"


def test_sweep_spec_validates_plugins_by_name(registry, plugin_module):
    from platebench.bench.sweep.spec import SpecError, parse_spec
    spec = parse_spec({"sweep": {"methods": ["paper", f"{plugin_module}:flat_guess"]}, "base": SMALL,
                       "grid": {"bend_deg": [0]}})
    assert spec.methods == ("paper", f"{plugin_module}:flat_guess")
    with pytest.raises(SpecError, match="sweep.methods: method 'nope' is not known"):
        parse_spec({"sweep": {"methods": ["nope"]}, "base": SMALL, "grid": {"bend_deg": [0]}})


# ----------------------------------------------------------------------------- running (a small render)
@pytest.mark.render
def test_plugins_run_in_compare_and_sweep_task(registry, plugin_module, small_sample_dir, tmp_path, capsys):
    from platebench.bench.cli.main import main
    from platebench.bench.run.methods import MethodContext
    from platebench.bench.run.plugins import run_plugin
    out = tmp_path / "cmp"
    assert main(["compare", str(small_sample_dir), "--methods", f"sgbm,{plugin_module}:flat_guess",
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    doc = json.loads((out / "compare.json").read_text())
    guess = doc["methods"][f"{plugin_module}:flat_guess"]
    assert guess["kind"] == "depth" and 0 < guess["depth_rms_mm"] < 20 and guess["coverage_frac"] == 1.0
    assert doc["methods"]["sgbm"]["middlebury"]["mb_nonocc_bad_1_0_pct"] is not None
    assert "flat_guess" in text and (out / "compare.png").stat().st_size > 1000
    # as a sweep worker runs it: output, error map + score.json in its reconstruction directory, metrics as a row
    rdir = tmp_path / "recon" / "guess"
    res = get_method(f"{plugin_module}:flat_guess").run(MethodContext(small_sample_dir, rdir, None, None))
    cols = res.metrics.columns()
    assert cols["depth_rms_mm"] == pytest.approx(guess["depth_rms_mm"])
    assert cols["method_guess_depth_mm"] == pytest.approx(400.0, abs=1.0) and cols["depth_a99_mm"] > 0
    assert sorted(p.name for p in rdir.iterdir()) == ["depth.exr", "error_map.npz", "score.json"]
    sj = json.loads((rdir / "score.json").read_text())
    assert sj["kind"] == "depth" and sj["method_metrics"] == {"guess_depth_mm": pytest.approx(400.0, abs=1.0)}
    # points: the plate centre lies on the true surface (the mesh is within 1 um of it)
    one = run_plugin(__import__(plugin_module).centre_point, "centre", small_sample_dir)
    assert one.score.distance.max_m < 1e-6 and one.row.columns()["outlier_count"] == 0
    with pytest.raises(PluginError, match="returned ndarray: return one of"):
        run_plugin(__import__(plugin_module).wrong, "wrong", small_sample_dir)


# ----------------------------------------------------------------------------- installed, in real sweeps
@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """The example plug-in installed by pip (its pyproject's entry points) into a fresh folder."""
    import shutil
    site = tmp_path_factory.mktemp("site")
    src = tmp_path_factory.mktemp("src") / EXAMPLE.name  # a copy: the build leaves egg-info/ and build/ behind
    shutil.copytree(EXAMPLE, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    p = subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(site),
                        str(src)], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    eps = next(site.glob("platebench_blockmatch-*.dist-info")) / "entry_points.txt"
    assert "blockmatch = platebench_blockmatch:block_match" in eps.read_text()
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return site, env


def _spec(tmp_path, methods) -> Path:
    import tomli_w
    spec = tmp_path / "spec.toml"
    spec.write_text(tomli_w.dumps({"sweep": {"name": "plugins", "methods": methods}, "base": SMALL,
                                   "grid": {"bend_deg": [0, 20]}}))
    return spec


def _sweep(env, *args):
    return subprocess.run([sys.executable, "-m", "platebench.bench.cli.main", "sweep", *map(str, args), "--no-progress"],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=900)


def _check_rows(out: Path, methods, sweep_pid=None):
    from platebench.bench.sweep.dataset import RESULT, read_results
    rows = read_results(out).to_pylist()
    assert [(r["sample_id"], r["method"]) for r in rows] == [(s, m) for s in ("0000", "0001") for m in methods]
    assert all(r["status"] == "ok" for r in rows), [(r["method"], r["error"]) for r in rows if r["status"] != "ok"]
    by = {}
    for r in rows:
        by.setdefault(r["method"], []).append(r)
    pids = set()
    for sid in ("0000", "0001"):
        res = json.loads((out / "samples" / sid / RESULT).read_text())
        pids.add(res["worker"]["pid"])
    assert sweep_pid not in pids
    return by, pids


@pytest.mark.slow
@pytest.mark.render
def test_installed_plugin_runs_in_a_local_sweep_with_two_workers(installed, tmp_path):
    site, env = installed
    methods = ["paper", "sgbm", "blockmatch", "platebench_blockmatch:block_match_points"]
    out = tmp_path / "ds"
    p = _sweep(env, _spec(tmp_path, methods), "--out", out, "--workers", 2)
    assert p.returncode == 0, p.stderr[-3000:]
    by, _ = _check_rows(out, methods)
    for r in by["blockmatch"]:  # a plug-in's disparity: Middlebury/ETH3D on all and non-occluded pixels
        for k in ("mb_all_bad_1_0_pct", "mb_nonocc_bad_0_5_pct", "eth_all_a90_px", "eth_nonocc_coverage_frac",
                  "depth_a50_mm", "method_matched_px_count", "method_search_range_px"):
            assert r[k] is not None, k
        assert r["depth_rms_mm"] > 0 and 0 < r["coverage_frac"] <= 1
    for r in by["platebench_blockmatch:block_match_points"]:  # points: distance, outliers, coverage
        assert r["surface_rms_mm"] > 0 and 0 <= r["outlier_frac"] <= 1 and r["coverage_frac"] >= 0
        assert r["method_points_count"] == r["points_count"] > 100 and r["mb_all_bad_1_0_pct"] is None
    for r in by["sgbm"]:  # the peers' Middlebury/ETH3D figures reach the table too
        assert r["mb_all_bad_1_0_pct"] is not None and r["eth_all_coverage_frac"] is not None
        assert r["mb_nonocc_avgerr_px"] is not None
    assert all(r["matched_count"] == 16 for r in by["paper"])
    assert (out / "samples" / "0000" / "recon" / "blockmatch" / "disparity.pfm").is_file()
    # a module:function method's folder is one safe path component (bench.io.layout.method_folder)
    assert (out / "samples" / "0000" / "recon" / "platebench_blockmatch_block_match_points" / "points.ply").is_file()
    header = (out / "results.csv").read_text().splitlines()[0].split(",")
    assert "mb_nonocc_bad_1_0_pct" in header and "method_matched_px_count" in header


@pytest.mark.slow
@pytest.mark.render
def test_installed_plugin_runs_on_a_two_worker_dask_cluster(installed, tmp_path):
    from platebench.bench.sweep.executors import LoopbackCluster
    site, env = installed
    methods = ["blockmatch", "blockmatch-points"]
    out = tmp_path / "ds"
    with LoopbackCluster(n_workers=2, nthreads=1, env={"PYTHONPATH": env["PYTHONPATH"]}) as cluster:
        workers = set(cluster.worker_pids().values())
        assert len(workers) == 2
        p = _sweep(env, _spec(tmp_path, methods), "--out", out, "--scheduler", cluster.address)
        assert p.returncode == 0, p.stderr[-3000:]
        by, pids = _check_rows(out, methods)
    assert pids <= workers  # the cluster's worker processes resolved the plug-ins by name
    assert all(r["mb_all_bad_1_0_pct"] is not None and r["method_matched_px_count"] > 0 for r in by["blockmatch"])
    assert all(r["surface_rms_mm"] is not None for r in by["blockmatch-points"])
    m = json.loads((out / "manifest.json").read_text())
    assert m["executor"]["kind"] == "dask" and m["counts"]["ok"] == 2
