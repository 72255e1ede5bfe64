"""Plug-ins are isolated: whatever a plug-in does (sys.exit, at import too, which only its own process
does; an exception; a crash; a loop that never returns; an output of the wrong type or dtype; a library
function given as a method) is that method's recorded failure with one clear line, in ``compare``, in a
local sweep and in a sweep on a real Dask cluster, and the other methods go on. A per-sample time limit
(``--method-time-limit-s``, ``sweep.method_time_limit_s``) stops a plug-in that never returns.

Real processes throughout: the plug-ins are a module on PYTHONPATH, run by the CLI in fresh processes.
"""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest
import tomli_w

from tools.faults.run_attacks import FAILURES, IMPORT_FAILURES, write_plugins

REPO = Path(__file__).resolve().parents[1]
SMALL = {"scene": {"width": 160, "height": 120}, "render": {"spp": 2, "seed": 4}}

@pytest.fixture
def plugin_env(tmp_path, monkeypatch):
    """The misbehaving plug-ins (``tools/faults/run_attacks.py``: the fault harness tries them too) as modules on
    the path of this process and of the commands it runs."""
    monkeypatch.syspath_prepend(str(tmp_path))
    return write_plugins(tmp_path)


def cli(env, *args, timeout=300):
    return subprocess.run([sys.executable, "-m", "platebench.bench.cli.main", *map(str, args)], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=timeout)


def one_error_line(r) -> str:
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("platebench: error: "), r.stderr
    assert "Traceback" not in r.stderr
    return lines[0]


# ----------------------------------------------------------------------------- every way to fail, one call each
@pytest.mark.render
def test_every_misbehaviour_is_the_methods_failure_with_one_line(plugin_env, small_sample_dir):
    from platebench.bench.run.plugins import PluginError, resolve_plugin, run_plugin
    for name, said in FAILURES.items():
        t0 = time.monotonic()
        with pytest.raises(PluginError) as e:
            run_plugin(resolve_plugin(name), name, small_sample_dir, time_limit_s=2)
        text = str(e.value)
        assert said in text and text.startswith(f"method {name!r}") and "\n" not in text, (name, text)
        assert time.monotonic() - t0 < 30, name  # the hanging one is stopped at its limit
    # and the process that runs plug-ins is fresh again for one that works
    ok = run_plugin(resolve_plugin("misbehave:good"), "misbehave:good", small_sample_dir)
    assert 0 < ok.row.columns()["depth_rms_mm"] < 50 and ok.row.columns()["method_plane_mm"] > 0
    # a module that fails at import: found without importing it, and failed by its first call, in its process
    for module, (_, said) in IMPORT_FAILURES.items():
        name = f"{module}:f"
        plugin = resolve_plugin(name)
        assert module not in sys.modules and plugin.description == f"plug-in {name}"
        with pytest.raises(PluginError) as e:
            run_plugin(plugin, name, small_sample_dir, time_limit_s=2)
        assert str(e.value).startswith(f"method {name!r}") and said in str(e.value), str(e.value)
    with pytest.raises(PluginError, match=r"method 'no_such_module:f': cannot import module 'no_such_module' "
                                          r"\(not found on the Python path\)"):
        resolve_plugin("no_such_module:f")


# ----------------------------------------------------------------------------- compare
@pytest.mark.render
def test_compare_records_plugin_failures_as_a_sweep_does(plugin_env, small_sample_dir, tmp_path):
    methods = ["misbehave:good", "misbehave:exits_0", "misbehave:exits_3", "misbehave:raises", "misbehave:hangs",
               "misbehave:complex_map", "numpy:save"]
    out = tmp_path / "cmp"
    r = cli(plugin_env, "compare", small_sample_dir, "--methods", ",".join(methods), "--out", out,
            "--method-time-limit-s", 2)
    assert r.returncode == 1, r.stderr  # some methods failed: recorded, and the exit status says so
    assert "Traceback" not in r.stderr
    assert r.stderr.strip().splitlines()[-1].startswith("platebench: compare ") and "6 of 7" in r.stderr
    doc = json.loads((out / "compare.json").read_text())
    assert list(doc["methods"]) == methods
    good = doc["methods"]["misbehave:good"]
    assert good["status"] == "ok" and good["error"] is None and 0 < good["depth_rms_mm"] < 50
    for m in methods[1:]:
        entry = doc["methods"][m]
        assert entry["status"] == "failed" and FAILURES[m] in entry["error"], (m, entry)
        assert f"{m}" in r.stdout and FAILURES[m] in r.stdout
    assert "failed      6 of 7 method(s)" in r.stdout
    # a plug-in whose module exits on import: its recorded failure, found in its own process
    r = cli(plugin_env, "compare", small_sample_dir, "--methods", "exits_on_import:f", "--out", tmp_path / "cmp2")
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    entry = json.loads((tmp_path / "cmp2" / "compare.json").read_text())["methods"]["exits_on_import:f"]
    assert entry["status"] == "failed" and IMPORT_FAILURES["exits_on_import"][1] in entry["error"]
    # a plug-in whose module is not on the path: refused before anything is written, one line
    line = one_error_line(cli(plugin_env, "compare", small_sample_dir, "--methods", "no_such_module:f", "--out",
                              tmp_path / "cmp4"))
    assert "method 'no_such_module:f': cannot import module 'no_such_module' (not found on the Python path)" in line
    assert not (tmp_path / "cmp4").exists()
    line = one_error_line(cli(plugin_env, "compare", small_sample_dir, "--methods", "misbehave:good",
                              "--method-time-limit-s", 0, "--out", tmp_path / "cmp3"))
    assert "--method-time-limit-s = 0.0 is out of range: allowed 1 to 86400 s" in line


