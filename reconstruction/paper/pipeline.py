"""The paper's reconstruction pipeline, end to end, as one pure function of images + calibration.

passive pair -> plate regions (Tsai threshold, contour following, corners)
             -> sub-pixel outlines -> boundary stereo (rows; corners for row-parallel edges)
             -> boundary plane (L1 contour integral, paper III) beside the least-squares plane
active pair  -> squares inside the passive boundary -> horizontal arrays -> Fig. 6 checks
             -> array and square matching (paper III) -> triangulation
             -> centres of squares cut in either image (by the plate's outline, or by the
                threshold: ``squares.Square.cut``) set apart (``CutSquares``), out of the
                points, the surface and every figure unless ``keep_cut_squares``
             -> false-boundary counting test (paper IV-B) against the projector's feature rays
             -> energy-minimising surface (paper V-D, thin plate) over the boundary domain

It never sees ground truth: only the four images, the stereo calibration, and the
projector's feature rays (from its calibration) with the pattern's feature table.
A calibration with lens distortion is honoured first: the images are resampled to the
cameras' pinholes (``reconstruction.calibration.undistort``), as Tsai-style calibration does,
and everything after works on the pinhole pair (``reconstruct``, ``passive_stereo`` and
``square_stereo`` each do it, so any entry point is safe; ``Reconstruction`` pixels are
undistorted pixels). World frame, metres; pixels in OpenCV convention.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from platebench.reconstruction.calibration.undistort import undistort_views
from platebench.reconstruction.paper.boundary_plane import (
    BoundaryPlane,
    fit_boundary_plane,
    least_squares_plane,
    plane_frame,
)
from platebench.reconstruction.paper.false_boundary import (
    FalseBoundaryTest,
    FeatureRays,
    false_boundary_test,
    rays_on_plane,
)
from platebench.reconstruction.paper.passive_boundary import boundary_stereo
from platebench.reconstruction.paper.plate_region import ReconstructionError
from platebench.reconstruction.paper.square_matching import (
    check_fig6,
    group_squares,
    match_squares,
)
from platebench.reconstruction.paper.squares import extract_squares
from platebench.reconstruction.paper.surface_interpolation import (
    interpolate_surface,
    surface_grid_to_mesh,
)
from platebench.reconstruction.paper.threshold import (
    otsu_threshold,
    tsai_moment_threshold,
)
from platebench.scenes.camera import Camera, triangulate_rectified
from platebench.scenes.naming import IMAGE_NAMES
from platebench.scenes.pattern import Pattern
from platebench.scenes.rig import StereoRig

PLANE_SAMPLE_M = 1e-3


@dataclass(frozen=True)
class PipelineOptions:
    grid_step_m: float = 2e-3  # surface grid spacing (m)
    boundary_in_surface: bool = True  # use the 3D boundary as data for the surface, besides the squares
    boundary_sample_m: float = 4e-3  # spacing of boundary samples used as surface data
    surface_data_weight: float | None = 1e3  # penalty weight of the data (None: exact interpolation)
    # True: the centres of squares cut in either image stay among the points (and the surface),
    # as the paper's pipeline has them; False: they are set apart (``Reconstruction.cut``)
    keep_cut_squares: bool = False


@dataclass(frozen=True)
class CutSquares:
    """Matched square centres whose square is cut in the left or right image (``squares.Square.cut``:
    by the plate's outline, or by the threshold): the centroid of a part, not the square's centre.
    World frame, metres: ``points`` (K,3), ``uv_left``/``uv_right`` (K,2), ``feature_id`` (K,)
    (-1 unknown); ``reasons`` (K,) e.g. "left: outline"."""

    points: np.ndarray
    uv_left: np.ndarray
    uv_right: np.ndarray
    feature_id: np.ndarray
    reasons: tuple[str, ...] = ()

    @classmethod
    def empty(cls) -> "CutSquares":
        return cls(np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, int))

    def __len__(self) -> int:
        return len(self.points)


@dataclass(frozen=True)
class Reconstruction:
    """What the method measured (world frame, metres) and every decision it took. ``points`` and
    the surface hold the whole squares' centres; those of squares cut in either image are in
    ``cut`` (unless ``PipelineOptions.keep_cut_squares``)."""

    points: np.ndarray  # (M,3) triangulated square centres
    uv_left: np.ndarray  # (M,2)
    uv_right: np.ndarray  # (M,2)
    feature_id: np.ndarray  # (M,) label from the projector prediction (-1 unknown)
    pattern_row: np.ndarray  # (M,)
    pattern_col: np.ndarray  # (M,)
    boundary: np.ndarray  # (N,3) closed 3D boundary
    boundary_source: np.ndarray  # (N,) corner / side / top-bottom
    boundary_plane: BoundaryPlane
    least_squares_plane: BoundaryPlane
    surface_vertices: np.ndarray
    surface_faces: np.ndarray
    false_boundary: FalseBoundaryTest
    fig6: dict  # image name -> Fig6Check
    unmatched: tuple[str, ...]
    corner_row_mismatch_px: np.ndarray
    thresholds: dict
    timings_s: dict = field(default_factory=dict)
    cut: CutSquares = field(default_factory=CutSquares.empty)  # centres of cut squares, set apart


def projector_feature_rays(projector: Camera, pattern: Pattern) -> FeatureRays:
    """Feature rays from the projector's pinhole calibration (K, R, t) and the pattern's feature table."""
    centers = np.array([f.center for f in pattern.features], float).reshape(-1, 2)
    o, d = projector.rays(centers)
    return FeatureRays(np.repeat(o[None], len(d), 0), d, np.array([f.id for f in pattern.features], int))


def _label(points_left_uv, rays: FeatureRays, plane: BoundaryPlane, left: Camera, max_px: float):
    """Nearest predicted feature (ray cut with the boundary plane, seen by the left camera)."""
    hits = rays_on_plane(rays, plane)
    pred = left.project(np.nan_to_num(hits, nan=0.0))
    pred[~np.all(np.isfinite(hits), axis=1)] = np.nan
    ids = np.full(len(points_left_uv), -1)
    for i, uv in enumerate(points_left_uv):
        d = np.linalg.norm(pred - uv, axis=1)
        if np.isfinite(d).any():
            k = int(np.nanargmin(d))
            if d[k] <= max_px:
                ids[i] = rays.ids[k]
    return ids


def reconstruct(images: dict, rig: StereoRig, rays: FeatureRays, pattern: Pattern,
                options: PipelineOptions = PipelineOptions()) -> Reconstruction:
    """Run the paper's pipeline on the four images (keys: left/right_passive/active)."""
    missing = [n for n in IMAGE_NAMES if n not in images]
    if missing:
        raise ReconstructionError(f"missing image {missing[0]}")
    for n in IMAGE_NAMES:
        if np.asarray(images[n]).shape != (rig.left.height, rig.left.width):
            raise ReconstructionError(f"{n}: size {np.asarray(images[n]).shape[::-1]} differs from the "
                                      f"calibration's {rig.left.width}x{rig.left.height}")
    timings = {}
    t = time.perf_counter()

    def lap(name):
        nonlocal t
        now = time.perf_counter()
        timings[name] = now - t
        t = now

    distorted = rig.left.distortion is not None or rig.right.distortion is not None
    images, rig = undistort_views(images, rig)
    if distorted:
        lap("undistort_s")

    # -- passive stereo: boundary ------------------------------------------------
    passive = passive_stereo(images["left_passive"], images["right_passive"], rig)
    timings.update(passive.timings_s)
    t = time.perf_counter()
    regions, stereo, plane, ls_plane = passive.regions, passive.stereo, passive.plane, passive.least_squares_plane

    # -- active stereo: squares ---------------------------------------------------
    sq = square_stereo(images, {c: regions[c].mask for c in ("left", "right")}, rig)
    dets, matches, pts, uvl, uvr = sq.detections, sq.matches, sq.points, sq.uv_left, sq.uv_right
    fig6 = {f"{c}_active": check_fig6(dets[c].squares, sq.groups[c], f"{c}_active") for c in ("left", "right")}
    heights = [s.bbox[3] - s.bbox[1] + 1 for s in dets["left"].squares]
    timings.update(sq.timings_s)
    t = time.perf_counter()
    labels = _label(uvl, rays, plane, rig.left, max_px=float(np.median(heights)))
    reasons = [", ".join(f"{c}: {sq_.cut}" for c, sq_ in (("left", dets["left"].squares[i]),
                                                           ("right", dets["right"].squares[j])) if sq_.cut)
               for i, j in matches.pairs]
    cut = CutSquares.empty()
    if not options.keep_cut_squares:
        away = np.array([bool(r) for r in reasons], bool)
        cut = CutSquares(pts[away], uvl[away], uvr[away], labels[away], tuple(r for r in reasons if r))
        pts, uvl, uvr, labels = pts[~away], uvl[~away], uvr[~away], labels[~away]
    feats = {f.id: f for f in pattern.features}
    rows = np.array([feats[i].row if i in feats else -1 for i in labels], int)
    cols = np.array([feats[i].col if i in feats else -1 for i in labels], int)
    lap("triangulation_s")

    fb = false_boundary_test({f"{c}_active": complete_square_count(dets[c].squares) for c in ("left", "right")},
                             rays, plane, stereo.points,
                             arrays_disagree=matches.count_mismatch,
                             cut={f"{c}_active": sum(sq_.cut is not None for sq_ in dets[c].squares)
                                  for c in ("left", "right")})
    lap("false_boundary_test_s")

    # -- surface -------------------------------------------------------------------
    verts, faces = _surface(pts, stereo.points, plane, options)
    lap("surface_s")
    thresholds = {}
    for n in IMAGE_NAMES:
        img = np.asarray(images[n])
        thresholds[n] = {"tsai": float(tsai_moment_threshold(img).threshold), "otsu": float(otsu_threshold(img))}
    lap("threshold_report_s")
    timings["total_s"] = sum(timings.values())
    return Reconstruction(pts, uvl, uvr, labels, rows, cols, stereo.points, stereo.source, plane, ls_plane,
                          verts, faces, fb, fig6, matches.unmatched, stereo.corner_row_mismatch_px, thresholds,
                          timings, cut)


@dataclass(frozen=True)
class SquareStereo:
    """The active pair's squares (paper III): detections per camera ("left"/"right"), the horizontal
    arrays, the matches, and the triangulated centres (M,3) (world, metres) with their (M,2) pixels."""

    detections: dict
    groups: dict
    matches: object  # SquareMatches
    points: np.ndarray
    uv_left: np.ndarray
    uv_right: np.ndarray
    timings_s: dict


def square_stereo(images: dict, masks: dict, rig: StereoRig) -> SquareStereo:
    """Squares of ``images["left_active"]``/``["right_active"]`` inside the plate masks ((H,W) bool,
    by camera, in undistorted pixels), sorted into horizontal arrays, matched by the paper's
    criteria and triangulated (images through a distorted lens are undistorted first)."""
    t0 = time.perf_counter()
    images, rig = undistort_views({k: images[k] for k in ("left_active", "right_active")}, rig)
    dets = {c: extract_squares(images[f"{c}_active"], masks[c], f"{c}_active") for c in ("left", "right")}
    t1 = time.perf_counter()
    groups = {c: group_squares(dets[c].squares) for c in ("left", "right")}
    ys = sorted(dets["left"].squares[g[0]].centroid[1] for g in groups["left"])
    heights = [s.bbox[3] - s.bbox[1] + 1 for s in dets["left"].squares]
    if len(ys) > 1:  # arrays are matched by their leftmost squares' y within half the arrays' spacing
        tol_px = 0.5 * float(np.median(np.diff(ys)))
    else:
        tol_px = float(np.median(heights)) if heights else 0.0
    matches = match_squares(dets["left"].squares, dets["right"].squares, groups["left"], groups["right"], tol_px)
    t2 = time.perf_counter()
    uvl = np.array([dets["left"].squares[i].centroid for i, _ in matches.pairs]).reshape(-1, 2)
    uvr = np.array([dets["right"].squares[j].centroid for _, j in matches.pairs]).reshape(-1, 2)
    pts = triangulate_rectified(uvl[:, 0], 0.5 * (uvl[:, 1] + uvr[:, 1]), uvr[:, 0], rig.left, rig.baseline_m)
    return SquareStereo(dets, groups, matches, pts, uvl, uvr,
                        {"squares_s": t1 - t0, "square_matching_s": t2 - t1})


@dataclass(frozen=True)
class PassiveResult:
    """Passive stereo alone (sensing stages 1 and 2): regions, matched boundary, boundary planes."""

    regions: dict
    stereo: object  # BoundaryStereo
    plane: BoundaryPlane
    least_squares_plane: BoundaryPlane
    timings_s: dict

    @property
    def boundary(self) -> np.ndarray:
        return self.stereo.points


def passive_stereo(left_passive: np.ndarray, right_passive: np.ndarray, rig: StereoRig) -> PassiveResult:
    """Plate regions, sub-pixel outlines, boundary stereo and the boundary plane (world, metres);
    images through a distorted lens are undistorted first (regions in undistorted pixels)."""
    timings = {}
    t = time.perf_counter()
    views, rig = undistort_views({"left_passive": left_passive, "right_passive": right_passive}, rig)
    left_passive, right_passive = views["left_passive"], views["right_passive"]
    # The paper's corner method where it applies, else the general outline stereo (stereo.method).
    regions, stereo = boundary_stereo(left_passive, right_passive, rig)
    timings["boundary_stereo_s"] = time.perf_counter() - t
    t = time.perf_counter()
    toward = rig.center - stereo.points.mean(axis=0)
    # The plane's contour integral on the boundary resampled every PLANE_SAMPLE_M of arc
    # (the measured polyline has ~0.2 mm vertex spacing; the plane moves < 1 um).
    loop = _resample_closed(stereo.points, PLANE_SAMPLE_M)
    plane = fit_boundary_plane(loop, toward=toward)
    ls_plane = least_squares_plane(loop, toward=toward)
    timings["boundary_plane_s"] = time.perf_counter() - t
    return PassiveResult(regions, stereo, plane, ls_plane, timings)


def complete_square_count(squares) -> int:
    """Squares counted by the false-boundary test: whole ones (area >= half the median area).

    A square cut by the plate's edge is seen but its centre ray may fall outside the boundary;
    counting it would hide a missing whole square elsewhere."""
    if not squares:
        return 0
    areas = np.array([s.area_px for s in squares])
    return int(np.sum(areas >= 0.5 * np.median(areas)))


def _resample_closed(poly: np.ndarray, step: float) -> np.ndarray:
    seg = np.linalg.norm(np.roll(poly, -1, 0) - poly, axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    closed = np.vstack([poly, poly[:1]])
    q = np.arange(0.0, s[-1], step)
    return np.column_stack([np.interp(q, s, closed[:, k]) for k in range(3)])


def _surface(points: np.ndarray, boundary: np.ndarray, plane: BoundaryPlane, opt: PipelineOptions):
    """Thin-plate surface in the boundary-plane frame, clipped to the boundary; world-frame mesh."""
    R, origin = plane_frame(plane)
    data = points
    if opt.boundary_in_surface:
        data = np.vstack([points, _resample_closed(boundary, opt.boundary_sample_m)])
    local = (data - origin) @ R.T
    poly = ((boundary - origin) @ R.T)[:, :2]
    if len(local) < 3:
        raise ReconstructionError("surface: fewer than 3 measured points")
    grid = interpolate_surface(local[:, :2], local[:, 2], poly, opt.grid_step_m, smoothness="thin_plate",
                               data_weight=opt.surface_data_weight)
    return surface_grid_to_mesh(grid, frame=(R, origin))
