"""One sweep sample as a task: render, reconstruct with each method, evaluate, record.

``run_sample(task)`` is what every executor runs (local process pool, in-process, or a
Dask worker). It is idempotent: if the sample's ``result.json`` already exists and
validates, it is returned unchanged; otherwise the sample is (re)made from scratch,
every output staged and renamed into place, and ``result.json`` written last. Any
error of the sample (rendering, a method, scoring) is caught and recorded in the
result with status "failed": it never stops the sweep.

Each worker process keeps one ``PlateRenderer`` (module global) and passes it back to
``render_sample`` for its next sample, so compiled kernels are reused. A lock makes
samples of one process run one at a time (run Dask workers with ``--nthreads 1``).

``METHODS`` is the registry of reconstruction methods a sweep may run: "paper" (the
paper's pipeline, scored by ``bench.cmd_evaluate.evaluate``) and, when their modules
import, the peer methods of ``platebench compare`` (dense depth maps: their rows fill
depth_rms_mm / depth_max_mm / depth_median_mm / coverage_frac only). Add one with
``register_method(name, description, run)`` where ``run(ctx: MethodContext) ->
MethodOutput``.
"""
from __future__ import annotations

import inspect
import math
import os
import resource
import socket
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from bench.atomic import staged_directory, write_json
from bench.dataset import (RESULT_FORMAT, VERSION, file_sha256, now_utc, sample_dir, sweep_sample_leftovers,
                           validate_result, write_json_result)


# ----------------------------------------------------------------------------- tasks
@dataclass(frozen=True)
class SampleTask:
    """What a worker needs for one sample (plain data: picklable, no arrays)."""

    dataset: str  # absolute path of the dataset directory (shared with the workers)
    sample_id: str
    index: int
    config: dict  # SampleConfig.to_dict()
    pose: dict | None
    methods: tuple
    config_sha256: str
    params: dict = field(default_factory=dict)
    redo_failed: bool = False  # a valid result.json with status "failed" does not count as done


def tasks_from_spec(spec, dataset: Path, redo_failed: bool = False) -> list[SampleTask]:
    ds = str(Path(dataset).resolve())
    return [SampleTask(ds, p.sample_id, p.index, p.config.to_dict(), p.pose, tuple(spec.methods), p.config_sha256,
                       p.params, redo_failed) for p in spec.samples]


# ----------------------------------------------------------------------------- methods
@dataclass
class MethodContext:
    sample_dir: Path  # the written sample (reconstruction reads only its images and calibration)
    recon_dir: Path  # where the method writes its outputs (staged)
    sample: object  # RenderedSample in memory
    renderer: object  # the worker's PlateRenderer (for methods that render more patterns)
    config: object  # SampleConfig
    pose: dict | None


@dataclass
class MethodOutput:
    metrics: dict  # flat, units in the names (bench.dataset.METRIC_COLUMNS)
    time_recon_s: float
    time_eval_s: float
    time_render_extra_s: float = 0.0  # renders of the method's own pattern sequences


@dataclass(frozen=True)
class Method:
    name: str
    description: str
    run: Callable[[MethodContext], MethodOutput]
    rerenders_from_config: bool = False  # re-creates the scene from sample.json (no pose there)


METHODS: dict[str, Method] = {}


def register_method(name: str, description: str, run: Callable[[MethodContext], MethodOutput],
                    rerenders_from_config: bool = False) -> None:
    METHODS[name] = Method(name, description, run, rerenders_from_config)


def _f(x):
    if x is None:
        return None
    try:
        x = float(x)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def paper_metrics(score: dict) -> dict:
    """Flatten an ``evaluate`` score dict into the results-table metrics (units in the names)."""
    p, m = score.get("points", {}), score.get("matching", {})
    b, s, fb = score.get("boundary_3d", {}), score.get("surface", {}), score.get("false_boundary", {})
    return {"depth_rms_mm": _f(p.get("depth_rms_mm")), "depth_max_mm": _f(p.get("depth_max_mm")),
            "xy_rms_mm": _f(p.get("xy_rms_mm")), "err3d_rms_mm": _f(p.get("err3d_rms_mm")),
            "boundary_mean_mm": _f(b.get("mean_sym_mm")), "boundary_hausdorff_mm": _f(b.get("hausdorff_mm")),
            "surface_rms_mm": _f(s.get("dist_rms_mm")), "coverage_frac": _f(s.get("coverage_frac")),
            "matched_count": m.get("matched_count"), "correct_match_count": m.get("correct_match_count"),
            "expected_count_gt": m.get("expected_count_gt"), "false_boundary_gt": fb.get("ground_truth_any"),
            "false_boundary_detected": fb.get("detected"),
            "paper_bound_met": (score.get("paper_bound") or {}).get("met")}


