"""Benchmark ``gpu``: the throughput figures of a GPU machine, each beside its baseline, in one run.

On a machine with a CUDA device (``cuda_ad_rgb``) the run measures, at the reference experiment
(1280 x 960, spp 16 unless told otherwise), with the machine's CPU (``llvm_ad_rgb``) as the
baseline where the figure has one:

1. **Host pixels** (``subnormal``): one render of each variant copied to the host the plain way
   (the RGB tensor, then numpy's channel mean): its subnormal floats counted per channel, and
   numpy's ``mean(axis=2)`` timed on it, on a copy with the subnormals flushed to zero and on
   random values of the same shape; the sensor's digitisation and an EXR write timed on its
   channel mean with and without them; the bench's device-side mean (``scenes.render.film``)
   timed beside them. This verifies (or refutes) subnormal floats as the cause of a slow host
   channel mean, and shows what the bench's images cost on the host.
2. **Whole sample** (``sample``): raw ``mitsuba.render`` of the 4 images with their pixels read on
   the host (the baseline) against a whole sample (the 4 images and all ground truth,
   ``render_sample``), best of ``repeat``, wall-clock and CPU seconds; kernel compiles of a second
   sample (another bend and distance). Target on a GPU: whole sample <= 0.15 s.
3. **Variants** (``variants``): ``platebench perf variants`` on the same machine: cuda against
   llvm, the same pixels (share within 1e-5, against seed noise), whole-sample times, the
   paper's pipeline scored on each.
4. **Sweep** (``sweep``): the paper's method on bends 0-170 degrees up and down at this size: the
   two-stage pipeline (one render worker owning the renderer, ``workers`` CPU workers;
   ``sweep --pipeline``) in samples per second, against one local worker making whole samples.
   Target on a GPU: >= 10 samples/s.
5. **Study** (``study``, with ``full``): ``platebench study false-boundary`` (61 plates, 640 x
   480, spp 2) with ``workers`` workers: wall time and its outcome counts. Target on a GPU:
   <= 60 s.

Without a CUDA device the same run reports the llvm figures and says that no GPU is present
(the GPU rows stay open).
"""
from __future__ import annotations

import os
import platform
import tempfile
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from platebench.bench.config import SampleConfig
from platebench.bench.io.perf_records import GpuTargetFigures
from platebench.bench.io.report_records import RunTimings
from platebench.scenes.scene_spec import RenderSettings

__all__ = ["perf_gpu", "TARGETS_GPU"]



@dataclass(frozen=True)
class GpuTargets:
    """The targets of a GPU machine (module doc): a whole sample in at most ``whole_sample_s`` seconds,
    the sweep pipeline at ``sweep_samples_per_s`` samples per second or more, the 61-plate study in
    at most ``study_s`` seconds."""

    whole_sample_s: float = 0.15
    sweep_samples_per_s: float = 10.0
    study_s: float = 60.0

    def met(self, seen: GpuTargetFigures, full: bool) -> dict:
        """Target -> met, for the figures ``seen`` (a figure not measured misses its target; the study's
        target is None without ``full``)."""
        return {"whole_sample_s": _or(seen.whole_sample_s, np.inf) <= self.whole_sample_s,
                "sweep_samples_per_s": _or(seen.sweep_samples_per_s, 0.0) >= self.sweep_samples_per_s,
                "study_s": _or(seen.study_s, np.inf) <= self.study_s if full else None}


def _or(v, default):
    return default if v is None else v


@dataclass(frozen=True)
class HostPixelTimes:
    """Best seconds over the repeats of each host-side operation on one render (module doc, 1): the
    channel mean of the render, of its flushed copy and of random values; the slice sum; the
    digitisation and the EXR write of the channel mean with and without subnormals; the bench's
    device mean and copy."""

    mean_axis2_render_s: float
    mean_axis2_flushed_s: float
    mean_axis2_random_s: float
    slice_sum_render_s: float
    digitize_render_s: float
    digitize_flushed_s: float
    write_exr_render_s: float
    write_exr_flushed_s: float
    device_mean_to_host_s: float


