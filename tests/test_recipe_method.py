"""The recipe "A peer method" (docs/extending.md): one module (``tests/recipes/toy_method.py``) adds a
method, and it appears in ``platebench compare`` and in a sweep.

Two routes into the one registry (``reconstruction.methods``): the module's ``register_method``
decorator (the method runs in the calling process: what a built-in peer of ``reconstruction.peers``
does), and an entry point of ``platebench.methods`` (what an installed package declares: the real CLI
finds it by name, without importing it, and runs it in a process of its own). One tiny render serves
every test of this file.
"""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO, run_cli

RECIPES = REPO / "tests" / "recipes"


def _install_entry_point(site: Path) -> None:
    """What pip leaves in site-packages for a package declaring ``toy = toy_method:constant_depth``."""
    d = site / "toy_method-1.0.dist-info"
    d.mkdir(parents=True)
    (d / "METADATA").write_text("Metadata-Version: 2.1\nName: toy-method\nVersion: 1.0\n")
    (d / "entry_points.txt").write_text("[platebench.methods]\ntoy = toy_method:constant_depth\n")


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    """(a 160x120 spp-1 sample from ``platebench render``, the environment in which ``toy`` is installed)."""
    root = tmp_path_factory.mktemp("toy")
    site = root / "site"
    _install_entry_point(site)
    path = os.pathsep.join([str(site), str(RECIPES), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env = {"PYTHONPATH": path}
    r = run_cli("render", "--out", root / "s", "--width", 160, "--height", 120, "--spp", 1, env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    return root / "s", env


@pytest.fixture
def registered_toy(monkeypatch):
    """The toy module imported here (its decorator registers "toy" in this process), forgotten afterwards."""
    from platebench.bench.run import methods as runners
    from platebench.reconstruction.methods import METHODS
    before = dict(METHODS)
    monkeypatch.syspath_prepend(str(RECIPES))
    sys.modules.pop("toy_method", None)
    import toy_method  # noqa: F401  (registers "toy")
    yield METHODS["toy"]
    METHODS.clear()
    METHODS.update(before)
    runners._RUNNERS.pop("toy", None)
    sys.modules.pop("toy_method", None)


def test_the_registry_holds_every_built_in_method_in_one_order():
    """Built-in peers, the paper's pipeline and their descriptions come from the one registry; a name is
    registered once and an entry says what it returns."""
    from platebench.bench.run import plugins  # noqa: F401  (imports reconstruction.peers: registers them)
    from platebench.errors import UserValueError
    from platebench.reconstruction.methods import (
        METHODS,
        MethodEntry,
        MethodOutputError,
        add_method,
        builtin_names,
        check_output,
        default_names,
    )
    assert builtin_names() == ("paper", "graycode", "graycode-subpx", "phase", "sgbm", "phase-opencv", "sgbm-passive")
    assert default_names() == ("paper", "graycode", "graycode-subpx", "phase", "sgbm")
    assert METHODS["sgbm-passive"].images == ("left_passive", "right_passive")
    assert METHODS["graycode-subpx"].sequence.name == METHODS["graycode"].sequence.name == "graycode"
    with pytest.raises(UserValueError, match="'sgbm' is empty or already registered"):
        add_method(MethodEntry("sgbm", "again", len))
    with pytest.raises(UserValueError, match="output 'volume' is not one of disparity, depth, points, mesh"):
        add_method(MethodEntry("volumetric", "?", len, output="volume"))
    with pytest.raises(MethodOutputError, match="returned list: return one of"):
        check_output([1.0], "x")


@pytest.mark.render
def test_an_installed_method_appears_in_compare_and_a_sweep(toy, tmp_path):
    sample, env = toy
    r = run_cli("compare", sample, "--methods", "toy", "--out", tmp_path / "cmp", env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    row = next(line for line in r.stdout.splitlines() if line.startswith("toy "))
    assert row.split()[1] == "depth", row
    doc = json.loads((tmp_path / "cmp" / "compare.json").read_text())["methods"]["toy"]
    assert doc["status"] == "ok" and doc["kind"] == "depth"
    assert doc["description"] == "A plane at the depth of the world origin (toy)."  # its docstring, read unexecuted
    assert doc["notes"] == ["one plane, no matching"] and doc["coverage_frac"] == 1.0

    spec = tmp_path / "spec.toml"
    spec.write_text('[sweep]\nname = "toy"\n[base.scene]\nwidth = 160\nheight = 120\n[base.render]\nspp = 1\n'
                    "[grid]\nbend_deg = [10]\n")
    out = tmp_path / "sweep"
    r = run_cli("sweep", spec, "--methods", "toy", "--out", out, "--no-progress", env=env)
    assert r.returncode == 0, r.stderr[-3000:]
    from platebench.bench.sweep.dataset import read_results
    rows = read_results(out).to_pylist()
    assert [(x["method"], x["status"]) for x in rows] == [("toy", "ok")], rows
    assert rows[0]["coverage_frac"] == 1.0 and rows[0]["method_plane_depth_mm"] > 0
    assert "toy" in (out / "results.csv").read_text()


@pytest.mark.render
def test_a_registered_module_runs_in_process_through_the_same_registry(toy, registered_toy):
    from platebench.bench.run.compare import compare_sample
    from platebench.bench.run.methods import get_method, method_names
    from platebench.bench.sweep.spec import parse_spec
    from platebench.reconstruction.methods import builtin_names
    sample, _ = toy
    assert not registered_toy.isolated and registered_toy.output == "depth"
    assert "toy" in builtin_names() and "toy" in method_names()
    assert get_method("toy").description == "a plane at the depth of the world origin (toy)"
    cmp = compare_sample(sample, ("toy",))
    (row,) = cmp.rows
    assert (row.name, row.kind, row.status, row.n_images) == ("toy", "depth", "ok", 1)
    assert row.figures.coverage_frac == 1.0 and row.notes == ("one plane, no matching",)
    assert cmp.scene_reproduced is None  # it projects nothing of its own: no scene is re-created
    spec = parse_spec({"sweep": {"methods": ["toy"]}, "base": {"scene": {"width": 160, "height": 120}},
                       "grid": {"bend_deg": [0]}})
    assert spec.methods == ("toy",) and not get_method("toy").rerenders_from_config


def test_an_in_process_method_that_raises_is_a_recorded_failure(toy, monkeypatch):
    """A registered method that raises becomes a row with status "failed" and its one-line error (as a
    plug-in's failure is), beside the other methods' rows; ``compare`` then exits 1, not with a traceback."""
    from platebench.bench.run import methods as runners
    from platebench.bench.run.compare import compare_sample
    from platebench.reconstruction.methods import METHODS, register_method
    before = dict(METHODS)

    @register_method("raises", "a method that raises (test)", "depth")
    def _raises(given):
        raise RuntimeError("no depth here\nsecond line")

    try:
        sample, _ = toy
        cmp = compare_sample(sample, ("raises", "sgbm"))
        rows = {r.name: r for r in cmp.rows}
        assert rows["raises"].status == "failed" and rows["raises"].error == "RuntimeError: no depth here"
        assert rows["sgbm"].status == "ok"
    finally:
        METHODS.clear()
        METHODS.update(before)
        runners._RUNNERS.pop("raises", None)
