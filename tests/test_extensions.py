"""The extension points reached from a user's own package (docs/extending.md): the toy family, metric and
cure rule of tests/recipes/, each declared as an entry point of its group (``platebench.families``,
``platebench.metrics``, ``platebench.cure_rules``) by a distribution's metadata on the Python path, as
pip leaves it, and nothing imported by hand. ``bench.run.extensions.load_extensions`` imports them in
every process that needs them: the command line, a sweep's spawned workers, a process pool's workers
and the facade. An entry point that cannot be loaded refuses the command with one line, status 2.

Every check runs in fresh processes (the test's own registries stay the built-ins); one sweep of one
160 x 120, spp 1 sample is the only render."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.conftest import REPO, run_cli

RECIPES = REPO / "tests" / "recipes"
TOYS = ("[platebench.families]\ntoy_ripple = toy_family\n"
        "[platebench.metrics]\ntoy_matched_frac = toy_metric\n"
        "[platebench.cure_rules]\ntoy_step_back = toy_cure:TOY_CURE\n")


def _install(site: Path, dist: str, entry_points: str) -> None:
    """What pip leaves in site-packages for the distribution ``dist`` declaring ``entry_points``."""
    d = site / f"{dist}-1.0.dist-info"
    d.mkdir(parents=True)
    (d / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist.replace('_', '-')}\nVersion: 1.0\n")
    (d / "entry_points.txt").write_text(entry_points)


def _env(site: Path) -> dict:
    path = os.pathsep.join([str(site), str(RECIPES), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return {"PYTHONPATH": path, "PLATEBENCH_DEBUG": ""}


@pytest.fixture(scope="module")
def toys(tmp_path_factory) -> dict:
    """The environment of a fresh process in which the three toys are installed by entry point."""
    site = tmp_path_factory.mktemp("toys") / "site"
    _install(site, "toy_extensions", TOYS)
    return _env(site)


def _python(code: str, env: dict, folder: Path) -> subprocess.CompletedProcess:
    """Run ``code`` as the script ``folder/script.py`` (its spawned workers import it again)."""
    (folder / "script.py").write_text(code)
    return subprocess.run([sys.executable, "script.py"], cwd=folder, env={**os.environ, **env}, capture_output=True,
                          text=True, timeout=300)


def test_the_command_line_loads_each_group_into_its_registry(toys):
    r = run_cli("info", env=toys)
    assert r.returncode == 0, r.stderr[-3000:]
    ext = json.loads(r.stdout)["extensions"]
    assert [(e["group"], e["name"], e["distribution"]) for e in ext["entry_points"]] == [
        ("platebench.families", "toy_ripple", "toy-extensions"),
        ("platebench.metrics", "toy_matched_frac", "toy-extensions"),
        ("platebench.cure_rules", "toy_step_back", "toy-extensions")]
    assert ext["families"][-1] == "toy_ripple" and "cylinder" in ext["families"]  # after the built-ins
    assert ext["metrics"] == ["toy_matched_frac"]
    assert ext["cure_rules"] == ["cure 1", "cure 2", "toy step back"]  # the paper's first


def test_loading_is_once_per_process_and_reaches_pool_workers(toys, tmp_path):
    """A second call returns what the first loaded (no second registration); a spawned pool worker
    (``pool_worker_init``: the study's and the benchmark score's pools) knows the three toys."""
    code = """
import multiprocessing, os
from concurrent.futures import ProcessPoolExecutor
from platebench.bench.run.extensions import load_extensions
from platebench.bench.run.workers import pool_worker_init

def names():
    from platebench.evaluation.metrics_row import METRICS
    from platebench.plates.spec import FAMILIES
    from platebench.reconstruction.strategy.cures import cure_rules
    return list(FAMILIES)[-1], list(METRICS), [r.name for r in cure_rules()]

if __name__ == "__main__":
    first = load_extensions()
    assert load_extensions() is first and len(first) == 3, first
    assert names() == ("toy_ripple", ["toy_matched_frac"], ["cure 1", "cure 2", "toy step back"]), names()
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn"), initializer=pool_worker_init,
                             initargs=(os.getpid(), None)) as pool:
        print(pool.submit(names).result())
"""
    r = _python(code, toys, tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.strip() == "('toy_ripple', ['toy_matched_frac'], ['cure 1', 'cure 2', 'toy step back'])"


def test_the_facade_loads_them_before_its_work(toys, tmp_path):
    code = """
