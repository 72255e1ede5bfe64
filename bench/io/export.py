"""Export a PlateBench dataset to the layouts stereo code reads: Middlebury (2014 SDK) and KITTI 2015.

Each sample is read as a ``PlateBenchDataset`` item (``bench.io.dataset_reader``) and written in
the layout the format's own tools read unchanged; the file trees, ``calib.txt`` and
``calib_cam_to_cam`` fields are in docs/reference.md ("Export layouts"). Images:
``images="active"`` (default) takes the camera images under the projected square grid (a plain
white plate under passive light has no texture to match), ``"passive"`` those under the overhead
light.

Middlebury (``fmt="middlebury"``): ``OUT/trainingF/<scene>/`` only (full resolution; ``<scene>``
is ``scene_name`` of the sample id, two colliding names refused); depth Z = baseline f / (d + doffs)
in the baseline's unit (mm). ``shift`` = s crops the left image to columns [s, W) and the right one
to [0, W - s): every disparity becomes d - s and doffs grows by s. Allowed: 0 to ``max_shift_px``
(``floor(d_min) - 1``, d_min the smallest true disparity of any sample's plate), else refused,
naming the value and the range, before anything is written; ``shift="auto"`` picks s per sample
(the plate's disparities then start at ``min_disparity_px``).

KITTI 2015 (``fmt="kitti"``): ``OUT/training/``, one K for both rectified cameras, Z = f B / d
(metres, no disparity offset) and 0 < d < 256 px (uint16 = round(256 d)). A sample whose largest
true disparity does not fit is reduced by the smallest whole factor k that fits (area averaging of
k x k blocks; K with it: f / k, principal point (c + 0.5) / k - 0.5; disparities the block mean
where all its pixels have one, divided by k), recorded in export.json (``resample_factor``,
``resampled``, ``f_px``, ``baseline_m``). Principal points that differ (doffs not 0) or a
``shift`` are refused with the reason.

A sweep whose manifest lists more samples than the dataset holds rendered is refused with one line
naming how many of how many, unless ``allow_incomplete`` (then ``ExportSummary.note`` says so and
export.json records it under ``sweep``). Pairs that are no rectified pair (``unrectified``: a
robot's pair or a distorting lens) are left out, counted in the note and listed in export.json
(``left_out_unrectified``), unless ``include_unrectified`` (then exported and marked).

``OUT/export.json`` lists every exported sample. The output follows the output rule
(``bench.io.outputs``: never the dataset itself nor inside it; an existing ``OUT`` replaced only
with ``overwrite`` and only when it is an export), staged and renamed into place. Every sample is
checked against its recorded checksums before the first is written or ``progress`` is told.
"""
from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from platebench.bench.io.atomic import write_json, write_text
from platebench.bench.io.dataset_reader import MIN_DISPARITY_PX, PlateBenchDataset, StereoPair
from platebench.bench.io.images import DatasetError, read_pfm, write_pfm, write_png
from platebench.bench.io.layout import SAMPLES
from platebench.bench.io.middlebury import write_calib
from platebench.bench.io.outputs import check_output, output_dir
from platebench.bench.io.records import Record
from platebench.bench.io.verify import dataset_manifest, sample_checksums, verify_sample
from platebench.tolerances import tol

__all__ = ["FORMATS", "IMAGES", "MIDDLEBURY_TREE", "ExportSummary", "ExportedSample", "export_dataset", "KITTI_SCALE",
           "KITTI_MAX_DISPARITY_PX", "nocc_mask_png", "KittiPair", "kitti_pair", "kitti_resample_factor", "unrectified",
           "scene_name", "max_shift_px", "sweep_completeness"]

