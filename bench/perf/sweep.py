"""Sweep throughput benchmark: samples per minute with 1 and 2 local workers and a 2-worker Dask cluster.

``perf_sweep()`` runs the same small bend sweep (render + the paper's pipeline + scoring
per sample) three ways in one run and prints, for each:

* end-to-end throughput: samples / wall time of ``run_sweep`` (includes starting the
  worker processes and their first Mitsuba import; the Dask cluster itself is started
  beforehand, as a user's cluster would be);
* steady-state throughput: (n - 1) samples over the time from the first result to the
  last (start-up excluded);
* peak memory of each worker process: ``resource.getrusage(RUSAGE_SELF).ru_maxrss``
  measured inside the worker and returned with each sample's result.

A warm-up sample is run first so that no configuration pays for kernel compilation
that the others then reuse from the drjit disk cache. Run ``platebench perf sweep`` or
``python -m platebench.bench.perf.sweep``.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path


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
    row = {"config": name, "samples": n, "ok": summary.ok, "failed": summary.failed, "wall_s": wall,
           "samples_per_min": 60.0 * n / wall, "steady_samples_per_min": steady,
           "first_result_s": arrivals[0] - t0 if arrivals else float("nan"), "workers": workers}
    peaks = ", ".join(f"{v['peak_rss_mib']:.0f} MiB ({v['samples']} samples)" for v in workers.values())
    log(f"{name:14s} {n:3d} samples {wall:7.1f} s  {row['samples_per_min']:6.1f}/min end-to-end  "
        f"{steady:6.1f}/min steady  first result {row['first_result_s']:.1f} s  worker peak RSS: {peaks}")
    return row


def perf_sweep(n_samples: int = 8, width: int = 320, height: int = 240, spp: int = 8, log=print) -> dict:
    """Throughput (samples/min) and per-worker peak memory of the same sweep run with 1 and 2 local
    workers and on a 2-worker loopback Dask cluster (real ``dask scheduler``/``dask worker``)."""
    import os  # noqa: PLC0415

    from platebench.bench.sweep.executors import (  # noqa: PLC0415
        DaskExecutor,
        LocalExecutor,
        LoopbackCluster,
        run_sweep,
    )
    spec = _spec(n_samples, width, height, spp)
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
            out["dask_cluster_start_s"] = time.perf_counter() - t
            out["runs"].append(_measure("dask 2 workers", spec, DaskExecutor(cluster.address), root, log))
        log(f"(dask cluster start-up, not counted above: {out['dask_cluster_start_s']:.1f} s)")
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m platebench.bench.perf.sweep", description=__doc__.splitlines()[0])
    p.add_argument("--samples", type=int, default=8)
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
