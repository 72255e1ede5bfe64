"""Peer methods side by side on one written sample (``platebench compare``).

Methods are listed and resolved through the registry ``reconstruction.methods`` (built-in peers of
``reconstruction.peers``, plug-ins found by ``bench.run.plugins.find_method``). Re-creates the sample's
plate and scene from ``SAMPLE_DIR/sample.json`` (its calibration must agree with ``calib.json``) when a
method needs a projector sequence of its own (``MethodEntry.sequence``), renders each sequence once with
one renderer (``bench.run.pattern_sequences``; a sequence whose frames all lie in another requested one
of the same name is taken from it), runs each method on ``MethodInputs`` and scores its output by kind
against the sample's ground truth with ``evaluation.dense``:

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

The paper row's reconstruction is checked before any method runs (``paper_reconstruction``): its files
must match the checksums its stamp records and it must have been made from the sample
(``bench.run.score.check_made_from``); an edited one, or one made from other images, is refused
(``DatasetError``), as ``platebench evaluate`` refuses it.
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from platebench.bench.config import SampleConfig
from platebench.bench.io.codecs import decode, encode
from platebench.bench.io.field_truth import load_field_truth
from platebench.bench.io.images import DatasetError
from platebench.bench.io.points import read_points_csv
from platebench.bench.io.records import MethodFigures
from platebench.bench.io.sample_files import load_ground_truth, load_inputs, load_true_cameras, read_mesh
from platebench.bench.io.verify import verify_reconstruction
from platebench.bench.run.pattern_sequences import render_pattern_sequence
from platebench.bench.run.outputs import jsonable, score_output
from platebench.bench.run.plugins import find_method, plugin_names, run_plugin
from platebench.bench.run.score import check_made_from
from platebench.errors import UserValueError
from platebench.evaluation.dense import SparseDepthScore, score_points_depth
from platebench.evaluation.error_maps import DepthErrorMap, PointDistanceMap, output_error_map
from platebench.evaluation.field_scores import DepthScore, DisparityScore, MeshScore, PointCloudScore
from platebench.evaluation.pixel_coverage import coverage_of_mesh
from platebench.plates import build_plate
from platebench.reconstruction.methods import MethodEntry, MethodInputs, builtin_names, check_output
from platebench.scenes.naming import image_seed
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.scene_spec import RenderSettings
from platebench.tolerances import tol
from platebench.bench.io.report_records import RunTimings

__all__ = ["PAPER_ROW", "MethodRow", "Comparison", "compare_sample", "resolve_methods", "paper_reconstruction",
           "comparison_json"]

PAPER_ROW = "paper's projected squares (read from platebench reconstruct output)"  # the paper row's description


def paper_reconstruction(sample_dir: Path, recon_dir: Path | None) -> tuple[Path, dict] | None:
    """(directory, recon.json dict or {}) of the paper row's ``platebench reconstruct`` output: ``recon_dir``,
    else the first of the sample's parent directory and ``SAMPLE_DIR/recon`` that holds ``points.csv``;
    None when none does. Checked before it is read: its files against the checksums its stamp records
    (``bench.io.verify.verify_reconstruction``, the check of ``platebench evaluate``) and that it was made
    from the sample (``bench.run.score.check_made_from``); ``DatasetError`` (one line naming the file)
    otherwise. Reads recon.json and the stamped files' bytes, nothing else."""
    cands = [Path(recon_dir)] if recon_dir is not None else [Path(sample_dir).resolve().parent,
                                                              Path(sample_dir) / "recon"]
    for d in cands:
        if (d / "points.csv").is_file():
            verify_reconstruction(d)
            meta = {}
            if (d / "recon.json").is_file():
                try:
                    meta = json.loads((d / "recon.json").read_text())
                except json.JSONDecodeError as e:
                    raise DatasetError(f"{d / 'recon.json'}: invalid JSON ({e.msg})") from None
            check_made_from(sample_dir, d, meta)
            return d, meta
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
    # the output the method returned (``reconstruction.methods``: Disparity, Depth, Points or Mesh); None for
    # the paper row and a method that failed
    output: object = None
    kind: str | None = "disparity"  # None for a method that failed
    status: str = "ok"  # "ok" or "failed"
    error: str | None = None  # a failed method's one-line error
    # the output's error map, scored with it (``evaluation.error_maps.output_error_map``): a DepthErrorMap
    # (signed depth error over the left view's plate pixels) of a disparity or depth output, what the
    # compare figure draws; a PointDistanceMap of points or a mesh; None for the paper row and a failure
    error_map: DepthErrorMap | PointDistanceMap | None = None

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


