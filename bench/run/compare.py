"""Peer methods side by side on one written sample (``platebench compare``).

Re-creates the sample's plate and scene from ``SAMPLE_DIR/sample.json`` (its calibration
must agree with ``calib.json``), renders the projector sequences the chosen methods need
with one renderer (``bench.run.pattern_sequences``), runs each method
(``reconstruction.peers``: pure functions of images and calibration) and scores it against
the sample's ground truth with ``evaluation.dense``:

* depth: |Z_est - Z_gt| (left camera z-depth, mm) over plate pixels with an estimate:
  mean, median, RMS, max, A50-A99, signed mean; ``coverage_frac`` = those pixels / plate pixels
  (gt mask; ``evaluation.pixel_coverage``); estimates off the plate are counted separately (the
  disparity metrics ignore them);
* disparity: Middlebury v3 and ETH3D two-view metrics on all and on non-occluded pixels
  (``evaluation.field_scores.score_disparity``).

Plug-in methods (``bench.run.plugins``: an installed entry point of ``platebench.methods`` or
``module:function``) run on the sample's images and calibration, in a process of their own with a
time limit, and are scored by the kind of output they return (disparity, depth, points or mesh). A
plug-in that fails (raises, exits, runs past the limit, returns what is not an output) gets a row
with ``status`` "failed" and its one-line ``error``, as in a sweep; the other methods go on.

The "paper" row is read, not computed: a directory holding ``points.csv`` (world x, y, z in
metres) and optionally ``recon.json`` and ``surface.ply`` from ``platebench reconstruct``; its
points are scored by depth error at their left-image projection and by distance to the true plate
surface, and its ``coverage_frac`` is the share of the left plate pixels whose true ray hits
``surface.ply`` (0 without a surface). Without points.csv the row is left out, with a note.

The stereo matchers that take a pair rather than a pattern sequence of their own ("sgbm") match
the active pair (``left_active``/``right_active``: the projected grid gives them texture inside
the plate) by default; "sgbm-passive" matches the passive pair.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from platebench.bench.config import SampleConfig
from platebench.bench.io.field_truth import load_field_truth
from platebench.bench.io.images import DatasetError
from platebench.bench.io.points import read_points_csv
from platebench.bench.io.records import MethodFigures
from platebench.bench.io.sample_files import load_ground_truth, load_inputs, load_true_cameras, read_mesh
from platebench.bench.run.pattern_sequences import render_pattern_sequence
from platebench.bench.run.plugins import describe, jsonable, plugin_names, resolve_plugin, run_plugin
from platebench.errors import UserValueError
from platebench.evaluation.dense import SparseDepthScore, score_points_depth
from platebench.evaluation.field_scores import DepthScore, DisparityScore, MeshScore, PointCloudScore, score_disparity
from platebench.evaluation.pixel_coverage import coverage_of_mesh
from platebench.plates import build_plate
from platebench.reconstruction.peers import graycode, phase_shift, sgbm
from platebench.scenes.naming import image_seed
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.scene_spec import RenderSettings
from platebench.tolerances import tol

__all__ = ["METHODS", "ALL_METHODS", "DESCRIPTIONS", "PAIR_IMAGES", "MethodRow", "Comparison", "compare_sample",
           "find_paper_reconstruction", "comparison_json"]


METHODS = ("paper", "graycode", "graycode-subpx", "phase", "sgbm")


DESCRIPTIONS = {
    "paper": "paper's projected squares (read from platebench reconstruct output)",
    "graycode": "Gray code, OpenCV GrayCodePattern.decode",
    "graycode-subpx": "Gray code, sub-pixel column matching along rows (numpy)",
    "phase": "4-step phase shifting + Gray-code unwrapping (numpy)",
    "phase-opencv": "3-step phase shifting, OpenCV SinusoidalPattern wrapped phase + Gray-code unwrapping",
    "sgbm": "OpenCV StereoSGBM on the active pair (the projected grid; sgbm-passive: the passive pair)",
    "sgbm-passive": "OpenCV StereoSGBM on the passive pair (nothing to match inside a plain plate)",
}


ALL_METHODS = METHODS + ("phase-opencv", "sgbm-passive")
# the built-in stereo matchers of one pair: (left image, right image) of the sample they match
PAIR_IMAGES = {"sgbm": ("left_active", "right_active"), "sgbm-passive": ("left_passive", "right_passive")}


def find_paper_reconstruction(sample_dir: Path, recon_dir: Path | None):
    """(points (N,3), recon.json dict, directory) of a ``platebench reconstruct`` output, or None."""
    cands = [Path(recon_dir)] if recon_dir is not None else [Path(sample_dir).resolve().parent,
                                                              Path(sample_dir) / "recon"]
    for d in cands:
        pts_path = d / "points.csv"
        if pts_path.is_file():
            meta = {}
            if (d / "recon.json").is_file():
                try:
                    meta = json.loads((d / "recon.json").read_text())
                except json.JSONDecodeError as e:
                    raise DatasetError(f"{d / 'recon.json'}: invalid JSON ({e.msg})") from None
            return read_points_csv(pts_path), meta, d
    return None


@dataclass(frozen=True)
class MethodRow:
    """One method on the sample: ``score`` is the typed score of its kind (``evaluation.field_scores``;
    ``evaluation.dense.SparseDepthScore`` for the paper row, scored from its points.csv; None for a
    method that failed), ``figures`` its key figures (``MethodFigures``)."""

    name: str
    description: str
    n_images: int
    time_s: float
    render_s: float
    score: object = None
    notes: tuple = ()
    result: object = None  # a dense result (.depth, .valid, left view) for the error figure; None otherwise
    kind: str | None = "disparity"  # None for a method that failed
    status: str = "ok"  # "ok" or "failed"
    error: str | None = None  # a failed method's one-line error

    @property
    def figures(self) -> MethodFigures:
        return method_figures(self)


def method_figures(row: MethodRow) -> MethodFigures:
    """The key figures of a row's typed score, by its kind (``MethodFigures``)."""
    mm = 1e3
    times = {"n_images": row.n_images, "time_s": row.time_s, "render_s": row.render_s}
    s = row.score
    if s is None:
        return MethodFigures(**times)
    if isinstance(s, SparseDepthScore):
        return MethodFigures("centres", **times, centres_depth_median_mm=s.centres_depth_median_mm,
                             centres_depth_rms_mm=s.centres_depth_rms_mm, centres_depth_max_mm=s.centres_depth_max_mm,
                             points_on_plate=s.points_on_plate, surface_rms_mm=s.surface_rms_mm,
                             coverage_frac=s.coverage_frac)
    if isinstance(s, (DisparityScore, DepthScore)):
        d = s.depth if isinstance(s, DisparityScore) else s
        bad = dict(s.middlebury.all.bad_pct).get(1.0) if isinstance(s, DisparityScore) else None
        return MethodFigures(row.kind, **times, depth_median_mm=d.errors.median_m * mm, depth_rms_mm=d.errors.rms_m * mm,
                             depth_max_mm=d.errors.max_m * mm, coverage_frac=d.coverage_frac, mb_all_bad_1_0_pct=bad)
    if isinstance(s, PointCloudScore):
        return MethodFigures("cloud", **times, dist_median_mm=s.distance.median_m * mm,
                             dist_rms_mm=s.distance.rms_m * mm, surface_rms_mm=s.distance.rms_m * mm,
                             coverage_frac=s.coverage.coverage_frac)
    if isinstance(s, MeshScore):
        return MethodFigures("mesh", **times, accuracy_median_mm=s.accuracy.median_m * mm,
                             accuracy_rms_mm=s.accuracy.rms_m * mm, surface_rms_mm=s.accuracy.rms_m * mm,
                             coverage_frac=s.coverage_frac)
    raise TypeError(f"{row.name}: no figures for a score of type {type(s).__name__}")


