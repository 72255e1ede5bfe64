"""A plug-in is imported only in its own, time-limited process, and everything it starts dies with that
process: a module that loops at import is that method's recorded failure within its time limit (exit 1
from ``compare`` and ``sweep``), never a hang of the command, and naming it imports nothing in the
calling process; a plug-in that starts ``sleep 300`` (or a ``multiprocessing`` child) leaves nothing
running when it times out, when it returns, or when the command is killed with -9.

Real processes throughout: the plug-ins are modules on PYTHONPATH, run by the CLI in fresh processes.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import tomli_w

from tools.faults.run_attacks import IMPORT_FAILURES, write_plugins

REPO = Path(__file__).resolve().parents[1]
LIMIT_S = 4  # --method-time-limit-s of these runs
SLACK_S = 20  # what a command may take beyond the limits it was given: start-up, the host's own start, scoring
GONE_WITHIN_S = 5.0  # how soon a killed plug-in's children must be gone
SWEEP_BASE = {"scene": {"width": 160, "height": 120}, "render": {"spp": 1, "seed": 1}}

SPAWNING = '''
"""Plug-ins that start processes and record their ids (one a line) in spawning.pids beside this file."""
import multiprocessing
import os
import subprocess
import time
from pathlib import Path

import numpy as np
from platebench.bench.run.plugins import Depth

PIDS = Path(__file__).with_suffix(".pids")


def _record(pid):
    with open(PIDS, "a") as f:
        f.write(f"{pid}\\n")


def _sleep():
    _record(subprocess.Popen(["sleep", "300"]).pid)


def hangs(inputs):
    _sleep()
    while True:
        pass


def returns(inputs):
    """Starts a sleep and returns a plane."""
    _sleep()
    z0 = float(inputs.rig.left.depth(np.zeros((1, 3)))[0])
    return Depth(np.full(inputs.images["left_passive"].shape, z0))


def mp_hangs(inputs):
    child = multiprocessing.get_context("fork").Process(target=time.sleep, args=(300,))
    child.start()
    _record(child.pid)
    while True:
        time.sleep(1)
'''

SPAWNS_ON_IMPORT = '''
import subprocess
from pathlib import Path

with open(Path(__file__).with_name("spawning.pids"), "a") as f:
    f.write(f"{subprocess.Popen(['sleep', '300']).pid}\\n")
while True:
    pass
'''


@pytest.fixture
def plugin_env(tmp_path):
    """The bad-input harness's plug-ins (``loops_on_import`` among them) and the spawning ones, on PYTHONPATH
    of the commands run here; every process they record is killed after the test whatever it found."""
    env = write_plugins(tmp_path)
    (tmp_path / "spawning.py").write_text(SPAWNING)
    (tmp_path / "spawns_on_import.py").write_text(SPAWNS_ON_IMPORT)
    yield env
    for pid in recorded(tmp_path):
        if alive(pid):
            os.kill(pid, signal.SIGKILL)


def recorded(folder: Path) -> list[int]:
    pids = folder / "spawning.pids"
    return [int(x) for x in pids.read_text().split()] if pids.is_file() else []


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, dead and waiting to be reaped, does not)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_bytes().rpartition(b")")[2].split()[0]
    except (OSError, IndexError):
        return False
    return state not in (b"Z", b"X")


def survivors(pids, within_s: float = GONE_WITHIN_S) -> list[int]:
    deadline = time.monotonic() + within_s
    while True:
        left = [p for p in pids if alive(p)]
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.1)


def cli(env, *args, timeout=600):
    return subprocess.run([sys.executable, "-m", "platebench.bench.cli.main", *map(str, args)], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=timeout)


# ----------------------------------------------------------------------------- naming a plug-in imports nothing
def test_naming_a_plugin_runs_none_of_its_code(plugin_env, tmp_path):
    """get_method in a fresh process returns at once for a module that loops at import, a dotted name's
    parent package is not imported either, and the description comes from the source."""
    pkg = tmp_path / "loopy_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("while True:\n    pass\n")
    (pkg / "mod.py").write_text('def f(inputs):\n    """Reads its docstring without running."""\n')
    code = ("import sys, time\n"
            "from platebench.bench.run.methods import get_method\n"
            "t = time.monotonic()\n"
            "a = get_method('loops_on_import:f')\n"
            "b = get_method('loopy_pkg.mod:f')\n"
            "print(a.description, '|', b.description, '|', 'loops_on_import' in sys.modules or 'loopy_pkg' in "
            "sys.modules, '|', round(time.monotonic() - t, 3))\n")
    p = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=plugin_env, capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 0, p.stderr
    desc_a, desc_b, imported, seconds = (x.strip() for x in p.stdout.split("|"))
    assert desc_a == "plug-in loops_on_import:f" and desc_b == "Reads its docstring without running."
    assert imported == "False" and float(seconds) < LIMIT_S


# ----------------------------------------------------------------------------- a module that loops at import
@pytest.mark.render
def test_compare_fails_a_plugin_that_loops_at_import_within_its_limit(plugin_env, small_sample_dir, tmp_path):
    out = tmp_path / "cmp"
    methods = ["loops_on_import:f", "misbehave:good"]
    t0 = time.monotonic()
    r = cli(plugin_env, "compare", small_sample_dir, "--methods", ",".join(methods), "--out", out,
            "--method-time-limit-s", LIMIT_S)
    seconds = time.monotonic() - t0
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr  # recorded, and the exit status says so
    assert seconds < LIMIT_S + SLACK_S, seconds
    doc = json.loads((out / "compare.json").read_text())["methods"]
    said = IMPORT_FAILURES["loops_on_import"][1]
    assert doc["loops_on_import:f"]["status"] == "failed" and said in doc["loops_on_import:f"]["error"]
    assert f"time limit of {LIMIT_S:g} s" in doc["loops_on_import:f"]["error"]
    assert doc["misbehave:good"]["status"] == "ok"  # the next method had a fresh process


@pytest.mark.render
def test_sweep_fails_a_plugin_that_loops_at_import_on_each_sample_within_its_limit(plugin_env, tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text(tomli_w.dumps({"sweep": {"name": "hang", "methods": ["loops_on_import:f"],
                                             "method_time_limit_s": LIMIT_S},
                                   "base": SWEEP_BASE, "grid": {"bend_deg": [0, 10]}}))
    out = tmp_path / "ds"
    r = cli(plugin_env, "sweep", spec, "--out", out, "--workers", 1, "--no-progress", timeout=900)
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    from platebench.bench.sweep.dataset import read_manifest, read_results
    assert read_manifest(out)["counts"] == {"total": 2, "ok": 0, "failed": 2, "pending": 0}
    rows = read_results(out).to_pylist()
    assert [r["method"] for r in rows] == ["loops_on_import:f"] * 2
    assert all(r["status"] == "failed" and "no answer within the time limit" in r["error"] for r in rows), rows
    for sid in ("0000", "0001"):  # the time each sample spent on the method: its limit and a little more
        t = json.loads((out / "samples" / sid / "result.json").read_text())["timings_s"]
        method_s = t["total_s"] - t["render_s"] - t.get("write_s", 0.0)
        assert LIMIT_S <= method_s < LIMIT_S + SLACK_S, t


# ----------------------------------------------------------------------------- children die with the plug-in
@pytest.mark.render
def test_children_of_a_plugin_die_when_it_times_out_returns_or_fails_at_import(plugin_env, small_sample_dir,
                                                                                tmp_path):
    folder = Path(plugin_env["PYTHONPATH"].split(os.pathsep)[0])
    methods = ["spawning:hangs", "spawning:mp_hangs", "spawns_on_import:f", "spawning:returns"]
    t0 = time.monotonic()
    r = cli(plugin_env, "compare", small_sample_dir, "--methods", ",".join(methods), "--out", tmp_path / "cmp",
            "--method-time-limit-s", LIMIT_S)
    assert r.returncode == 1 and "Traceback" not in r.stderr, r.stderr
    assert time.monotonic() - t0 < 3 * LIMIT_S + SLACK_S
    doc = json.loads((tmp_path / "cmp" / "compare.json").read_text())["methods"]
    assert [doc[m]["status"] for m in methods] == ["failed", "failed", "failed", "ok"], doc
    pids = recorded(folder)
    assert len(pids) == 4, pids  # one child per method
    assert not survivors(pids), f"children of plug-ins still running after compare: {survivors(pids, 0)}"


@pytest.mark.render
def test_children_of_a_plugin_die_when_the_command_is_killed(plugin_env, small_sample_dir, tmp_path):
    folder = Path(plugin_env["PYTHONPATH"].split(os.pathsep)[0])
    p = subprocess.Popen([sys.executable, "-m", "platebench.bench.cli.main", "compare", str(small_sample_dir),
                          "--methods", "spawning:hangs", "--out", str(tmp_path / "cmp"), "--method-time-limit-s",
                          "600"], cwd=REPO, env=plugin_env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120
        while not recorded(folder) and time.monotonic() < deadline and p.poll() is None:
            time.sleep(0.1)
        pids = recorded(folder)
        assert pids and p.poll() is None, "the plug-in did not start"
        p.kill()  # -9: no handler, no atexit of the command runs
        p.wait(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
    assert not survivors(pids), "the plug-in's child outlived the command killed with -9"
