"""Dask faults with a real scheduler and real workers on 127.0.0.1.

The scheduler and workers are the ``dask`` CLIs of this environment (``LoopbackCluster``), killed
by PID (kill -9 of the process group). A lost scheduler or the loss of every worker is an error
of the sweep (one line, exit != 0, manifest "interrupted", no sample marked failed for it), and
``--resume`` on a new cluster finishes the sweep without redoing a committed sample.
"""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import tomli_w

from platebench.bench.sweep.dataset import RESULT, read_manifest, read_results, stale_files, validate_result

REPO = Path(__file__).resolve().parents[1]
SMALL = {"scene": {"width": 160, "height": 120}, "render": {"spp": 2, "seed": 5}}
pytestmark = pytest.mark.slow


def sweep_cmd(spec: Path, out: Path, *extra) -> list[str]:
    return [sys.executable, "-m", "platebench.bench.cli.main", "sweep", str(spec), "--out", str(out),
            "--no-progress", *map(str, extra)]


def committed(out: Path) -> dict:
    """sample id -> mtime_ns of its committed result.json."""
    return {p.parent.name: p.stat().st_mtime_ns for p in (out / "samples").glob(f"*/{RESULT}")}


def listening(pids: set[int]) -> list[tuple[str, int]]:
    import psutil
    out = []
    for pid in pids:
        try:
            procs = [psutil.Process(pid), *psutil.Process(pid).children(recursive=True)]
        except psutil.NoSuchProcess:
            continue
        for p in procs:
            try:
                conns = p.net_connections(kind="inet")
            except psutil.NoSuchProcess:
                continue
            out += [(c.laddr.ip, c.laddr.port) for c in conns if c.status == psutil.CONN_LISTEN]
    return out


def test_cluster_binds_loopback_only_without_dashboard():
    """Scheduler, nannies, workers and their HTTP servers listen on 127.0.0.1 only, and no
    dashboard is served (nothing on 8787) unless asked for."""
    from platebench.bench.sweep.executors import LoopbackCluster
    with LoopbackCluster(n_workers=2) as c:
        socks = listening({c.scheduler.pid, *(w.pid for w in c.workers)})
        assert len(socks) >= 5, socks  # scheduler + its HTTP server, 2 x (nanny + worker + worker HTTP)
        assert {ip for ip, _ in socks} == {"127.0.0.1"}, socks
        assert 8787 not in {port for _, port in socks}