@dataclass(frozen=True)
class DenseView:
    """A plug-in's dense output as the error figure reads it: (H, W) depth (metres) and validity."""

    depth: np.ndarray
    valid: np.ndarray


@dataclass
class Comparison:
    sample_dir: Path
    rows: list
    notes: list
    scene_reproduced: bool | None
    gt_depth: np.ndarray
    gt_mask: np.ndarray


def _check_calibration(told, calib) -> None:
    """Refuse a sample whose re-created told rig (``told``, a ``StereoRig``) is not its calib.json's."""
    for name in ("left", "right"):
        a, b = getattr(told, name), getattr(calib.rig, name)
        if not (np.allclose(a.K, b.K, atol=tol.rebuilt_px) and np.allclose(a.R, b.R, atol=tol.rebuilt_pose)
                and np.allclose(a.t, b.t, atol=tol.rebuilt_pose) and (a.width, a.height) == (b.width, b.height)):
            raise DatasetError(f"sample.json's configuration does not reproduce calib.json ({name} camera); "
                               "the sample cannot be re-rendered for the peer methods")


def _resolve_plugins(methods) -> dict:
    """{name: plug-in function} of the methods that are not built in; UserValueError for an unknown one."""
    plugins = {m: resolve_plugin(m) for m in methods if m not in ALL_METHODS}
    unknown = [m for m, fn in plugins.items() if fn is None]
    if unknown:
        raise UserValueError(f"unknown method {unknown[0]!r}: choose from {', '.join(ALL_METHODS)}, an installed "
                             f"plug-in ({', '.join(plugin_names()) or 'none installed'}) or module:function")
    return plugins


