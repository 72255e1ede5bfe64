"""Score methods on a built benchmark: methods run by the bench, or folders of another program's outputs.

``score_benchmark(dataset, methods=..., outputs=...)`` checks that ``dataset`` is a whole, verified
build of its split (``bench.benchmark.verify``: a half-built or altered copy is refused), then, per
sample, runs each method (a built-in, a plug-in ``module:function`` or an installed entry point, as
``bench.run.methods.get_method`` resolves it) into a scratch folder, reads what it wrote and scores
it by the protocol (``platebench.evaluation.protocol``); a folder of outputs is read the same way.
Every sample of the split gets one row per method (``bench.benchmark.records.BenchmarkRow``).

A folder of outputs (``--outputs DIR``) holds one folder per sample, named by its id
(``DIR/cyl-0007/``), with exactly one of these files (``OUTPUT_FILES``), in the formats
``platebench evaluate`` reads (``bench.io.method_outputs``):

===========================  ===========================================================
file                         holds
===========================  ===========================================================
``disparity.pfm``            left-view disparity, px, float32; +inf or NaN: no estimate
``disparity.png``            left-view disparity as KITTI writes it: uint16 = 256 d, 0: none
``depth.exr|.pfm|.npy``      left-view z-depth, metres; NaN, inf or <= 0: no estimate
``mesh.ply|.obj|.stl``       a surface in the world frame, metres
``points.ply|.csv|.npy``     points in the world frame, metres
===========================  ===========================================================

A sample without its folder, or with none of these files, is a row of status "missing": no
estimate anywhere (every plate pixel bad, coverage 0), never skipped. Two of them in one folder, an
unreadable file or a method that raises is "failed", with the reason, and counts the same.

The paper's pipeline writes its reconstruction folder (``bench.io.recon_files``): its dense output
is its surface (``surface.ply``, scored as a mesh), and its square centres (``points.ply``) are
sparse points, scored apart (``SparseRow``).
"""
from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from platebench.bench.benchmark.records import BenchmarkRow, SparseRow, bend_bin
from platebench.bench.benchmark.split import Split
from platebench.bench.io.images import DatasetError
from platebench.bench.io.layout import SAMPLE, SAMPLES
from platebench.errors import UserValueError

__all__ = ["OUTPUT_FILES", "ScoreSummary", "find_output", "protocol_truth", "score_sample", "score_benchmark",
           "OutputsFolder"]

# Output file names a folder of outputs may hold (module doc), by kind.
OUTPUT_FILES = {
    "disparity": ("disparity.pfm", "disparity.png"),
    "depth": ("depth.exr", "depth.pfm", "depth.npy"),
    "mesh": ("mesh.ply", "mesh.obj", "mesh.stl"),
    "points": ("points.ply", "points.csv", "points.npy"),
}
KITTI_DISPARITY_SCALE = 256.0  # a 16-bit PNG disparity holds 256 d (KITTI 2015's devkit)
_PAPER_SURFACE = "surface.ply"  # the paper's dense output in its reconstruction folder
_PAPER_CENTRES = "points.ply"  # its square centres (sparse)
_PAPER_MARKER = "recon.json"


class OutputMissing(Exception):
    """A sample has no output (the row's status is "missing")."""


@dataclass(frozen=True)
class OutputsFolder:
    """A folder of another program's outputs, scored under ``name``."""

    name: str
    path: Path


@dataclass(frozen=True)
class _Job:
    sample_id: str
    sample_dir: Path
    methods: tuple[str, ...]
    folders: tuple[OutputsFolder, ...]
    scratch: Path
    time_limit_s: float | None
    split: str
    descriptors: "SampleDescriptors"


@dataclass(frozen=True)
class ScoreSummary:
    """What ``score_benchmark`` made: the rows and sparse rows, in split order, and the wall time (s)."""

    rows: tuple[BenchmarkRow, ...]
    sparse: tuple[SparseRow, ...]
    wall_s: float


