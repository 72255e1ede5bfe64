"""Scores of any method's output against a sample's exact ground truth, by the kind of output.

A method (the bench's own, a plug-in, or another program whose output is scored from a file)
gives one of four kinds of result, each scored with the metrics its field uses:

* **disparity** (H, W) px of the left view, d = u_left - u_right (Middlebury's convention, Z = f B /
  (d + doffs)); +inf or NaN = no estimate. Middlebury v3 with the SDK's rules (other values,
  0 and negative ones too, are estimates clipped to [0, ndisp]; bad 0.5/1/2/4 px, invalid,
  avgerr, rms, A50-A99) against the sample's float32 truth file, and ETH3D two-view metrics
  (estimates finite and > 0; ``evaluation.disparity_metrics``) on all
  pixels with known truth and on the non-occluded ones (``evaluation.stereo_truth``), plus the
  depth error the disparities imply (scored as a depth map).
* **depth** (H, W) z-depth in metres along the left optical axis; non-finite or <= 0 = no
  estimate. Over the plate's pixels (ground-truth mask): |Z_est - Z_gt| (mean, median, RMS, max,
  nearest-rank quantiles A50-A99, signed mean), the share of estimates off by more than 0.1 /
  0.5 / 1 / 2 mm, ``coverage_frac`` = plate pixels with an estimate / plate pixels, and the count
  of estimates off the plate.
* **points** (N, 3) world frame, metres. Exact distance of each point to the true surface
  (``evaluation.point_metrics``, not trimesh's closest point, which is off by up to 0.08 mm on
  plate meshes in metres); outliers = points farther than ``outlier_m`` (default 2 mm, the
  paper's depth bound); ``coverage_frac`` = plate pixels into which a point projects through the
  true left camera / plate pixels, and the surface coverage ``surface_coverage_frac`` of the
  plate's top surface at a lateral radius (``evaluation.surface_metrics``, outliers excluded).
* **mesh** (a trimesh.Trimesh, world frame, metres). Both ways, as DTU and Tanks and Temples do:
  accuracy = distance from points sampled uniformly on the estimate to the true surface,
  completeness = distance from points sampled on the true plate's top surface to the estimate;
  at each threshold tau, precision = share of estimate samples within tau, recall = share of
  truth samples within tau, F = 2 P R / (P + R); DTU's "overall" = (mean accuracy + mean
  completeness) / 2; ``coverage_frac`` = plate pixels whose true ray (left camera centre through
  the pixel's true world point) hits the mesh / plate pixels.

``coverage_frac`` has one meaning for every kind, the share of the left view's plate pixels with an
estimate (``evaluation.pixel_coverage``).

Every score is a frozen dataclass with values in metres (pixels for disparities); its JSON layout,
with the unit in every key (mm, px, pct, frac, count, px counts as ``_px``), is its codec in
``bench.io.codecs.evaluation``, and its results-table row is ``bench.run.outputs.score_row``. Bad
inputs raise ``FieldScoreError`` (one line naming the input).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from platebench.errors import UserValueError
from platebench.evaluation.disparity_metrics import (
    QUANTILES_PCT,
    Eth3dScore,
    MiddleburyScore,
    eth3d_metrics,
    middlebury_metrics,
)
from platebench.evaluation.pixel_coverage import (
    PixelCoverage,
    coverage_of_map,
    coverage_of_mesh,
    coverage_of_points,
)
from platebench.evaluation.point_metrics import closest_point_on_mesh
from platebench.evaluation.stats import nearest_rank_quantile
from platebench.evaluation.stereo_truth import (
    RectifiedPair,
    disparity_from_depth,
    ndisp_for,
    nonoccluded_mask,
    rectified_pair,
)
from platebench.evaluation.surface_metrics import SurfaceScore, sample_mesh_surface, score_surface
from platebench.scenes.rig import StereoRig
from platebench.tolerances import tol

if TYPE_CHECKING:
    import trimesh  # annotations only: importing trimesh takes a second

__all__ = ["FieldScoreError", "KINDS", "FieldTruth", "AbsErrors", "DepthScore", "DisparityScore",
           "PointCloudScore", "MeshScore", "score_depth", "score_disparity", "score_point_cloud", "score_mesh",
           "implied_depth", "DEPTH_BAD_MM", "OUTLIER_M",
           "COVERAGE_RADIUS_M", "SAMPLE_SPACING_M", "MESH_THRESHOLDS_M"]

KINDS = ("disparity", "depth", "points", "mesh")
DEPTH_BAD_MM: tuple[float, ...] = (0.1, 0.5, 1.0, 2.0)
OUTLIER_M = 2e-3  # the paper's depth bound (section V-D)
COVERAGE_RADIUS_M = 1e-3
SAMPLE_SPACING_M = 0.5e-3
MESH_THRESHOLDS_M: tuple[float, ...] = (0.1e-3, 0.2e-3, 0.5e-3, 1e-3, 2e-3)
MM = 1e3  # millimetres per metre: the unit of every figure the file forms hold


class FieldScoreError(UserValueError):
    """A method's output cannot be scored (wrong size, nothing finite, wrong shape): one line."""


