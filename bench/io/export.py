"""Export a PlateBench dataset to the layouts stereo code reads: Middlebury (v3 / 2014) and KITTI 2015.

Each sample is read as a ``PlateBenchDataset`` item (``bench.io.dataset_reader``: passive or active
images, optional shift so disparities fall where learned stereo works) and written as:

Middlebury (``--format middlebury``), one folder per sample ``OUT/<sample id>/``::

    im0.png, im1.png     left / right image (the camera's 8- or 16-bit grey DN)
    disp0GT.pfm          left true disparity, float32 px, +inf unknown (Middlebury PFM, rows bottom-up)
    disp1GT.pfm          right true disparity (its pixel u matches the left u + d)
    mask0nocc.png        255 = seen by both cameras, 128 = occluded in the right view, 0 = unknown
    calib.txt            cam0, cam1, doffs (shift included), baseline (mm), width, height, ndisp,
                         isint, tight vmin/vmax, dyavg/dymax (``bench.io.middlebury``)

KITTI 2015 (``--format kitti``), ``OUT/training/``::

    image_2/NNNNNN_10.png, image_3/NNNNNN_10.png        left / right image
    disp_occ_0/NNNNNN_10.png, disp_noc_0/NNNNNN_10.png  uint16 = round(256 d), 0 = unknown; all / non-occluded
    calib_cam_to_cam/NNNNNN.txt                          P_rect_02, P_rect_03 (3 x 4; baseline in metres
                                                         in P_rect_03[0, 3] = -f B; the shift in the
                                                         principal points) and the Middlebury doffs
    KITTI's 16-bit disparities hold 0 < d < 256 px: a larger true disparity is refused (use --shift auto).

``OUT/export.json`` lists every exported sample with its source directory and shift. The output
follows the output rule (``bench.io.outputs``: never the dataset itself nor inside it; an existing
``OUT`` is replaced only with ``overwrite`` and only when it is an export), is staged and renamed
into place: it appears complete or not at all. Every sample is checked against its recorded
checksums (``PlateBenchDataset.check``) before the first is written or ``progress`` is told.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from platebench.bench.io.atomic import write_json, write_text
from platebench.bench.io.dataset_reader import MIN_DISPARITY_PX, PlateBenchDataset, StereoPair
from platebench.bench.io.images import DatasetError, write_pfm, write_png
from platebench.bench.io.middlebury import write_calib
from platebench.bench.io.outputs import check_output, output_dir

__all__ = ["FORMATS", "ExportSummary", "export_dataset", "KITTI_SCALE", "nocc_mask_png"]

FORMATS = ("middlebury", "kitti")
KITTI_SCALE = 256.0  # KITTI's disparity PNG: uint16 value = 256 d


@dataclass(frozen=True)
class ExportSummary:
    out: Path
    format: str
    samples: tuple  # ({"id", "source", "shift_px", "vmin", "vmax"}, ...)


def nocc_mask_png(pair: StereoPair) -> np.ndarray:
    """Middlebury's mask0nocc: 255 non-occluded, 128 occluded (truth known), 0 unknown."""
    return np.where(pair.nonocc, 255, np.where(pair.mask, 128, 0)).astype(np.uint8)


def _write_middlebury(d: Path, pair: StereoPair) -> None:
    d.mkdir(parents=True)
    write_png(d / "im0.png", pair.left)
    write_png(d / "im1.png", pair.right)
    write_pfm(d / "disp0GT.pfm", pair.disparity)
    write_pfm(d / "disp1GT.pfm", pair.disparity_right)
    write_png(d / "mask0nocc.png", nocc_mask_png(pair))
    write_calib(d / "calib.txt", pair.calib)