def _run_paper(ctx: MethodContext) -> MethodOutput:
    from bench.cmd_evaluate import evaluate  # noqa: PLC0415
    from bench.cmd_reconstruct import name_the_file  # noqa: PLC0415
    from bench.recon_io import image_checksums, write_reconstruction  # noqa: PLC0415
    from bench.sample import load_inputs  # noqa: PLC0415
    from reconstruction.pipeline import projector_feature_rays, reconstruct  # noqa: PLC0415
    from reconstruction.plate_region import ReconstructionError  # noqa: PLC0415

    t0 = time.perf_counter()
    inputs = load_inputs(ctx.sample_dir)  # what a user of the dataset gets: images + calibration
    rays = projector_feature_rays(inputs.calibration.projector_camera, inputs.pattern)
    try:
        rec = reconstruct(inputs.images, inputs.calibration.rig, rays, inputs.pattern)
    except ReconstructionError as e:
        raise ReconstructionError(name_the_file(str(e), ctx.sample_dir)) from None
    write_reconstruction(ctx.recon_dir, rec, ctx.sample_dir, image_checksums(inputs.images), overwrite=True)
    t1 = time.perf_counter()
    score = evaluate(ctx.sample_dir, ctx.recon_dir)
    write_json(ctx.recon_dir / "score.json", score)
    return MethodOutput(paper_metrics(score), t1 - t0, time.perf_counter() - t1)


register_method("paper", "the paper's pipeline: projected squares + passive boundary (Chen & Zheng 1995)", _run_paper)


def _peer_runner(name: str):
    def run(ctx: MethodContext) -> MethodOutput:
        import numpy as np  # noqa: PLC0415

        from bench.cmd_compare import compare_sample  # noqa: PLC0415
        from bench.image_io import write_pfm  # noqa: PLC0415
        t0 = time.perf_counter()
        cmp = compare_sample(ctx.sample_dir, (name,), renderer=ctx.renderer)
        row = next(r for r in cmp.rows if r.name == name)
        wall = time.perf_counter() - t0
        s = row.scores
        with staged_directory(ctx.recon_dir, overwrite=True) as d:
            doc = {"method": name, "description": row.description, "n_images": row.n_images, "time_s": row.time_s,
                   "render_s": row.render_s, "notes": list(row.notes) + list(cmp.notes), "scores": s}
            write_json(d / "score.json", _jsonable(doc))
            res = row.result
            if res is not None and getattr(res, "disparity", None) is not None:
                disp = np.asarray(res.disparity, np.float32)
                write_pfm(d / "disparity.pfm", np.where(np.isfinite(disp), disp, np.inf).astype(np.float32))
        cov = _f(s.get("coverage_pct"))
        metrics = {"depth_rms_mm": _f(s.get("depth_rms_mm")), "depth_max_mm": _f(s.get("depth_max_mm")),
                   "depth_median_mm": _f(s.get("depth_median_mm")),
                   "coverage_frac": None if cov is None else cov / 100.0}
        render_s = _f(row.render_s) or 0.0
        recon_s = _f(row.time_s)
        return MethodOutput(metrics, recon_s if recon_s is not None else wall - render_s,
                            max(wall - render_s - (recon_s or 0.0), 0.0), render_s)
    return run