def threshold_key(x: float) -> str:
    """0.5 -> '0_5', 2.0 -> '2_0' (a threshold in a file form's key)."""
    return f"{x:g}".replace(".", "_") if not float(x).is_integer() else f"{x:.1f}".replace(".", "_")


# ----------------------------------------------------------------------------- truth
@dataclass(frozen=True)
class FieldTruth:
    """What the four kinds are scored against (world frame, metres; left view for maps).

    ``depth``: (H, W) float64 z-depth, inf off the plate; ``mask``: (H, W) bool plate pixels;
    ``disparity``: (H, W) float64 f B / Z - doffs, inf unknown, as the sample's ``gt/disp0GT.pfm`` holds
    it (float32 values: the truth a user is given, and what Middlebury's SDK would score against);
    ``nonocc``: (H, W) bool plate pixels
    the right camera sees too; ``disparity_right``: the right view's (Middlebury's disp1: its pixel u
    matches u + d in the left view); ``mesh``: the plate; ``top_faces``: (F,) bool, the faces of its
    top surface (what surface coverage and completeness are measured on); ``points``: (H, W, 3) the
    true world point seen at each left pixel, NaN off the plate, and ``true_left``: the left camera
    really posed (``scenes.camera.Camera``): a cloud's points project through it, a mesh's true rays
    start at its centre and pass through ``points`` (``coverage_frac``; None: a mesh's coverage is not
    measured)."""

    rig: StereoRig
    pair: RectifiedPair
    depth: np.ndarray
    mask: np.ndarray
    disparity: np.ndarray
    nonocc: np.ndarray
    disparity_right: np.ndarray
    mesh: trimesh.Trimesh
    top_faces: np.ndarray
    points: np.ndarray | None = None
    true_left: object = None

    @classmethod
    def from_maps(cls, rig: StereoRig, depth_left, mask_left, points_left, depth_right, mask_right,
                  mesh: trimesh.Trimesh, top_faces=None, disparity_left=None, true_left=None) -> "FieldTruth":
        """Derive both disparities and the non-occlusion mask from the two views' ground-truth maps.
        ``disparity_left``: the left true disparity as written (``gt/disp0GT.pfm``); it must agree with
        the depth map's (same known pixels, values within float32 rounding) and is what disparities
        are scored against. Without it, the depth map's, rounded to float32 as the file would be.
        ``true_left``: the left camera the true points were cast from (default ``rig.left``); given, the
        pair was posed by a robot and ``disparity_left`` is taken as written (the disparity its images
        have), checked only for the pixels that have a truth."""
        pair = rectified_pair(rig)
        mask_left, mask_right = np.array(mask_left, bool), np.asarray(mask_right, bool)
        depth = np.where(mask_left, np.asarray(depth_left, np.float64), np.inf)
        d0 = np.where(mask_left, disparity_from_depth(depth, pair), np.inf)
        d1 = np.where(mask_right, disparity_from_depth(depth_right, pair), np.inf)
        nonocc = nonoccluded_mask(points_left, mask_left, d0, rig.right, d1, mask_right)
        if disparity_left is None:
            given = d0.astype(np.float32).astype(np.float64)
        else:
            given = np.asarray(disparity_left, np.float64)
            if given.shape != d0.shape or not np.array_equal(np.isfinite(given), np.isfinite(d0)):
                raise ValueError("the left true disparity (disp0GT.pfm) and the depth map disagree on which pixels "
                                 "have a truth")
            known = np.isfinite(d0)
            far = np.abs(given[known] - d0[known])
            # a pair a robot took (``true_left`` given) is no rectified pair: its file holds the disparity
            # its images really have (``bench.io.sample_files.pair_disparity``), not f B / Z of the told rig
            if true_left is None and far.size and far.max() > tol.disparity_file_px:
                raise ValueError(f"the left true disparity (disp0GT.pfm) differs from the depth map's by up to "
                                 f"{far.max():.3g} px: allowed {tol.disparity_file_px:g} px")
        d0 = given
        top = np.ones(len(mesh.faces), bool) if top_faces is None else np.asarray(top_faces, bool)
        pts = np.array(points_left, np.float64)
        for a in (depth, d0, nonocc, mask_left, d1, pts):
            a.setflags(write=False)
        return cls(rig, pair, depth, mask_left, d0, nonocc, d1, mesh, top, pts,
                   rig.left if true_left is None else true_left)

    @property
    def shape(self) -> tuple[int, int]:
        return self.mask.shape