def _recreate_scene(cfg: SampleConfig, inputs, gt, renderer):
    """(renderer on the sample's re-created scene, whether it reproduces the sample's left_passive bytes:
    same variant and seed should)."""
    plate = build_plate(cfg.plate)
    spec = cfg.scene.build()
    told = spec.rig
    if not cfg.realism.is_ideal:  # the rig as the sample took it: the same draw of its errors (bench.run.render)
        from platebench.bench.run.realism import realise_sample  # noqa: PLC0415
        acq = realise_sample(cfg, spec.rig)
        spec, told = spec.with_rig(acq.taken), acq.told
    _check_calibration(told, inputs.calibration)
    if renderer is None:
        renderer = PlateRenderer(spec, plate, cfg.variant)
    else:
        renderer.set_scene(spec)
        renderer.set_plate(plate)
    img = cfg.sensor.digitize(renderer.render("left", "passive", cfg.render),
                              seed=image_seed(cfg.render.seed, "left", "passive"))
    want = gt.meta.get("images", {}).get("left_passive")
    return renderer, want is None or hashlib.sha256(img.tobytes()).hexdigest() == want


def _plugin_row(name: str, fn, sample_dir: Path, truth, time_limit_s: float | None = None) -> MethodRow:
    """Run a plug-in on the sample's inputs and score its output for its kind; a row with status "failed"
    and the one-line error when it fails (``bench.run.plugins``: whatever the plug-in does is its failure)."""
    try:
        run = run_plugin(fn, name, sample_dir, truth=truth, time_limit_s=time_limit_s)
    except Exception as e:  # noqa: BLE001  (recorded, as a sweep records it; interrupts go on up)
        msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        return MethodRow(name, describe(fn), 0, float("nan"), 0.0, kind=None, status="failed",
                         error=f"{type(e).__name__}: {msg}"[:500])
    view = None
    if run.output.kind in ("disparity", "depth"):
        z = _implied_depth(run.output, truth)
        view = DenseView(z, np.isfinite(z))
    n_images = run.output.metrics.get("n_images", 2)
    n_images = int(n_images) if isinstance(n_images, (int, float)) and np.isfinite(n_images) else 2
    return MethodRow(name, describe(fn), n_images, run.time_recon_s, 0.0, run.score, (), view, run.output.kind)


