"""Peer method: phase shifting with Gray-code unwrapping, between the two cameras.

Sequence (``phase_shift_sequence``): ``steps`` sinusoidal fringe frames along the
projector columns, period ``period_px`` projector pixels, then the ``n_gray`` most
significant column planes of OpenCV's Gray code (pattern frames only, no inverses),
which number blocks of ``period_px / 2`` columns. Per camera pixel:

* wrapped phase: N-step phase shifting with numpy (default ``backend="numpy"``:
  I_n = A + B cos(phi - 2 pi n / N), phi = atan2(sum I_n sin, sum I_n cos)), or
  OpenCV's ``SinusoidalPattern.computePhaseMap`` (``backend="opencv"``: its own
  three PSP frames, sin fringes shifted by 2 pi / 3, wrapped phase after its
  Fourier band-pass filtering);
* order: the Gray-code block (bit = frame > A, the fringe mean), unwrapping
  ``col = col_wrapped + P * round((col_gray_centre - col_wrapped) / P)`` (a Gray
  decoding error at a block edge moves the estimate by half a period at most, so
  the order stays right);
* valid where the fringe modulation B exceeds ``min_modulation`` DN.

The continuous projector column of each left pixel is then found on the same row of
the right image by linear interpolation between neighbouring right pixels
(``peer_graycode.match_columns_along_rows``), giving a sub-pixel disparity.

What OpenCV 5.0's ``cv2.structured_light.SinusoidalPattern`` does from Python
(``OPENCV_FINDINGS``; ``tests/test_peers.py`` checks that they hold):

* ``generate`` works (3 frames for PSP/FAPS/FTP; sin fringes; period = width // nbrOfPeriods).
* ``computePhaseMap`` works (returns the wrapped phase and a shadow mask) for PSP, FTP
  and FAPS; PSP's phase equals 2 pi x / period - pi / 2 on full-field fringes.
* ``unwrapPhaseMap`` runs but is spatial (histogram-guided) unwrapping: the result has
  an arbitrary 2 pi k offset per connected region and per camera, so two cameras'
  maps cannot be matched; absolute phase would need the markers, whose conversion
  (``convertToAbsolutePhaseMap``) is not exposed.
* ``findProCamMatches`` returns an empty tuple from Python.
* ``decode`` is a stub in C++: it returns True and leaves the disparity map empty
  (``None`` in Python).

Hence the unwrapping (Gray code) and the matching are numpy; only the wrapped phase
can come from OpenCV. Pure function of images + calibration (no renderer, no ground truth).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import cv2
import numpy as np

from platebench.reconstruction.methods import Disparity, MethodInputs, Projection, register_method
from platebench.reconstruction.peers.graycode import (
    DenseResult,
    as_disparity,
    consistent_columns,
    dense_result,
    graycode_sequence,
    match_columns_along_rows,
    profile_from_column_map,
)
from platebench.scenes.rig import StereoRig

__all__ = ["OPENCV_FINDINGS", "PhaseShiftSequence", "phase_shift_sequence", "decode_phase_columns",
           "decode_phase_shift", "BACKENDS", "phase_numpy",
           "phase_opencv"]

BACKENDS = ("numpy", "opencv")

OPENCV_FINDINGS = (
    "OpenCV SinusoidalPattern (5.0, Python): generate and computePhaseMap work; unwrapPhaseMap is spatial "
    "(relative phase, arbitrary 2*pi*k offset per region and camera, unusable for matching two cameras); "
    "findProCamMatches returns an empty tuple; decode is a C++ stub (returns True, no disparity map). "
    "Unwrapping (Gray code) and matching are done with numpy.",
)


@dataclass(frozen=True)
class PhaseShiftSequence:
    """Projector frames (uint8, (N, Hp, Wp)): ``steps`` fringes, then ``n_gray`` Gray-code planes (MSB first)."""

    images: np.ndarray
    steps: int
    period_px: int
    n_gray: int
    backend: str
    phase_offset_rad: float  # wrapped phase at projector column 0 (OpenCV backend: measured on its own frames)
    proj_width: int
    proj_height: int

    @property
    def n_images(self) -> int:
        return int(self.images.shape[0])

    @property
    def block_px(self) -> int:
        return self.period_px // 2


def _opencv_params(width, height, period_px):
    sl = cv2.structured_light
    p = sl.SinusoidalPattern.Params()
    p.width, p.height = int(width), int(height)
    p.nbrOfPeriods = int(width // period_px)
    p.methodId = sl.PSP
    p.horizontal = False
    p.setMarkers = False
    return p


def phase_shift_sequence(proj_width: int = 1024, proj_height: int = 768, period_px: int = 16, steps: int = 4,
                         backend: str = "numpy") -> PhaseShiftSequence:
    """Fringe + Gray-code frames for a projector of the given size."""
    if backend not in BACKENDS:
        raise ValueError(f"backend = {backend!r} is not allowed: choose one of {BACKENDS}")
    if period_px < 4 or period_px & (period_px - 1) or proj_width % period_px:
        raise ValueError(f"period_px = {period_px} is out of range: allowed a power of two >= 4 dividing "
                         f"the projector width {proj_width}")
    gseq = graycode_sequence(proj_width, proj_height)
    n_all = len(gseq.col_pairs)
    n_gray = n_all - int(math.log2(period_px // 2))
    gray = [gseq.images[gseq.col_pairs[i][0]] for i in range(n_gray)]
    j = np.arange(proj_width, dtype=np.float64)
    if backend == "numpy":
        if steps < 3:
            raise ValueError(f"steps = {steps} is out of range: allowed >= 3")
        fr = [0.5 + 0.5 * np.cos(2 * np.pi * j / period_px - 2 * np.pi * n / steps) for n in range(steps)]
        fringes = [np.tile(np.clip(np.rint(f * 255), 0, 255).astype(np.uint8), (proj_height, 1)) for f in fr]
        offset = 0.0
    else:
        sp = cv2.structured_light.SinusoidalPattern.create(_opencv_params(proj_width, proj_height, period_px))
        ok, pats = sp.generate()
        if not ok:
            raise RuntimeError("cv2.structured_light.SinusoidalPattern.generate failed")
        fringes = [np.asarray(p, np.uint8) for p in pats]
        steps = len(fringes)
        # Phase offset of OpenCV's PSP on its own frames (projector = camera): calibrates the convention.
        crop = [np.ascontiguousarray(f[: min(proj_height, 128)]) for f in fringes]
        wrapped, _ = sp.computePhaseMap(crop)
        row = np.asarray(wrapped, np.float64)[len(crop[0]) // 2, 64:-64]
        ref = 2 * np.pi * j[64:proj_width - 64] / period_px
        offset = float(np.angle(np.mean(np.exp(1j * (row - ref)))))
    images = np.stack(fringes + gray).astype(np.uint8)
    images.setflags(write=False)
    return PhaseShiftSequence(images, steps, period_px, n_gray, backend, offset, proj_width, proj_height)


def _wrapped_numpy(fr: np.ndarray, steps: int):
    n = np.arange(steps, dtype=np.float64)[:, None, None]
    S = np.sum(fr * np.sin(2 * np.pi * n / steps), axis=0)
    C = np.sum(fr * np.cos(2 * np.pi * n / steps), axis=0)
    phi = np.arctan2(S, C)
    B = 2.0 / steps * np.hypot(S, C)
    return phi, B


def _wrapped_opencv(fr: np.ndarray, seq: PhaseShiftSequence):
    sp = cv2.structured_light.SinusoidalPattern.create(_opencv_params(seq.proj_width, seq.proj_height, seq.period_px))
    imgs = [np.ascontiguousarray(f.astype(np.uint8)) for f in fr]
    try:
        wrapped, _ = sp.computePhaseMap(imgs)
    except cv2.error as e:
        line = next((x for x in str(e).strip().splitlines() if "error:" in x), str(e).strip()[:200])
        raise ValueError(f"OpenCV's SinusoidalPattern.computePhaseMap refused the {imgs[0].shape[1]}x"
                         f"{imgs[0].shape[0]} fringe captures ({line.strip()})") from None
    return np.asarray(wrapped, np.float64)


def decode_phase_columns(stack, seq: PhaseShiftSequence, min_modulation: float = 8.0):
    """Continuous projector column per pixel of one camera, (H, W) float64, NaN where invalid.

    Also returns the modulation B (DN) of the fringes.
    """
    s = np.asarray(stack)
    if s.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"phase decoding needs integer camera images (uint8/uint16), got {s.dtype}")
    if s.ndim != 3 or s.shape[0] != seq.n_images:
        raise ValueError(f"expected ({seq.n_images}, H, W) captures of the sequence, got {s.shape}")
    fr = s[:seq.steps].astype(np.float64)
    A = fr.mean(axis=0)
    phi, B = _wrapped_numpy(fr, seq.steps)  # B (modulation) is valid for any equal-step sequence
    if seq.backend == "opencv":
        phi = _wrapped_opencv(fr, seq)
    P = float(seq.period_px)
    col_w = np.mod((phi - seq.phase_offset_rad) / (2 * np.pi) * P, P)
    bits = s[seq.steps:].astype(np.float64) > A[None]
    binary = np.bitwise_xor.accumulate(bits, axis=0)
    weights = (1 << np.arange(seq.n_gray - 1, -1, -1)).astype(np.int64)
    code = np.tensordot(weights, binary.astype(np.int64), axes=(0, 0))
    h = seq.block_px
    centre = code * h + (h - 1) / 2.0
    col = col_w + P * np.round((centre - col_w) / P)
    valid = B > min_modulation
    return np.where(valid, col, np.nan), B


def decode_phase_shift(left, right, seq: PhaseShiftSequence, rig: StereoRig, min_modulation: float = 8.0,
                       max_step: float | None = None) -> DenseResult:
    """Phase-shift stereo (see module doc) -> left disparity as a ``DenseResult``.

    ``max_step``: largest projector-column difference between two neighbouring right
    pixels that may be interpolated across (default: half a period, which rejects
    unwrapping errors of a whole period).
    """
    t0 = time.perf_counter()
    col_l, _ = decode_phase_columns(left, seq, min_modulation)
    col_r, _ = decode_phase_columns(right, seq, min_modulation)
    t_dec = time.perf_counter()
    step = seq.period_px / 2.0 if max_step is None else float(max_step)
    col_l = consistent_columns(col_l, step)
    u_right = match_columns_along_rows(col_l, profile_from_column_map(col_r), max_step=step)
    disp = np.arange(col_l.shape[1])[None, :] - u_right
    t_match = time.perf_counter()
    notes = [f"{seq.steps}-step phase shifting ({seq.backend} wrapped phase), period {seq.period_px} projector px, "
             f"{seq.n_gray} Gray-code planes for the order", OPENCV_FINDINGS[0]]
    res = dense_result(f"phase-{seq.backend}" if seq.backend != "numpy" else "phase", disp, rig, seq.n_images,
                       {}, notes)
    return replace(res, timings={"decode_s": t_dec - t0, "match_s": t_match - t_dec,
                                 "total_s": time.perf_counter() - t0})


# ----------------------------------------------------------------------------- registered methods
@register_method("phase", "4-step phase shifting + Gray-code unwrapping (numpy)", "disparity",
                 sequence=Projection("phase", lambda w, h: phase_shift_sequence(w, h, backend="numpy")), default=True)
def phase_numpy(inputs: MethodInputs) -> Disparity:
    """Phase shifting, numpy wrapped phase (``decode_phase_shift``)."""
    return as_disparity(decode_phase_shift(inputs.captures["left"], inputs.captures["right"], inputs.sequence,
                                           inputs.rig))


@register_method("phase-opencv", "3-step phase shifting, OpenCV SinusoidalPattern wrapped phase + Gray-code "
                 "unwrapping", "disparity",
                 sequence=Projection("phase-opencv", lambda w, h: phase_shift_sequence(w, h, backend="opencv")))
def phase_opencv(inputs: MethodInputs) -> Disparity:
    """Phase shifting, OpenCV's wrapped phase (``decode_phase_shift``)."""
    return as_disparity(decode_phase_shift(inputs.captures["left"], inputs.captures["right"], inputs.sequence,
                                           inputs.rig))