def find_output(folder: Path) -> tuple[str, Path]:
    """(kind, file) of the one output in ``folder`` (``OUTPUT_FILES``; a paper reconstruction folder's
    surface). Raises ``OutputMissing`` when there is none, ``DatasetError`` when there are several."""
    folder = Path(folder)
    if not folder.is_dir() or folder.is_symlink():
        raise OutputMissing(f"{folder.name}: no output folder")
    if (folder / _PAPER_MARKER).is_file():
        if (folder / _PAPER_SURFACE).is_file():
            return "mesh", folder / _PAPER_SURFACE
        raise OutputMissing(f"{folder.name}: the reconstruction has no surface")
    found = [(k, folder / n) for k, names in OUTPUT_FILES.items() for n in names if (folder / n).exists()]
    if not found:
        raise OutputMissing(f"{folder.name}: none of {', '.join(n for v in OUTPUT_FILES.values() for n in v)}")
    if len(found) > 1:
        raise DatasetError(f"{folder}: {len(found)} outputs ({', '.join(p.name for _, p in found)}): allowed one")
    return found[0]


def _read(kind: str, path: Path):
    from platebench.bench.io import method_outputs as mo  # noqa: PLC0415
    if path.is_symlink():
        raise DatasetError(f"{path}: a symbolic link: not followed")
    if kind == "disparity":
        return mo.read_disparity(path, KITTI_DISPARITY_SCALE if path.suffix.lower() == ".png" else None)
    if kind == "depth":
        return mo.read_depth(path)
    if kind == "mesh":
        return mo.read_mesh(path)
    return mo.read_points(path)


def _one_line(e: BaseException) -> str:
    text = str(e).strip().splitlines()
    return f"{type(e).__name__}: {text[0] if text else ''}"[:300]


def _row(job: _Job, method: str, status: str, error: str, kind: str, fig, time_s) -> BenchmarkRow:
    d = job.descriptors
    return BenchmarkRow(job.split, job.sample_id, method, status, error, d.family, d.bend_deg,
                        bend_bin(d.bend_deg), d.direction, d.axis_deg, d.distance_m, d.material,
                        d.realism, d.false_boundary_gt, kind, fig.plate_px, fig.estimated_px, fig.coverage_frac,
                        fig.bad_2mm_pct, fig.bad_0_5mm_pct, fig.depth_rms_mm, fig.depth_median_abs_mm,
                        fig.depth_mean_signed_mm, time_s)


def protocol_truth(sample_dir: Path):
    """(the protocol's ``ProtocolTruth`` of a written sample, its plate mesh): the left view's true
    depth, plate mask and world points (``gt/``), the left camera as really posed (``gt/cameras.json``
    where a robot took the pair, else calib.json's) and the told rig's f B and doffs (calib.json)."""
    from platebench.bench.io.sample_files import load_calibration, load_ground_truth, load_true_cameras  # noqa: PLC0415
    from platebench.evaluation.protocol import ProtocolTruth  # noqa: PLC0415
    from platebench.evaluation.stereo_truth import rectified_pair  # noqa: PLC0415
    gt = load_ground_truth(sample_dir)
    told = load_calibration(sample_dir).rig
    posed = load_true_cameras(sample_dir)
    try:
        pair = rectified_pair(told)
        fb, doffs = pair.fb, pair.doffs_px
    except ValueError:
        fb = doffs = None
    truth = ProtocolTruth(np.asarray(gt.depth["left"], np.float64), np.asarray(gt.mask["left"], bool),
                          np.asarray(gt.points["left"], np.float64), posed.left if posed else told.left, fb, doffs)
    return truth, gt.mesh


def _sparse(job: _Job, method: str, points: np.ndarray, truth, mesh) -> SparseRow:
    """Sparse points (the paper's square centres) against the true surface
    (``evaluation.protocol.sparse_figures``)."""
    from platebench.evaluation.protocol import sparse_figures  # noqa: PLC0415
    f = sparse_figures(points, truth, mesh)
    return SparseRow(job.split, job.sample_id, method, "square_centres", f.count, f.distance_rms_mm,
                     f.distance_max_mm, f.depth_rms_mm)