def resolve_methods(methods) -> dict[str, MethodEntry]:
    """{name: registry entry} of ``methods`` (``bench.run.plugins.find_method``); ``UserValueError`` naming an
    unknown one and what is allowed."""
    entries = {m: find_method(m) for m in methods}
    unknown = [m for m, e in entries.items() if e is None]
    if unknown:
        raise UserValueError(f"unknown method {unknown[0]!r}: choose from {', '.join(builtin_names())}, an installed "
                             f"plug-in ({', '.join(plugin_names()) or 'none installed'}) or module:function")
    return entries


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


def _plugin_row(entry: MethodEntry, sample_dir: Path, truth, time_limit_s: float | None = None) -> MethodRow:
    """Run an isolated entry (a plug-in) on the sample's inputs in its own process and score its output for
    its kind; a row with status "failed" and the one-line error when it fails (``bench.run.plugins``: whatever
    the plug-in does is its failure)."""
    name, fn = entry.name, entry.function
    try:
        run = run_plugin(fn, name, sample_dir, truth=truth, time_limit_s=time_limit_s)
    except Exception as e:  # noqa: BLE001  (recorded, as a sweep records it; interrupts go on up)
        return _failed_row(entry, e)
    n_images = run.output.metrics.get("n_images", 2)
    n_images = int(n_images) if isinstance(n_images, (int, float)) and np.isfinite(n_images) else 2
    return MethodRow(name, entry.description, n_images, run.time_recon_s, 0.0, run.score, tuple(run.output.notes),
                     run.output, run.output.kind, error_map=_error_map(run.output, truth))


def _paper_row(sample_dir: Path, recon_dir, found, rig, gt, notes: list) -> MethodRow | None:
    """The paper's row from the ``platebench reconstruct`` output ``found`` (``paper_reconstruction``'s,
    checked) (None, with a note, when there is none); its coverage from ``surface.ply`` through the left
    camera really posed."""
    if found is None:
        where = recon_dir if recon_dir is not None else f"{sample_dir.resolve().parent} or {sample_dir / 'recon'}"
        notes.append(f"paper row left out: no points.csv from 'platebench reconstruct' in {where} "
                     "(pass --recon DIR)")
        return None
    d, meta = found
    pts = read_points_csv(d / "points.csv")
    sc = score_points_depth(pts, rig.left, gt.depth["left"], gt.mesh)
    surface = read_mesh(d / "surface.ply") if (d / "surface.ply").is_file() else None
    posed = load_true_cameras(sample_dir)
    eye = (rig if posed is None else posed).left.center
    sc = dataclasses.replace(sc, coverage=coverage_of_mesh(surface, eye, gt.points["left"], gt.mask["left"]))
    rt = RunTimings.of(meta)
    t_total = float("nan") if rt.total_s is None else float(rt.total_s)
    return MethodRow("paper", PAPER_ROW, int(meta.get("n_images", 2)), t_total, 0.0, sc,
                     (f"read from {d}",), kind="paper")


def compare_sample(sample_dir: Path, methods=("graycode", "graycode-subpx", "phase", "sgbm", "paper"),
                   recon_dir: Path | None = None, spp: int | None = None, depth_range_m=None,
                   renderer=None, progress=None, method_time_limit_s: float | None = None) -> Comparison:
    """Run and score ``methods`` on a written sample (see module doc); ``method_time_limit_s``: the longest a
    plug-in may run (default ``plugins.METHOD_TIME_LIMIT_S``); ``depth_range_m``: (Z_min, Z_max) metres given
    to the methods as ``MethodInputs.depth_range_m``."""
    say = progress or (lambda msg: None)
    sample_dir = Path(sample_dir)
    entries = resolve_methods(methods)
    paper = paper_reconstruction(sample_dir, recon_dir) if "paper" in methods else None  # refused before any work
    inputs = load_inputs(sample_dir)
    gt = load_ground_truth(sample_dir)
    cfg = decode(SampleConfig, gt.meta["config"])
    rig = inputs.calibration.rig
    notes, rows = [], []
    truth = load_field_truth(sample_dir) if any(m != "paper" for m in methods) else None
    scene_reproduced = None
    sequenced = {m: e for m, e in entries.items() if m != "paper" and not e.isolated and e.sequence is not None}
    if sequenced:
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

    captures = _Captures({m: e.sequence for m, e in sequenced.items()}, pw, ph, sequence)
    for name in methods:
        entry = entries[name]
        if name == "paper":
            continue
        if entry.isolated:
            say(f"method {name} (plug-in)")
            rows.append(_plugin_row(entry, sample_dir, truth, method_time_limit_s))
            continue
        _check_image_size(entry, inputs.images)
        seq, caps, render_s = captures.of(name) if name in sequenced else (None, {}, 0.0)
        say(f"method {name}")
        given = MethodInputs(dict(inputs.images), inputs.calibration, inputs.pattern, seq, caps, depth_range_m)
        t0 = time.perf_counter()
        try:
            out = check_output(entry.function(given), name)
        except UserValueError:
            raise
        except Exception as e:  # noqa: BLE001  (a method that fails is recorded, as a plug-in's failure is)
            rows.append(_failed_row(entry, e))
            continue
        time_s = time.perf_counter() - t0
        if entry.output is not None and out.kind != entry.output:
            raise UserValueError(f"method {name!r} returned a {out.kind} output: it is registered as {entry.output}")
        score = score_output(out, truth, what=f"{name} {out.kind}")
        n_images = entry.exposures(given)
        rows.append(MethodRow(name, entry.description, n_images, time_s, render_s, score, tuple(out.notes), out,
                              out.kind, error_map=_error_map(out, truth)))
    if "paper" in methods:
        row = _paper_row(sample_dir, recon_dir, paper, rig, gt, notes)
        if row is not None:
            rows.insert(0, row)
    return Comparison(sample_dir, rows, notes, scene_reproduced, gt.depth["left"], gt.mask["left"])


