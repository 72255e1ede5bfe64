"""Middlebury stereo ``calib.txt``: written for every sample and every exported pair, and read back.

The format (Middlebury 2014 / v3)::

    cam0=[f 0 cx0; 0 f cy; 0 0 1]     left intrinsics, px
    cam1=[f 0 cx1; 0 f cy; 0 0 1]     right intrinsics, px
    doffs=cx1-cx0                     x-difference of the principal points, px
    baseline=B                        camera baseline, MILLIMETRES
    width=W  height=H                 image size, px
    ndisp=N                           conservative bound on the disparity levels: a matcher may search
                                      d = 0 .. N-1. Here vmax + 1 rounded up to a multiple of 16 (what
                                      OpenCV's block matchers take)
    isint=0                           disparities are not integers
    vmin=a  vmax=b                    tight bounds of the true disparities: floor(min d), ceil(max d)
                                      over the pixels with known truth
    dyavg=y  dymax=y                  mean and largest |v_right - v_left| of those pixels (px): the
                                      residual vertical disparity of the rectification (0 for the
                                      bench's rigs, whose cameras share fy and cy)

Depth from a disparity d (px): Z = baseline * f / (d + doffs), in the baseline's unit (mm here).
Everything is computed from the rig and the true disparity map (``evaluation.stereo_truth``), so
the sample writer and the exporter (``bench.io.export``) write the same figures for the same pair.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from platebench.bench.files import JSON_MAX_BYTES, read_capped
from platebench.bench.io.atomic import write_text
from platebench.bench.io.images import DatasetError
from platebench.evaluation.stereo_truth import (
    NDISP_MULTIPLE,
    RectifiedPair,
    ndisp_for,
    rectified_pair,
    vertical_disparity,
)
from platebench.scenes.rig import StereoRig

__all__ = ["MiddleburyCalib", "calib_txt", "read_calib", "write_calib", "NDISP_MULTIPLE"]



@dataclass(frozen=True)
class MiddleburyCalib:
    """The fields of a Middlebury ``calib.txt`` (px; ``baseline_mm`` in millimetres, as the format)."""

    cam0: np.ndarray
    cam1: np.ndarray
    doffs: float
    baseline_mm: float
    width: int
    height: int
    ndisp: int
    vmin: int
    vmax: int
    dyavg: float
    dymax: float
    isint: int = 0

    @property
    def f_px(self) -> float:
        return float(self.cam0[0, 0])

    def depth_m(self, disparity) -> np.ndarray:
        """z-depth in metres of disparities (px): baseline * f / (d + doffs); NaN where d + doffs <= 0 or
        d is not finite."""
        d = np.asarray(disparity, np.float64) + self.doffs
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(np.isfinite(d) & (d > 0), self.baseline_mm * 1e-3 * self.f_px / d, np.nan)

    def to_text(self) -> str:
        def mat(K):
            return "[" + "; ".join(" ".join(f"{v:.12g}" for v in row) for row in np.asarray(K)) + "]"
        return (f"cam0={mat(self.cam0)}\ncam1={mat(self.cam1)}\ndoffs={self.doffs:.12g}\n"
                f"baseline={self.baseline_mm:.12g}\nwidth={self.width}\nheight={self.height}\nndisp={self.ndisp}\n"
                f"isint={self.isint}\nvmin={self.vmin}\nvmax={self.vmax}\ndyavg={self.dyavg:.6g}\n"
                f"dymax={self.dymax:.6g}\n")

    @classmethod
    def for_pair(cls, pair: RectifiedPair, disparity, *, x0_left: int = 0, x0_right: int = 0, y0: int = 0,
                 width: int | None = None, height: int | None = None) -> "MiddleburyCalib":
        """Calibration of a pair's images cropped at columns x0_left (left) / x0_right (right) and row y0
        (``width`` x ``height``; default the whole image), given the TRUE disparity of the cropped left
        view (px, inf unknown; vmin = vmax = 0 when none is known). The crop moves the principal
        points, and ``doffs`` with them."""
        d = np.asarray(disparity, np.float64)
        known = d[np.isfinite(d)]
        vmin, vmax = (math.floor(known.min()), math.ceil(known.max())) if known.size else (0, 0)
        dy = vertical_disparity(d, pair) if known.size else np.zeros(1)
        cam0 = np.array([[pair.f_px, 0, pair.cx_left - x0_left], [0, pair.fy_left, pair.cy_left - y0], [0, 0, 1]])
        cam1 = np.array([[pair.f_px, 0, pair.cx_right - x0_right], [0, pair.fy_right, pair.cy_right - y0],
                         [0, 0, 1]])
        ndisp = ndisp_for(d)
        return cls(cam0, cam1, float(cam1[0, 2] - cam0[0, 2]), pair.baseline_m * 1e3,
                   int(width if width is not None else pair.width), int(height if height is not None else pair.height),
                   ndisp, vmin, vmax, float(dy.mean()), float(dy.max()))


def calib_txt(rig: StereoRig, disparity) -> str:
    """The ``calib.txt`` text of a whole (uncropped) sample pair with true left disparity ``disparity``."""
    return MiddleburyCalib.for_pair(rectified_pair(rig), disparity).to_text()


def write_calib(path: Path, calib: MiddleburyCalib) -> None:
    write_text(Path(path), calib.to_text())


_NUM = r"[-+0-9.eE]+"


def read_calib(path: Path) -> MiddleburyCalib:
    """Parse a Middlebury ``calib.txt`` (ours or the benchmark's; dyavg/dymax default to 0)."""
    path = Path(path)
    text = read_capped(path, JSON_MAX_BYTES, "Middlebury calib.txt", DatasetError, missing="file is missing")
    fields = {}
    for line in text.decode("utf-8", "replace").splitlines():
        if "=" in line:
            k, _, v = line.partition("=")
            fields[k.strip()] = v.strip()
    try:
        def mat(text):
            rows = [[float(x) for x in re.findall(_NUM, r)] for r in text.strip("[]").split(";")]
            K = np.array(rows, np.float64)
            if K.shape != (3, 3):
                raise ValueError(f"a 3x3 matrix, got {K.shape}")
            return K
        return MiddleburyCalib(mat(fields["cam0"]), mat(fields["cam1"]), float(fields.get("doffs", 0.0)),
                               float(fields["baseline"]), int(fields["width"]), int(fields["height"]),
                               int(fields["ndisp"]), int(float(fields.get("vmin", 0))),
                               int(float(fields.get("vmax", 0))), float(fields.get("dyavg", 0.0)),
                               float(fields.get("dymax", 0.0)), int(fields.get("isint", 0)))
    except (KeyError, ValueError) as e:
        raise DatasetError(f"{path}: not a Middlebury calib.txt ({type(e).__name__}: {e})") from None