def _score_folder(job: _Job, method: str, folder: Path, truth, mesh, time_s, sparse: list) -> BenchmarkRow:
    from platebench.evaluation.protocol import dense_figures, left_depth, no_estimate  # noqa: PLC0415
    plate_px = int(truth.mask.sum())
    try:
        kind, path = find_output(folder)
    except OutputMissing as e:
        return _row(job, method, "missing", str(e), "", no_estimate(plate_px), time_s)
    except (DatasetError, OSError, ValueError) as e:
        return _row(job, method, "failed", _one_line(e), "", no_estimate(plate_px), time_s)
    try:
        z = left_depth(kind, _read(kind, path), truth)
        fig = dense_figures(z, truth.depth, truth.mask)
    except (DatasetError, OSError, ValueError) as e:
        return _row(job, method, "failed", _one_line(e), kind, no_estimate(plate_px), time_s)
    centres = folder / _PAPER_CENTRES
    if (folder / _PAPER_MARKER).is_file() and centres.is_file():
        try:
            sparse.append(_sparse(job, method, _read("points", centres), truth, mesh))
        except (DatasetError, OSError, ValueError):
            sparse.append(SparseRow(job.split, job.sample_id, method, "square_centres", 0, None, None, None))
    return _row(job, method, "ok", "", kind, fig, time_s)


def score_sample(job: _Job) -> tuple[list[BenchmarkRow], list[SparseRow]]:
    """Run and score every method and folder of ``job`` on its sample (in a worker process)."""
    from platebench.bench.io.layout import method_folder  # noqa: PLC0415
    from platebench.bench.run.methods import MethodContext, get_method  # noqa: PLC0415
    from platebench.evaluation.protocol import no_estimate  # noqa: PLC0415

    truth, mesh = protocol_truth(job.sample_dir)
    rows: list[BenchmarkRow] = []
    sparse: list[SparseRow] = []
    for name in job.methods:
        recon = job.scratch / job.sample_id / method_folder(name)
        t0 = time.perf_counter()
        try:
            method = get_method(name)
            renderer = _renderer(job.sample_dir) if method.rerenders_from_config else None
            method.run(MethodContext(job.sample_dir, recon, renderer, None, job.time_limit_s))
        except Exception as e:  # noqa: BLE001  (a method's failure is its row's, never the run's)
            rows.append(_row(job, name, "failed", _one_line(e), "", no_estimate(int(truth.mask.sum())),
                             time.perf_counter() - t0))
            continue
        rows.append(_score_folder(job, name, recon, truth, mesh, time.perf_counter() - t0, sparse))
        shutil.rmtree(recon, ignore_errors=True)
    for f in job.folders:
        rows.append(_score_folder(job, f.name, f.path / job.sample_id, truth, mesh, None, sparse))
    return rows, sparse


_WORKER: dict = {"renderer": None}  # this worker process's renderer (``_renderer``)


def _renderer(sample_dir: Path):
    """This worker's renderer, made once (from the first sample that needs one) for the methods that
    render their own pattern sequences: they re-aim it at each sample by parameter update
    (``bench.run.compare``), so no scene is built and no kernel compiled again per sample."""
    from platebench.bench.config import SampleConfig  # noqa: PLC0415
    from platebench.bench.io.codecs import decode  # noqa: PLC0415
    from platebench.bench.io.sample_files import read_json  # noqa: PLC0415
    cfg = decode(SampleConfig, read_json(Path(sample_dir) / "sample.json")["config"])
    r = _WORKER["renderer"]
    if r is None or (cfg.variant and r.variant != cfg.variant):
        from platebench.plates import build_plate  # noqa: PLC0415
        from platebench.scenes.render.renderer import PlateRenderer  # noqa: PLC0415
        r = _WORKER["renderer"] = PlateRenderer(cfg.scene.build(), build_plate(cfg.plate), cfg.variant)
    return r