# ----------------------------------------------------------------------------- statistics
@dataclass(frozen=True)
class AbsErrors:
    """Statistics of absolute errors (metres): mean, median, RMS, max, nearest-rank quantiles
    (``stats.nearest_rank_quantile``, as Middlebury's A50-A99) and, for signed errors, their mean."""

    count: int
    mean_m: float
    median_m: float
    rms_m: float
    max_m: float
    quantiles_m: tuple[tuple[int, float], ...]
    signed_mean_m: float | None = None

    @classmethod
    def of(cls, errors_m, signed: bool) -> "AbsErrors":
        e = np.asarray(errors_m, np.float64).ravel()
        a = np.abs(e)
        if a.size == 0:
            nan = math.nan
            return cls(0, nan, nan, nan, nan, tuple((q, nan) for q in QUANTILES_PCT), nan if signed else None)
        return cls(int(a.size), float(a.mean()), float(np.median(a)), float(np.sqrt(np.mean(a * a))),
                   float(a.max()), tuple((q, nearest_rank_quantile(a, q)) for q in QUANTILES_PCT),
                   float(e.mean()) if signed else None)


# ----------------------------------------------------------------------------- depth
@dataclass(frozen=True)
class DepthScore:
    """A left-view z-depth map against the true depth over the plate's pixels (see module doc)."""

    plate_px: int
    estimated_px: int
    off_plate_px: int
    errors: AbsErrors  # |Z_est - Z_gt| over the estimated plate pixels (signed mean: + = too far)
    bad_pct: tuple[tuple[float, float], ...]  # ((threshold mm, % of estimated plate px beyond it), ...)

    @property
    def coverage(self) -> PixelCoverage:
        return PixelCoverage(self.plate_px, self.estimated_px)

    @property
    def coverage_frac(self) -> float:
        """The share of the plate's pixels with an estimate (``evaluation.pixel_coverage``)."""
        return self.coverage.coverage_frac


def _map(values, truth: FieldTruth, what: str) -> np.ndarray:
    a = np.asarray(values)
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[..., 0]
    if a.ndim != 2:
        raise FieldScoreError(f"{what}: expected a single-channel (H, W) map, got shape {a.shape}")
    if a.shape != truth.shape:
        raise FieldScoreError(f"{what}: size {a.shape[1]}x{a.shape[0]} does not match the sample's left image "
                              f"{truth.shape[1]}x{truth.shape[0]}")
    a = a.astype(np.float64)
    if not np.any(np.isfinite(a) & (a > 0)):
        raise FieldScoreError(f"{what}: no finite value > 0 (all NaN, inf or <= 0): nothing to score")
    return a