def _jsonable(o):
    if isinstance(o, dict):
        return {str(k): _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if hasattr(o, "item") and callable(o.item):
        try:
            return _jsonable(o.item())
        except (TypeError, ValueError):
            return str(o)
    return o


def _register_peers() -> None:
    """Register the peer methods of ``platebench compare`` when their modules import."""
    try:
        from bench import cmd_compare  # noqa: PLC0415
        import bench.pattern_sequences  # noqa: F401, PLC0415
        import reconstruction.peer_graycode  # noqa: F401, PLC0415
        import reconstruction.peer_phase_shift  # noqa: F401, PLC0415
        import reconstruction.peer_sgbm  # noqa: F401, PLC0415
        names = tuple(getattr(cmd_compare, "ALL_METHODS", ()))
        descriptions = getattr(cmd_compare, "DESCRIPTIONS", {})
        if "renderer" not in inspect.signature(cmd_compare.compare_sample).parameters:
            return
    except Exception:  # noqa: BLE001  (a peer module missing or broken: just "paper")
        return
    for name in names:
        if name != "paper" and name not in METHODS:
            register_method(name, descriptions.get(name, name), _peer_runner(name),
                            rerenders_from_config=name != "sgbm")


_register_peers()


# ----------------------------------------------------------------------------- pose
def pose_supported() -> str:
    """'' if rig poses other than the reference can be rendered here, else the reason."""
    try:
        from bench.sample import render_sample  # noqa: PLC0415
        from scenes import scene_spec  # noqa: PLC0415
    except ImportError as e:
        return str(e)
    if not hasattr(scene_spec, "scene_for_pose"):
        return "scenes.scene_spec.scene_for_pose is missing"
    if "scene" not in inspect.signature(render_sample).parameters:
        return "bench.sample.render_sample takes no scene"
    return ""


def posed_scene(scene, distance_m: float, pose: dict):
    """``scene`` with the rig tilted by ``tilt_deg`` from vertical toward azimuth ``azimuth_deg``
    (from +X around +Z), its mid-baseline point ``distance_m`` from the plate centre, looking at
    it; the baseline stays as close to the reference baseline direction as the tilt allows."""
    import numpy as np  # noqa: PLC0415

    from scenes.scene_spec import scene_for_pose  # noqa: PLC0415
    tilt = math.radians(float(pose.get("tilt_deg", 0.0)))
    az = math.radians(float(pose.get("azimuth_deg", 0.0)))
    center = distance_m * np.array([math.sin(tilt) * math.cos(az), math.sin(tilt) * math.sin(az), math.cos(tilt)])
    baseline_dir = np.asarray(scene.rig.left.R[0], float)  # camera +x (the baseline) in the world frame
    return scene_for_pose(center, np.zeros(3), baseline_dir, scene)


# ----------------------------------------------------------------------------- worker state
_STATE = {"renderer": None, "samples": 0, "parent": None}
_LOCK = threading.Lock()


def set_render_threads(n: int | None) -> bool:
    """Limit the renderer's CPU threads in this process (N workers on C cores: C // N each), through
    ``scenes.runtime.set_thread_count`` when the runtime offers it (bench never imports drjit)."""
    if not n:
        return False
    try:
        from scenes import runtime  # noqa: PLC0415
    except ImportError:
        return False
    fn = getattr(runtime, "set_thread_count", None)
    if fn is None:
        return False
    fn(int(n))
    return True


def worker_init(parent_pid: int | None = None, render_threads: int | None = None) -> None:
    """Initializer of local pool workers: die with the parent (Linux PR_SET_PDEATHSIG), so a sweep
    killed with -9 leaves no worker writing behind it; share the CPU cores between workers."""
    _STATE["parent"] = parent_pid
    _STATE["render_threads"] = render_threads if set_render_threads(render_threads) else None
    if sys.platform.startswith("linux"):
        try:
            import ctypes  # noqa: PLC0415
            import signal  # noqa: PLC0415
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if parent_pid is not None and os.getppid() != parent_pid:
        os._exit(1)  # the parent is already gone


def worker_info() -> dict:
    r = _STATE["renderer"]
    return {"host": socket.gethostname(), "pid": os.getpid(),
            "maxrss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,  # Linux: KiB
            "samples_in_process": _STATE["samples"], "render_threads": _STATE.get("render_threads"),
            "scene_builds": getattr(r, "scene_builds", None)}


def _error_text(e: BaseException) -> str:
    msg = str(e).strip().splitlines()[0] if str(e).strip() else ""
    text = f"{type(e).__name__}: {msg}" if msg else type(e).__name__
    return text[:500]


def failed_result(task: SampleTask, error: str, phase: str = "executor") -> dict:
    """A result for a sample whose task could not run at all (e.g. its worker kept dying)."""
    return {"format": RESULT_FORMAT, "version": VERSION, "sample_id": task.sample_id, "index": task.index,
            "config_sha256": task.config_sha256, "status": "failed", "error": error, "phase": phase,
            "params": task.params, "config": task.config, "pose": task.pose, "methods": list(task.methods),
            "variant": None, "false_boundary_gt": None,
            "rows": [{"method": m, "status": "failed", "error": error, "metrics": {}} for m in task.methods],
            "timings_s": {}, "files": {}, "images": {}, "worker": None, "finished_utc": now_utc()}


def run_sample(task: SampleTask) -> dict:
    """Make one sample (idempotent; see module doc) and return its result dict."""
    with _LOCK:
        return _run_sample(task)


def _run_sample(task: SampleTask) -> dict:
    dataset = Path(task.dataset)
    done = validate_result(dataset, task.sample_id, task.config_sha256)
    if done is not None and (done["status"] == "ok" or not task.redo_failed):
        done["cached"] = True
        return done
    from bench.config import SampleConfig  # noqa: PLC0415
    from bench.sample import render_sample, write_sample  # noqa: PLC0415

    t0 = time.perf_counter()
    sdir = sample_dir(dataset, task.sample_id)
    sdir.mkdir(parents=True, exist_ok=True)
    sweep_sample_leftovers(dataset, task.sample_id)
    res = failed_result(task, None, None)
    res.update(status="ok", error=None, phase=None, rows=[])
    timings = res["timings_s"]
    files = res["files"]
    sample = None
    try:
        cfg = SampleConfig.from_dict(task.config)
        t = time.perf_counter()
        kwargs = {}
        if task.pose:
            kwargs["scene"] = posed_scene(cfg.scene.build(), cfg.scene.distance_m, task.pose)
        renderer = _STATE["renderer"]
        if renderer is not None and cfg.variant and renderer.variant != cfg.variant:
            renderer = None
        try:
            sample, renderer = render_sample(cfg, renderer, **kwargs)
        except BaseException:
            _STATE["renderer"] = None  # its state is unknown now: start afresh next time
            raise
        _STATE["renderer"] = renderer
        timings["render_s"] = time.perf_counter() - t
        t = time.perf_counter()
        write_sample(sdir / "sample", sample, overwrite=True)
        timings["write_s"] = time.perf_counter() - t
        res["variant"] = sample.variant
        res["false_boundary_gt"] = bool(any(v.false_boundary for v in sample.visibility.values()))
        files["sample/sample.json"] = file_sha256(sdir / "sample" / "sample.json")
        import json  # noqa: PLC0415
        res["images"] = json.loads((sdir / "sample" / "sample.json").read_text()).get("images", {})
    except Exception as e:  # noqa: BLE001  (recorded, the sweep goes on)
        err = _error_text(e)
        res.update(status="failed", error=err, phase="render",
                   rows=[{"method": m, "status": "failed", "error": err, "metrics": {}} for m in task.methods])
    if sample is not None:
        for name in task.methods:
            rdir = sdir / "recon" / name
            ctx = MethodContext(sdir / "sample", rdir, sample, _STATE["renderer"], cfg, task.pose)
            try:
                out = METHODS[name].run(ctx)
                row = {"method": name, "status": "ok", "error": None, "metrics": out.metrics,
                       "time_recon_s": out.time_recon_s, "time_eval_s": out.time_eval_s,
                       "time_render_extra_s": out.time_render_extra_s}
                for p in sorted(rdir.rglob("*.json")):
                    files[str(p.relative_to(sdir))] = file_sha256(p)
            except Exception as e:  # noqa: BLE001
                row = {"method": name, "status": "failed", "error": _error_text(e), "metrics": {}}
            res["rows"].append(row)
        failed = [r for r in res["rows"] if r["status"] != "ok"]
        if failed:
            res.update(status="failed", phase="method",
                       error="; ".join(f"{r['method']}: {r['error']}" for r in failed)[:1000])
    del sample
    _STATE["samples"] += 1
    timings["total_s"] = time.perf_counter() - t0
    res["worker"] = worker_info()
    res["finished_utc"] = now_utc()
    write_json_result(dataset, task.sample_id, res)  # last: the sample counts as done from here on
    return res
