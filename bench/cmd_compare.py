"""``platebench compare``: score peer reconstruction methods side by side on one sample.

Re-creates the sample's plate and scene from ``SAMPLE_DIR/sample.json`` (its calibration
must agree with ``calib.json``), renders the projector sequences the chosen methods need
with one renderer (``bench.pattern_sequences``), runs each method (``reconstruction.peer_*``:
pure functions of images and calibration) and scores it against the sample's ground truth:

* depth: |Z_est - Z_gt| (left camera z-depth, mm) over plate pixels with an estimate:
  median, RMS, p95, max, signed mean; coverage = those pixels / plate pixels (gt mask);
  estimates off the plate are counted separately (the disparity metrics ignore them);
* disparity: Middlebury v3 and ETH3D two-view metrics against ``gt/disp0GT.pfm``.

The "paper" row is read, not computed: ``--recon DIR`` (or the sample's parent
directory) holding ``points.csv`` (world x, y, z in metres) and optionally
``recon.json`` from ``platebench reconstruct``; its points are scored by depth error at
their left-image projection and by distance to the true plate surface. Without such
files the row is left out, with a note.

Outputs (``--out``, default ``SAMPLE_DIR/compare``): ``compare.json`` (every figure)
and ``compare.png`` (signed depth-error map per method).
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from bench.atomic import write_bytes, write_json
from bench.config import SampleConfig
from bench.image_io import DatasetError
from bench.sample import load_ground_truth, load_inputs

METHODS = ("paper", "graycode", "graycode-subpx", "phase", "sgbm")
DESCRIPTIONS = {
    "paper": "paper's projected squares (read from platebench reconstruct output)",
    "graycode": "Gray code, OpenCV GrayCodePattern.decode",
    "graycode-subpx": "Gray code, sub-pixel column matching along rows (numpy)",
    "phase": "4-step phase shifting + Gray-code unwrapping (numpy)",
    "phase-opencv": "3-step phase shifting, OpenCV SinusoidalPattern wrapped phase + Gray-code unwrapping",
    "sgbm": "OpenCV StereoSGBM on the passive pair",
}
ALL_METHODS = METHODS + ("phase-opencv",)


# ----------------------------------------------------------------------------- scoring
def _f(x) -> float | None:
    """JSON-safe float: None for NaN/inf."""
    x = float(x)
    return x if math.isfinite(x) else None


def score_dense(depth_est, disparity_est, valid, gt_depth, gt_mask, gt_disparity) -> dict:
    """Depth error (mm), coverage and Middlebury/ETH3D disparity metrics of a dense left map."""
    from evaluation.disparity_metrics import eth3d_metrics, middlebury_metrics  # noqa: PLC0415
    mask = np.asarray(gt_mask, bool)
    est = np.asarray(valid, bool) & mask & np.isfinite(gt_depth)
    n_plate = int(mask.sum())
    err = (np.asarray(depth_est, np.float64)[est] - np.asarray(gt_depth, np.float64)[est]) * 1e3
    a = np.abs(err)
    out = {"plate_px": n_plate, "estimated_px": int(est.sum()),
           "coverage_pct": 100.0 * est.sum() / n_plate if n_plate else float("nan"),
           "off_plate_px": int((np.asarray(valid, bool) & ~mask).sum())}
    if a.size:
        out.update(depth_median_mm=float(np.median(a)), depth_rms_mm=float(np.sqrt(np.mean(a * a))),
                   depth_p95_mm=float(np.percentile(a, 95)), depth_max_mm=float(a.max()),
                   depth_mean_signed_mm=float(err.mean()))
    else:
        out.update(depth_median_mm=float("nan"), depth_rms_mm=float("nan"), depth_p95_mm=float("nan"),
                   depth_max_mm=float("nan"), depth_mean_signed_mm=float("nan"))
    disp = np.where(np.isfinite(disparity_est), disparity_est, np.inf)
    out["middlebury"] = middlebury_metrics(disp, gt_disparity).to_dict()
    out["eth3d"] = eth3d_metrics(disp, gt_disparity).to_dict()
    return out


def _bilinear(img: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear lookup at (N,2) pixel coordinates; NaN unless all four neighbours are finite."""
    H, W = img.shape
    u, v = uv[:, 0], uv[:, 1]
    ok = np.isfinite(u) & np.isfinite(v) & (u >= 0) & (v >= 0) & (u <= W - 1) & (v <= H - 1)
    out = np.full(len(uv), np.nan)
    u0 = np.clip(np.floor(u[ok]).astype(int), 0, W - 2)
    v0 = np.clip(np.floor(v[ok]).astype(int), 0, H - 2)
    fu, fv = u[ok] - u0, v[ok] - v0
    g = img.astype(np.float64)
    val = (g[v0, u0] * (1 - fu) * (1 - fv) + g[v0, u0 + 1] * fu * (1 - fv)
           + g[v0 + 1, u0] * (1 - fu) * fv + g[v0 + 1, u0 + 1] * fu * fv)
    out[ok] = val
    return out


