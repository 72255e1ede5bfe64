"""Sweep throughput benchmark: samples per minute with 1 and 2 local workers, a 2-worker Dask cluster
and the two-stage pipeline (one render worker, CPU workers finishing).

``perf_sweep()`` runs the same bend sweep (render + the paper's pipeline + scoring per sample,
20 samples by default) in one run and prints, for each way:

* end-to-end throughput: samples / wall time of ``run_sweep`` (includes starting the
  worker processes and their first Mitsuba import; a Dask cluster itself is started
  beforehand, as a user's cluster would be);
* steady-state throughput: (n - 1) samples over the time from the first result to the
  last (start-up excluded);
* peak memory of each worker process: ``resource.getrusage(RUSAGE_SELF).ru_maxrss``
  measured inside the worker and returned with each sample's result.

Ratios: 2 local workers / 1 (target >= 1.7 on a 2-core machine), end to end and steady; the
machine's one-minute load average before and after is reported with them, and the machine's own
2-over-1 (``cpu_capacity``: the CPU one and two busy processes of this session obtain), since on
a shared machine the scheduler may give a session one share however many processes it runs
(Linux's per-session autogroups); Dask workers and the pipeline's run in sessions of their own.

A warm-up sample is run first so that no configuration pays for kernel compilation
that the others then reuse from the drjit disk cache. Run ``platebench perf sweep`` or
``python -m platebench.bench.perf.sweep``.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from platebench.tolerances import tol


def _spec(n: int, width: int, height: int, spp: int):
    from platebench.bench.sweep.spec import parse_spec  # noqa: PLC0415
    bends = [round(60.0 * i / max(n - 1, 1), 6) for i in range(n)]
    return parse_spec({"sweep": {"name": "perf"}, "base": {"scene": {"width": width, "height": height},
                                                          "render": {"spp": spp}},
                       "grid": {"bend_deg": bends}})


def _measure(name: str, spec, executor, root: Path, log) -> dict:
    from platebench.bench.sweep.executors import run_sweep  # noqa: PLC0415
    arrivals = []
    t0 = time.perf_counter()
    summary = run_sweep(spec, root / name, executor, progress=False,
                        on_result=lambda r: arrivals.append(time.perf_counter()))
    wall = time.perf_counter() - t0
    n = summary.run
    steady = 60.0 * (n - 1) / (arrivals[-1] - arrivals[0]) if n > 1 and arrivals[-1] > arrivals[0] else float("nan")
    workers = {k: {"samples": v["samples"], "peak_rss_mib": round(v["maxrss_mb"], 1)}
               for k, v in sorted(summary.worker_stats.items())}
    first = arrivals[0] - t0 if arrivals else float("nan")
    row = {"config": name, "samples": n, "ok": summary.ok, "failed": summary.failed, "wall_s": wall,
           "samples_per_min": 60.0 * n / wall, "steady_samples_per_min": steady,
           "first_result_s": first, "workers": workers}
    peaks = ", ".join(f"{v['peak_rss_mib']:.0f} MiB ({v['samples']} samples)" for v in workers.values())
    log(f"{name:14s} {n:3d} samples {wall:7.1f} s  {row['samples_per_min']:6.1f}/min end-to-end  "
        f"{steady:6.1f}/min steady  first result {first:.1f} s  worker peak RSS: {peaks}")
    return row


SCALING_TARGET = 1.7  # 2 local workers / 1 on a 2-core machine


def _spin(seconds: float) -> float:
    """CPU seconds one busy process obtains in ``seconds`` of wall time."""
    t, c = time.perf_counter(), time.process_time()
    while time.perf_counter() - t < seconds:
        pass
    return time.process_time() - c


def cpu_capacity(processes: int, seconds: float = 3.0) -> float:
    """Cores' worth of CPU that ``processes`` busy processes of this session obtain together (the same-run
    baseline of a scaling ratio: on a shared machine the scheduler may give a session one share,
    however many processes it runs)."""
    import multiprocessing  # noqa: PLC0415
    with multiprocessing.get_context("spawn").Pool(processes) as pool:
        return sum(pool.map(_spin, [seconds] * processes)) / seconds


def perf_sweep(n_samples: int = 20, width: int = 320, height: int = 240, spp: int = 8, log=print) -> dict:
    """Throughput (samples/min) and per-worker peak memory of the same sweep run with 1 and 2 local
    workers, on a 2-worker loopback Dask cluster (real ``dask scheduler``/``dask worker``) and as the
    two-stage pipeline (1 render worker + 2 CPU workers); the 2-over-1 ratio."""
    import os  # noqa: PLC0415

    from platebench.bench.sweep.executors import (  # noqa: PLC0415
        DaskExecutor,
        LocalExecutor,
        LoopbackCluster,
        PipelineExecutor,
        run_sweep,
    )
    spec = _spec(n_samples, width, height, spp)
    load0 = os.getloadavg()[0]
    log(f"== perf sweep: {n_samples} samples ({width}x{height}, spp {spp}, bend 0..60 deg, method paper), "
        f"{os.cpu_count()} CPUs")
    out = {"n_samples": n_samples, "width": width, "height": height, "spp": spp, "cpus": os.cpu_count(), "runs": []}
    with tempfile.TemporaryDirectory(prefix="platebench-perf-sweep-") as tmp:
        root = Path(tmp)
        run_sweep(_spec(1, width, height, spp), root / "warmup", LocalExecutor(1), progress=False)
        out["runs"].append(_measure("local x1", spec, LocalExecutor(1), root, log))
        out["runs"].append(_measure("local x2", spec, LocalExecutor(2), root, log))
        t = time.perf_counter()
        with LoopbackCluster(n_workers=2, nthreads=1) as cluster:
            start_s = out["dask_cluster_start_s"] = time.perf_counter() - t
            out["runs"].append(_measure("dask 2 workers", spec, DaskExecutor(cluster.address), root, log))
        with LoopbackCluster(n_workers=3, nthreads=1, render_workers=1) as cluster:
            out["runs"].append(_measure("pipeline 1+2", spec, PipelineExecutor(cluster.address), root, log))
        log(f"(dask cluster start-up, not counted above: {start_s:.1f} s)")
    out["cpu_capacity_cores"] = {"1_process": cpu_capacity(1), "2_processes": cpu_capacity(2)}
    cap = out["cpu_capacity_cores"]["2_processes"] / max(out["cpu_capacity_cores"]["1_process"], tol.tiny)
    out["ratio_capacity_2_over_1"] = cap
    one, two = out["runs"][0], out["runs"][1]
    out["ratio_2_over_1_workers"] = two["samples_per_min"] / one["samples_per_min"]
    out["ratio_2_over_1_workers_steady"] = two["steady_samples_per_min"] / one["steady_samples_per_min"]
    out["ratio_target"] = SCALING_TARGET
    out["load_average_1min_before_after"] = [load0, os.getloadavg()[0]]
    log(f"2 workers / 1 worker: {out['ratio_2_over_1_workers']:.2f} end to end, "
        f"{out['ratio_2_over_1_workers_steady']:.2f} steady (target >= {SCALING_TARGET:g}); load average "
        f"{load0:.1f} before, {os.getloadavg()[0]:.1f} after on {os.cpu_count()} CPUs; busy processes obtained "
        f"{out['cpu_capacity_cores']['1_process']:.2f} cores (1) and {out['cpu_capacity_cores']['2_processes']:.2f} "
        f"(2): the machine's own 2-over-1 is {cap:.2f}" + (" (it gave this run no second core: the scaling target "
                                                            "cannot be judged here)" if cap < 1.5 else ""))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m platebench.bench.perf.sweep", description=__doc__.splitlines()[0])
    p.add_argument("--samples", type=int, default=20)
    p.add_argument("--width", type=int, default=320)
    p.add_argument("--height", type=int, default=240)
    p.add_argument("--spp", type=int, default=8)
    p.add_argument("--json", type=Path, help="also write the figures as JSON here")
    a = p.parse_args(argv)
    res = perf_sweep(a.samples, a.width, a.height, a.spp)
    if a.json:
        from platebench.bench.io.atomic import write_json  # noqa: PLC0415
        write_json(a.json, res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