TARGETS_GPU = GpuTargets()
STUDY_TIMEOUT_S = 300.0  # perf gpu --full: the study is stopped after five times its 60-s target
CPU_VARIANT, GPU_VARIANT = "llvm_ad_rgb", "cuda_ad_rgb"


def _best(fn, repeat: int) -> tuple[float, float]:
    """(best wall s, best CPU s) of ``repeat`` calls."""
    wall = cpu = np.inf
    for _ in range(repeat):
        c, t = time.process_time(), time.perf_counter()
        fn()
        wall, cpu = min(wall, time.perf_counter() - t), min(cpu, time.process_time() - c)
    return wall, cpu


def machine() -> dict:
    """The machine: CPU model, cores, load, GPU (``nvidia-smi`` when present)."""
    import shutil  # noqa: PLC0415
    import subprocess  # noqa: PLC0415
    model = platform.processor()
    try:
        model = next(ln.split(":", 1)[1].strip() for ln in Path("/proc/cpuinfo").read_text().splitlines()
                     if ln.startswith("model name"))
    except (OSError, StopIteration):
        pass
    gpu = None
    if shutil.which("nvidia-smi"):
        p = subprocess.run(["nvidia-smi", "--query-gpu=name,memory.total,driver_version", "--format=csv,noheader"],
                           capture_output=True, text=True, timeout=30)
        gpu = p.stdout.strip() or None
    return {"cpu": model, "cpus": os.cpu_count(), "load_average_1min": os.getloadavg()[0], "gpu": gpu,
            "python": platform.python_version()}


def available_variants() -> list[str]:
    """The variants this machine can render: cuda first where there is a CUDA device."""
    from platebench.scenes.render import runtime  # noqa: PLC0415
    return ([GPU_VARIANT] if runtime.has_cuda() else []) + [CPU_VARIANT]


def subnormal_check(cfg: SampleConfig, repeat: int = 3, log=print) -> dict:
    """Host pixels and subnormal floats (module doc) of a render of ``cfg.variant``."""
    from platebench.bench.run.render import render_sample  # noqa: PLC0415
    from platebench.scenes.naming import image_seed  # noqa: PLC0415
    from platebench.scenes.render.film import FLOAT32_TINY, count_subnormal, grey_to_host  # noqa: PLC0415
    from platebench.bench.io.images import write_exr  # noqa: PLC0415
    _, r = render_sample(cfg)
    mi = r.mi
    out = {"variant": r.variant}
    exr = Path(tempfile.mkdtemp(prefix="platebench-perf-exr-")) / "grey.exr"
    for light in ("passive", "active"):
        r.set_lighting(light)
        img = mi.render(r.scene, sensor=0, spp=cfg.render.spp, seed=image_seed(cfg.render.seed, "left", light))
        a = np.array(img, dtype=np.float32)  # the RGB tensor on the host, the plain way
        flushed = a.copy()
        flushed[np.abs(flushed) < FLOAT32_TINY] = 0.0
        rand = np.random.default_rng(0).random(a.shape, dtype=np.float32)
        grey, grey_flushed = a.mean(axis=2), flushed.mean(axis=2)
        t = HostPixelTimes(_best(lambda: a.mean(axis=2), repeat)[0],  # noqa: B023
                           _best(lambda: flushed.mean(axis=2), repeat)[0],  # noqa: B023
                           _best(lambda: rand.mean(axis=2), repeat)[0],  # noqa: B023
                           _best(lambda: a[..., 0] + a[..., 1] + a[..., 2], repeat)[0],  # noqa: B023
                           _best(lambda: cfg.sensor.digitize(grey, seed=1), repeat)[0],  # noqa: B023
                           _best(lambda: cfg.sensor.digitize(grey_flushed, seed=1), repeat)[0],  # noqa: B023
                           _best(lambda: write_exr(exr, grey), repeat)[0],  # noqa: B023
                           _best(lambda: write_exr(exr, grey_flushed), repeat)[0],  # noqa: B023
                           _best(lambda: grey_to_host(mi, img), repeat)[0])  # noqa: B023
        sub = [count_subnormal(a[..., c]) for c in range(3)]
        out[light] = {"subnormal_per_channel": sub, "subnormal_in_channel_mean": count_subnormal(grey),
                      "pixels": int(a.shape[0] * a.shape[1]), "nan": int(np.isnan(a).sum()),
                      "c_contiguous": bool(a.flags["C_CONTIGUOUS"]), **asdict(t)}
        log(f"{r.variant:12s} {light:7s}: subnormal floats per channel {sub} of {a.shape[0] * a.shape[1]} px; "
            f"host mean(axis=2) {t.mean_axis2_render_s * 1e3:.1f} ms (flushed copy "
            f"{t.mean_axis2_flushed_s * 1e3:.1f}, random {t.mean_axis2_random_s * 1e3:.1f}); digitize "
            f"{t.digitize_render_s * 1e3:.1f} ms (flushed {t.digitize_flushed_s * 1e3:.1f}); EXR write "
            f"{t.write_exr_render_s * 1e3:.1f} ms (flushed {t.write_exr_flushed_s * 1e3:.1f}); the bench's "
            f"device mean + copy {t.device_mean_to_host_s * 1e3:.1f} ms")
    import shutil  # noqa: PLC0415
    shutil.rmtree(exr.parent, ignore_errors=True)
    return out