def _paper_row(sample_dir: Path, recon_dir, rig, gt, notes: list) -> MethodRow | None:
    """The paper's row from a ``platebench reconstruct`` output beside the sample (None, with a note,
    when there is none); its coverage from ``surface.ply`` through the left camera really posed."""
    found = find_paper_reconstruction(sample_dir, recon_dir)
    if found is None:
        where = recon_dir if recon_dir is not None else f"{sample_dir.resolve().parent} or {sample_dir / 'recon'}"
        notes.append(f"paper row left out: no points.csv from 'platebench reconstruct' in {where} "
                     "(pass --recon DIR)")
        return None
    pts, meta, d = found
    sc = score_points_depth(pts, rig.left, gt.depth["left"], gt.mesh)
    surface = read_mesh(d / "surface.ply") if (d / "surface.ply").is_file() else None
    posed = load_true_cameras(sample_dir)
    eye = (rig if posed is None else posed).left.center
    sc = dataclasses.replace(sc, coverage=coverage_of_mesh(surface, eye, gt.points["left"], gt.mask["left"]))
    t = meta.get("timings_s", meta.get("timings", {}))
    t_total = t.get("total_s", float("nan")) if isinstance(t, dict) else float("nan")
    return MethodRow("paper", DESCRIPTIONS["paper"], int(meta.get("n_images", 2)), t_total, 0.0, sc,
                     (f"read from {d}",), kind="paper")


def compare_sample(sample_dir: Path, methods=("graycode", "graycode-subpx", "phase", "sgbm", "paper"),
                   recon_dir: Path | None = None, spp: int | None = None, depth_range_m=None,
                   renderer=None, progress=None, method_time_limit_s: float | None = None) -> Comparison:
    """Run and score ``methods`` on a written sample (see module doc); ``method_time_limit_s``: the longest a
    plug-in may run (default ``plugins.METHOD_TIME_LIMIT_S``)."""
    say = progress or (lambda msg: None)
    sample_dir = Path(sample_dir)
    plugins = _resolve_plugins(methods)
    inputs = load_inputs(sample_dir)
    gt = load_ground_truth(sample_dir)
    cfg = SampleConfig.from_dict(gt.meta["config"])
    rig = inputs.calibration.rig
    notes, rows = [], []
    truth = load_field_truth(sample_dir) if any(m != "paper" for m in methods) else None
    scene_reproduced = None
    if any(m not in ("paper", *PAIR_IMAGES) and m not in plugins for m in methods):
        say("scene")
        renderer, scene_reproduced = _recreate_scene(cfg, inputs, gt, renderer)
        if not scene_reproduced:
            notes.append("re-rendered left_passive differs from the sample's bytes (other Mitsuba variant or "
                         "version?); peer sequences are rendered from the re-created scene")
    settings = RenderSettings(spp=spp or cfg.render.spp, seed=cfg.render.seed)
    pw, ph = inputs.calibration.projector_camera.width, inputs.calibration.projector_camera.height

    def sequence(frames, name):
        say(f"render {name} ({len(frames)} frames x 2 cameras)")
        cap = render_pattern_sequence(renderer, frames, settings, cfg.sensor, name=name)
        if cfg.sensor.bit_depth != 8:  # the structured-light decoders (and OpenCV's) take 8-bit DN
            cap = dataclasses.replace(cap, images={c: (a >> 8).astype(np.uint8) for c, a in cap.images.items()})
            if "8-bit" not in " ".join(notes):
                notes.append(f"{cfg.sensor.bit_depth}-bit captures reduced to 8-bit for the structured-light decoders")
        return cap

    # Gray code: one 42-frame sequence serves both decoders (the sub-pixel one uses 22 of them).
    gray_seq = gray_cap = None
    if "graycode" in methods or "graycode-subpx" in methods:
        gray_seq = graycode.graycode_sequence(pw, ph)
        if "graycode" not in methods:
            gray_seq = gray_seq.columns_only()
        gray_cap = sequence(gray_seq.images, "graycode")
    for name in methods:
        if name == "paper":
            continue
        if name in plugins:
            say(f"method {name} (plug-in)")
            rows.append(_plugin_row(name, plugins[name], sample_dir, truth, method_time_limit_s))
            continue
        if name not in ("phase", "phase-opencv"):
            say(f"method {name}")
        res, render_s = _run_peer(name, gray_seq, gray_cap, sequence, inputs, rig, pw, ph, depth_range_m, say)
        score = score_disparity(np.where(res.valid, res.disparity, np.inf), truth, what=f"{name} disparity")
        rows.append(MethodRow(name, DESCRIPTIONS[name], res.n_images, res.timings.get("total_s", float("nan")),
                              render_s, score, tuple(res.notes), res, "disparity"))
    if "paper" in methods:
        row = _paper_row(sample_dir, recon_dir, rig, gt, notes)
        if row is not None:
            rows.insert(0, row)
    return Comparison(sample_dir, rows, notes, scene_reproduced, gt.depth["left"], gt.mask["left"])