def test_lost_scheduler_is_an_error_of_the_sweep_and_resume_finishes_it(tmp_path):
    """Kill -9 the scheduler after a few results: the sweep exits != 0 with one line, the
    manifest says "interrupted" with no sample failed, the orphaned workers commit nothing; --resume
    on a new cluster redoes no committed sample and completes the sweep."""
    from platebench.bench.sweep.executors import LoopbackCluster
    spec = tmp_path / "s.toml"
    spec.write_text(tomli_w.dumps({"sweep": {"name": "lost"}, "base": SMALL,
                                   "grid": {"bend_deg": [0, 5, 10, 15, 20, 25, 30, 35, 40, 45]}}))
    out = tmp_path / "ds"
    with LoopbackCluster(n_workers=2) as c:
        sweep = subprocess.Popen(sweep_cmd(spec, out, "--scheduler", c.address), cwd=REPO,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 180
            while len(committed(out)) < 3 and sweep.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            assert len(committed(out)) >= 3, sweep.communicate(timeout=10)
            os.killpg(c.scheduler.pid, signal.SIGKILL)  # the scheduler, by PID
            _, stderr = sweep.communicate(timeout=120)
        finally:
            if sweep.poll() is None:
                sweep.kill()
                sweep.wait()
        assert sweep.returncode == 2, stderr
        lines = [ln for ln in stderr.strip().splitlines() if ln.strip()]
        assert lines[-1].startswith("platebench: error: lost the Dask scheduler"), stderr
        assert "--resume" in lines[-1] and "Traceback" not in stderr and "Exception ignored" not in stderr
        before = committed(out)
        time.sleep(6)  # the workers outlive their scheduler and finish their samples: they commit nothing
        assert committed(out) == before
    m = read_manifest(out)
    assert m["state"] == "interrupted", m["state"]
    assert m["counts"]["failed"] == 0 and m["counts"]["ok"] == len(before) and m["counts"]["pending"] > 0
    for sid in before:
        assert validate_result(out, sid).status == "ok"

    with LoopbackCluster(n_workers=2) as c:
        r = subprocess.run(sweep_cmd(spec, out, "--scheduler", c.address, "--resume"), cwd=REPO,
                           capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert f"resume: {len(before)} of 10 samples already done" in r.stderr
    after = committed(out)
    assert {k: after[k] for k in before} == before  # not one committed sample redone
    m = read_manifest(out)
    assert m["state"] == "complete" and m["counts"] == {"total": 10, "ok": 10, "failed": 0, "pending": 0}
    rows = read_results(out).to_pylist()
    assert [r["sample_id"] for r in rows] == [f"{i:04d}" for i in range(10)]  # no duplicate row
    assert all(validate_result(out, f"{i:04d}") for i in range(10))
    assert not stale_files(out)


def test_all_workers_lost_stops_the_sweep_with_an_error(tmp_path):
    """Kill -9 every worker: the sweep stops within its worker timeout with one line instead of
    waiting forever; the manifest says "interrupted"."""
    from platebench.bench.sweep.executors import LoopbackCluster
    spec = tmp_path / "s.toml"
    spec.write_text(tomli_w.dumps({"sweep": {"name": "noworkers"}, "base": SMALL,
                                   "grid": {"bend_deg": [0, 10, 20, 30, 40, 50, 60, 70]}}))
    out = tmp_path / "ds"
    with LoopbackCluster(n_workers=2) as c:
        sweep = subprocess.Popen(sweep_cmd(spec, out, "--scheduler", c.address, "--worker-timeout-s", 5), cwd=REPO,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 180
            while not committed(out) and sweep.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            assert committed(out), sweep.communicate(timeout=10)
            for i in range(len(c.workers)):
                c.kill_worker(i)
            t_kill = time.monotonic()
            _, stderr = sweep.communicate(timeout=90)
            waited = time.monotonic() - t_kill
        finally:
            if sweep.poll() is None:
                sweep.kill()
                sweep.wait()
    assert sweep.returncode == 2, stderr
    assert waited < 60
    last = stderr.strip().splitlines()[-1]
    assert last.startswith("platebench: error: every Dask worker of") and "--resume" in last, stderr
    m = read_manifest(out)
    failed = [(e.get("id"), e.get("error")) for e in m.get("samples", []) if e.get("status") == "failed"]
    assert m["state"] == "interrupted" and m["counts"]["failed"] == 0, failed


def test_scheduler_address_errors_are_one_line_within_a_time_limit(tmp_path):
    """A listening port that is not Dask, and tcp://127.0.0.1 without a port, fail with one line
    (no 'Exception ignored' traceback), within the connection time limit, writing nothing."""
    spec = tmp_path / "s.toml"
    spec.write_text(tomli_w.dumps({"base": SMALL, "grid": {"bend_deg": [0]}}))
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    accepted = []
    threading.Thread(target=lambda: accepted.append(srv.accept()), daemon=True).start()
    try:
        for address, needle, limit in ((f"tcp://127.0.0.1:{srv.getsockname()[1]}", "within 3 s", 30),
                                       ("tcp://127.0.0.1", "allowed tcp://HOST:PORT", 15)):
            out = tmp_path / f"ds{limit}"
            t0 = time.monotonic()
            r = subprocess.run(sweep_cmd(spec, out, "--scheduler", address, "--connect-timeout-s", 3), cwd=REPO,
                               capture_output=True, text=True, timeout=120)
            took = time.monotonic() - t0
            lines = r.stderr.strip().splitlines()
            assert r.returncode == 2 and len(lines) == 1, r.stderr
            assert lines[0].startswith("platebench: error:") and needle in lines[0], lines
            assert took < limit, took
            assert not out.exists()
    finally:
        srv.close()
    assert accepted  # the probe did reach the port (it is the handshake that went unanswered)