FORMATS = ("middlebury", "kitti")
IMAGES = "active"  # the images exported unless told: the projected grid (module doc)
MIDDLEBURY_TREE = "trainingF"  # the Middlebury SDK's folder of full-resolution training scenes
KITTI_SCALE = 256.0  # KITTI's disparity PNG: uint16 value = 256 d
KITTI_MAX_DISPARITY_PX = 65535 / KITTI_SCALE  # the largest disparity a KITTI PNG holds (255.996 px)
_DEPTH_RULE = {"middlebury": "Z = baseline f / (d + doffs), from calib.txt (baseline in mm)",
               "kitti": "Z = f B / d, f = P_rect_02[0, 0], B = (P_rect_02[0, 3] - P_rect_03[0, 3]) / f (metres)"}


_KITTI_ONLY = ("resample_factor", "resampled", "f_px", "baseline_m")


@dataclass(frozen=True)
class ExportedSample(Record):
    """One exported sample (a row of export.json's ``samples``): its id, its files in the export,
    the sample it came from, the shift of its disparities (px) and Middlebury's doffs (px), its
    disparity range (px, as the format's vmin/vmax) and image size (px). KITTI only: the factor its
    images were reduced by, why (None: not reduced), its focal length (px) and baseline (m)."""

    id: str
    files: str
    source: str
    shift_px: int
    doffs_px: float
    vmin: int
    vmax: int
    width: int
    height: int
    resample_factor: int | None = None
    resampled: str | None = None
    f_px: float | None = None
    baseline_m: float | None = None
    unrectified: str | None = None  # why the pair is no rectified pair (exported with include_unrectified)

    def to_dict(self) -> dict:
        d = super().to_dict()
        order = ("id", "files", "source", "shift_px", "doffs_px", *_KITTI_ONLY, "vmin", "vmax", "width", "height",
                 "unrectified")
        return {k: d[k] for k in order if (self.resample_factor is not None or k not in _KITTI_ONLY)
                and (k != "unrectified" or self.unrectified is not None)}


@dataclass(frozen=True)
class ExportSummary:
    """What ``export_dataset`` wrote: the output folder, the format, a row per exported sample, the
    images taken ("active"/"passive"), the largest shift the dataset allows (px; None for KITTI) and
    a note for the user (None, or how many of a sweep's samples an incomplete export holds)."""

    out: Path
    format: str
    samples: tuple[ExportedSample, ...]
    images: str = IMAGES
    max_shift_px: int | None = None
    note: str | None = None


def nocc_mask_png(pair: StereoPair) -> np.ndarray:
    """Middlebury's mask0nocc: 255 non-occluded, 128 occluded (truth known), 0 unknown."""
    return np.where(pair.nonocc, 255, np.where(pair.mask, 128, 0)).astype(np.uint8)


_UNSAFE_SCENE = re.compile(r"[^A-Za-z0-9._-]")


def scene_name(sample_id: str) -> str:
    """The Middlebury scene folder of a sample: its id with every character outside letters, digits
    and ``. _ -`` replaced by ``_``, and a leading ``.`` too (a folder the SDK's listing would skip)."""
    name = _UNSAFE_SCENE.sub("_", str(sample_id))
    return "_" + name[1:] if name.startswith(".") else name or "_"


def max_shift_px(ds: PlateBenchDataset) -> tuple[int, float, str]:
    """(the largest shift ``ds`` allows (px, >= 0 unless a plate has disparities under 1 px: then -1
    or less, and only 0 is allowed), the smallest true disparity of any sample's plate (px, whole
    unshifted view), the id of that sample): floor(d_min) - 1 (module doc). Reads each sample's
    ``gt/disp0GT.pfm``, the truth the items are made of."""
    d_min, where = math.inf, ""
    for i, d in enumerate(ds.sample_dirs):
        disp = read_pfm(d / "gt" / "disp0GT.pfm")
        known = disp[np.isfinite(disp)]
        if known.size and float(known.min()) < d_min:
            d_min, where = float(known.min()), ds.sample_id(i)
    if not math.isfinite(d_min):
        raise DatasetError(f"{ds.root}: no sample has a plate pixel with a true disparity")
    return math.floor(d_min) - 1, d_min, where


