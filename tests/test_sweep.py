"""Sweeps: spec expansion and validation, a local-pool sweep into a dataset, failures, resume after kill -9.

Real components throughout: real renders (160 x 120, spp 2), the paper's pipeline, real
worker processes, a real ``platebench sweep`` subprocess killed with SIGKILL.
"""
from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import tomli_w

from platebench.bench.sweep.dataset import (
    RESULT,
    read_manifest,
    read_results,
    stale_files,
    validate_result,
)
from platebench.bench.sweep.spec import SpecError, load_spec, parse_spec

REPO = Path(__file__).resolve().parents[1]
SMALL = {"scene": {"width": 160, "height": 120}, "render": {"spp": 2, "seed": 1}}


def write_spec(path: Path, doc: dict) -> Path:
    path.write_text(tomli_w.dumps(doc))
    return path


def cli(*args, timeout=180):
    return subprocess.run([sys.executable, "-m", "platebench.bench.cli.main", *map(str, args)], cwd=REPO, capture_output=True,
                          text=True, timeout=timeout)


# ----------------------------------------------------------------------------- spec expansion
def test_grid_expansion_order_ids_and_configs():
    spec = parse_spec({"base": SMALL, "grid": {"bend_deg": {"start": 0, "stop": 60, "step": 20},
                                               "material": ["diffuse", "roughconductor"]}})
    assert [s.sample_id for s in spec.samples] == [f"{i:04d}" for i in range(8)]
    got = [(round(math.degrees(s.config.plate.deformation.angle_rad)), s.config.scene.material.get("kind"))
           for s in spec.samples]
    assert got == [(b, m) for b in (0, 20, 40, 60) for m in ("diffuse", "roughconductor")]  # first axis outermost
    assert all(s.config.scene.width == 160 and s.config.render.spp == 2 for s in spec.samples)
    assert len({s.config_sha256 for s in spec.samples}) == 8


def test_grid_forms_family_switch_and_duplicates():
    spec = parse_spec({"grid": {"family": ["flat", "cylinder", "fold"], "bend_deg": [0, 30],
                                "resolution": ["160x120"], "distance_m": {"start": 0.4, "stop": 0.5, "num": 2}}})
    fams = [s.config.plate.deformation.family for s in spec.samples]
    # bend_deg does not apply to a flat plate: its two bends give one sample (kept once)
    assert fams.count("flat") == 2 and fams.count("cylinder") == 4 and fams.count("fold") == 4
    assert spec.duplicates == 2 and spec.ignored == {"bend_deg": 4}
    fold = next(s for s in spec.samples if s.params["family"] == "fold" and s.params["bend_deg"] == 30)
    assert fold.config.plate.deformation.angle_rad == pytest.approx(math.radians(30))
    assert {(s.config.scene.width, s.config.scene.height) for s in spec.samples} == {(160, 120)}
    assert {s.config.scene.distance_m for s in spec.samples} == {0.4, 0.5}


def test_random_draws_are_seeded_and_order_independent():
    axes = {"bend_deg": {"min": 0, "max": 60}, "family": ["cylinder", "fold"], "spp": {"min": 2, "max": 8, "int": True},
            "noise": ["none", "low"], "distance_m": 0.45}
    a = parse_spec({"sweep": {"seed": 5, "count": 6}, "base": SMALL, "random": axes})
    b = parse_spec({"sweep": {"seed": 5, "count": 6}, "base": SMALL, "random": dict(reversed(list(axes.items())))})
    c = parse_spec({"sweep": {"seed": 6, "count": 6}, "base": SMALL, "random": axes})
    more = parse_spec({"sweep": {"seed": 5, "count": 9}, "base": SMALL, "random": axes})
    sha = lambda s: [p.config_sha256 for p in s.samples]  # noqa: E731
    assert sha(a) == sha(b)  # same seed -> same samples, whatever the key order
    assert sha(a) != sha(c)
    assert sha(more)[:6] == sha(a)  # raising count keeps the first samples
    for p in a.samples:
        assert 0 <= math.degrees(p.config.plate.deformation.angle_rad) <= 60
        assert 2 <= p.config.render.spp <= 8 and p.config.scene.distance_m == 0.45
    assert a.sha256 == b.sha256 != c.sha256


