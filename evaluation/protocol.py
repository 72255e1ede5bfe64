"""The benchmark protocol's dense figures: one definition each, for every kind of output.

Every output is first turned into one left-view z-depth map (metres, NaN where there is no
estimate), then scored over the plate's pixels in the left view, ``P`` = the truth's plate mask:

=============  ======================================================================================
kind           its left-view depth map
=============  ======================================================================================
depth          as given
disparity      Z = f B / (d + doffs) with the rig the method is told (``evaluation.stereo_truth``);
               d <= 0, NaN and +inf are no estimate
mesh           the first hit of each plate pixel's true ray (from the left camera's centre through
               the true world point the pixel sees), its z-depth; no hit: no estimate
points         each point projected into the left view (through the lens) and rounded to the nearest
               pixel; a pixel keeps its nearest point's z-depth; a pixel no point falls in: no estimate
=============  ======================================================================================

Figures (``DenseFigures``), over ``P`` (``plate_px`` pixels), ``E`` its pixels with an estimate
(finite depth > 0) and e = Z_est - Z_true:

* ``coverage_frac`` = |E| / |P|: the share of the plate's pixels with an estimate, as everywhere in the
  bench (``evaluation.pixel_coverage``). Reported beside the error figures, never mixed into them.
* ``bad_2mm_pct`` (the primary figure) = 100 (|{E: |e| > 2 mm}| + |P \\ E|) / |P|: the share of plate
  pixels whose depth error exceeds the paper's depth bound (Chen & Zheng 1995, V-D: depth within 2 mm)
  or that have no estimate. A method answering on a tenth of the pixels scores at least 90.
* ``bad_0_5mm_pct``: the same at 0.5 mm.
* ``depth_rms_mm``, ``depth_median_abs_mm``, ``depth_mean_signed_mm`` (+ = too far): over E only
  (None when E is empty).

Estimates off the plate are not scored (the truth holds no plate there).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["DenseFigures", "ProtocolTruth", "PRIMARY_BAD_MM", "SECONDARY_BAD_MM", "OUTPUT_KINDS", "dense_figures",
           "no_estimate",
           "depth_from_disparity", "first_hits", "mesh_hits", "depth_from_mesh", "depth_from_points", "left_depth"]

PRIMARY_BAD_MM = 2.0  # the paper's depth bound (Chen & Zheng 1995, V-D: "within 2 mm" in depth)
SECONDARY_BAD_MM = 0.5  # a tighter threshold, a quarter of the paper's bound
OUTPUT_KINDS = ("disparity", "depth", "points", "mesh")
_MM = 1e3


@dataclass(frozen=True)
class DenseFigures:
    """The dense figures of one output on one sample (module doc); percentages 0..100."""

    plate_px: int
    estimated_px: int
    coverage_frac: float
    bad_2mm_pct: float
    bad_0_5mm_pct: float
    depth_rms_mm: float | None
    depth_median_abs_mm: float | None
    depth_mean_signed_mm: float | None


def no_estimate(plate_px: int) -> DenseFigures:
    """The figures of a sample on which a method gave nothing: every plate pixel bad, coverage 0."""
    return DenseFigures(int(plate_px), 0, 0.0, 100.0, 100.0, None, None, None)


def dense_figures(depth_m: np.ndarray, truth_depth_m: np.ndarray, plate_mask: np.ndarray) -> DenseFigures:
    """Score a left-view z-depth map (H, W), metres, NaN/inf/<= 0 = no estimate, against the true
    z-depth (H, W) over ``plate_mask`` (H, W) bool (module doc)."""
    z = np.asarray(depth_m, np.float64)
    zt = np.asarray(truth_depth_m, np.float64)
    m = np.asarray(plate_mask, bool)
    if z.shape != m.shape or zt.shape != m.shape:
        raise ValueError(f"depth map {z.shape[::-1]} and truth {m.shape[::-1]} differ in size (W, H)")
    n = int(m.sum())
    if n == 0:
        raise ValueError("the truth has no plate pixel in the left view: nothing to score")
    with np.errstate(invalid="ignore"):
        est = m & np.isfinite(z) & (z > 0)
    e = z[est] - zt[est]
    a_mm = np.abs(e) * _MM
    k = int(est.sum())
    missing = n - k

    def bad(t_mm: float) -> float:
        return 100.0 * (int(np.count_nonzero(a_mm > t_mm)) + missing) / n

    if k:
        rms = float(math.sqrt(float(np.mean(e * e)))) * _MM
        med = float(np.median(a_mm))
        signed = float(np.mean(e)) * _MM
    else:
        rms = med = signed = None
    return DenseFigures(n, k, k / n, bad(PRIMARY_BAD_MM), bad(SECONDARY_BAD_MM), rms, med, signed)


@dataclass(frozen=True)
class ProtocolTruth:
    """What the protocol scores against, for one sample's left view (world frame, metres).

    ``depth``: (H, W) true z-depth, non-finite off the plate; ``mask``: (H, W) bool plate pixels;
    ``points``: (H, W, 3) the true world point seen at each pixel; ``camera``: the left camera as really
    posed (``scenes.camera.Camera``); ``fb`` and ``doffs_px``: f B (px m) and the disparity offset (px)
    of the rig the method is told, which turn its disparities into depth (None when the told rig is
    not a rectified pair: a disparity cannot then be read as depth)."""

    depth: np.ndarray
    mask: np.ndarray
    points: np.ndarray
    camera: object
    fb: float | None
    doffs_px: float | None

    @property
    def shape(self) -> tuple[int, int]:
        return self.mask.shape


def depth_from_disparity(disparity_px: np.ndarray, fb: float, doffs_px: float) -> np.ndarray:
    """(H, W) z-depth (m) of a left-view disparity map (px): ``fb / (d + doffs_px)``; NaN where d is not
    a finite value > 0."""
    d = np.asarray(disparity_px, np.float64)
    s = d + doffs_px
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(d) & (d > 0) & (s > 0), fb / s, np.nan)


def mesh_hits(mesh, eye_m, points_left_m: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where the plate pixels' true rays meet a world-frame mesh (``trimesh.Trimesh``): each ray starts
    at ``eye_m`` (the left camera centre, (3,)) and passes through the true world point its pixel sees
    (``points_left_m``, (H, W, 3)); a plate pixel (``mask``, (H, W) bool) without a finite true point has
    no ray. Returns (v, u, first hit (K, 3)) of the K rays that hit, first hit along the ray."""
    m = np.asarray(mask, bool)
    empty = (np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros((0, 3)))
    if mesh is None or len(getattr(mesh, "faces", ())) == 0 or not m.any():
        return empty
    eye = np.asarray(eye_m, np.float64).reshape(3)
    v, u = np.nonzero(m)
    d = np.asarray(points_left_m, np.float64)[v, u] - eye
    n = np.linalg.norm(d, axis=1)
    ok = np.isfinite(n) & (n > 0)
    if not ok.any():
        return empty
    v, u = v[ok], u[ok]
    hit, points = first_hits(mesh, eye, d[ok] / n[ok, None])
    return v[hit], u[hit], points