def sample_figures(cfg: SampleConfig, repeat: int = 3, log=print) -> dict:
    """Whole sample against raw renders (module doc) in ``cfg.variant``."""
    from platebench.bench.perf.benchmarks import _raw_renders  # noqa: PLC0415
    from platebench.bench.run.render import render_sample  # noqa: PLC0415
    from platebench.plates import CylindricalBend  # noqa: PLC0415
    from platebench.scenes.render.runtime import KernelCounter  # noqa: PLC0415
    _, r = render_sample(cfg)  # warm-up: kernels compiled or loaded
    raw = whole = (np.inf, np.inf)
    gt = np.inf
    for _ in range(repeat):  # alternately: a busy machine slows both alike
        raw = np.minimum(raw, _best(_raw_renders(r, cfg), 1))
        c, t = time.process_time(), time.perf_counter()
        s, _ = render_sample(cfg, r)
        whole = np.minimum(whole, (time.perf_counter() - t, time.process_time() - c))
        gt = min(gt, RunTimings.from_dict(s.timings_s).ground_truth_s)
    other = replace(cfg, plate=replace(cfg.plate, deformation=CylindricalBend(np.radians(40.0), "up")),
                    scene=replace(cfg.scene, distance_m=cfg.scene.distance_m * 1.25))
    with KernelCounter() as kc:
        render_sample(other, r)
    out = {"variant": r.variant, "raw_4_images_s": float(raw[0]), "raw_4_images_cpu_s": float(raw[1]),
           "whole_sample_s": float(whole[0]), "whole_sample_cpu_s": float(whole[1]), "ground_truth_s": float(gt),
           "ratio_whole_over_raw": float(whole[0] / raw[0]), "ratio_whole_over_raw_cpu": float(whole[1] / raw[1]),
           "second_sample_kernel_compiles": kc.compiled}
    log(f"{r.variant:12s} raw mitsuba.render, 4 images {raw[0]:7.3f} s (CPU {raw[1]:.2f} s); whole sample "
        f"{whole[0]:7.3f} s (CPU {whole[1]:.2f} s), ratio {out['ratio_whole_over_raw']:.2f} (CPU "
        f"{out['ratio_whole_over_raw_cpu']:.2f}); ground truth {gt:.3f} s; second sample: {kc.compiled} compiles")
    return out