def _failed_row(entry: MethodEntry, e: Exception) -> MethodRow:
    """The row of a method that raised: status "failed" and its one-line error (type and first line)."""
    msg = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
    return MethodRow(entry.name, entry.description, 0, float("nan"), 0.0, kind=None, status="failed",
                     error=f"{type(e).__name__}: {msg}"[:500])


def _check_image_size(entry: MethodEntry, images) -> None:
    """Refuse (``UserValueError``) images smaller than the method's ``min_image_px``."""
    h, w = np.asarray(images["left_passive"]).shape[:2]
    if min(h, w) < entry.min_image_px:
        raise UserValueError(f"method {entry.name!r} needs images of at least {entry.min_image_px} px a side: the "
                             f"sample's are {w}x{h}")


class _Captures:
    """The captures of the methods' projector sequences, each sequence rendered once (module doc): a method's
    sequence whose frames all lie in a larger requested sequence of the same name is cut from its captures,
    with that share of its render time."""

    def __init__(self, projections: dict, pw: int, ph: int, render):
        self._made = {m: p.make(pw, ph) for m, p in projections.items()}
        self._names = {m: p.name for m, p in projections.items()}
        self._render = render
        self._done: dict = {}

    def _host(self, method: str):
        """(the method whose sequence is rendered for ``method``, frame indices in it or None)."""
        own = np.asarray(self._made[method].images)
        best = (method, None)
        for other, seq in self._made.items():
            frames = np.asarray(seq.images)
            if other == method or self._names[other] != self._names[method] or len(frames) <= len(own):
                continue
            at = {}
            for i, f in enumerate(frames):
                at.setdefault(f.tobytes(), i)
            idx = [at.get(f.tobytes()) for f in own]
            if None not in idx and (best[1] is None or len(frames) > len(self._made[best[0]].images)):
                best = (other, idx)
        return best

    def of(self, method: str):
        """(the method's sequence, camera -> (N, H, W) captures, seconds of rendering they took)."""
        host, idx = self._host(method)
        if host not in self._done:
            self._done[host] = self._render(self._made[host].images, self._names[host])
        cap = self._done[host]
        if idx is None:
            return self._made[method], dict(cap.images), cap.render_s
        n_host = len(self._made[host].images)
        return (self._made[method], {c: a[idx] for c, a in cap.images.items()},
                cap.render_s * len(idx) / n_host)


def _error_map(out, truth) -> DepthErrorMap | PointDistanceMap:
    """The error map of an output of any kind against the sample's truth, scored as its score is
    (``evaluation.error_maps.output_error_map``)."""
    return output_error_map(out.kind, getattr(out, out.kind), truth)


def comparison_json(cmp: Comparison) -> dict:
    return jsonable({
        "sample": str(cmp.sample_dir), "scene_reproduced": cmp.scene_reproduced, "notes": cmp.notes,
        "units": "depth errors in mm, disparity metrics in px / %, times in s; n_images = exposures per camera",
        "methods": {r.name: {"status": r.status, "error": r.error, "kind": r.kind, "description": r.description,
                             "n_images": r.n_images, "time_s": r.time_s, "render_s": r.render_s,
                             **(encode(r.score) if r.score is not None else {}),
                             "figures": r.figures.to_dict(), "notes": list(r.notes)} for r in cmp.rows}})

