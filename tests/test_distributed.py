"""Sweeps on a real Dask cluster: ``dask scheduler`` + 2 ``dask worker`` processes on 127.0.0.1.

Not a mock and not LocalCluster: the CLIs of this environment are started on free loopback
ports (bench.sweep.executors.LoopbackCluster) and always torn down. One test kills a worker
(kill -9 of its process group: nanny + worker process) while tasks run; no sample is lost.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from platebench.bench.sweep.dataset import (
    RESULT,
    read_manifest,
    read_results,
    stale_files,
    validate_result,
)
from platebench.bench.sweep.spec import parse_spec

REPO = Path(__file__).resolve().parents[1]
SMALL = {"scene": {"width": 160, "height": 120}, "render": {"spp": 2, "seed": 2}}


@pytest.fixture
def cluster():
    from platebench.bench.sweep.executors import LoopbackCluster
    c = LoopbackCluster(n_workers=2, nthreads=1, startup_timeout_s=90)
    try:
        c.start()
        yield c
    finally:
        c.close()
        for p in [c.scheduler, *c.workers]:
            assert p is None or p.poll() is not None


@pytest.mark.render
def test_dask_sweep_on_two_loopback_workers(cluster, tmp_path):
    from platebench.bench.sweep.executors import DaskExecutor, run_sweep
    pids = set(cluster.worker_pids().values())
    assert len(pids) == 2
    spec = parse_spec({"sweep": {"name": "dask"}, "base": SMALL, "grid": {"bend_deg": [0, 10, 20, 30]}})
    out = tmp_path / "ds"
    summary = run_sweep(spec, out, DaskExecutor(cluster.address), progress=False)
    assert (summary.ok, summary.failed, summary.run) == (4, 0, 4)
    m = read_manifest(out)
    assert m["state"] == "complete" and m["executor"]["kind"] == "dask" and m["executor"]["workers"] == 2
    rows = read_results(out).to_pylist()
    assert [r["sample_id"] for r in rows] == ["0000", "0001", "0002", "0003"]
    assert all(r["status"] == "ok" and r["matched_count"] == 16 for r in rows)
    used = {json.loads((out / "samples" / r["sample_id"] / RESULT).read_text())["worker"]["pid"] for r in rows}
    assert used <= pids and os.getpid() not in used  # made by the cluster's worker processes
    assert all(st["maxrss_mb"] > 50 for st in summary.worker_stats.values())
    assert not stale_files(out)


@pytest.mark.render
def test_worker_killed_mid_sweep_loses_no_sample(cluster, tmp_path):
    import tomli_w
    from distributed import Client
    spec = tmp_path / "s.toml"
    spec.write_text(tomli_w.dumps({"sweep": {"name": "kill"}, "base": SMALL,
                                   "grid": {"bend_deg": [0, 10, 20, 30, 40, 50]}}))
    out = tmp_path / "ds"
    pids = cluster.worker_pids()  # address -> worker process pid
    group = {addr: next(i for i, w in enumerate(cluster.workers) if w.pid == os.getpgid(pid))
             for addr, pid in pids.items()}
    sweep = subprocess.Popen([sys.executable, "-m", "platebench.bench.cli.main", "sweep", str(spec), "--out", str(out),
                              "--scheduler", cluster.address, "--no-progress"], cwd=REPO,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        with Client(cluster.address, timeout="30s", set_as_default=False) as client:
            deadline = time.monotonic() + 120
            victim, in_flight = None, []
            while time.monotonic() < deadline and sweep.poll() is None:
                done_before = {p.parent.name for p in (out / "samples").glob(f"*/{RESULT}")}
                if done_before:
                    busy = {a: [k.split("-")[3] for k in keys] for a, keys in client.processing().items()}
                    busy = {a: ids for a, ids in busy.items() if set(ids) - done_before}
                    if busy:
                        victim = next(iter(busy))
                        in_flight = set(busy[victim]) - done_before
                        cluster.kill_worker(group[victim])  # kill -9 nanny + worker while tasks run
                        break
                time.sleep(0.02)
            assert victim is not None, "no task was running when a sample finished"
        stdout, stderr = sweep.communicate(timeout=180)
    finally:
        if sweep.poll() is None:
            sweep.kill()
            sweep.wait()
    assert sweep.returncode == 0, stderr
    assert "6 ok, 0 failed" in stdout
    assert cluster.workers[group[victim]].poll() is not None
    killed_pid = pids[victim]
    for sid in [f"{i:04d}" for i in range(6)]:
        res = validate_result(out, sid)
        assert res is not None and res.status == "ok"
        if sid in in_flight:  # lost with the worker, then retried elsewhere
            assert res.worker["pid"] != killed_pid
    assert [r["status"] for r in read_results(out).to_pylist()] == ["ok"] * 6
    assert read_manifest(out)["counts"]["ok"] == 6
    assert not stale_files(out)


@pytest.mark.render
def test_pipeline_renders_on_the_render_worker_and_finishes_on_cpu_workers(tmp_path):
    """The two-stage sweep (``PipelineExecutor``) on a loopback cluster whose workers declare resources
    (one GPU=1, two CPU=1): every sample rendered by the render worker and written, reconstructed and
    scored by a CPU worker; the same rows as the in-process sweep, a failing sample recorded as its
    own, committed with checksums by this process, and --resume redoes nothing."""
    from distributed import Client

    from platebench.bench.sweep.executors import (
        LocalExecutor,
        LoopbackCluster,
        PipelineExecutor,
        run_sweep,
    )
    spec = parse_spec({"sweep": {"name": "pipe", "methods": ["paper", "sgbm"]}, "base": SMALL,
                       "grid": {"bend_deg": [0, 20], "distance_m": [0.4, 0.2]}})  # at 0.2 m the plate leaves the view
    local = run_sweep(spec, tmp_path / "local", LocalExecutor(0), progress=False)
    out = tmp_path / "pipe"
    with LoopbackCluster(n_workers=3, nthreads=1, render_workers=1) as cluster:
        with Client(cluster.address, timeout="30s", set_as_default=False) as c:
            info = c.scheduler_info()["workers"]
            pids = c.run(os.getpid)
        gpu = {pids[a] for a, w in info.items() if w["resources"].get("GPU")}
        cpu = {pids[a] for a, w in info.items() if w["resources"].get("CPU")}
        assert len(gpu) == 1 and len(cpu) == 2
        summary = run_sweep(spec, out, PipelineExecutor(cluster.address, max_in_flight=2), progress=False)
        m = read_manifest(out)
        again = run_sweep(spec, out, PipelineExecutor(cluster.address), resume=True, progress=False)
    assert summary.run == 4 and again.run == 0 and again.skipped == 4
    assert (summary.ok, summary.failed) == (local.ok, local.failed) == (2, 2)
    assert m["state"] == "complete" and m["executor"]["kind"] == "dask-pipeline"
    assert m["executor"]["render_workers"] == 1 and m["executor"]["finish_workers"] == 2
    rows, ref = read_results(out).to_pylist(), read_results(tmp_path / "local").to_pylist()
    assert len(rows) == len(ref) == 8
    for r, e in zip(rows, ref):  # the same renders (seeded, bit-identical across processes), the same scores
        assert (r["sample_id"], r["method"], r["status"]) == (e["sample_id"], e["method"], e["status"])
        assert r["depth_rms_mm"] == e["depth_rms_mm"] and r.get("matched_count") == e.get("matched_count")
    for sid in ("0000", "0001", "0002", "0003"):
        res = validate_result(out, sid)  # committed: its files match the checksums it lists
        assert res is not None and res.render_worker["pid"] in gpu and res.worker["pid"] in cpu
    assert not stale_files(out)


@pytest.mark.render
def test_pipeline_refuses_a_cluster_without_render_and_cpu_workers(cluster):
    from platebench.bench.sweep.executors import ExecutorError, PipelineExecutor
    with pytest.raises(ExecutorError, match="GPU=1"):
        PipelineExecutor(cluster.address).connect()
