"""General passive boundary stereo: the plate's outline matched along rectified rows, any shape.

The paper's boundary stereo (``passive_boundary``) needs a quadrilateral outline with straight
top and bottom edges (their disparity is interpolated between the four corners). Folds, curls,
twists and oblique bends give other outlines: five or six corners, or curved edges running
along the rows. This module handles any closed outline:

1. The plate region's outer border (``plate_region.plate_mask``) is the backbone: an ordered,
   closed chain of border pixels.
2. Each border pixel is refined to sub-pixel along its row where the outline is steep (it
   crosses rows at >= 30 degrees) and along its column elsewhere. The edge model is the pixel's
   covered fraction, normalised by the plate level *next to the edge* (the two nearest inner
   pixels), not the level deeper inside: a steep part of a bent plate is lit at a grazing angle
   and darkens toward its edge, which would otherwise pull the edge inward by pixels.
3. Rows are rectified (conventional geometry), so row ``v`` of the left image and row ``v`` of
   the right image see the same epipolar plane. On each row the region's crossings (where it is
   entered and left, in order of u) are matched in order when both images have the same
   sequence (ordered crossings); a matched crossing gives a disparity where the outline crosses
   the row at >= ``MATCH_STEEP_DEG`` in both images.
4. Where the outline runs along the rows (or a row's crossings differ), the disparity is filled
   by continuity along the outline: linear in arc length between the nearest matched points on
   either side (exact along a straight 3D edge seen as a straight horizontal image line).

Output: a ``BoundaryStereo`` (points in the world frame, metres) whose ``source`` says per point
"row" (matched) or "fill" (continuity), and whose ``method`` is "contour-rows".
Pixel coordinates follow OpenCV: pixel centres at integers, u right, v down.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.reconstruction.paper.boundary_types import BoundaryStereo
from platebench.reconstruction.paper.plate_region import PlateMask, ReconstructionError
from platebench.scenes.camera import triangulate_rectified
from platebench.scenes.rig import StereoRig
from platebench.tolerances import tol

TANGENT_HALF_PX = 4  # border pixels on either side used for the outline's local direction
REFINE_STEEP_SIN = np.sin(np.radians(30.0))  # refine along the row when |dv/ds| >= this
MATCH_STEEP_DEG = 30.0  # a crossing gives a disparity only if the outline crosses the row this steeply
MAX_DISPARITY_JUMP_PX = 3.0  # a matched disparity this far from its neighbours' median is dropped
NEIGHBOURS = 7  # matched points on either side for that median
NOTCH_PX = 2  # a row's gaps and runs this narrow are outline noise (``_row_runs``)
ANCHOR_POINTS = 8  # matched points on each side of a gap that anchor its fill
ANCHOR_EXTRAPOLATION_PX = 10  # a gap's fill extrapolates its anchors' d(v) by at most this many rows
METHOD = "contour-rows"


@dataclass(frozen=True)
class ImageContour:
    """Sub-pixel outline of the plate in one image, ordered along the border (closed).

    ``points``: (N,2) u, v; ``along_row``: (N,) True where refined along the row (steep outline);
    ``tangent``: (N,2) unit outline direction; ``line``: (N,) the row (or column) index of the
    refinement; ``inner``: (N,) the first plate pixel's u (row refinement) or v (column) on it;
    ``side``: (N,) +1 when the plate lies toward larger u (v), -1 otherwise.
    """

    points: np.ndarray
    along_row: np.ndarray
    tangent: np.ndarray
    line: np.ndarray
    inner: np.ndarray
    side: np.ndarray


def edge_position(profile: np.ndarray, inside: np.ndarray, b: int, s: int, background: float) -> float:
    """Sub-pixel edge between pixel ``b - s`` (outside) and ``b`` (the first plate pixel) of a line.

    ``s`` = +1 when the plate lies toward larger indices. The plate level is the mean of the two
    inner pixels next to ``b`` (``b`` itself when the region is thinner); the covered fractions of
    ``b`` and of the outer neighbour give the edge: ``e = b + s (0.5 - (c_b + c_a))``.
    """
    n = len(profile)
    inner = [b + s * k for k in (1, 2) if 0 <= b + s * k < n and inside[b + s * k]]
    level = float(np.mean(profile[inner])) if inner else float(profile[b])
    level = max(level, float(profile[b]))
    if level - background <= 0:
        return float(b) - 0.5 * s
    a = b - s
    c_b = np.clip((profile[b] - background) / (level - background), 0.0, 1.0)
    c_a = np.clip((profile[a] - background) / (level - background), 0.0, 1.0) if 0 <= a < n else 0.0
    return float(b + s * (0.5 - min(c_a + c_b, 1.5)))


def _refine(img: np.ndarray, mask: np.ndarray, u: int, v: int, along_row: bool, background: float):
    """Sub-pixel edge at border pixel (u, v) along its row (or column): (line, first plate pixel,
    side, edge position), or None when the pixel has no outside neighbour on that line."""
    profile, inside, b, line = (img[v], mask[v], u, v) if along_row else (img[:, u], mask[:, u], v, u)
    n = len(inside)
    if b - 1 >= 0 and not inside[b - 1]:
        s = 1
    elif b + 1 < n and not inside[b + 1]:
        s = -1
    else:
        return None
    return line, b, s, edge_position(profile, inside, b, s, background)


def image_contour(image: np.ndarray, region: PlateMask) -> ImageContour:
    """The region's border refined to sub-pixel (see module doc), in border order."""
    img = np.asarray(image, np.float64)
    mask = region.mask
    B = np.asarray(region.contour, np.int64)
    n = len(B)
    if n < 8:
        raise ReconstructionError(f"plate outline: only {n} border pixels")
    k = TANGENT_HALF_PX
    t = (np.roll(B, -k, axis=0) - np.roll(B, k, axis=0)).astype(float)
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), tol.zero_length)
    pts, rows, tang, line, inner, side = [], [], [], [], [], []
    seen = set()
    for i, (u, v) in enumerate(B):
        steep = abs(t[i, 1]) >= REFINE_STEEP_SIN
        for along_row in ((True, False) if steep else (False, True)):
            hit = _refine(img, mask, int(u), int(v), along_row, region.background_level)
            if hit is None:
                continue
            ln, b, s, e = hit
            key = (along_row, ln, b, s)
            if key not in seen:
                seen.add(key)
                pts.append((e, float(ln)) if along_row else (float(ln), e))
                rows.append(along_row)
                tang.append(t[i])
                line.append(ln)
                inner.append(b)
                side.append(s)
            break
    if len(pts) < 8:
        raise ReconstructionError(f"plate outline: only {len(pts)} refinable border pixels")
    return ImageContour(np.array(pts), np.array(rows), np.array(tang), np.array(line), np.array(inner),
                        np.array(side))