def _score_depth_values(z: np.ndarray, truth: FieldTruth, bad_mm) -> DepthScore:
    valid = np.isfinite(z) & (z > 0)
    est = valid & truth.mask
    err = z[est] - truth.depth[est]
    a_mm = np.abs(err) * MM
    cov = coverage_of_map(valid, truth.mask)
    n = cov.estimated_px
    bad = tuple((float(t), 100.0 * int(np.count_nonzero(a_mm > t)) / n if n else math.nan) for t in bad_mm)
    return DepthScore(cov.plate_px, n, int((valid & ~truth.mask).sum()), AbsErrors.of(err, signed=True), bad)


def score_depth(depth_m, truth: FieldTruth, *, bad_mm=DEPTH_BAD_MM, what: str = "depth map") -> DepthScore:
    """Score a left-view z-depth map (H, W) in metres (module doc)."""
    return _score_depth_values(_map(depth_m, truth, what), truth, bad_mm)


# ----------------------------------------------------------------------------- disparity
@dataclass(frozen=True)
class DisparityScore:
    """A left-view disparity map: Middlebury and ETH3D metrics (all / non-occluded pixels) and the
    depth error it implies through Z = f B / (d + doffs)."""

    middlebury: MiddleburyScore
    eth3d: Eth3dScore
    depth: DepthScore
    nonocc_px: int
    doffs_px: float


def implied_depth(disparity_px, fb: float, doffs_px: float) -> np.ndarray:
    """(H, W) z-depth (metres) of a left-view disparity map (px): Z = f B / (d + doffs), ``fb`` the
    focal length times the baseline (px m), ``doffs_px`` the principal points' offset. An estimate is
    a finite d > 0 (ETH3D's rule) with d + doffs > 0; NaN elsewhere. The depth a disparity is scored
    by (``score_disparity``) and drawn by (``evaluation.error_maps``)."""
    d = np.asarray(disparity_px, np.float64)
    s = d + doffs_px
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.isfinite(d) & (d > 0) & (s > 0), fb / s, np.nan)


def score_disparity(disparity_px, truth: FieldTruth, *, bad_mm=DEPTH_BAD_MM,
                    what: str = "disparity map") -> DisparityScore:
    """Score a left-view disparity map (H, W) in px (module doc)."""
    d = _map(disparity_px, truth, what)
    est = np.where(np.isfinite(d) & (d > 0), d, np.inf)  # ETH3D's and the implied depth's estimates
    mb = middlebury_metrics(d, truth.disparity, truth.nonocc, max_disparity_px=ndisp_for(truth.disparity))
    eth = eth3d_metrics(est, truth.disparity, truth.nonocc)
    z = implied_depth(d, truth.pair.fb, truth.pair.doffs_px)
    return DisparityScore(mb, eth, _score_depth_values(z, truth, bad_mm), int(truth.nonocc.sum()),
                          truth.pair.doffs_px)


# ----------------------------------------------------------------------------- points
@dataclass(frozen=True)
class PointCloudScore:
    """World points against the true surface: distances, outliers, ``coverage`` (the plate's pixels
    into which a point projects) and ``surface`` (the surface coverage of the top surface)."""

    count: int
    dropped_count: int  # rows with NaN/inf, left out
    distance: AbsErrors  # unsigned distance to the true surface (metres)
    outlier_threshold_m: float
    outlier_count: int
    surface: SurfaceScore  # outliers excluded; coverage_radius_m is the lateral radius
    coverage: PixelCoverage  # left plate pixels into which a point projects (true left camera)

    @property
    def outlier_frac(self) -> float:
        return self.outlier_count / self.count if self.count else math.nan


def _points(points_m, what: str) -> tuple[np.ndarray, int]:
    P = np.asarray(points_m, np.float64)
    if P.ndim != 2 or P.shape[1] != 3:
        raise FieldScoreError(f"{what}: expected (N, 3) world points in metres, got shape {P.shape}")
    ok = np.all(np.isfinite(P), axis=1)
    if not ok.any():
        raise FieldScoreError(f"{what}: no finite point (all {len(P)} rows hold NaN or inf, or the cloud is empty)")
    return P[ok], int((~ok).sum())