def _refuse_shift(ds: PlateBenchDataset, shift: int, allowed: int, d_min: float, where: str) -> None:
    """One line: ``shift`` is beyond ``allowed``, and what it would do to the first sample it spoils."""
    rng = f"allowed 0 to {allowed} px" if allowed >= 0 else "allowed 0 only"
    what = ""
    worst = math.inf
    for i, d in enumerate(ds.sample_dirs):
        disp = read_pfm(d / "gt" / "disp0GT.pfm")[:, shift:]
        kept = disp[np.isfinite(disp)]
        if kept.size == 0:
            what = (f"; at {shift} px sample {ds.sample_id(i)} keeps no plate pixel with a true disparity in the "
                    "exported view")
            break
        if float(kept.min()) - shift < min(worst, 1.0):
            worst = float(kept.min()) - shift
            what = f"; at {shift} px sample {ds.sample_id(i)}'s true disparities would go down to {worst:.2f} px"
    raise DatasetError(f"--shift {shift} is out of range for {ds.root}: {rng} (floor of its smallest true disparity, "
                       f"{d_min:.2f} px in sample {where}, minus 1: every exported disparity stays >= 1 px), or "
                       f"'auto'{what}")


def sweep_completeness(ds: PlateBenchDataset) -> tuple[int, int, str] | None:
    """(samples rendered, samples the sweep's manifest lists, its state) when ``ds.root`` is a sweep
    dataset (``platebench sweep``), else None. The state is as it stands ("running" only while a sweep
    holds the dataset; "interrupted" for one that was killed: ``bench.io.dataset_state.live_state``)."""
    manifest = dataset_manifest(ds.root)
    if manifest is None or not isinstance(manifest.get("samples"), list):
        return None
    from platebench.bench.io.dataset_state import live_state  # noqa: PLC0415
    state = str(live_state(manifest, ds.root).get("state"))
    under = (ds.root / SAMPLES).resolve()
    rendered = sum(1 for d in ds.sample_dirs if d.resolve().is_relative_to(under))
    return rendered, len(manifest["samples"]), state


def _check_files(ds: PlateBenchDataset) -> None:
    """Every sample's files against their recorded checksums (``bench.io.verify``): all of them but the
    linear-radiance EXRs of the camera images, both lightings' PNGs included (module doc)."""
    manifest = dataset_manifest(ds.root)
    for d in ds.sample_dirs:
        checks = sample_checksums(d, manifest)
        if checks is not None:
            verify_sample(d, checks, [n for n in checks.files
                                      if not (n.startswith("images/") and n.endswith(".exr"))])


def _write_middlebury(d: Path, pair: StereoPair) -> None:
    d.mkdir(parents=True)
    write_png(d / "im0.png", pair.left)
    write_png(d / "im1.png", pair.right)
    write_pfm(d / "disp0GT.pfm", pair.disparity)
    write_pfm(d / "disp1GT.pfm", pair.disparity_right)
    write_png(d / "mask0nocc.png", nocc_mask_png(pair))
    write_calib(d / "calib.txt", pair.calib)


@dataclass(frozen=True)
class KittiPair:
    """A stereo pair as KITTI 2015 holds it: ``left``/``right`` images, ``disparity`` (H, W) float64
    px (NaN unknown), ``nonocc`` (H, W) bool, ``K`` the shared 3x3 intrinsics (px), ``baseline_m``,
    ``factor`` the whole factor the sample's images were reduced by (1: as rendered)."""

    left: np.ndarray
    right: np.ndarray
    disparity: np.ndarray
    nonocc: np.ndarray
    K: np.ndarray
    baseline_m: float
    factor: int


def kitti_resample_factor(max_disparity_px: float) -> int:
    """The smallest whole k with max_disparity_px / k under KITTI's largest disparity (module doc)."""
    return max(1, math.floor(max_disparity_px / KITTI_MAX_DISPARITY_PX) + 1)