def _row_runs(mask_row: np.ndarray) -> list[tuple[int, int]]:
    """The plate's runs on one row, (first, last) plate pixel each, left to right, with slivers of
    at most ``NOTCH_PX`` plate pixels dropped and then gaps of at most ``NOTCH_PX`` closed: the
    filled outline's one-pixel spurs and dents along an edge that runs with the rows differ
    between the two images, and would otherwise make their rows' sequences differ (and lose the
    steep crossings of the same rows). A row of slivers only keeps them."""
    m = np.asarray(mask_row, np.int8)
    d = np.diff(np.concatenate([[0], m, [0]]))
    runs = [[int(a), int(b) - 1] for a, b in zip(np.nonzero(d == 1)[0], np.nonzero(d == -1)[0])]
    wide = [r for r in runs if r[1] - r[0] + 1 > NOTCH_PX] or runs
    merged: list[list[int]] = []
    for r in wide:
        if merged and r[0] - merged[-1][1] - 1 <= NOTCH_PX:
            merged[-1][1] = r[1]
        else:
            merged.append(list(r))
    return [(a, b) for a, b in merged]


def _row_crossings(mask: np.ndarray) -> dict:
    """Row -> list of (first plate pixel u, s), left to right, where the region is entered (s=+1,
    plate to the right) or left (s=-1) (``_row_runs``: slivers and notches of at most
    ``NOTCH_PX`` ignored)."""
    out = {}
    for v in np.nonzero(mask.any(axis=1))[0]:
        out[int(v)] = [c for a, b in _row_runs(mask[v]) for c in ((a, 1), (b, -1))]
    return out