def score_points_depth(points, left_camera, gt_depth, mesh=None) -> dict:
    """Depth error of sparse world points at their left-image projection, and distance to the true surface."""
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    uv = left_camera.project(pts)
    z_gt = _bilinear(np.where(np.isfinite(gt_depth), gt_depth, np.nan), uv)
    z = left_camera.depth(pts)
    ok = np.isfinite(z_gt)
    a = np.abs(z[ok] - z_gt[ok]) * 1e3
    out = {"points": int(len(pts)), "points_on_plate": int(ok.sum())}
    out["depth_median_mm"] = float(np.median(a)) if a.size else float("nan")
    out["depth_rms_mm"] = float(np.sqrt(np.mean(a * a))) if a.size else float("nan")
    out["depth_max_mm"] = float(a.max()) if a.size else float("nan")
    if mesh is not None and len(pts):
        from evaluation.point_metrics import point_to_surface_distance  # noqa: PLC0415
        d = point_to_surface_distance(pts, mesh) * 1e3
        out["surface_rms_mm"] = float(np.sqrt(np.mean(d * d)))
        out["surface_max_mm"] = float(d.max())
    return out


# ----------------------------------------------------------------------------- paper row
def _read_points_csv(path: Path) -> np.ndarray:
    rows = list(csv.reader(path.read_text().splitlines()))
    rows = [r for r in rows if r and not r[0].lstrip().startswith("#")]
    if not rows:
        return np.zeros((0, 3))
    header = [h.strip().lower() for h in rows[0]]
    try:
        [float(x) for x in rows[0]]
        body, cols = rows, [0, 1, 2]
    except ValueError:
        body = rows[1:]
        cols = []
        for name in ("x", "y", "z"):
            for cand in (name, f"{name}_m", f"{name}_world_m", f"world_{name}", f"{name}_world"):
                if cand in header:
                    cols.append(header.index(cand))
                    break
        if len(cols) != 3:
            raise DatasetError(f"{path}: cannot find x, y, z columns in header {rows[0]}")
    try:
        return np.array([[float(r[c]) for c in cols] for r in body], np.float64).reshape(-1, 3)
    except (ValueError, IndexError) as e:
        raise DatasetError(f"{path}: bad point row ({e})") from None


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
            return _read_points_csv(pts_path), meta, d
    return None


# ----------------------------------------------------------------------------- running
@dataclass
class MethodRow:
    name: str
    description: str
    n_images: int
    time_s: float
    render_s: float
    scores: dict
    notes: list = field(default_factory=list)
    result: object = None  # DenseResult, None for the paper row


@dataclass
class Comparison:
    sample_dir: Path
    rows: list
    notes: list
    scene_reproduced: bool | None
    gt_depth: np.ndarray
    gt_mask: np.ndarray


def _check_calibration(spec, calib) -> None:
    for name in ("left", "right"):
        a, b = getattr(spec.rig, name), getattr(calib.rig, name)
        if not (np.allclose(a.K, b.K, atol=1e-6) and np.allclose(a.R, b.R, atol=1e-9)
                and np.allclose(a.t, b.t, atol=1e-9) and (a.width, a.height) == (b.width, b.height)):
            raise DatasetError(f"sample.json's configuration does not reproduce calib.json ({name} camera); "
                               "the sample cannot be re-rendered for the peer methods")