def score_point_cloud(points_m, truth: FieldTruth, *, outlier_m: float = OUTLIER_M,
                      coverage_radius_m: float = COVERAGE_RADIUS_M, sample_spacing_m: float = SAMPLE_SPACING_M,
                      seed: int = 0, what: str = "points") -> PointCloudScore:
    """Score (N, 3) world points in metres (module doc); rows with NaN/inf are dropped and counted."""
    P, dropped = _points(points_m, what)
    _, dist, _ = closest_point_on_mesh(P, truth.mesh)
    cov = score_surface(P, truth.mesh, sample_spacing_m=sample_spacing_m, coverage_radius_m=coverage_radius_m,
                        max_distance_m=outlier_m, coverage_faces=truth.top_faces, seed=seed)
    return PointCloudScore(len(P), dropped, AbsErrors.of(dist, signed=False), float(outlier_m),
                           int(np.count_nonzero(dist > outlier_m)), cov,
                           coverage_of_points(P, truth.true_left or truth.rig.left, truth.mask))


# ----------------------------------------------------------------------------- mesh
@dataclass(frozen=True)
class MeshScore:
    """A surface mesh against the true plate, both ways (DTU / Tanks and Temples; module doc)."""

    accuracy: AbsErrors  # estimate samples -> true surface
    completeness: AbsErrors  # true top-surface samples -> estimate
    thresholds: tuple[tuple[float, float, float, float], ...]  # (tau m, precision, recall, F) fractions
    sample_spacing_m: float
    faces_count: int
    coverage: PixelCoverage | None = None  # left plate pixels whose true ray hits the mesh (None: no true rays)

    @property
    def coverage_frac(self) -> float | None:
        """The share of the plate's pixels whose true ray hits the mesh (``evaluation.pixel_coverage``)."""
        return None if self.coverage is None else self.coverage.coverage_frac

    @property
    def overall_m(self) -> float:
        """DTU's overall figure: (mean accuracy + mean completeness) / 2."""
        return 0.5 * (self.accuracy.mean_m + self.completeness.mean_m)


def score_mesh(mesh: trimesh.Trimesh, truth: FieldTruth, *, thresholds_m=MESH_THRESHOLDS_M,
               sample_spacing_m: float = SAMPLE_SPACING_M, seed: int = 0, what: str = "mesh") -> MeshScore:
    """Score a surface mesh (world frame, metres) both ways (module doc). Both surfaces are sampled
    uniformly by area at ``sample_spacing_m`` (seeded); distances are exact point-to-triangle ones."""
    faces = np.asarray(getattr(mesh, "faces", np.zeros((0, 3))))
    if len(faces) == 0:
        raise FieldScoreError(f"{what}: the mesh has no faces")
    if not np.all(np.isfinite(np.asarray(mesh.vertices))):
        raise FieldScoreError(f"{what}: mesh vertices hold NaN or inf")
    if not float(mesh.area) > 0:
        raise FieldScoreError(f"{what}: the mesh has zero area")
    try:
        est_samples, _ = sample_mesh_surface(mesh, sample_spacing_m, seed)
        gt_samples, _ = sample_mesh_surface(truth.mesh, sample_spacing_m, seed + 1, truth.top_faces)
    except ValueError as e:
        raise FieldScoreError(f"{what}: {e}") from None
    _, acc, _ = closest_point_on_mesh(est_samples, truth.mesh)
    _, comp, _ = closest_point_on_mesh(gt_samples, mesh)
    rows = []
    for t in thresholds_m:
        p = float(np.mean(acc <= t))
        r = float(np.mean(comp <= t))
        rows.append((float(t), p, r, 2 * p * r / (p + r) if p + r > 0 else 0.0))
    cov = None if truth.points is None else coverage_of_mesh(mesh, (truth.true_left or truth.rig.left).center,
                                                             truth.points, truth.mask)
    return MeshScore(AbsErrors.of(acc, signed=False), AbsErrors.of(comp, signed=False), tuple(rows),
                     float(sample_spacing_m), int(len(faces)), cov)