def first_hits(mesh, eye_m, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(hit (N,) bool, first hits (K, 3)) of N rays from ``eye_m`` (3,) along unit ``dirs`` (N, 3)
    against a world-frame mesh: the nearest intersection along each ray that meets it."""
    eye = np.asarray(eye_m, np.float64).reshape(3)
    locs, ray_idx, _ = mesh.ray.intersects_location(np.broadcast_to(eye, dirs.shape).copy(), dirs,
                                                   multiple_hits=False)
    first = np.full(len(dirs), np.inf)
    if len(ray_idx):
        np.minimum.at(first, ray_idx, np.einsum("ij,ij->i", locs - eye, dirs[ray_idx]))
    hit = np.isfinite(first)
    return hit, eye + dirs[hit] * first[hit, None]


def depth_from_mesh(mesh, eye_m, points_left_m: np.ndarray, mask: np.ndarray, camera) -> np.ndarray:
    """(H, W) z-depth (m) in ``camera`` of a world-frame mesh: the first hit of each plate pixel's true
    ray (``mesh_hits``); NaN where it hits nothing, off the plate and where the truth has no point."""
    out = np.full(np.asarray(mask).shape, np.nan)
    v, u, hits = mesh_hits(mesh, eye_m, points_left_m, mask)
    if len(hits):
        out[v, u] = camera.depth(hits)
    return out


def depth_from_points(points_m: np.ndarray, camera, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) = ``shape`` z-depth (m) of world points (N, 3) in ``camera``: each projected (through the
    lens) to its nearest pixel (OpenCV's pixel centres at whole numbers), the nearest point's z-depth
    kept per pixel; NaN where none falls."""
    p = np.asarray(points_m, np.float64).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    out = np.full(shape, np.inf)
    if len(p):
        uv = camera.project(p)
        z = camera.depth(p)
        ok = np.all(np.isfinite(uv), axis=1) & (z > 0)
        u = np.rint(uv[ok, 0]).astype(np.int64)
        v = np.rint(uv[ok, 1]).astype(np.int64)
        inside = (u >= 0) & (u < shape[1]) & (v >= 0) & (v < shape[0])
        np.minimum.at(out, (v[inside], u[inside]), z[ok][inside])
    out[~np.isfinite(out)] = np.nan
    return out


def left_depth(kind: str, value, truth: ProtocolTruth) -> np.ndarray:
    """The left-view z-depth map (H, W), metres, NaN = no estimate, of an output of ``kind``
    (``OUTPUT_KINDS``): a depth or disparity map (H, W), a mesh, or points (N, 3). Raises ValueError
    for a map of another size, or a disparity when the told rig is not a rectified pair."""
    if kind in ("depth", "disparity"):
        a = np.asarray(value, np.float64)
        if a.ndim == 3 and a.shape[2] == 1:
            a = a[..., 0]
        if a.shape != truth.shape:
            raise ValueError(f"{kind} map of {a.shape[::-1]} px: the sample's left view is {truth.shape[::-1]} (W, H)")
        if kind == "depth":
            return a
        if truth.fb is None or truth.doffs_px is None:
            raise ValueError("the rig the method is told is not a rectified pair: its disparities are not depths")
        return depth_from_disparity(a, truth.fb, truth.doffs_px)
    if kind == "mesh":
        return depth_from_mesh(value, truth.camera.center, truth.points, truth.mask, truth.camera)
    if kind == "points":
        return depth_from_points(value, truth.camera, truth.shape)
    raise ValueError(f"output kind {kind!r} is not known: allowed {', '.join(OUTPUT_KINDS)}")


@dataclass(frozen=True)
class SparseFigures:
    """Sparse points (the paper's square centres) against the true surface: ``count`` finite points,
    the RMS and largest distance to the surface (mm), and the RMS z-depth error (mm) along each point's
    ray from the left camera against the surface's first hit on that ray (None where no ray hits)."""

    count: int
    distance_rms_mm: float | None
    distance_max_mm: float | None
    depth_rms_mm: float | None


def sparse_figures(points_m: np.ndarray, truth: ProtocolTruth, mesh) -> SparseFigures:
    """The ``SparseFigures`` of world-frame points (N, 3) in metres (rows with a non-finite coordinate
    left out) against the true mesh (``trimesh.Trimesh``, world frame): distances by
    ``evaluation.point_metrics.point_to_surface_distance``, first hits by ``first_hits``."""
    from platebench.evaluation.point_metrics import point_to_surface_distance  # noqa: PLC0415
    p = np.asarray(points_m, np.float64).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    if not len(p):
        return SparseFigures(0, None, None, None)
    dist = point_to_surface_distance(p, mesh)
    cam = truth.camera
    dirs = p - cam.center
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    hit, locs = first_hits(mesh, cam.center, dirs)
    zt = np.full(len(p), np.nan)
    zt[hit] = cam.depth(locs)
    e = cam.depth(p) - zt
    e = e[np.isfinite(e)]
    mm = 1e3
    return SparseFigures(len(p), float(math.sqrt(np.mean(dist * dist))) * mm, float(np.max(dist)) * mm,
                         float(math.sqrt(np.mean(e * e))) * mm if e.size else None)