def compare_sample(sample_dir: Path, methods=("graycode", "graycode-subpx", "phase", "sgbm", "paper"),
                   recon_dir: Path | None = None, spp: int | None = None, depth_range_m=None,
                   renderer=None, progress=None) -> Comparison:
    """Run and score ``methods`` on a written sample (see module doc)."""
    from bench.pattern_sequences import render_pattern_sequence  # noqa: PLC0415
    from plates import build_plate  # noqa: PLC0415
    from reconstruction import peer_graycode, peer_phase_shift, peer_sgbm  # noqa: PLC0415
    from scenes.renderer import PlateRenderer, RenderSettings, image_seed  # noqa: PLC0415

    say = progress or (lambda msg: None)
    sample_dir = Path(sample_dir)
    unknown = [m for m in methods if m not in ALL_METHODS]
    if unknown:
        raise ValueError(f"unknown method {unknown[0]!r}: choose from {', '.join(ALL_METHODS)}")
    inputs = load_inputs(sample_dir)
    gt = load_ground_truth(sample_dir)
    cfg = SampleConfig.from_dict(gt.meta["config"])
    rig = inputs.calibration.rig
    notes = []
    rows = []
    gt_depth, gt_mask = gt.depth["left"], gt.mask["left"]

    needs_render = [m for m in methods if m not in ("paper", "sgbm")]
    scene_reproduced = None
    if needs_render:
        say("scene")
        plate = build_plate(cfg.plate)
        spec = cfg.scene.build()
        _check_calibration(spec, inputs.calibration)
        if renderer is None:
            renderer = PlateRenderer(spec, plate, cfg.variant)
        else:
            renderer.set_scene(spec)
            renderer.set_plate(plate)
        # Does the re-created scene give the sample's own bytes? (Same variant and seed: it should.)
        img = cfg.sensor.digitize(renderer.render("left", "passive", cfg.render),
                                  seed=image_seed(cfg.render.seed, "left", "passive"))
        import hashlib  # noqa: PLC0415
        want = gt.meta.get("images", {}).get("left_passive")
        scene_reproduced = want is None or hashlib.sha256(img.tobytes()).hexdigest() == want
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
        gray_seq = peer_graycode.graycode_sequence(pw, ph)
        if "graycode" not in methods:
            gray_seq = gray_seq.columns_only()
        gray_cap = sequence(gray_seq.images, "graycode")
    for name in methods:
        if name == "paper":
            continue
        if name not in ("phase", "phase-opencv"):
            say(f"method {name}")
        if name == "graycode":
            res = peer_graycode.decode_opencv(gray_cap["left"], gray_cap["right"], gray_seq, rig)
            render_s = gray_cap.timings_s["render_s"]
        elif name == "graycode-subpx":
            cols = gray_seq.columns_only()
            if gray_seq.row_pairs:
                idx = [i for p in gray_seq.col_pairs for i in p] + [gray_seq.black, gray_seq.white]
                L, R = gray_cap["left"][idx], gray_cap["right"][idx]
            else:
                L, R = gray_cap["left"], gray_cap["right"]
            res = peer_graycode.decode_subpixel(L, R, cols, rig)
            render_s = gray_cap.timings_s["render_s"] * cols.n_images / gray_seq.n_images
        elif name in ("phase", "phase-opencv"):
            backend = "numpy" if name == "phase" else "opencv"
            seq = peer_phase_shift.phase_shift_sequence(pw, ph, backend=backend)
            cap = sequence(seq.images, name)
            say(f"method {name}")
            res = peer_phase_shift.decode_phase_shift(cap["left"], cap["right"], seq, rig)
            render_s = cap.timings_s["render_s"]
        elif name == "sgbm":
            res = peer_sgbm.sgbm(inputs.images["left_passive"], inputs.images["right_passive"], rig,
                                 depth_range_m=depth_range_m)
            render_s = 0.0
        sc = score_dense(res.depth, res.disparity, res.valid, gt_depth, gt_mask, gt.disparity)
        rows.append(MethodRow(name, DESCRIPTIONS[name], res.n_images, res.timings.get("total_s", float("nan")),
                              render_s, sc, list(res.notes), res))
    if "paper" in methods:
        found = find_paper_reconstruction(sample_dir, recon_dir)
        if found is None:
            where = recon_dir if recon_dir is not None else f"{sample_dir.resolve().parent} or {sample_dir / 'recon'}"
            notes.append(f"paper row left out: no points.csv from 'platebench reconstruct' in {where} "
                         "(pass --recon DIR)")
        else:
            pts, meta, d = found
            sc = score_points_depth(pts, rig.left, gt_depth, gt.mesh)
            t = meta.get("timings_s", meta.get("timings", {}))
            t_total = t.get("total_s", float("nan")) if isinstance(t, dict) else float("nan")
            rows.insert(0, MethodRow("paper", DESCRIPTIONS["paper"], int(meta.get("n_images", 2)), t_total, 0.0, sc,
                                     [f"read from {d}"]))
    return Comparison(sample_dir, rows, notes, scene_reproduced, gt_depth, gt_mask)