def _run_peer(name, gray_seq, gray_cap, sequence, inputs, rig, pw, ph, depth_range_m, say):
    """(the peer's dense result, seconds of extra rendering it needed) for a built-in peer ``name``."""
    if name == "graycode":
        return graycode.decode_opencv(gray_cap["left"], gray_cap["right"], gray_seq, rig), \
            gray_cap.timings_s["render_s"]
    if name == "graycode-subpx":
        cols = gray_seq.columns_only()
        if gray_seq.row_pairs:
            idx = [i for p in gray_seq.col_pairs for i in p] + [gray_seq.black, gray_seq.white]
            L, R = gray_cap["left"][idx], gray_cap["right"][idx]
        else:
            L, R = gray_cap["left"], gray_cap["right"]
        return graycode.decode_subpixel(L, R, cols, rig), \
            gray_cap.timings_s["render_s"] * cols.n_images / gray_seq.n_images
    if name in ("phase", "phase-opencv"):
        seq = phase_shift.phase_shift_sequence(pw, ph, backend="numpy" if name == "phase" else "opencv")
        cap = sequence(seq.images, name)
        say(f"method {name}")
        return phase_shift.decode_phase_shift(cap["left"], cap["right"], seq, rig), cap.timings_s["render_s"]
    if name in PAIR_IMAGES:
        left, right = PAIR_IMAGES[name]
        return sgbm.sgbm(inputs.images[left], inputs.images[right], rig, depth_range_m=depth_range_m), 0.0
    raise ValueError(f"not a built-in peer: {name!r}")


def _implied_depth(out, truth) -> np.ndarray:
    """(H, W) z-depth (metres) of a disparity or depth output; NaN where there is no estimate."""
    if out.kind == "depth":
        z = np.asarray(out.depth, np.float64)
        return np.where(np.isfinite(z) & (z > 0), z, np.nan)
    d = np.asarray(out.disparity, np.float64) + truth.pair.doffs_px
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(d) & (d > 0), truth.pair.fb / d, np.nan)


def comparison_json(cmp: Comparison) -> dict:
    return jsonable({
        "sample": str(cmp.sample_dir), "scene_reproduced": cmp.scene_reproduced, "notes": cmp.notes,
        "units": "depth errors in mm, disparity metrics in px / %, times in s; n_images = exposures per camera",
        "methods": {r.name: {"status": r.status, "error": r.error, "kind": r.kind, "description": r.description,
                             "n_images": r.n_images, "time_s": r.time_s, "render_s": r.render_s,
                             **(r.score.to_dict() if r.score is not None else {}),
                             "figures": r.figures.to_dict(), "notes": list(r.notes)} for r in cmp.rows}})