def _blocks(a: np.ndarray, k: int) -> np.ndarray:
    """(H//k, W//k, k*k) blocks of a 2D array (the last rows/columns that fill no block are dropped)."""
    H, W = (a.shape[0] // k) * k, (a.shape[1] // k) * k
    return a[:H, :W].reshape(H // k, k, W // k, k).transpose(0, 2, 1, 3).reshape(H // k, W // k, k * k)


def kitti_pair(pair: StereoPair) -> KittiPair:
    """``pair`` (unshifted) in KITTI's conventions: equal principal points, Z = f B / d, d < 256 px;
    reduced by ``kitti_resample_factor`` where its disparities are larger (module doc)."""
    c = pair.calib
    where = str(pair.sample_dir)
    if pair.shift_px:
        raise DatasetError(f"{where}: --shift {pair.shift_px} is not allowed with --format kitti: KITTI loaders take "
                           "Z = f B / d with equal principal points, which a shift breaks (the export resamples "
                           "instead; use --shift 0)")
    if not np.allclose(c.cam0, c.cam1, atol=tol.pixel, rtol=0):
        raise DatasetError(f"{where}: the cameras' intrinsics differ (doffs {c.doffs:g} px): KITTI's calibration "
                           "holds one K for both cameras and no disparity offset; export --format middlebury")
    d = np.where(pair.mask & np.isfinite(pair.disparity), pair.disparity.astype(np.float64), np.nan)
    known = d[np.isfinite(d)]
    if known.size and known.min() <= 0.5 / KITTI_SCALE:
        raise DatasetError(f"{where}: true disparities down to {known.min():.3f} px: KITTI's PNG holds only "
                           f"d > {0.5 / KITTI_SCALE:g} px (a plate this far away has no KITTI disparity)")
    k = kitti_resample_factor(float(known.max()) if known.size else 0.0)
    K = np.array(c.cam0, np.float64)
    if k == 1:
        return KittiPair(pair.left, pair.right, d, pair.nonocc & np.isfinite(d), K, c.baseline_mm * 1e-3, 1)
    H, W = pair.left.shape[0] // k, pair.left.shape[1] // k
    shrink = [cv2.resize(np.ascontiguousarray(im[:H * k, :W * k]), (W, H), interpolation=cv2.INTER_AREA)
              for im in (pair.left, pair.right)]
    blocks = _blocks(d, k)
    with np.errstate(invalid="ignore"):
        dk = np.where(np.all(np.isfinite(blocks), axis=2), blocks.mean(axis=2), np.nan) / k
    nonocc = np.all(_blocks(pair.nonocc, k), axis=2) & np.isfinite(dk)
    Kk = np.array([[K[0, 0] / k, 0.0, (K[0, 2] + 0.5) / k - 0.5], [0.0, K[1, 1] / k, (K[1, 2] + 0.5) / k - 0.5],
                   [0.0, 0.0, 1.0]])
    return KittiPair(shrink[0], shrink[1], dk, nonocc, Kk, c.baseline_mm * 1e-3, k)


def _kitti_disp(disp: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """KITTI's uint16 disparity PNG: round(256 d) where ``keep``, 0 elsewhere."""
    return np.where(keep & np.isfinite(disp), np.rint(np.nan_to_num(disp) * KITTI_SCALE), 0).astype(np.uint16)


def _kitti_calib(kp: KittiPair) -> str:
    """calib_cam_to_cam: both rectified cameras with one K; the right one's P[0, 3] = -f B (metres)."""
    h, w = kp.left.shape[:2]

    def P(tx):
        M = np.hstack([kp.K, [[tx], [0.0], [0.0]]])
        return " ".join(f"{v:.12e}" for v in M.ravel())
    return (f"S_rect_02: {w:.6e} {h:.6e}\nR_rect_02: 1 0 0 0 1 0 0 0 1\nP_rect_02: {P(0.0)}\n"
            f"S_rect_03: {w:.6e} {h:.6e}\nR_rect_03: 1 0 0 0 1 0 0 0 1\nP_rect_03: {P(-kp.K[0, 0] * kp.baseline_m)}\n")


def _write_kitti(root: Path, k: int, kp: KittiPair) -> None:
    name = f"{k:06d}_10.png"
    t = root / "training"
    write_png(t / "image_2" / name, kp.left)
    write_png(t / "image_3" / name, kp.right)
    write_png(t / "disp_occ_0" / name, _kitti_disp(kp.disparity, np.isfinite(kp.disparity)))
    write_png(t / "disp_noc_0" / name, _kitti_disp(kp.disparity, kp.nonocc))
    write_text(t / "calib_cam_to_cam" / f"{k:06d}.txt", _kitti_calib(kp))


def unrectified(sample_dir: Path) -> str | None:
    """Why a sample's image pair is no rectified pair (None when it is one): a pair a robot took
    (``gt/cameras.json``: the cameras really posed differ from the told rig) or a lens that distorts
    (calib.json's cameras). Both formats assume a rectified, undistorted pair, so Z = f B / (d + doffs)
    does not hold exactly for such a sample's true disparities."""
    if (Path(sample_dir) / "gt" / "cameras.json").is_file():
        return "taken by a robot: the cameras really posed are not the told rectified rig"
    try:
        cal = json.loads((Path(sample_dir) / "calib.json").read_text())
    except (OSError, ValueError):
        return None
    if any(isinstance(cal.get(c), dict) and cal[c].get("distortion_k1_k2_p1_p2_k3") for c in ("left", "right")):
        return "its lens distorts the images"
    return None


def export_dataset(root: Path, out: Path, fmt: str, *, images: str = IMAGES, shift: int | str = 0,
                   min_disparity_px: float = MIN_DISPARITY_PX, allow_incomplete: bool = False,
                   include_unrectified: bool = False, overwrite: bool = False, progress=None) -> ExportSummary:
    """Write every sample under ``root`` to ``out`` in ``fmt`` ("middlebury": ``OUT/trainingF/<scene>/``;
    "kitti": ``OUT/training/``), with ``OUT/export.json`` (module doc).

    ``images``: "active" (the projected grid, default) or "passive". ``shift``: Middlebury only, a
    whole number of px from 0 to ``max_shift_px`` or "auto"; ``min_disparity_px``: the smallest true
    disparity "auto" leaves. ``allow_incomplete``: export the samples an incomplete sweep dataset
    holds (else it is refused). ``include_unrectified``: also export the samples whose pair is no
    rectified pair (``unrectified``), marked in export.json; without it they are left out, and the
    summary's note says how many and why. ``progress(message)`` is told of each sample as it is written.
    Raises ``DatasetError`` (one line) for a request or a dataset that cannot be exported."""
    if fmt not in FORMATS:
        raise DatasetError(f"format {fmt!r} is not known: choose {' or '.join(FORMATS)}")
    if fmt == "kitti" and shift != 0:
        raise DatasetError(f"--shift {shift} is not allowed with --format kitti: KITTI loaders take Z = f B / d with "
                           "equal principal points, which a shift breaks; the KITTI export resamples the images "
                           "instead where the disparities exceed 256 px (leave --shift out)")
    check_output(out, "export", overwrite=overwrite, inputs=[root])
    ds = PlateBenchDataset(root, images=images, shift=shift, min_disparity_px=min_disparity_px)
    note, sweep = None, None
    done = sweep_completeness(ds)
    if done is not None and done[0] < done[1]:
        n, total, state = done
        if not allow_incomplete:
            raise DatasetError(f"{ds.root}: the sweep is {state} and holds {n} of its {total} samples rendered: finish "
                               "it (platebench sweep SPEC --out DATASET --resume), or export the samples it holds with "
                               "--allow-incomplete")
        note = f"{ds.root} is an incomplete sweep ({state}): exporting the {n} of its {total} samples it holds"
        sweep = {"state": state, "samples_total": total, "samples_exported": n}
    _check_files(ds)
    allowed = None
    if fmt == "middlebury":
        allowed, d_min, where = max_shift_px(ds)
        if shift != "auto" and shift > max(allowed, 0):
            _refuse_shift(ds, int(shift), allowed, d_min, where)
    names = [scene_name(ds.sample_id(k)) for k in range(len(ds))]
    if fmt == "middlebury" and len(set(names)) < len(names):
        a = next(k for k in range(len(names)) if names.count(names[k]) > 1)
        b = next(k for k in range(a + 1, len(names)) if names[k] == names[a])
        raise DatasetError(f"{ds.sample_dirs[a]} and {ds.sample_dirs[b]} both give the Middlebury scene name "
                           f"{names[a]!r}: rename one of the folders")
    say = progress or (lambda msg: None)
    why = {k: unrectified(ds.sample_dirs[k]) for k in range(len(ds))}
    left_out = [k for k in range(len(ds)) if why[k] and not include_unrectified]
    if left_out:
        reasons = sorted({why[k] for k in left_out})
        note = ((note + "; ") if note else "") + (
            f"{len(left_out)} of the {len(ds)} samples are left out: their pair is no rectified pair ("
            + "; ".join(reasons) + "), which the format assumes; --include-unrectified exports them, marked")
    rows = []
    with output_dir(out, "export", overwrite=overwrite, inputs=[root]) as d:
        for k in range(len(ds)):
            if k in left_out:
                continue
            pair = ds[k]
            say(f"{pair.sample_id} ({k + 1}/{len(ds)})")
            if not np.isfinite(pair.disparity).any():
                raise DatasetError(f"{pair.sample_dir}: no plate pixel with a true disparity in the exported view")
            if fmt == "middlebury":
                folder = f"{MIDDLEBURY_TREE}/{names[k]}"
                _write_middlebury(d / folder, pair)
                rows.append(ExportedSample(id=pair.sample_id, files=folder, source=str(pair.sample_dir.resolve()),
                                           shift_px=pair.shift_px, doffs_px=pair.calib.doffs, vmin=pair.calib.vmin,
                                           vmax=pair.calib.vmax, width=pair.calib.width, height=pair.calib.height,
                                           unrectified=why[k]))
            else:
                kp = kitti_pair(pair)
                n = len(rows)  # KITTI numbers the exported pairs 000000, 000001, ... without gaps
                _write_kitti(d, n, kp)
                known = kp.disparity[np.isfinite(kp.disparity)]
                rows.append(ExportedSample(
                    id=pair.sample_id, files=f"training/*/{n:06d}_10.png", source=str(pair.sample_dir.resolve()),
                    shift_px=0, doffs_px=0.0, resample_factor=kp.factor,
                    resampled=(f"images reduced {kp.factor}x (area average of {kp.factor}x{kp.factor} "
                               f"pixel blocks) so that the true disparities, "
                               f"{pair.calib.vmin} to {pair.calib.vmax} px as rendered, fit KITTI's "
                               f"d < {KITTI_MAX_DISPARITY_PX:.2f} px") if kp.factor > 1 else None,
                    f_px=float(kp.K[0, 0]), baseline_m=kp.baseline_m,
                    vmin=math.floor(known.min()) if known.size else 0,
                    vmax=math.ceil(known.max()) if known.size else 0,
                    width=int(kp.left.shape[1]), height=int(kp.left.shape[0]), unrectified=why[k]))
        doc = {"format": fmt, "images": images, "shift": shift, "min_disparity_px": min_disparity_px}
        if fmt == "middlebury":
            doc.update(tree=f"{MIDDLEBURY_TREE}/<scene>", max_shift_px=max(allowed, 0))
        if sweep is not None:
            doc["sweep"] = sweep
        if left_out:
            doc["left_out_unrectified"] = [ds.sample_id(k) for k in left_out]
        doc.update(samples=[r.to_dict() for r in rows],
                   units="px; baseline in calib.txt in mm (Middlebury), in P_rect_03 in m (KITTI)",
                   depth=_DEPTH_RULE[fmt])
        write_json(d / "export.json", doc)
    return ExportSummary(Path(out), fmt, tuple(rows), images, max(allowed, 0) if allowed is not None else None, note)