def test_example_spec_and_seed_per_sample():
    spec = load_spec(REPO / "examples" / "bend_sweep.toml")
    assert [s.params["bend_deg"] for s in spec.samples] == [0, 20, 40, 60]
    assert spec.methods == ("paper",)
    seeded = parse_spec({"sweep": {"seed_per_sample": True}, "base": SMALL, "grid": {"bend_deg": [0, 10, 20]}})
    assert [s.config.render.seed for s in seeded.samples] == [1, 2, 3]


@pytest.mark.parametrize("doc,needles", [
    ({"grid": {"bend_deg": [0, 400]}}, ["grid.bend_deg = 400", "0 to 350 deg"]),
    ({"grid": {"family": ["fold"], "bend_deg": [200]}}, ["grid.bend_deg = 200", "0 to 180 deg"]),
    ({"grid": {"distance_m": [0.4, 9.0]}}, ["grid.distance_m = 9.0", "0.05 to 5.0"]),
    ({"grid": {"spp": [0]}}, ["grid.spp = 0", "1 to 65536"]),
    ({"grid": {"bend_dg": [0]}}, ["bend_dg", "bend_deg"]),
    ({"grid": {"bend_deg": [0]}, "extra": {}}, ["extra", "allowed keys"]),
    ({"sweep": {"nme": "x"}, "grid": {"bend_deg": [0]}}, ["sweep.nme", "allowed keys"]),
    ({"grid": {}}, ["[grid] is empty"]),
    ({"grid": {"bend_deg": []}}, ["grid.bend_deg is empty"]),
    ({"base": {"scene": {"wdth": 3}}, "grid": {"spp": [1]}}, ["scene.wdth", "allowed keys"]),
    ({"grid": {"albedo": [1.5]}}, ["grid.albedo = 1.5", "0 to 1"]),
    ({"grid": {"scene.foo": [1]}}, ["scene.foo"]),
    ({"sweep": {"count": 3}, "random": {"bend_deg": {"min": 0, "max": 500}}}, ["random.bend_deg", "0 to 350 deg"]),
    ({"sweep": {"methods": ["nope"]}, "grid": {"spp": [1]}}, ["nope", "paper"]),
])
def test_bad_specs_are_refused_naming_the_key(tmp_path, doc, needles):
    path = write_spec(tmp_path / "bad.toml", doc)
    with pytest.raises(SpecError) as e:
        load_spec(path)
    msg = str(e.value)
    assert "\n" not in msg
    for n in needles:
        assert n in msg, msg


def test_bad_spec_on_the_command_line_writes_nothing(tmp_path):
    spec = write_spec(tmp_path / "bad.toml", {"base": SMALL, "grid": {"bend_deg": [0, 20, 400]}})
    out = tmp_path / "ds"
    r = cli("sweep", spec, "--out", out, "--workers", "2")
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("platebench: error:")
    assert "grid.bend_deg = 400" in lines[0] and "allowed 0 to 350 deg" in lines[0]
    assert not out.exists()


