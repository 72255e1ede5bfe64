"""Installs are reproducible. The lock pins exact versions (pip-compile of
pyproject.toml), README's commands and CI install from it, ``platebench info`` compares."""
from __future__ import annotations

import json
import os
import re
from pathlib import Path

from conftest import run_cli

from platebench.bench.io.versions import check_lock, normalize, read_lock

REPO = Path(__file__).resolve().parents[1]
LOCK = REPO / "requirements.lock"


def test_lock_pins_exact_versions_of_what_the_bench_depends_on():
    pins = read_lock(LOCK)
    assert len(pins) >= 5
    assert "pip-compile" in LOCK.read_text()  # made by a standard tool
    for name, version in (("mitsuba", "3.9.1"), ("drjit", "1.5.0"), ("opencv-contrib-python-headless", "5.0.0.93")):
        assert pins[name][0] == version, (name, pins[name])
    for name in ("numpy", "trimesh", "karellen-llvm-core", "dask", "distributed", "pyarrow", "pandas", "jinja2",
                 "pytest", "pytest-xdist", "scipy", "openexr"):
        assert re.fullmatch(r"[0-9][0-9A-Za-z.+-]*", pins[name][0]), (name, pins.get(name))
    declared = re.findall(r'^\s*"([A-Za-z0-9_.-]+)', (REPO / "pyproject.toml").read_text().split("[project.scripts]")[0],
                          re.M)
    for name in declared:
        if name not in ("setuptools",):
            assert normalize(name) in pins, f"{name} of pyproject.toml is not in the lock"


def test_set_up_commands_install_from_the_lock():
    make = (REPO / "Makefile").read_text()
    assert "pip install --quiet -r requirements.lock" in make and "pip install --quiet --no-deps -e ." in make
    assert "make test" in (REPO / ".ci" / "run").read_text()
    readme = (REPO / "README.md").read_text()
    assert "requirements.lock" in readme and "make lock" in readme


def test_info_prints_versions_against_the_lock_and_flags_differences(tmp_path):
    r = run_cli("info")
    assert r.returncode == 0, r.stderr
    lock = json.loads(r.stdout)["lock"]
    assert lock["file"] == str(LOCK) and lock["packages"] == len(read_lock(LOCK))
    # a lock that differs from what is installed is flagged, package by package
    other = tmp_path / "requirements.lock"
    other.write_text("numpy==0.0.1\nmitsuba==3.9.1\nnot-installed-pkg==1.0\nwinonly==1.0 ; sys_platform == 'win32'\n")
    check = check_lock(other)
    status = {name: st for name, _, _, st in check.rows}
    assert status == {"numpy": "differs", "mitsuba": "ok", "not-installed-pkg": "missing",
                      "winonly": "not for this platform"}
    assert check.to_dict()["differs"]["numpy"]["locked"] == "0.0.1"


def _fake_numpy(folder: Path) -> Path:
    """A stray ``numpy-99.0.dist-info`` (metadata only, no package): what ``importlib.metadata`` finds first
    when ``folder`` leads the Python path, while ``import numpy`` still takes the installed one."""
    d = folder / "numpy-99.0.dist-info"
    d.mkdir(parents=True)
    (d / "METADATA").write_text("Metadata-Version: 2.1\nName: numpy\nVersion: 99.0\n")
    return folder


def test_lock_check_compares_what_python_imports_and_names_a_shadowing_copy(tmp_path, monkeypatch):
    import numpy
    locked = read_lock(LOCK)["numpy"][0]
    monkeypatch.syspath_prepend(str(_fake_numpy(tmp_path)))
    check = check_lock(LOCK)
    row = next(r for r in check.rows if r[0] == "numpy")
    assert row == ("numpy", locked, numpy.__version__, "shadowed")
    (line,) = [ln for ln in check.problem_lines() if ln.startswith("numpy ")]
    assert "99.0" in line and numpy.__version__ in line and str(tmp_path / "numpy-99.0.dist-info") in line
    assert check.to_dict()["shadowed"]["numpy"]["imported"] == numpy.__version__


def test_info_check_lock_fails_on_a_shadowing_copy_and_passes_without_it(tmp_path):
    import numpy
    r = run_cli("info", "--check-lock")
    assert r.returncode == 0, r.stderr  # this environment is the lock's
    pythonpath = os.pathsep.join(p for p in (str(_fake_numpy(tmp_path)), os.environ.get("PYTHONPATH")) if p)
    r = run_cli("info", "--check-lock", env={"PYTHONPATH": pythonpath})
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("platebench: error: ") and "numpy" in last and "99.0" in last
    assert numpy.__version__ in last and str(tmp_path) in last