@dataclass(frozen=True)
class SampleDescriptors:
    """What a benchmark row says of its sample: the split's descriptors (family, bend in degrees, bend
    direction, axis in degrees, distance in metres, material, realism) and ground truth's false
    boundary (part of the true boundary hidden from the left or the right camera)."""

    family: str
    bend_deg: float
    direction: str
    axis_deg: float
    distance_m: float
    material: str
    realism: str
    false_boundary_gt: bool


def _descriptors(split: Split, sample_id: str, sample_dir: Path) -> SampleDescriptors:
    from platebench.bench.io.report_records import visibility_records  # noqa: PLC0415
    from platebench.bench.io.sample_files import read_json  # noqa: PLC0415
    s = split.sample(sample_id)
    vis = visibility_records(read_json(sample_dir / "gt" / "visibility.json"))
    fb = any(bool(vis[v].false_boundary) for v in ("left", "right") if v in vis)
    return SampleDescriptors(s.family, s.bend_deg, s.direction, s.axis_deg, s.distance_m, s.material, s.realism, fb)


def score_benchmark(dataset: Path, split: Split, *, methods=(), outputs=(), workers: int = 1,
                    time_limit_s: float | None = None, progress: bool | None = None, say=None) -> ScoreSummary:
    """Score ``methods`` (names) and ``outputs`` (``OutputsFolder``s) on every sample of ``split`` in the
    built ``dataset`` (which the caller has verified). ``workers``: processes (0: this one)."""
    from platebench.bench.progress import bar  # noqa: PLC0415
    from platebench.bench.run.workers import pool_worker_init, stop_pool  # noqa: PLC0415
    say = say or (lambda m: None)
    methods, outputs = tuple(methods), tuple(outputs)
    names = list(methods) + [f.name for f in outputs]
    if not names:
        raise UserValueError("nothing to score: give --methods or --outputs")
    if len(set(names)) != len(names):
        raise UserValueError(f"a method name is given twice ({', '.join(names)}): each row's method must be one")
    dataset = Path(dataset)
    t0 = time.perf_counter()
    scratch = Path(tempfile.mkdtemp(prefix=".platebench-score-", dir=os.environ.get("TMPDIR")))
    jobs = [_Job(s.sample_id, dataset / SAMPLES / s.sample_id / SAMPLE, methods, outputs, scratch, time_limit_s,
                 split.name, _descriptors(split, s.sample_id, dataset / SAMPLES / s.sample_id / SAMPLE))
            for s in split.samples]
    results: dict[str, tuple] = {}
    pbar = bar(len(jobs), "benchmark score", "sample", progress)
    try:
        if workers == 0:
            for j in jobs:
                results[j.sample_id] = score_sample(j)
                pbar.update(1)
        else:
            ctx = multiprocessing.get_context("spawn")
            threads = max(1, (os.cpu_count() or 1) // max(1, workers))
            pool = cf.ProcessPoolExecutor(workers, mp_context=ctx, initializer=pool_worker_init,
                                          initargs=(os.getpid(), threads))
            try:
                futs = {pool.submit(score_sample, j): j for j in jobs}
                for fut in cf.as_completed(futs):
                    results[futs[fut].sample_id] = fut.result()
                    pbar.update(1)
            except BaseException:
                stop_pool(pool)
                raise
            pool.shutdown(wait=True)
    finally:
        pbar.close()
        shutil.rmtree(scratch, ignore_errors=True)
    rows, sparse = [], []
    for j in jobs:
        r, s = results[j.sample_id]
        rows.extend(r)
        sparse.extend(s)
    say(f"scored {len(jobs)} samples x {len(names)} method(s)")
    return ScoreSummary(tuple(rows), tuple(sparse), time.perf_counter() - t0)
