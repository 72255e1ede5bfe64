"""Active stereo square matching (paper section III) and the Fig. 6 conditions.

Algorithm, as the paper states it:
1. sort the squares of each image into groups (horizontal square arrays): two squares
   are x-neighbours when their y extents overlap and no other such square lies between
   them in x; groups are the connected chains of x-neighbours;
2. match groups across the images by the y of their leftmost squares (conventional
   geometry: corresponding points share their row);
3. match squares within matched groups by their order in x.

Fig. 6 conditions are checked on the detected squares, and a violation is reported
(with where it happens) instead of becoming a silent wrong match:
* condition 1: squares adjacent in x within a horizontal array overlap in y (and the
  array has no gap wider than 1.6 times the image's median pitch, which signals a lost square);
* condition 2: no square is x-adjacent (y-overlapping) to a square of another array.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from platebench.reconstruction.paper.squares import Square

GAP_FACTOR = 1.6


def _overlap(a: tuple[float, float], b: tuple[float, float]) -> float:
    return min(a[1], b[1]) - max(a[0], b[0])


def group_squares(squares: tuple[Square, ...]) -> list[list[int]]:
    """Horizontal square arrays: lists of square indices sorted by x; arrays sorted by leftmost y."""
    n = len(squares)
    parent = list(range(n))

    def find(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    cx = np.array([s.centroid[0] for s in squares])
    for i, s in enumerate(squares):
        cand = [j for j in range(n) if j != i and cx[j] > cx[i] and _overlap(s.v_extent, squares[j].v_extent) > 0]
        if cand:
            j = min(cand, key=lambda k: cx[k])  # nearest y-overlapping square to the right
            parent[find(j)] = find(i)
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(find(i), []).append(i)
    out = [sorted(g, key=lambda k: cx[k]) for g in groups.values()]
    return sorted(out, key=lambda g: squares[g[0]].centroid[1])


@dataclass(frozen=True)
class Fig6Check:
    """Result of checking the two Fig. 6 conditions in one image."""

    condition_1_ok: bool
    condition_2_ok: bool
    violations: tuple[str, ...] = ()


def check_fig6(squares: tuple[Square, ...], groups: list[list[int]], image_name: str) -> Fig6Check:
    """Check the two Fig. 6 conditions on detected squares; describe each violation."""
    v1, v2 = [], []
    pitches = [np.diff([squares[k].centroid[0] for k in g]) for g in groups if len(g) > 1]
    med = float(np.median(np.concatenate(pitches))) if pitches else np.inf  # image-wide median pitch
    for gi, g in enumerate(groups):
        xs = np.array([squares[k].centroid[0] for k in g])
        for a, b in zip(g, g[1:]):
            if _overlap(squares[a].v_extent, squares[b].v_extent) <= 0:
                v1.append(f"{image_name}: array {gi}: squares at {np.round(squares[a].centroid, 1).tolist()} and "
                          f"{np.round(squares[b].centroid, 1).tolist()} are x-adjacent but do not overlap in y")
        if len(xs) >= 2:
            pitch = np.diff(xs)
            for k in np.nonzero(pitch > GAP_FACTOR * med)[0]:
                v1.append(f"{image_name}: array {gi}: gap of {pitch[k]:.1f} px (median pitch {med:.1f} px) after "
                          f"square at {np.round(squares[g[k]].centroid, 1).tolist()}: a square is missing")
    owner = {k: gi for gi, g in enumerate(groups) for k in g}
    for i, si in enumerate(squares):
        for j, sj in enumerate(squares):
            if j <= i or owner[i] == owner[j]:
                continue
            if _overlap(si.v_extent, sj.v_extent) > 0:
                v2.append(f"{image_name}: squares at {np.round(si.centroid, 1).tolist()} (array {owner[i]}) and "
                          f"{np.round(sj.centroid, 1).tolist()} (array {owner[j]}) overlap in y across arrays")
    return Fig6Check(not v1, not v2, tuple(v1 + v2))


@dataclass(frozen=True)
class SquareMatches:
    """Matched square pairs (indices into each image's squares) and what could not be matched."""

    pairs: tuple[tuple[int, int], ...]
    group_pairs: tuple[tuple[int, int], ...]
    unmatched: tuple[str, ...] = field(default_factory=tuple)
    count_mismatch: bool = False  # some matched arrays hold different numbers of squares (Fig. 2)


def match_squares(left: tuple[Square, ...], right: tuple[Square, ...], left_groups: list[list[int]],
                  right_groups: list[list[int]], row_tolerance_px: float) -> SquareMatches:
    """Match arrays by the y of their leftmost squares, then squares by x order."""
    ly = np.array([left[g[0]].centroid[1] for g in left_groups])
    ry = np.array([right[g[0]].centroid[1] for g in right_groups])
    pairs, gpairs, notes = [], [], []
    used_r = set()
    mismatch = False
    for gi, y in enumerate(ly):
        if ry.size == 0:
            notes.append(f"left array {gi} (y {y:.1f}) has no partner in the right image")
            continue
        j = int(np.argmin(np.abs(ry - y)))
        if abs(ry[j] - y) > row_tolerance_px or j in used_r:
            notes.append(f"left array {gi} (leftmost y {y:.1f} px) has no right array within {row_tolerance_px:.1f} px")
            continue
        used_r.add(j)
        gl, gr = left_groups[gi], right_groups[j]
        if len(gl) != len(gr):
            mismatch = True
            notes.append(f"array at y {y:.1f} px: {len(gl)} squares in the left image, {len(gr)} in the right: "
                         "x order is ambiguous, not matched (false boundary suspected)")
            continue
        gpairs.append((gi, j))
        pairs.extend(zip(gl, gr))
    for j in set(range(len(right_groups))) - used_r:
        notes.append(f"right array {j} (leftmost y {ry[j]:.1f} px) has no partner in the left image")
    return SquareMatches(tuple(pairs), tuple(gpairs), tuple(notes), mismatch)