def _sweep_spec(n: int, width: int, height: int, spp: int):
    from platebench.bench.sweep.spec import parse_spec  # noqa: PLC0415
    k = max(1, (n + 1) // 2)
    bends = [round(170.0 * i / max(k - 1, 1), 6) for i in range(k)]
    return parse_spec({"sweep": {"name": "perf-gpu", "methods": ["paper"]},
                       "base": {"scene": {"width": width, "height": height}, "render": {"spp": spp}},
                       "grid": {"bend_deg": bends, "direction": ["up", "down"]}})


def sweep_figures(width: int, height: int, spp: int, samples: int, workers: int, baseline_samples: int,
                  log=print) -> dict:
    """The sweep pipeline against one local worker (module doc)."""
    from platebench.bench.sweep.executors import LocalExecutor, LoopbackCluster, PipelineExecutor, run_sweep  # noqa: PLC0415
    out = {"workers": workers}
    rates = {}  # "pipeline", "one_worker" -> samples per second
    with tempfile.TemporaryDirectory(prefix="platebench-perf-gpu-") as tmp:
        root = Path(tmp)
        run_sweep(_sweep_spec(1, width, height, spp), root / "warm", LocalExecutor(1), progress=False)
        for name, n, make in (("one worker, whole samples", baseline_samples, lambda: LocalExecutor(1)),
                              (f"pipeline, 1 render + {workers} CPU workers", samples, None)):
            spec = _sweep_spec(n, width, height, spp)
            arrivals = []
            if make is None:
                with LoopbackCluster(n_workers=workers + 1, render_workers=1) as cluster:
                    ex = PipelineExecutor(cluster.address)
                    ex.connect()
                    run_sweep(_sweep_spec(2, width, height, spp), root / "warm2", ex, progress=False)
                    t0 = time.perf_counter()
                    s = run_sweep(spec, root / "pipe", PipelineExecutor(cluster.address), progress=False,
                                  on_result=lambda r: arrivals.append(time.perf_counter()))  # noqa: B023
            else:
                t0 = time.perf_counter()
                s = run_sweep(spec, root / "one", make(), progress=False,
                              on_result=lambda r: arrivals.append(time.perf_counter()))  # noqa: B023
            wall = time.perf_counter() - t0
            steady = (len(arrivals) - 1) / (arrivals[-1] - arrivals[0]) if len(arrivals) > 1 else float("nan")
            key = "pipeline" if make is None else "one_worker"
            rates[key] = s.run / wall
            out[key] = {"samples": s.run, "ok": s.ok, "failed": s.failed, "wall_s": wall,
                        "samples_per_s": rates[key], "steady_samples_per_s": steady,
                        "peak_rss_mib": {k: round(v["maxrss_mb"], 1) for k, v in s.worker_stats.items()}}
            log(f"sweep {name}: {s.run} samples ({s.ok} ok) in {wall:.1f} s = {s.run / wall:.2f} samples/s "
                f"(steady {steady:.2f}/s)")
    out["ratio_pipeline_over_one_worker"] = rates["pipeline"] / rates["one_worker"]
    return out


def study_figures(workers: int, log=print) -> dict:
    """``platebench study false-boundary`` with ``workers`` workers: its time and outcomes (module doc)."""
    import json  # noqa: PLC0415
    import subprocess  # noqa: PLC0415
    import sys  # noqa: PLC0415
    with tempfile.TemporaryDirectory(prefix="platebench-perf-study-") as tmp:
        out_dir = Path(tmp) / "study"
        t0 = time.perf_counter()  # the command as a user runs it, start-up included
        try:
            rc = subprocess.run([sys.executable, "-m", "platebench", "study", "false-boundary", "--out", str(out_dir),
                                 "--workers", str(workers)], stdout=subprocess.DEVNULL,
                                timeout=STUDY_TIMEOUT_S).returncode
        except subprocess.TimeoutExpired:  # a stalled plate: the section says so and the run goes on
            raise TimeoutError(f"the study did not end within {STUDY_TIMEOUT_S:g} s (its workers stopped with it)") \
                from None
        wall = time.perf_counter() - t0
        doc = json.loads((out_dir / "study.json").read_text()) if rc == 0 else {}
    rows = doc.get("rows", [])
    outcomes: dict = {}
    for row in rows:
        outcomes[row.get("outcome")] = outcomes.get(row.get("outcome"), 0) + 1
    out = {"workers": workers, "plates": len(rows), "wall_s": wall, "exit_status": rc, "outcomes": outcomes,
           "targets": doc.get("targets"),
           # each plate's outcome, to compare with a CPU run of the same study (same seed) plate by plate
           "plate_outcomes": {row.get("case"): row.get("outcome") for row in rows}}
    log(f"study false-boundary: {len(rows)} plates, {workers} workers, {wall:.0f} s; outcomes {outcomes}")
    return out


def perf_gpu(width: int = 1280, height: int = 960, spp: int = 16, repeat: int = 3, full: bool = False,
             workers: int | None = None, sweep_samples: int | None = None, log=print, on_section=None) -> dict:
    """Every figure of the module doc in one run (``full``: with the 61-plate study and a longer sweep).
    A section that fails is recorded (``errors``) and the run goes on; ``on_section(figures)`` is
    called after each section (the CLI writes the JSON there, so a run cut short keeps what it measured)."""
    workers = workers or max(1, (os.cpu_count() or 2) - 1)
    variants = available_variants()
    gpu = GPU_VARIANT in variants
    info = machine()
    log(f"machine: {info['cpu']}, {info['cpus']} CPUs, load {info['load_average_1min']:.1f}; GPU: "
        f"{info['gpu'] or 'none'}; variants {', '.join(variants)}")
    if not gpu:
        log("no GPU present: the llvm figures below are this machine's CPU; the GPU rows are not measured here "
            "(run `platebench perf gpu --full` on a machine with a CUDA device)")
    out = {"machine": info, "gpu_present": gpu, "variants": variants, "image_size_px": [width, height], "spp": spp,
           "targets_gpu": asdict(TARGETS_GPU), "errors": {}}
    base = SampleConfig(render=RenderSettings(spp=spp))
    base = replace(base, scene=replace(base.scene, width=width, height=height))
    n = sweep_samples or (90 if full else 18)

    def variants_compared():
        from platebench.bench.perf.variants import perf_variants  # noqa: PLC0415
        return perf_variants(variants, width, height, spp, max(1, repeat - 1), log=log)

    sections = [("subnormal", "host pixels: subnormal floats",
                 lambda: {v: subnormal_check(replace(base, variant=v), repeat, log) for v in variants}),
                ("sample", "whole sample vs raw renders",
                 lambda: {v: sample_figures(replace(base, variant=v), repeat, log) for v in variants}),
                ("variants_compared", "variants: same pixels?", variants_compared),
                ("sweep", "sweep", lambda: sweep_figures(width, height, spp, n, workers, 18 if full else min(n, 6), log))]
    if full:
        sections.append(("study", "study", lambda: study_figures(workers + 1, log)))
    for key, title, fn in sections:
        log(f"== {title}")
        t0 = time.perf_counter()
        try:
            out[key] = fn()
        except Exception as e:  # noqa: BLE001  (one section's failure is a figure too; the others still run)
            out["errors"][key] = f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"[:500]
            log(f"{title}: FAILED ({out['errors'][key]})")
        out.setdefault("section_s", {})[key] = time.perf_counter() - t0
        if on_section is not None:
            on_section(out)
    if not full:
        log("study false-boundary: not run (--full runs the 61 plates)")
    if gpu:
        out["targets_met"] = TARGETS_GPU.met(GpuTargetFigures.from_dict(out, GPU_VARIANT), full)
        log(f"GPU targets: {out['targets_met']}")
    return out