def _kitti_disp(disp: np.ndarray, keep: np.ndarray, where: str) -> np.ndarray:
    d = np.where(keep & np.isfinite(disp), disp.astype(np.float64), np.nan)
    known = d[np.isfinite(d)]
    if known.size and (known.max() >= 65535 / KITTI_SCALE or known.min() <= 0.5 / KITTI_SCALE):
        raise DatasetError(f"{where}: true disparities {known.min():.2f} to {known.max():.2f} px do not fit KITTI's "
                           f"16-bit PNG (0 < d < {65535 / KITTI_SCALE:.2f}): export with --shift auto")
    return np.where(np.isfinite(d), np.rint(np.nan_to_num(d) * KITTI_SCALE), 0).astype(np.uint16)


def _kitti_calib(pair: StereoPair) -> str:
    c = pair.calib
    b_m = c.baseline_mm * 1e-3

    def P(K, tx):
        M = np.hstack([K, [[tx], [0.0], [0.0]]])
        return " ".join(f"{v:.12e}" for v in M.ravel())
    K0, K1 = c.cam0, c.cam1
    return (f"S_rect_02: {c.width:.6e} {c.height:.6e}\nR_rect_02: 1 0 0 0 1 0 0 0 1\nP_rect_02: {P(K0, 0.0)}\n"
            f"S_rect_03: {c.width:.6e} {c.height:.6e}\nR_rect_03: 1 0 0 0 1 0 0 0 1\n"
            f"P_rect_03: {P(K1, -K1[0, 0] * b_m)}\ndoffs: {c.doffs:.12g}\n")


def _write_kitti(root: Path, k: int, pair: StereoPair) -> None:
    name = f"{k:06d}_10.png"
    t = root / "training"
    write_png(t / "image_2" / name, pair.left)
    write_png(t / "image_3" / name, pair.right)
    write_png(t / "disp_occ_0" / name, _kitti_disp(pair.disparity, pair.mask, str(pair.sample_dir)))
    write_png(t / "disp_noc_0" / name, _kitti_disp(pair.disparity, pair.nonocc, str(pair.sample_dir)))
    write_text(t / "calib_cam_to_cam" / f"{k:06d}.txt", _kitti_calib(pair))


def export_dataset(root: Path, out: Path, fmt: str, *, images: str = "passive", shift: int | str = 0,
                   min_disparity_px: float = MIN_DISPARITY_PX, overwrite: bool = False,
                   progress=None) -> ExportSummary:
    """Write every sample under ``root`` to ``out`` in ``fmt`` ("middlebury" or "kitti"; module doc)."""
    if fmt not in FORMATS:
        raise DatasetError(f"format {fmt!r} is not known: choose {' or '.join(FORMATS)}")
    check_output(out, "export", overwrite=overwrite, inputs=[root])
    ds = PlateBenchDataset(root, images=images, shift=shift, min_disparity_px=min_disparity_px)
    ds.check()
    say = progress or (lambda msg: None)
    rows = []
    with output_dir(out, "export", overwrite=overwrite, inputs=[root]) as d:
        for k in range(len(ds)):
            pair = ds[k]
            say(f"{pair.sample_id} ({k + 1}/{len(ds)})")
            if not np.isfinite(pair.disparity).any():
                raise DatasetError(f"{pair.sample_dir}: no plate pixel with a true disparity in the exported view")
            if fmt == "middlebury":
                _write_middlebury(d / pair.sample_id, pair)
                where = pair.sample_id
            else:
                _write_kitti(d, k, pair)
                where = f"training/*/{k:06d}_10.png"
            rows.append({"id": pair.sample_id, "files": where, "source": str(pair.sample_dir.resolve()),
                         "shift_px": pair.shift_px, "doffs_px": pair.calib.doffs, "vmin": pair.calib.vmin,
                         "vmax": pair.calib.vmax, "width": pair.calib.width, "height": pair.calib.height})
        write_json(d / "export.json", {"format": fmt, "images": images, "shift": shift,
                                       "min_disparity_px": min_disparity_px, "samples": rows,
                                       "units": "px; baseline in calib.txt in mm (Middlebury), in P_rect_03 in m "
                                                "(KITTI)"})
    return ExportSummary(Path(out), fmt, tuple(rows))
