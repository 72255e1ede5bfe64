"""Concurrent runs, duplicate rows, poisoned samples, damaged files,
staged outputs, stale state. Real renders (small), real processes, real kills by PID."""
from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import tomli_w

from platebench.bench.sweep.dataset import RESULT, read_manifest, read_results, stale_files, validate_result

REPO = Path(__file__).resolve().parents[1]
SMALL = {"scene": {"width": 160, "height": 120}, "render": {"spp": 2, "seed": 7}}
TINY = ["--width", "64", "--height", "48", "--spp", "1"]


def cli_cmd(*args) -> list[str]:
    return [sys.executable, "-m", "platebench.bench.cli.main", *map(str, args)]


def cli(*args, timeout=300):
    return subprocess.run(cli_cmd(*args), cwd=REPO, capture_output=True, text=True, timeout=timeout)


def write_spec(path: Path, bends, name="t") -> Path:
    path.write_text(tomli_w.dumps({"sweep": {"name": name}, "base": SMALL, "grid": {"bend_deg": list(bends)}}))
    return path


def mtimes(d: Path) -> dict:
    return {str(p.relative_to(d)): p.stat().st_mtime_ns for p in sorted(d.rglob("*")) if p.is_file()}


def wait_for(cond, timeout=180, proc=None):
    deadline = time.monotonic() + timeout
    while not cond():
        if proc is not None and proc.poll() is not None:
            raise AssertionError(f"process ended first: {proc.communicate()}")
        if time.monotonic() > deadline:
            raise AssertionError("timed out")
        time.sleep(0.02)


def n_committed(out: Path) -> int:
    return len(list((out / "samples").glob(f"*/{RESULT}"))) if (out / "samples").is_dir() else 0