# ----------------------------------------------------------------------------- a real sweep
@pytest.mark.render
def test_local_sweep_two_workers_with_a_failing_sample(tmp_path):
    """4 samples on 2 worker processes; albedo 0 (a black plate) makes the paper's pipeline fail:
    recorded as failed, the sweep goes on; manifest + CSV + Parquet have the right rows."""
    from platebench.bench.sweep.executors import LocalExecutor, run_sweep
    spec = parse_spec({"sweep": {"name": "t"}, "base": SMALL, "grid": {"bend_deg": [0, 30], "albedo": [0.8, 0.0]}})
    out = tmp_path / "ds"
    summary = run_sweep(spec, out, LocalExecutor(2), progress=False)
    assert (summary.total, summary.ok, summary.failed, summary.run) == (4, 2, 2, 4)

    m = read_manifest(out)
    assert m["state"] == "complete" and m["counts"] == {"total": 4, "ok": 2, "failed": 2, "pending": 0}
    assert m["spec"]["sha256"] == spec.sha256 and m["packages"]["mitsuba"] and m["executor"]["workers"] == 2
    by_id = {s["id"]: s for s in m["samples"]}
    assert {k: v["status"] for k, v in by_id.items()} == {"0000": "ok", "0001": "failed", "0002": "ok",
                                                           "0003": "failed"}
    assert "ReconstructionError" in by_id["0001"]["error"]
    assert set(by_id["0000"]["images_sha256"]) == {"left_passive", "right_passive", "left_active", "right_active"}

    table = read_results(out).to_pylist()
    assert [(r["sample_id"], r["method"], r["status"]) for r in table] == [
        ("0000", "paper", "ok"), ("0001", "paper", "failed"), ("0002", "paper", "ok"), ("0003", "paper", "failed")]
    for r in table:
        assert r["family"] == "cylinder" and r["width_px"] == 160 and r["spp"] == 2
        assert r["time_total_s"] > 0 and r["worker_maxrss_mb"] > 50
        if r["status"] == "ok":
            assert r["error"] is None and r["matched_count"] == 16 and r["expected_count_gt"] == 16
            assert 0 <= r["centres_depth_rms_mm"] < 3 and r["coverage_frac"] > 0.9
            assert r["depth_rms_mm"] is None  # the paper's figure is at the square centres, not over the pixels
        else:
            assert r["error"].startswith("ReconstructionError") and r["centres_depth_rms_mm"] is None
    assert [r["bend_deg"] for r in table] == pytest.approx([0, 0, 30, 30])
    csv_lines = (out / "results.csv").read_text().splitlines()
    assert len(csv_lines) == 5 and csv_lines[0].startswith("sample_id,index,method,status,error,family,bend_deg")
    # kernel reuse: a worker process that made several samples built its scene once
    results = [json.loads((out / "samples" / s / RESULT).read_text()) for s in by_id]
    by_pid = {}
    for r in results:
        by_pid.setdefault(r["worker"]["pid"], []).append(r["worker"])
    assert os.getpid() not in by_pid  # ran in worker processes
    busiest = max(by_pid.values(), key=len)
    assert len(busiest) >= 2 and {w["scene_builds"] for w in busiest} == {1}
    assert not stale_files(out)


@pytest.mark.render
def test_resume_after_kill_9(tmp_path):
    """Kill -9 a running sweep once its first sample is done; --resume redoes nothing completed,
    sweeps temporary leftovers and finishes the rest."""
    spec = write_spec(tmp_path / "s.toml", {"sweep": {"name": "resume"}, "base": SMALL,
                                            "grid": {"bend_deg": [0, 15, 30]}})
    out = tmp_path / "ds"
    p = subprocess.Popen([sys.executable, "-m", "platebench.bench.cli.main", "sweep", str(spec), "--out", str(out), "--workers", "1",
                          "--no-progress"], cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    first = out / "samples" / "0000" / RESULT
    try:
        deadline = time.monotonic() + 120
        while not first.exists() and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.02)
        assert first.exists(), p.communicate(timeout=5)
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=30)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
    assert p.returncode == -signal.SIGKILL
    done = [s for s in ("0000", "0001", "0002") if validate_result(out, s)]
    assert "0000" in done and len(done) < 3, "the sweep finished before it could be killed"
    worker_pid = json.loads(first.read_text())["worker"]["pid"]
    _wait_gone(worker_pid)  # the pool worker died with the sweep (no orphan writing behind it)
    before = {s: _mtimes(out / "samples" / s) for s in done}
    # a leftover of an interrupted staged write, as a kill -9 mid-write leaves
    leftover = out / "samples" / "0002" / ".tmp-sample-killed"
    leftover.mkdir(parents=True, exist_ok=True)
    (leftover / "half.png").write_bytes(b"\x89PNG")
    assert read_manifest(out)["counts"]["pending"] >= 1

    r = cli("sweep", spec, "--out", out, "--workers", "1", "--resume", "--progress")
    assert r.returncode == 0, r.stderr
    assert f"resume: {len(done)} of 3 samples already done" in r.stderr
    assert "failed 0" in r.stderr  # the progress bar's postfix
    for s in done:
        assert _mtimes(out / "samples" / s) == before[s], f"sample {s} was redone"
    assert all(validate_result(out, s) for s in ("0000", "0001", "0002"))
    assert not leftover.exists() and not stale_files(out)
    m = read_manifest(out)
    assert m["state"] == "complete" and m["counts"]["ok"] == 3
    assert [r["sample_id"] for r in read_results(out).to_pylist()] == ["0000", "0001", "0002"]
    # without --resume an existing dataset is refused
    r = cli("sweep", spec, "--out", out)
    assert r.returncode == 2 and "--resume" in r.stderr