import platebench
import platebench.errors
from platebench.plates.spec import FAMILIES
assert "toy_ripple" not in FAMILIES
try:
    platebench.sweep("missing.toml", "ds")
except platebench.errors.PlateBenchError:
    pass
print(list(FAMILIES)[-1], [e.name for e in platebench.load_extensions()])
"""
    r = _python(code, toys, tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.strip() == "toy_ripple ['toy_ripple', 'toy_matched_frac', 'toy_step_back']"


@pytest.mark.render
def test_an_installed_family_and_metric_reach_a_sweeps_spawned_worker(toys, tmp_path):
    """The CLI checks a sweep spec over the toy family; its spawned worker renders the ripple and its
    results table carries the toy metric after the shared columns."""
    from platebench.bench.sweep.dataset import read_results
    from platebench.evaluation.metrics_row import METRIC_NAMES
    spec = tmp_path / "spec.toml"
    spec.write_text('[sweep]\nname = "toys"\nmethods = ["paper"]\n[base.scene]\nwidth = 160\nheight = 120\n'
                    '[base.render]\nspp = 1\n[grid]\nfamily = ["toy_ripple"]\n')
    out = tmp_path / "ds"
    r = run_cli("sweep", spec, "--out", out, "--workers", 1, "--no-progress", env=toys)
    assert r.returncode == 0, r.stderr[-3000:]
    table = read_results(out)
    (row,) = table.to_pylist()
    assert (row["family"], row["method"], row["status"]) == ("toy_ripple", "paper", "ok"), row
    names = list(table.column_names)
    assert "toy_matched_frac" in names and names.index("toy_matched_frac") > names.index(METRIC_NAMES[-1])
    assert row["expected_count_gt"]
    assert row["toy_matched_frac"] == pytest.approx(row["matched_count"] / row["expected_count_gt"], rel=1e-12)
    assert "toy_matched_frac" in (out / "results.csv").read_text().splitlines()[0]


@pytest.mark.parametrize("entry_points, module, says", [
    ("[platebench.metrics]\nbroken = no_such_module\n", None,
     "entry point 'broken = no_such_module' of group platebench.metrics (distribution broken-ext) cannot be "
     "imported (ModuleNotFoundError: No module named 'no_such_module')"),
    ("[platebench.cure_rules]\nagain = clash_cure\n",
     "from platebench.reconstruction.strategy.cures import CURE_RULES, register_cure_rule\n"
     "register_cure_rule(CURE_RULES['cure 1'])\n",
     "entry point 'again = clash_cure' of group platebench.cure_rules (distribution broken-ext) registers a name "
     "that is registered already or not allowed (RegistrationError: cure rule 'cure 1' is registered already)"),
    ("[platebench.metrics]\ntwice = twice_metric\n",
     "from platebench.evaluation.metrics_row import Metric, register_metric\n"
     "m = Metric('twice_frac', 'a metric given twice', 'fraction', lambda score: None)\n"
     "register_metric(m)\nregister_metric(m)\n",
     "entry point 'twice = twice_metric' of group platebench.metrics (distribution broken-ext) registers a name "
     "that is registered already or not allowed (RegistrationError: metric name 'twice_frac' is not allowed: a new, "
     "non-empty name (not a shared column, an extra column's family or a registered metric))"),
    ("[platebench.metrics]\nvalue = value_metric\n", "raise ValueError('this value is not allowed')\n",
     "entry point 'value = value_metric' of group platebench.metrics (distribution broken-ext) failed while "
     "it was imported (ValueError: this value is not allowed)"),
    ("[platebench.families]\nraises = raising_family\n", "raise RuntimeError('no family here')\n",
     "entry point 'raises = raising_family' of group platebench.families (distribution broken-ext) failed while "
     "it was imported (RuntimeError: no family here)"),
])
def test_an_entry_point_that_cannot_be_loaded_refuses_the_command_in_one_line(tmp_path, entry_points, module, says):
    site = tmp_path / "site"
    _install(site, "broken_ext", entry_points)
    if module is not None:
        name = entry_points.split("= ")[1].strip()
        (site / f"{name}.py").write_text(module)
    env = _env(site)
    r = run_cli("info", env=env)
    assert r.returncode == 2, (r.returncode, r.stderr[-3000:])
    assert r.stderr.splitlines() == [f"platebench: error: {says}: fix or uninstall that distribution"], r.stderr
    assert "Traceback" not in r.stderr and not r.stdout
    assert run_cli("sweep", "--help", env=env).returncode == 0  # help still answers