def _fill_gaps(d: np.ndarray, known: np.ndarray, v: np.ndarray, arc: np.ndarray, total: float) -> np.ndarray:
    """Fill the unknown disparities of a closed outline by continuity.

    Each run of unknown points (a gap) lies between two matched stretches. On each side the
    disparity is extrapolated *along the rows* from the last ``ANCHOR_POINTS`` matched points
    (a straight line in v, at most ``ANCHOR_EXTRAPOLATION_PX`` rows beyond them): a side edge's
    disparity changes fast near a steep end and a flat interpolation would lag behind it. The two
    extrapolations are blended linearly in arc length across the gap, which is exact along a
    straight 3D edge seen as a horizontal image line (disparity affine in u)."""
    n = len(d)
    out = d.copy()
    if known.all():
        return out
    kidx = np.nonzero(known)[0]
    start = int(kidx[0])
    order = (np.arange(n) + start) % n  # begins on a known point
    kn = known[order]
    i = 0
    while i < n:
        if kn[i]:
            i += 1
            continue
        j = i
        while j < n and not kn[j]:
            j += 1
        gap = order[i:j]
        before = order[:i][kn[:i]][-ANCHOR_POINTS:]
        after_pos = np.concatenate([order[j:][kn[j:]], order[:i][kn[:i]]])[:ANCHOR_POINTS]
        s0 = arc[before[-1]]
        s1 = arc[after_pos[0]]
        span = (s1 - s0) % total
        w = ((arc[gap] - s0) % total) / span if span > 0 else np.full(len(gap), 0.5)

        def extrapolate(anchor):
            va, da = v[anchor], d[anchor]
            if len(anchor) >= 3 and np.ptp(va) >= 2:
                slope, icpt = np.polyfit(va, da, 1)
                lo, hi = va.min() - ANCHOR_EXTRAPOLATION_PX, va.max() + ANCHOR_EXTRAPOLATION_PX
                return slope * np.clip(v[gap], lo, hi) + icpt
            return np.full(len(gap), da[-1] if anchor is before else da[0])

        out[gap] = (1.0 - w) * extrapolate(before) + w * extrapolate(after_pos)
        i = j
    return out


def match_outlines(left_image: np.ndarray, right_image: np.ndarray, left: PlateMask, right: PlateMask,
                   rig: StereoRig):
    """Match the two outlines along rows (ordered crossings) and fill by continuity; returns a
    ``BoundaryStereo`` with ``method`` "contour-rows"."""
    cl = image_contour(left_image, left)
    cr = image_contour(right_image, right)
    xl, xr = _row_crossings(left.mask), _row_crossings(right.mask)
    # Sub-pixel u of every row-refined crossing of each image, keyed (row, first plate pixel, s).
    steep_sin = np.sin(np.radians(MATCH_STEEP_DEG))

    def table(c: ImageContour) -> dict:
        tab = {}
        for j in np.nonzero(c.along_row)[0]:
            tab[(int(c.line[j]), int(c.inner[j]), int(c.side[j]))] = (c.points[j, 0], abs(c.tangent[j, 1]) >= steep_sin)
        return tab

    tl, tr = table(cl), table(cr)
    disp = {}
    for v, seq_l in xl.items():
        seq_r = xr.get(v)
        if not seq_r or len(seq_r) != len(seq_l) or [s for _, s in seq_l] != [s for _, s in seq_r]:
            continue
        for (ul, s), (ur, _) in zip(seq_l, seq_r):
            a, b = tl.get((v, ul, s)), tr.get((v, ur, s))
            if a is None or b is None or not (a[1] and b[1]):
                continue
            disp[(v, ul, s)] = a[0] - b[0]
    N = len(cl.points)
    d = np.full(N, np.nan)
    for j in np.nonzero(cl.along_row)[0]:
        val = disp.get((int(cl.line[j]), int(cl.inner[j]), int(cl.side[j])))
        if val is not None and val > 0:
            d[j] = val
    known = np.isfinite(d)
    if known.sum() < 2:
        raise ReconstructionError("passive stereo: no row of the two outlines could be matched (images swapped, "
                                  "or the plate seen edge-on)")
    # Drop matched disparities that jump away from their neighbours along the outline.
    idx = np.nonzero(known)[0]
    dk = d[idx]
    m = len(idx)
    win = np.arange(-NEIGHBOURS, NEIGHBOURS + 1)
    med = np.median(dk[(np.arange(m)[:, None] + win[None, :]) % m], axis=1)
    bad = np.abs(dk - med) > MAX_DISPARITY_JUMP_PX
    known[idx[bad]] = False
    seg = np.linalg.norm(np.diff(np.vstack([cl.points, cl.points[:1]]), axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(seg)[:-1]])
    d = _fill_gaps(np.where(known, d, np.nan), known, cl.points[:, 1], arc, float(seg.sum()))
    uv = cl.points
    P = triangulate_rectified(uv[:, 0], uv[:, 1], uv[:, 0] - d, rig.left, rig.baseline_m)
    ok = np.all(np.isfinite(P), axis=1)
    source = np.where(known, "row", "fill")
    return BoundaryStereo(P[ok], uv[ok], d[ok], source[ok], np.zeros(0), METHOD)