def _mtimes(d: Path) -> dict:
    return {str(p.relative_to(d)): p.stat().st_mtime_ns for p in sorted(d.rglob("*")) if p.is_file()}


def _wait_gone(pid: int, timeout: float = 15.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
        except (FileNotFoundError, ProcessLookupError):
            return
        if state in ("Z", "X"):
            return
        time.sleep(0.05)
    raise AssertionError(f"worker process {pid} outlived the killed sweep")


@pytest.mark.render
def test_local_worker_killed_mid_sweep_is_retried(tmp_path):
    """kill -9 a pool worker while it works: the pool is rebuilt, its sample retried, none lost."""
    import threading

    from platebench.bench.sweep.executors import LocalExecutor, run_sweep
    spec = parse_spec({"sweep": {"name": "kill-local"}, "base": SMALL, "grid": {"bend_deg": [0, 10, 20, 30, 40, 50]}})
    out = tmp_path / "ds"
    killed = []

    def killer():
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            for p in (out / "samples").glob(f"*/{RESULT}"):
                pid = json.loads(p.read_text())["worker"]["pid"]
                os.kill(pid, signal.SIGKILL)  # it has already taken its next sample
                killed.append(pid)
                return
            time.sleep(0.01)

    t = threading.Thread(target=killer, daemon=True)
    t.start()
    summary = run_sweep(spec, out, LocalExecutor(2), progress=False)
    t.join(timeout=5)
    assert killed and (summary.ok, summary.failed) == (6, 0)
    pids = {json.loads((out / "samples" / f"{i:04d}" / RESULT).read_text())["worker"]["pid"] for i in range(6)}
    assert killed[0] in pids and len(pids) >= 2  # the killed worker made one; the rebuilt pool the rest
    assert not stale_files(out)


# ----------------------------------------------------------------------------- example specs shipped with the package
def _platebench_outside_the_repo(cwd: Path, *args) -> subprocess.CompletedProcess:
    """``platebench ARGS`` run from ``cwd`` (outside the repository), as a user of the installed package would."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run([sys.executable, "-m", "platebench.bench.cli.main", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120)


def test_an_example_spec_runs_from_anywhere(tmp_path):
    from platebench.bench.cli.sweep import example_names
    repo = Path(__file__).resolve().parents[1]
    assert example_names() == sorted(p.stem for p in (repo / "examples").glob("*.toml"))
    r = _platebench_outside_the_repo(tmp_path, "sweep", "--example", "bend_sweep", "--dry-run")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith("spec        bend_sweep (") and "samples, methods" in r.stdout
    assert not any(tmp_path.iterdir())  # a dry run writes nothing
    # an unknown name: one line, exit 2, naming the allowed ones
    r = _platebench_outside_the_repo(tmp_path, "sweep", "--example", "nosuch", "--dry-run")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "nosuch" in r.stderr and all(n in r.stderr for n in example_names())
    # exactly one of SPEC.toml and --example
    for args in (["--dry-run"], [str(repo / "examples" / "bend_sweep.toml"), "--example", "bend_sweep", "--dry-run"]):
        r = _platebench_outside_the_repo(tmp_path, "sweep", *args)
        assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
        assert "exactly one of SPEC.toml and --example" in r.stderr
    # the names are in --help
    r = _platebench_outside_the_repo(tmp_path, "sweep", "--help")
    assert r.returncode == 0 and all(n in " ".join(r.stdout.split()) for n in example_names())