# ----------------------------------------------------------------------------- reporting
def format_table(cmp: Comparison) -> str:
    head = (f"{'method':16s} {'img/cam':>7s} {'depth med mm':>12s} {'depth RMS mm':>12s} {'coverage':>9s} "
            f"{'bad1 %':>7s} {'time s':>7s} {'render s':>8s}")
    lines = [head, "-" * len(head)]
    for r in cmp.rows:
        s = r.scores
        if r.name == "paper":
            cov = f"{s['points_on_plate']} pts"
            bad = "-"
        else:
            cov = f"{s['coverage_pct']:.1f} %"
            bad = f"{s['middlebury']['mb_all_bad_1_0_pct']:.1f}"
        lines.append(f"{r.name:16s} {r.n_images:7d} {s['depth_median_mm']:12.4f} {s['depth_rms_mm']:12.4f} "
                     f"{cov:>9s} {bad:>7s} {r.time_s:7.3f} {r.render_s:8.1f}")
    return "\n".join(lines)


def _jsonable(o):
    if isinstance(o, dict):
        return {k: _jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_jsonable(v) for v in o]
    if isinstance(o, (float, np.floating)):
        return _f(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    return o


def comparison_json(cmp: Comparison) -> dict:
    return _jsonable({
        "sample": str(cmp.sample_dir), "scene_reproduced": cmp.scene_reproduced, "notes": cmp.notes,
        "units": "depth errors in mm, disparity metrics in px / %, times in s; n_images = exposures per camera",
        "methods": {r.name: {"description": r.description, "n_images": r.n_images, "time_s": r.time_s,
                             "render_s": r.render_s, **r.scores, "notes": r.notes} for r in cmp.rows}})


def error_figure(cmp: Comparison) -> bytes:
    """PNG: signed depth error (mm) per dense method on the plate's bounding box."""
    import io  # noqa: PLC0415

    import matplotlib  # noqa: PLC0415
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    dense = [r for r in cmp.rows if r.result is not None]
    n = max(len(dense), 1)
    fig, axes = plt.subplots(1, n, figsize=(3.6 * n, 4.4), squeeze=False)
    mask = cmp.gt_mask
    vs, us = np.nonzero(mask)
    if vs.size:
        m = 5
        v0, v1 = max(vs.min() - m, 0), min(vs.max() + m + 1, mask.shape[0])
        u0, u1 = max(us.min() - m, 0), min(us.max() + m + 1, mask.shape[1])
    else:
        v0, v1, u0, u1 = 0, mask.shape[0], 0, mask.shape[1]
    for ax, r in zip(axes[0], dense):
        res = r.result
        err = np.where(res.valid & mask, (res.depth.astype(np.float64) - cmp.gt_depth) * 1e3, np.nan)
        a = np.abs(err[np.isfinite(err)])
        lim = float(np.percentile(a, 95)) if a.size else 1.0
        lim = max(lim, 1e-3)
        back = np.where(mask, 0.45, 0.05)[v0:v1, u0:u1]
        ax.imshow(back, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        im = ax.imshow(err[v0:v1, u0:u1], cmap="coolwarm", vmin=-lim, vmax=lim, interpolation="nearest")
        s = r.scores
        ax.set_title(f"{r.name}\nmed {s['depth_median_mm']:.3f} / RMS {s['depth_rms_mm']:.3f} mm\n"
                     f"cov {s['coverage_pct']:.1f} %, {r.n_images} img/cam", fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
        fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04, label="Z_est - Z_gt (mm)")
    fig.suptitle(f"{cmp.sample_dir}: left-camera depth error (dark grey: plate pixel without estimate)", fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()


# ----------------------------------------------------------------------------- CLI
def _method_list(text: str) -> tuple:
    names = tuple(m.strip() for m in text.split(",") if m.strip())
    bad = [m for m in names if m not in ALL_METHODS]
    if bad or not names:
        raise argparse.ArgumentTypeError(f"unknown method {bad[0] if bad else text!r}: choose from "
                                         f"{', '.join(ALL_METHODS)}")
    return names


def add_parser(sub) -> None:
    p = sub.add_parser("compare", help="score peer methods (Gray code, phase shifting, SGBM) side by side",
                       description="Re-render a sample's scene under each peer method's projector sequence, "
                                   "reconstruct, and score against the sample's exact ground truth (depth error "
                                   "in mm, coverage of the plate, Middlebury/ETH3D disparity metrics). "
                                   "Writes compare.json and compare.png.")
    p.add_argument("sample", type=Path, metavar="SAMPLE_DIR", help="sample directory from 'platebench render'")
    p.add_argument("--methods", type=_method_list, default=METHODS,
                   help=f"comma-separated list from {', '.join(ALL_METHODS)} (default: {','.join(METHODS)})")
    p.add_argument("--out", type=Path, help="output directory (default SAMPLE_DIR/compare)")
    p.add_argument("--recon", type=Path, help="directory with the paper pipeline's points.csv / recon.json "
                   "(default: the sample's parent directory)")
    p.add_argument("--spp", type=int, help="samples per pixel for the pattern sequences (default: the sample's)")
    p.add_argument("--min-depth-mm", type=float, help="SGBM search range: nearest depth in MILLIMETRES")
    p.add_argument("--max-depth-mm", type=float, help="SGBM search range: farthest depth in MILLIMETRES")
    p.set_defaults(run=run)


def run(args) -> int:
    import sys  # noqa: PLC0415
    if not Path(args.sample).is_dir():
        raise FileNotFoundError(f"{args.sample}: sample directory is missing")
    if (args.min_depth_mm is None) != (args.max_depth_mm is None):
        raise ValueError("--min-depth-mm and --max-depth-mm go together")
    depth_range = None
    if args.min_depth_mm is not None:
        if not 0 < args.min_depth_mm < args.max_depth_mm:
            raise ValueError(f"depth range {args.min_depth_mm}-{args.max_depth_mm} mm is out of range: "
                             "need 0 < min < max")
        depth_range = (args.min_depth_mm / 1e3, args.max_depth_mm / 1e3)
    if args.spp is not None and not 1 <= args.spp <= 65536:
        raise ValueError(f"--spp = {args.spp} is out of range: allowed 1 to 65536")
    t0 = time.perf_counter()

    def say(msg):
        print(f"  {msg}", file=sys.stderr, flush=True)

    cmp = compare_sample(args.sample, args.methods, args.recon, args.spp, depth_range, progress=say)
    out = Path(args.out) if args.out is not None else Path(args.sample) / "compare"
    out.mkdir(parents=True, exist_ok=True)
    doc = comparison_json(cmp)
    doc["total_s"] = time.perf_counter() - t0
    write_json(out / "compare.json", doc)
    write_bytes(out / "compare.png", error_figure(cmp))
    print(f"sample      {args.sample}")
    print(format_table(cmp))
    for n in cmp.notes:
        print(f"note: {n}")
    print(f"wrote       {out / 'compare.json'}, {out / 'compare.png'}  ({doc['total_s']:.1f} s)")
    return 0
