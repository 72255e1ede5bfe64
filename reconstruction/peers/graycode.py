"""Peer method: Gray-code structured light between the two cameras (OpenCV structured_light).

The projector shows OpenCV's ``GrayCodePattern`` sequence (``graycode_sequence``):
for a 1024 x 768 projector, 10 column bit planes and 10 row bit planes, each as a
pattern and its inverse, most significant plane first, then an all-black and an
all-white frame: 42 images. Both cameras capture every frame (8-bit).

Two ways to turn the captures into a left disparity map (conventional geometry,
rows already rectified, ``d = u_left - u_right = f B / Z``):

* ``decode_opencv``: ``GrayCodePattern.decode`` as OpenCV ships it. In OpenCV 5.0 it
  decodes (column, row) of every camera pixel, groups each camera's pixels by the
  projector pixel they see, and writes at every first-camera pixel
  ``mean x(second camera) - mean x(first camera)`` of its projector pixel's group
  (0 = no match; whole or half pixels; no row constraint). It needs all 42 images.
  Pitfalls handled here: without the black/white images it segfaults; float
  images silently match nothing (8-bit only); ``getImagesForShadowMasks`` needs
  two placeholder arrays; thresholds are fixed DN counts (white - black > 40,
  |pattern - inverse| >= 5 on every plane).
* ``decode_subpixel``: the column planes only (2 x 10 + black + white = 22 images).
  Each camera's projector column is decoded from the bit planes with numpy (same
  rule as OpenCV's ``getProjPixel``: bit = pattern > inverse, Gray -> binary,
  shadow mask from white - black). Bit planes whose stripes the camera cannot
  resolve (median |pattern - inverse| below ``min_plane_contrast`` of white - black)
  are dropped, so the code counts blocks of 2^m columns. The decoded code is then
  made continuous along each row: between two neighbouring pixels whose codes
  differ, the stripe edge that separates them (a known projector column boundary)
  is located to sub-pixel precision from pattern - inverse (D) of the bit plane
  that flips there. Column as a function of u is piecewise linear through these
  edge "knots". For each left pixel, its column is read at the pixel centre, and
  the right image's row is searched for the sub-pixel position with the same
  column (linear interpolation between neighbouring right knots).
  ``edge_model``: "area" (default) assumes box pixels and a sharp edge, so the
  straddled pixel's D = A (2 f - 1) with A = white - black gives the covered
  fraction f (exact for the renderer's box filter; half the error of "linear" at
  320 x 240); "linear" is the classic zero crossing of D interpolated between the
  two pixel centres (better with optical blur); "midpoint" puts the edge halfway
  (code-only interpolation, for comparison). Unlike OpenCV, a weak plane does not
  invalidate a pixel by default (``white_threshold=0``): at a stripe edge the Gray
  code can only be off by one code, which the knots absorb.

Pure function of the images and the calibration (no renderer, no ground truth).
Units: pixels for images and disparity, metres for points (world frame).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from platebench.reconstruction.methods import Disparity, MethodInputs, Projection, register_method
from platebench.scenes.camera import triangulate_rectified
from platebench.scenes.rig import StereoRig

__all__ = ["DenseResult", "GrayCodeSequence", "ColumnDecode", "RowProfile", "graycode_sequence",
           "decode_columns", "decode_opencv", "decode_subpixel", "dense_result", "profile_from_column_map",
           "match_columns_along_rows", "consistent_columns", "column_knots", "column_map_from_knots", "as_disparity",
           "graycode_opencv", "graycode_subpixel"]


EDGE_MODELS = ("area", "linear", "midpoint")


# ----------------------------------------------------------------------------- result type
@dataclass(frozen=True)
class DenseResult:
    """A dense left-camera reconstruction of a conventional stereo pair.

    disparity: (H, W) float32, px, d = u_left - u_right; NaN where there is no estimate.
    depth: (H, W) float32 z-depth in the left camera, metres (f B / d); NaN where none.
    points: (N, 3) float64 world points, metres, one per ``valid`` pixel in row-major order.
    valid: (H, W) bool, True where the method gives an estimate.
    n_images: exposures each camera captures for this method (projector frames; 1 for the passive pair).
    timings: stage name -> seconds.
    notes: human-readable remarks (what was dropped, what failed in OpenCV, ...).
    """

    method: str
    disparity: np.ndarray
    depth: np.ndarray
    points: np.ndarray
    valid: np.ndarray
    n_images: int
    timings: dict = field(default_factory=dict)
    notes: tuple = ()

    @property
    def coverage_px(self) -> int:
        return int(np.count_nonzero(self.valid))


def dense_result(method: str, disparity: np.ndarray, rig: StereoRig, n_images: int, timings: dict,
                 notes=()) -> DenseResult:
    """Wrap a left disparity map (NaN/inf/<= 0 = none) as a ``DenseResult`` (triangulates the points)."""
    d = np.asarray(disparity, np.float64)
    valid = np.isfinite(d) & (d > 0)
    disp = np.where(valid, d, np.nan).astype(np.float32)
    v, u = np.nonzero(valid)
    dv = d[valid]
    pts = triangulate_rectified(u, v, u - dv, rig.left, rig.baseline_m)
    depth = np.full(d.shape, np.nan, np.float32)
    depth[valid] = rig.left.f_px * rig.baseline_m / dv
    for a in (disp, depth, valid, pts):
        a.setflags(write=False)
    return DenseResult(method, disp, depth, pts, valid, int(n_images), dict(timings), tuple(notes))


# ----------------------------------------------------------------------------- patterns
@dataclass(frozen=True)
class GrayCodeSequence:
    """OpenCV's Gray-code frames (uint8, (N, Hp, Wp)) and where each plane sits in the sequence.

    ``col_pairs[i]`` / ``row_pairs[i]`` = (pattern index, inverse index) of bit plane i,
    most significant first. ``black`` / ``white``: indices of the shadow-mask frames.
    """

    images: np.ndarray
    col_pairs: tuple
    row_pairs: tuple
    black: int
    white: int
    proj_width: int
    proj_height: int

    @property
    def n_images(self) -> int:
        return int(self.images.shape[0])

    @property
    def n_col_planes(self) -> int:
        return len(self.col_pairs)

    def columns_only(self) -> "GrayCodeSequence":
        """The 2 * n_col + 2 frames the sub-pixel decoder needs (column planes, black, white)."""
        idx = [i for p in self.col_pairs for i in p] + [self.black, self.white]
        n = len(self.col_pairs)
        return GrayCodeSequence(self.images[idx], tuple((2 * i, 2 * i + 1) for i in range(n)), (),
                                2 * n, 2 * n + 1, self.proj_width, self.proj_height)


def _gray(img: np.ndarray) -> np.ndarray:
    img = np.asarray(img)
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img


def _opencv_pattern(width: int, height: int):
    sl = cv2.structured_light
    return sl.GrayCodePattern.create(int(width), int(height))


def graycode_sequence(proj_width: int = 1024, proj_height: int = 768) -> GrayCodeSequence:
    """OpenCV ``GrayCodePattern`` frames for a projector of the given size, plus black and white."""
    if proj_width < 2 or proj_height < 2:
        raise ValueError(f"projector size {proj_width}x{proj_height} is out of range: allowed >= 2 px")
    gp = _opencv_pattern(proj_width, proj_height)
    ok, pats = gp.generate()
    if not ok:
        raise RuntimeError("cv2.structured_light.GrayCodePattern.generate failed")
    # Two placeholder arrays are required from Python (the C++ API writes into them).
    black, white = gp.getImagesForShadowMasks(np.zeros((1, 1), np.uint8), np.zeros((1, 1), np.uint8))
    frames = [_gray(p) for p in pats] + [_gray(black), _gray(white)]
    images = np.stack(frames).astype(np.uint8)
    n_col = int(math.ceil(math.log2(proj_width)))
    n_row = int(math.ceil(math.log2(proj_height)))
    if len(pats) != 2 * (n_col + n_row):
        raise RuntimeError(f"GrayCodePattern gave {len(pats)} frames, expected {2 * (n_col + n_row)}")
    col_pairs = tuple((2 * i, 2 * i + 1) for i in range(n_col))
    row_pairs = tuple((2 * n_col + 2 * i, 2 * n_col + 2 * i + 1) for i in range(n_row))
    images.setflags(write=False)
    return GrayCodeSequence(images, col_pairs, row_pairs, len(pats), len(pats) + 1, proj_width, proj_height)


def _check_stack(stack, seq: GrayCodeSequence, name: str) -> np.ndarray:
    s = np.asarray(stack)
    if s.dtype != np.uint8:
        # OpenCV accepts float images and silently matches nothing; refuse instead.
        raise TypeError(f"{name}: Gray-code decoding needs 8-bit camera images (uint8), got {s.dtype}")
    if s.ndim != 3 or s.shape[0] != seq.n_images:
        raise ValueError(f"{name}: expected ({seq.n_images}, H, W) captures of the sequence, got {s.shape}")
    return s


# ----------------------------------------------------------------------------- OpenCV decode
def decode_opencv(left, right, seq: GrayCodeSequence, rig: StereoRig, black_threshold: int = 40,
                  white_threshold: int = 5) -> DenseResult:
    """OpenCV ``GrayCodePattern.decode`` of the full sequence -> left disparity (see module doc)."""
    t0 = time.perf_counter()
    left = _check_stack(left, seq, "left")
    right = _check_stack(right, seq, "right")
    if not seq.row_pairs:
        raise ValueError("decode_opencv needs the full sequence (row planes too), not columns_only()")
    gp = _opencv_pattern(seq.proj_width, seq.proj_height)
    gp.setBlackThreshold(int(black_threshold))
    gp.setWhiteThreshold(int(white_threshold))
    n_pat = 2 * (len(seq.col_pairs) + len(seq.row_pairs))
    cams = [[np.ascontiguousarray(s[i]) for i in range(n_pat)] for s in (left, right)]
    blacks = [np.ascontiguousarray(s[seq.black]) for s in (left, right)]
    whites = [np.ascontiguousarray(s[seq.white]) for s in (left, right)]
    ok, disp = gp.decode(cams, blackImages=blacks, whiteImages=whites)
    t_dec = time.perf_counter() - t0
    if not ok or disp is None:
        raise RuntimeError("cv2.structured_light.GrayCodePattern.decode returned no disparity map")
    # OpenCV: x(second) - x(first) = u_right - u_left, 0 = no match.
    d = np.where(disp != 0, -np.asarray(disp, np.float64), np.nan)
    notes = ("OpenCV GrayCodePattern.decode: disparity = mean u of the projector pixel's right-camera pixels "
             "minus mean u of its left-camera pixels, written at each left pixel; no row constraint",)
    res = dense_result("graycode-opencv", d, rig, seq.n_images, {"decode_s": t_dec}, notes)
    return replace(res, timings={"decode_s": t_dec, "total_s": time.perf_counter() - t0})


# ----------------------------------------------------------------------------- numpy decode
@dataclass(frozen=True)
class ColumnDecode:
    """Projector column code of one camera, decoded from the column bit planes.

    code: (H, W) int32, projector column // 2**dropped (-1 where invalid).
    valid: (H, W) bool: lit (white - black > black_threshold) and every kept plane decided
        (|pattern - inverse| >= white_threshold).
    diff: (n_kept, H, W) int16, pattern - inverse per kept plane, most significant first.
    dropped: number of least significant planes left out (unresolved by the camera).
    plane_contrast: median |pattern - inverse| / (white - black) over lit pixels, per plane (all planes).
    """

    code: np.ndarray
    valid: np.ndarray
    diff: np.ndarray
    dropped: int
    plane_contrast: tuple
    span: np.ndarray  # (H, W) int16 white - black


def plane_contrasts(stack, seq: GrayCodeSequence, black_threshold: int = 40) -> tuple:
    """Median |pattern - inverse| / (white - black) over the lit pixels, per column plane."""
    s = np.asarray(stack)
    span = s[seq.white].astype(np.int16) - s[seq.black].astype(np.int16)
    lit = span > black_threshold
    if not lit.any():
        return tuple(0.0 for _ in seq.col_pairs)
    out = []
    for p, q in seq.col_pairs:
        d = np.abs(s[p][lit].astype(np.int16) - s[q][lit].astype(np.int16))
        out.append(float(np.median(d / span[lit])))
    return tuple(out)


def planes_to_drop(contrasts, min_plane_contrast: float) -> int:
    """How many least significant planes fall below ``min_plane_contrast`` (counting from the first that does)."""
    for i, c in enumerate(contrasts):
        if c < min_plane_contrast:
            return len(contrasts) - i
    return 0


def decode_columns(stack, seq: GrayCodeSequence, dropped: int = 0, black_threshold: int = 40,
                   white_threshold: int = 5) -> ColumnDecode:
    """Decode the projector column (in blocks of 2**dropped) of every pixel of one camera.

    Same decision rule as OpenCV's ``getProjPixel``: bit = pattern > inverse; a pixel is
    invalid if white - black <= black_threshold or any |pattern - inverse| < white_threshold.
    """
    s = _check_stack(stack, seq, "stack")
    n_all = len(seq.col_pairs)
    if not 0 <= dropped < n_all:
        raise ValueError(f"dropped = {dropped} is out of range: allowed 0 to {n_all - 1}")
    n = n_all - dropped
    span = s[seq.white].astype(np.int16) - s[seq.black].astype(np.int16)
    valid = span > black_threshold
    diff = np.empty((n,) + s.shape[1:], np.int16)
    for i, (p, q) in enumerate(seq.col_pairs[:n]):
        diff[i] = s[p].astype(np.int16) - s[q].astype(np.int16)
        valid &= np.abs(diff[i]) >= white_threshold
    gray = diff > 0
    binary = np.bitwise_xor.accumulate(gray, axis=0)
    weights = (1 << np.arange(n - 1, -1, -1)).astype(np.int32)
    code = np.tensordot(weights, binary.astype(np.int32), axes=(0, 0)).astype(np.int32)
    code[~valid] = -1
    return ColumnDecode(code, valid, diff, dropped, plane_contrasts(s, seq, black_threshold), span)


# ----------------------------------------------------------------------------- continuous columns
@dataclass(frozen=True)
class RowProfile:
    """Samples of a monotone function column(u) along image rows, in row-major order.

    row, u, col, seg: (K,) arrays; ``seg`` numbers runs of valid pixels (two samples may be
    interpolated between only when they share a run, i.e. the same row with no gap).
    """

    row: np.ndarray
    u: np.ndarray
    col: np.ndarray
    seg: np.ndarray


def _segments(valid: np.ndarray) -> np.ndarray:
    """Run ids of valid pixels along rows (row-major, increasing); -1 where invalid."""
    H, W = valid.shape
    start = valid.copy()
    start[:, 1:] &= ~valid[:, :-1]
    ids = np.cumsum(start.ravel()).reshape(H, W) - 1
    return np.where(valid, ids, -1).astype(np.int64)


def column_knots(dec: ColumnDecode, max_jump: int = 4, edge_model: str = "area") -> RowProfile:
    """Stripe-edge knots (u_edge, projector column of the edge) between neighbouring valid pixels.

    Between pixels u and u+1 with codes a < b (b - a <= max_jump), the boundary with the
    coarsest bit plane flipping lies at projector column n * 2**m - 0.5, with
    K = bit_length(a ^ b) - 1 and n = (b >> K) << K; that plane flips exactly once between
    a and b, and its pattern - inverse crosses zero at the edge.
    """
    if edge_model not in EDGE_MODELS:
        raise ValueError(f"edge_model = {edge_model!r} is not allowed: choose one of {EDGE_MODELS}")
    code, valid = dec.code, dec.valid
    seg = _segments(valid)
    a, b = code[:, :-1], code[:, 1:]
    pair = valid[:, :-1] & valid[:, 1:] & (b > a) & (b - a <= max_jump)
    v, u = np.nonzero(pair)
    a, b = a[v, u].astype(np.int64), b[v, u].astype(np.int64)
    x = a ^ b
    K = np.floor(np.log2(x)).astype(np.int64)
    nstar = (b >> K) << K
    n_kept = dec.diff.shape[0]
    plane = n_kept - 1 - K
    if edge_model == "midpoint":
        t = np.full(len(v), 0.5)
    else:
        d0 = dec.diff[plane, v, u].astype(np.float64)
        d1 = dec.diff[plane, v, u + 1].astype(np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            if edge_model == "linear":
                t = np.where(d0 * d1 < 0, d0 / (d0 - d1), 0.5)
            else:  # "area": box pixels, sharp edge: D = A (2 f - 1) in the straddled pixel
                amp = 0.5 * (dec.span[v, u] + dec.span[v, u + 1]).astype(np.float64)
                sign = np.where(d0 > d1, 1.0, -1.0)
                t = np.where(amp > 0, 0.5 + sign * (d0 + d1) / (2.0 * amp), 0.5)
        t = np.clip(t, 0.0, 1.0)
    col = nstar * float(1 << dec.dropped) - 0.5
    return RowProfile(v.astype(np.int64), u + t, col, seg[v, u])


def profile_from_column_map(col_map: np.ndarray) -> RowProfile:
    """Row profile sampled at pixel centres of a continuous column map (NaN = invalid)."""
    valid = np.isfinite(col_map)
    seg = _segments(valid)
    v, u = np.nonzero(valid)
    return RowProfile(v.astype(np.int64), u.astype(np.float64), col_map[v, u].astype(np.float64), seg[v, u])


def column_map_from_knots(knots: RowProfile, valid: np.ndarray, max_step: float | None = None) -> np.ndarray:
    """Column at every valid pixel centre, linear between the two knots around it in its run; NaN elsewhere."""
    H, W = valid.shape
    out = np.full((H, W), np.nan)
    if knots.u.size < 2:
        return out
    seg = _segments(valid)
    stride = W + 2.0
    key_k = knots.row * stride + knots.u
    v, u = np.nonzero(valid)
    key_q = v * stride + u
    hi = np.searchsorted(key_k, key_q, side="right")
    lo = hi - 1
    ok = (lo >= 0) & (hi < key_k.size)
    lo_c, hi_c = np.clip(lo, 0, key_k.size - 1), np.clip(hi, 0, key_k.size - 1)
    sq = seg[v, u]
    ok &= (knots.seg[lo_c] == sq) & (knots.seg[hi_c] == sq)
    du = knots.u[hi_c] - knots.u[lo_c]
    dc = knots.col[hi_c] - knots.col[lo_c]
    ok &= (du > 0) & (dc > 0)
    if max_step is not None:
        ok &= dc <= max_step
    with np.errstate(divide="ignore", invalid="ignore"):
        c = knots.col[lo_c] + (u - knots.u[lo_c]) / du * dc
    out[v[ok], u[ok]] = c[ok]
    return out


def _usable_pairs(prof: RowProfile, max_step: float | None):
    """Indices i of neighbouring samples (i, i+1) in one run with 0 < col step <= max_step."""
    i = np.arange(prof.u.size - 1)
    dc = prof.col[1:] - prof.col[:-1]
    ok = (prof.seg[1:] == prof.seg[:-1]) & (dc > 0)
    if max_step is not None:
        ok &= dc <= max_step
    return i[ok]


def match_columns_along_rows(col_left: np.ndarray, right: RowProfile, max_step: float | None = None) -> np.ndarray:
    """Sub-pixel right u with the same projector column as each left pixel, same row; NaN if none.

    Usable right intervals are neighbouring samples of one run whose column rises by no
    more than ``max_step`` (an isolated wrong sample, e.g. a phase-order error, breaks
    both of its intervals and so is never used). Intervals that step back below an
    earlier interval of the same row are dropped, so at most one interval holds each
    column; the left pixel's column is located in it and u interpolated linearly.
    """
    H, W = col_left.shape
    out = np.full((H, W), np.nan)
    if right.u.size < 2:
        return out
    i = _usable_pairs(right, max_step)
    if i.size == 0:
        return out
    big = float(np.nanmax(np.abs(right.col))) * 2 + 16.0
    lo_key = right.row[i] * big + right.col[i]
    hi_key = right.row[i] * big + right.col[i + 1]
    prev_hi = np.maximum.accumulate(hi_key)
    keep = np.ones(i.size, bool)
    keep[1:] = lo_key[1:] >= prev_hi[:-1]
    i, lo_key, hi_key = i[keep], lo_key[keep], hi_key[keep]
    v, u = np.nonzero(np.isfinite(col_left))
    c = col_left[v, u]
    q = v * big + c
    k = np.searchsorted(lo_key, q, side="right") - 1
    ok = k >= 0
    kc = np.clip(k, 0, max(i.size - 1, 0))
    ok &= q < hi_key[kc]
    a = i[kc]
    c0, c1 = right.col[a], right.col[a + 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        ur = right.u[a] + (c - c0) / (c1 - c0) * (right.u[a + 1] - right.u[a])
    out[v[ok], u[ok]] = ur[ok]
    return out


def consistent_columns(col_map: np.ndarray, max_step: float) -> np.ndarray:
    """NaN out pixels whose column rises by more than ``max_step`` (or falls) to both row neighbours."""
    c = np.asarray(col_map, np.float64)
    good = np.zeros(c.shape, bool)
    with np.errstate(invalid="ignore"):
        step = c[:, 1:] - c[:, :-1]
        pair = (step > 0) & (step <= max_step)
    good[:, :-1] |= pair
    good[:, 1:] |= pair
    return np.where(good, c, np.nan)


def decode_subpixel(left, right, seq: GrayCodeSequence, rig: StereoRig, min_plane_contrast: float = 0.6,
                    black_threshold: int = 40, white_threshold: int = 0, max_jump: int = 4,
                    edge_model: str = "area", dropped: int | None = None) -> DenseResult:
    """Sub-pixel Gray-code stereo from the column planes (see module doc) -> left disparity.

    ``seq`` may be the full sequence or ``columns_only()``; ``left``/``right`` are the
    (N, H, W) uint8 captures of ``seq.images``. ``dropped`` forces the number of least
    significant planes to leave out (default: from ``min_plane_contrast``).
    """
    t0 = time.perf_counter()
    left = _check_stack(left, seq, "left")
    right = _check_stack(right, seq, "right")
    notes = []
    if dropped is None:
        cl = plane_contrasts(left, seq, black_threshold)
        cr = plane_contrasts(right, seq, black_threshold)
        dropped = max(planes_to_drop(cl, min_plane_contrast), planes_to_drop(cr, min_plane_contrast))
        dropped = min(dropped, len(seq.col_pairs) - 1)
        notes.append("plane contrast (median |pattern - inverse| / (white - black)), MSB first: left "
                     + " ".join(f"{c:.2f}" for c in cl) + "; right " + " ".join(f"{c:.2f}" for c in cr))
    notes.append(f"{len(seq.col_pairs) - dropped} of {len(seq.col_pairs)} column planes used "
                 f"(code resolution {1 << dropped} projector columns), stripe edges by the {edge_model!r} model")
    dl = decode_columns(left, seq, dropped, black_threshold, white_threshold)
    dr = decode_columns(right, seq, dropped, black_threshold, white_threshold)
    t_dec = time.perf_counter()
    kl = column_knots(dl, max_jump, edge_model)
    kr = column_knots(dr, max_jump, edge_model)
    step = max_jump * float(1 << dropped)
    col_left = column_map_from_knots(kl, dl.valid, step)
    u_right = match_columns_along_rows(col_left, kr, max_step=step)
    u = np.arange(col_left.shape[1])[None, :]
    disp = u - u_right
    t_match = time.perf_counter()
    n_images = 2 * len(seq.col_pairs) + 2
    timings = {"decode_s": t_dec - t0, "match_s": t_match - t_dec}
    res = dense_result("graycode-subpx", disp, rig, n_images, timings, notes)
    return replace(res, timings={**timings, "total_s": time.perf_counter() - t0})


# ----------------------------------------------------------------------------- registered methods
def as_disparity(res: DenseResult) -> Disparity:
    """A ``DenseResult`` as the method contract's output: its disparity, +inf where it has no estimate."""
    return Disparity(np.where(res.valid, res.disparity, np.inf), notes=tuple(res.notes))


@register_method("graycode", "Gray code, OpenCV GrayCodePattern.decode", "disparity",
                 sequence=Projection("graycode", graycode_sequence), default=True)
def graycode_opencv(inputs: MethodInputs) -> Disparity:
    """OpenCV's decode of the full Gray-code sequence (``decode_opencv``)."""
    return as_disparity(decode_opencv(inputs.captures["left"], inputs.captures["right"], inputs.sequence, inputs.rig))


@register_method("graycode-subpx", "Gray code, sub-pixel column matching along rows (numpy)", "disparity",
                 sequence=Projection("graycode", lambda w, h: graycode_sequence(w, h).columns_only()), default=True)
def graycode_subpixel(inputs: MethodInputs) -> Disparity:
    """Sub-pixel Gray-code stereo from the column planes (``decode_subpixel``)."""
    return as_disparity(decode_subpixel(inputs.captures["left"], inputs.captures["right"], inputs.sequence,
                                        inputs.rig))