# ----------------------------------------------------------------------------- sweeps
def _spec(path: Path, methods, limit=None) -> Path:
    sweep = {"name": "plugins", "methods": methods}
    if limit is not None:
        sweep["method_time_limit_s"] = limit
    path.write_text(tomli_w.dumps({"sweep": sweep, "base": SMALL, "grid": {"bend_deg": [10]}}))
    return path


def _check_sweep(out: Path, methods) -> None:
    from platebench.bench.sweep.dataset import read_manifest, read_results, stale_files
    m = read_manifest(out)
    assert m["state"] == "complete" and m["counts"] == {"total": 1, "ok": 0, "failed": 1, "pending": 0}
    rows = {r["method"]: r for r in read_results(out).to_pylist()}
    assert list(rows) == methods
    assert rows["misbehave:good"]["status"] == "ok" and rows["misbehave:good"]["depth_rms_mm"] > 0
    for name in methods[1:]:
        assert rows[name]["status"] == "failed" and FAILURES[name] in rows[name]["error"], rows[name]
    assert not stale_files(out) and [p.name for p in (out / "samples").iterdir()] == ["0000"]


@pytest.mark.render
def test_local_sweep_records_plugin_failures_and_stops_one_that_never_returns(plugin_env, tmp_path):
    methods = ["misbehave:good", "misbehave:exits_0", "misbehave:exits_3", "misbehave:hangs", "misbehave:crashes"]
    out = tmp_path / "ds"
    t0 = time.monotonic()
    r = cli(plugin_env, "sweep", _spec(tmp_path / "s.toml", methods), "--out", out, "--workers", 1, "--no-progress",
            "--method-time-limit-s", 2)
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr  # its one sample failed: recorded
    assert "every sample failed" in r.stderr.strip().splitlines()[-1]
    assert "done        0 ok, 1 failed" in r.stdout and "called sys.exit(3)" in r.stdout
    assert time.monotonic() - t0 < 120
    _check_sweep(out, methods)
    r = cli(plugin_env, "sweep", _spec(tmp_path / "bad.toml", ["misbehave:good"], limit="ten"), "--out",
            tmp_path / "ds2")
    assert "sweep.method_time_limit_s = 'ten' is not a number: allowed 1 to 86400 s" in one_error_line(r)


@pytest.mark.slow
@pytest.mark.render
def test_dask_sweep_records_plugin_failures_and_applies_the_specs_time_limit(plugin_env, tmp_path):
    from platebench.bench.sweep.executors import LoopbackCluster
    methods = ["misbehave:good", "misbehave:hangs", "misbehave:exits_3"]
    out = tmp_path / "ds"
    with LoopbackCluster(n_workers=1, nthreads=1, env={"PYTHONPATH": plugin_env["PYTHONPATH"]}) as cluster:
        r = cli(plugin_env, "sweep", _spec(tmp_path / "s.toml", methods, limit=2), "--out", out, "--scheduler",
                cluster.address, "--no-progress")
        pids = set(cluster.worker_pids().values())
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr  # its one sample failed: recorded
    _check_sweep(out, methods)
    res = json.loads((out / "samples" / "0000" / "result.json").read_text())
    assert res["worker"]["pid"] in pids  # the cluster's worker ran it (and stopped the plug-in that hung)