# ----------------------------------------------------------------------------- the dataset lock
@pytest.mark.render
def test_second_sweep_into_a_dataset_is_refused_and_a_stale_lock_taken_over(tmp_path):
    spec = write_spec(tmp_path / "s.toml", [0, 5, 10, 15, 20, 25, 30, 35])
    out = tmp_path / "ds"
    first = subprocess.Popen(cli_cmd("sweep", spec, "--out", out, "--workers", "1", "--no-progress"), cwd=REPO,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        wait_for(lambda: n_committed(out) >= 1, proc=first)
        second = cli("sweep", spec, "--out", out, "--workers", "1", "--resume")
        assert second.returncode == 2, second.stderr
        line = second.stderr.strip().splitlines()
        assert len(line) == 1 and f"PID {first.pid} on host {os.uname().nodename}" in line[0], line
        _, err = first.communicate(timeout=300)
    finally:
        if first.poll() is None:
            first.kill()
            first.wait()
    assert first.returncode == 0, err
    rows = read_results(out).to_pylist()
    assert [r["sample_id"] for r in rows] == [f"{i:04d}" for i in range(8)]  # no duplicate row
    m = read_manifest(out)
    assert m["state"] == "complete"
    for e in m["samples"]:
        assert validate_result(out, e["id"], manifest_files=e["files_sha256"])
    # a lock left by a killed sweep is taken over, and said so
    lock = tmp_path / ".ds.lock"
    lock.write_text(json.dumps({"pid": 999999, "host": os.uname().nodename, "since": "earlier", "command": "x"}))
    r = cli("sweep", spec, "--out", out, "--workers", "1", "--resume")
    assert r.returncode == 0, r.stderr
    assert "took over the stale lock" in r.stderr and "PID 999999" in r.stderr
    assert not lock.exists() and not stale_files(out)


# ----------------------------------------------------------------------------- a failed write
@pytest.mark.render
def test_a_failed_write_is_an_error_of_the_output_not_a_failed_sample(tmp_path):
    """The dataset lives on a 96 KiB tmpfs (a user namespace): the render succeeds, writing it fails
    (no space left). That is no failure of the sample: the task raises the OSError (the sweep stops,
    bench.io.fs_errors) and leaves no attempt directory behind; the methods do not run."""
    if shutil.which("unshare") is None or subprocess.run(["unshare", "-rm", "true"]).returncode:
        pytest.skip("no user namespaces here (unshare -rm) for a small tmpfs")
    d = tmp_path / "full"
    d.mkdir()
    code = ("import errno, json, os; from pathlib import Path; from platebench.bench.sweep.spec import parse_spec; "
            "from platebench.bench.sweep.tasks import tasks_from_spec, run_sample; "
            f"spec = parse_spec({{'base': {SMALL!r}, 'sweep': {{'methods': ['paper', 'sgbm']}}, "
            "'grid': {'bend_deg': [10]}}); "
            f"(Path({str(d)!r}) / 'samples').mkdir(); "
            f"t = tasks_from_spec(spec, Path({str(d)!r}))[0]\n"
            "try:\n    run_sample(t); print(json.dumps({'raised': None}))\n"
            "except OSError as e:\n"
            f"    print(json.dumps({{'raised': errno.errorcode[e.errno], 'left': os.listdir({str(d)!r} + '/samples')}}))")
    r = subprocess.run(["unshare", "-rm", "sh", "-c",
                        f"mount -t tmpfs -o size=96k tmpfs {d} && exec {sys.executable} -c \"{code}\""],
                       cwd=REPO, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout.strip().splitlines()[-1])
    assert res == {"raised": "ENOSPC", "left": []}, res


# ----------------------------------------------------------------------------- poisoned samples
def _kill_attempts_of(out: Path, sid: str, stop: threading.Event, killed: list) -> None:
    """kill -9 every process that starts an attempt at sample ``sid`` (its attempt directory names it)."""
    from platebench.bench.io.atomic import temp_owner
    while not stop.is_set():
        if (out / "samples").is_dir():
            for p in list((out / "samples").glob(f".tmp-{sid}~*")):
                owner = temp_owner(p.name)  # (the sweep process itself commits a failed result: spare it)
                if owner and owner[1] not in killed and owner[1] != os.getpid():
                    killed.append(owner[1])
                    try:
                        os.kill(owner[1], signal.SIGKILL)
                    except ProcessLookupError:
                        pass
        time.sleep(0.01)


@pytest.mark.slow
@pytest.mark.render
def test_poisoned_sample_does_not_take_down_its_neighbour(tmp_path):
    from platebench.bench.sweep.executors import LocalExecutor, run_sweep
    from platebench.bench.sweep.spec import parse_spec
    spec = parse_spec({"sweep": {"name": "poison"}, "base": SMALL, "grid": {"bend_deg": [0, 10, 20]}})
    out = tmp_path / "ds"
    stop, killed = threading.Event(), []
    killer = threading.Thread(target=_kill_attempts_of, args=(out, "0001", stop, killed), daemon=True)
    killer.start()
    try:
        ex = LocalExecutor(2, retries=1)
        summary = run_sweep(spec, out, ex, progress=False)
        assert len(killed) >= 2  # once or more beside its neighbour, then alone until its retries ran out
        assert killed[-2:] and len(ex.isolated) >= 1
        status = {sid: (r.status, r.error or "") for sid, r in summary.results.items()}
        assert status["0001"][0] == "failed" and status["0001"][1].startswith("WorkerLost"), status
        assert status["0000"] == ("ok", "") and status["0002"] == ("ok", ""), status
        assert "0001" in ex.isolated
        ok_before = {s: mtimes(out / "samples" / s) for s in ("0000", "0002")}
        # --retry-failed runs the poisoned sample again; it fails alone again, the others are not touched
        summary = run_sweep(spec, out, LocalExecutor(2, retries=1), resume=True, retry_failed=True, progress=False)
        assert summary.run == 1 and summary.results["0001"].status == "failed"
        assert {s: mtimes(out / "samples" / s) for s in ("0000", "0002")} == ok_before
    finally:
        stop.set()
        killer.join(timeout=5)
    assert read_manifest(out)["counts"] == {"total": 3, "ok": 2, "failed": 1, "pending": 0}
    assert not stale_files(out)


# ----------------------------------------------------------------------------- resume verifies
@pytest.mark.render
def test_resume_redoes_samples_whose_files_do_not_match(tmp_path):
    from platebench.bench.sweep.executors import LocalExecutor, run_sweep
    from platebench.bench.sweep.spec import parse_spec
    spec = parse_spec({"sweep": {"name": "damage"}, "base": SMALL, "grid": {"bend_deg": [0, 10, 20]}})
    out = tmp_path / "ds"
    run_sweep(spec, out, LocalExecutor(0), progress=False)
    img = out / "samples" / "0000" / "sample" / "images" / "left_active.png"
    img.write_bytes(img.read_bytes()[:100])  # truncated
    (out / "samples" / "0001" / "recon" / "paper" / "points.csv").unlink()
    untouched = mtimes(out / "samples" / "0002")
    said = []
    summary = run_sweep(spec, out, LocalExecutor(0), resume=True, progress=False, log=said.append)
    assert summary.run == 2 and summary.skipped == 1
    assert any("1 of 3 samples already done, 2 to run (2 whose files no longer match" in m for m in said), said
    assert mtimes(out / "samples" / "0002") == untouched
    for sid in ("0000", "0001", "0002"):
        assert validate_result(out, sid).status == "ok"
    assert read_manifest(out)["state"] == "complete"


# ----------------------------------------------------------------------------- staged outputs
@pytest.mark.render
def test_simultaneous_renders_to_one_out_one_wins_the_other_is_refused(tmp_path):
    out = tmp_path / "s"
    procs = [subprocess.Popen(cli_cmd("render", "--out", out, *TINY, "--seed", str(i)), cwd=REPO,
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for i in range(2)]
    results = [(p.wait(timeout=300), p.stderr.read()) for p in procs]
    codes = sorted(rc for rc, _ in results)
    assert codes == [0, 2], results
    refused = next(err for rc, err in results if rc == 2).strip().splitlines()
    assert len(refused) == 1
    assert "is being written by another platebench process (PID" in refused[0] or "already exists" in refused[0]
    winner = next(i for i, (rc, _) in enumerate(results) if rc == 0)
    assert json.loads((out / "sample.json").read_text())["config"]["render"]["seed"] == winner
    assert not [p for p in tmp_path.iterdir() if p.name != "s"]  # no staging, no lock left


@pytest.mark.render
def test_killed_overwrite_render_keeps_the_old_sample_and_leaves_nothing_the_next_run_does_not_clean(tmp_path):
    out = tmp_path / "s"
    assert cli("render", "--out", out, *TINY).returncode == 0
    before = mtimes(out)
    p = subprocess.Popen(cli_cmd("render", "--out", out, *TINY, "--seed", "9", "--overwrite"), cwd=REPO,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    wait_for(lambda: any(x.name.startswith(".tmp-s~") for x in tmp_path.iterdir()), proc=p)
    p.kill()  # kill -9 mid-render
    p.wait()
    assert mtimes(out) == before
    assert any(x.name.startswith(".tmp-s~") for x in tmp_path.iterdir())  # what kill -9 leaves...
    r = cli("render", "--out", out, *TINY, "--seed", "9", "--overwrite")
    assert r.returncode == 0, r.stderr
    assert "took over the stale lock" in r.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["s"]  # ...the next run cleans
    assert json.loads((out / "sample.json").read_text())["config"]["render"]["seed"] == 9
    # SIGTERM: the staging is removed at once, exit 143
    p = subprocess.Popen(cli_cmd("render", "--out", out, *TINY, "--seed", "3", "--overwrite"), cwd=REPO,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    wait_for(lambda: any(x.name.startswith(".tmp-s~") for x in tmp_path.iterdir()), proc=p)
    p.terminate()
    assert p.wait(timeout=60) == 143
    assert sorted(x.name for x in tmp_path.iterdir()) == ["s"]
    assert json.loads((out / "sample.json").read_text())["config"]["render"]["seed"] == 9


def test_render_checks_the_target_before_rendering(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    t0 = time.monotonic()
    r = cli("render", "--out", blocker / "s")  # the reference render would take several seconds
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert str(blocker) in r.stderr and time.monotonic() - t0 < 20
    assert blocker.read_text() == "x"


@pytest.mark.slow
@pytest.mark.render
def test_killed_overwrite_sweep_keeps_the_old_dataset(tmp_path):
    spec = write_spec(tmp_path / "s.toml", [0, 10, 20])
    out = tmp_path / "ds"
    assert cli("sweep", spec, "--out", out, "--workers", "0").returncode == 0
    before = mtimes(out)
    p = subprocess.Popen(cli_cmd("sweep", spec, "--out", out, "--workers", "0", "--overwrite", "--no-progress"),
                         cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    stage = lambda: [x for x in tmp_path.iterdir() if x.name.startswith(".tmp-ds~")]  # noqa: E731
    wait_for(lambda: any(n_committed(s) >= 1 for s in stage()), proc=p)
    p.kill()
    p.wait()
    assert mtimes(out) == before and read_manifest(out)["state"] == "complete"
    r = cli("sweep", spec, "--out", out, "--workers", "0", "--overwrite")
    assert r.returncode == 0, r.stderr
    assert sorted(x.name for x in tmp_path.iterdir()) == ["ds", "s.toml"]
    assert read_manifest(out)["state"] == "complete" and not stale_files(out)


@pytest.mark.render
def test_demo_is_staged(tmp_path):
    out = tmp_path / "demo"
    out.mkdir()
    (out / "keep.txt").write_text("old")
    r = cli("demo", "--quick", "--out", out)
    assert r.returncode == 2 and "already exists" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    r = cli("demo", "--quick", "--out", out, "--overwrite")  # not a demo output: never replaced
    assert r.returncode == 2 and "keep.txt, not a PlateBench demo output" in r.stderr, r.stderr
    shutil.rmtree(out)
    from platebench.bench.io.outputs import STAMP, output_dir
    with output_dir(out, "demo output") as d:  # an earlier demo's output (its marker and stamp)
        (d / "demo.json").write_text(json.dumps({"generator": "platebench demo"}))
        (d / "keep.txt").write_text("old")
    p = subprocess.Popen(cli_cmd("demo", "--quick", "--out", out, "--overwrite"), cwd=REPO,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    wait_for(lambda: any(x.name.startswith(".tmp-demo~") for x in tmp_path.iterdir()), proc=p)
    p.terminate()
    assert p.wait(timeout=60) == 143
    assert sorted(x.name for x in out.iterdir()) == [STAMP, "demo.json", "keep.txt"]
    assert sorted(x.name for x in tmp_path.iterdir()) == ["demo"]


# ----------------------------------------------------------------------------- stale manifests
def test_manifest_is_not_left_running_and_keeps_up_with_the_samples(tmp_path):
    spec = write_spec(tmp_path / "s.toml", [0, 10, 20, 30])
    out = tmp_path / "ds"
    # SIGTERM: the sweep closes its manifest as "interrupted" and exits 143
    p = subprocess.Popen(cli_cmd("sweep", spec, "--out", out, "--workers", "1", "--no-progress"), cwd=REPO,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    wait_for(lambda: n_committed(out) >= 1, proc=p)
    p.terminate()
    assert p.wait(timeout=60) == 143
    raw = json.loads((out / "manifest.json").read_text())
    assert raw["state"] == "interrupted" and raw["counts"]["ok"] == n_committed(out)
    # kill -9: the file says "running", but nobody holds the lock: it reads as "interrupted"
    p = subprocess.Popen(cli_cmd("sweep", spec, "--out", out, "--workers", "1", "--no-progress", "--resume"),
                         cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    done = n_committed(out)
    wait_for(lambda: n_committed(out) > done, proc=p)
    p.kill()
    p.wait()
    assert json.loads((out / "manifest.json").read_text())["state"] == "running"
    m = read_manifest(out)
    assert m["state"] == "interrupted" and "killed" in m["state_note"]
    # the manifest and the table follow each committed sample (no flush interval behind)
    from platebench.bench.sweep.executors import LocalExecutor, run_sweep
    from platebench.bench.sweep.spec import load_spec
    seen = []

    def check(res):
        m = read_manifest(out)
        seen.append((m["counts"]["ok"], n_committed(out), len(read_results(out))))

    # flush_every_s=0: after every sample (by default a flush is skipped while the last one cost more
    # than 5 % of the time since it, and this spec's 64 x 48 samples come faster than that)
    run_sweep(load_spec(spec), out, LocalExecutor(0), resume=True, progress=False, on_result=check, flush_every_s=0.0)
    assert seen and all(a == b == c for a, b, c in seen), seen
    assert read_manifest(out)["state"] == "complete"


def test_compare_is_staged(tmp_path):
    sample = tmp_path / "s"
    assert cli("render", "--out", sample, "--width", "160", "--height", "120", "--spp", "2").returncode == 0
    out = tmp_path / "cmp"
    r = cli("compare", sample, "--methods", "sgbm", "--out", out)
    assert r.returncode == 0, r.stderr
    first = mtimes(out)
    r = cli("compare", sample, "--methods", "sgbm", "--out", out)
    assert r.returncode == 2 and "already exists" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    assert mtimes(out) == first
    r = cli("compare", sample, "--methods", "sgbm", "--out", out, "--overwrite")
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in out.iterdir()) == [".platebench-output.json", "compare.json", "compare.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cmp", "s"]
