"""Score a reconstruction against a sample's exact ground truth.

Inputs are plain arrays and geometry types (bench/ reads the files). Every JSON key
carries its unit. Sections:

* ``points``: 3D error of each triangulated square centre against the true centre
  (projector ray through the feature centre, cut with the plate mesh). The true
  identity of a reconstructed point is the ground-truth feature lighting its left
  pixel; errors are split into depth (along the left optical axis) and x/y, as in the
  paper; plus the distance of each point to the true surface.
* ``matching``: detected / matched / visible / expected counts and the correct-match
  rate (left and right pixels lit by the same feature).
* ``boundary_3d`` (mm) and ``boundary_image`` (px, left image, against the GT mask).
* ``surface``: interpolated surface against the plate mesh (RMS, max, and ``surface_coverage_frac``:
  the share of the true plate's area within the coverage radius of the estimate).
* ``coverage``: the bench's ``coverage_frac`` (``evaluation.pixel_coverage``): the share of the
  left view's plate pixels whose true ray hits the interpolated surface mesh.
* ``false_boundary``: ground truth (a true-boundary point hidden from a camera, ``BoundaryTruth``) vs
  the counting test's verdict (``reconstruction.paper.false_boundary.FalseBoundaryTest``).
* ``per_point``: what an error map draws (``PerPointErrors``): each square centre's error (the 3D
  error against its true centre where its identity is known, else its distance to the true
  surface) and each surface vertex's exact distance to the true surface.
* ``paper_bound`` (depth <= 2 mm, x/y <= 1 mm, paper V-D) and ``goals`` (depth RMS <=
  0.03 mm, x/y RMS <= 0.05 mm, boundary mean <= 0.2 mm).

The JSON layout of every part (score.json) is its codec in ``bench.io.codecs.evaluation``.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from platebench.errors import UserValueError
from platebench.evaluation.boundary_metrics import (
    BoundaryScore,
    contour_pixels_distance,
    polyline_distance,
)
from platebench.evaluation.pixel_coverage import PixelCoverage, coverage_of_mesh
from platebench.evaluation.point_metrics import (
    PointScore,
    point_to_surface_distance,
    score_points,
)
from platebench.evaluation.surface_metrics import SurfaceScore, score_surface
from platebench.evaluation.truth import (
    feature_at_pixels,
    feature_visibility,
    true_feature_points,
)
from platebench.reconstruction.paper.false_boundary import FalseBoundaryTest
from platebench.scenes.camera import Camera
from platebench.scenes.rig import StereoRig

if TYPE_CHECKING:
    import trimesh  # annotations only: importing trimesh takes a second

    from platebench.scenes.render.ground_truth import BoundaryVisibility

__all__ = ["ScoreError", "BoundaryTruth", "SampleTruth", "ReconstructionData", "PointErrors", "PerPointErrors",
           "Matching", "FalseBoundaryVerdict",
           "PaperBound", "Goals", "Score", "score_reconstruction", "format_table",
           "PAPER_DEPTH_MM", "PAPER_XY_MM", "GOAL_DEPTH_RMS_MM", "GOAL_XY_RMS_MM", "GOAL_BOUNDARY_MEAN_MM"]

# The paper's bound (section V-D: depth within 2 mm, x and y within 1 mm each) and the bench's goals.
PAPER_DEPTH_MM, PAPER_XY_MM = 2.0, 1.0
GOAL_DEPTH_RMS_MM, GOAL_XY_RMS_MM, GOAL_BOUNDARY_MEAN_MM = 0.03, 0.05, 0.2
SURFACE_SAMPLE_SPACING_M = 1e-3


class ScoreError(UserValueError):
    """Sample and reconstruction cannot be scored together."""


@dataclass(frozen=True)
class BoundaryTruth:
    """Ground truth of one camera's view of the true boundary: the share of it the camera sees
    (``visible_fraction``, 0..1 by arc length) and whether part of it is hidden (``false_boundary``)."""

    false_boundary: bool
    visible_fraction: float

    @classmethod
    def of(cls, visibility: BoundaryVisibility) -> "BoundaryTruth":
        """The truth a ground-truth cast (``scenes.render.ground_truth.BoundaryVisibility``) gives."""
        return cls(bool(visibility.false_boundary), float(visibility.visible_fraction))


@dataclass(frozen=True)
class SampleTruth:
    mesh: trimesh.Trimesh
    boundary: np.ndarray
    masks: dict
    feature_maps: dict
    rig: StereoRig
    projector: Camera
    feature_ids: np.ndarray
    feature_centers: np.ndarray
    visibility: Mapping[str, BoundaryTruth]  # camera -> its view of the true boundary
    # (H, W, 3) world point (metres) seen at each left pixel (gt/left_points.exr): the true rays of
    # the coverage; None: coverage is not measured
    points_left: np.ndarray | None = None


@dataclass(frozen=True)
class ReconstructionData:
    points: np.ndarray
    uv_left: np.ndarray
    uv_right: np.ndarray
    feature_id: np.ndarray
    boundary: np.ndarray
    surface_vertices: np.ndarray | None
    false_boundary: FalseBoundaryTest  # the method's counting test (recon.json's false_boundary section)
    # the centres the method set apart as cut squares (scored apart, in ``Score.cut_points``): (K,3), (K,2), (K,2)
    cut_points: np.ndarray | None = None
    cut_uv_left: np.ndarray | None = None
    cut_uv_right: np.ndarray | None = None
    surface_faces: np.ndarray | None = None  # (F, 3) vertex indices of the surface mesh; None: no mesh


def _mm(x: float | None) -> float | None:
    return None if x is None else float(x) * 1e3


@dataclass(frozen=True)
class PointErrors:
    """Triangulated square centres against the true centres (``stats``, metres), and the distance
    of every reconstructed point to the true surface (metres)."""

    stats: PointScore
    to_surface_rms_m: float
    to_surface_max_m: float

    @property
    def count(self) -> int:
        return self.stats.count

    @property
    def xy_per_axis_rms_m(self) -> float:
        """sqrt((x_rms^2 + y_rms^2) / 2): the RMS of the lateral error per image axis."""
        return math.sqrt((self.stats.x.rms ** 2 + self.stats.y.rms ** 2) / 2.0)

    @property
    def xy_per_axis_max_m(self) -> float:
        """max(x_max, y_max): the largest lateral error along either image axis (the paper's x/y)."""
        return max(self.stats.x.max, self.stats.y.max)


@dataclass(frozen=True, eq=False)
class PerPointErrors:
    """Each reconstructed square centre's and surface vertex's error against the truth (metres; what an
    error map draws). ``centre_error_m`` (N,): per centre (``ReconstructionData.points``' order) the 3D
    error against the true centre where ``centre_known`` (N,) (its identity read in the ground-truth
    feature map at its left pixel), else its exact distance to the true surface;
    ``surface_distance_m`` (V,): each surface vertex's exact distance to the true surface (None: no
    surface)."""

    centre_error_m: np.ndarray
    centre_known: np.ndarray
    surface_distance_m: np.ndarray | None = None


@dataclass(frozen=True)
class Matching:
    """Counts of the active stereo: detected, matched (and correctly), seen by ground truth, expected."""

    matched_count: int
    correct_match_count: int
    label_correct_rate_frac: float
    detected_count: dict = field(default_factory=dict)  # image name -> whole squares the method counted
    visible_count: dict = field(default_factory=dict)  # camera -> features ground truth says it sees
    visible_in_both_count: int = 0
    expected_count_gt: int = 0  # features whose ray hits the plate
    expected_count_method: int = -1  # features the method expected inside its boundary (-1: unknown)

    @property
    def correct_match_rate_frac(self) -> float:
        return self.correct_match_count / self.matched_count if self.matched_count else 0.0


@dataclass(frozen=True)
class FalseBoundaryVerdict:
    """Ground truth (per camera: is part of the true boundary hidden?) against the method's flag."""

    ground_truth: dict  # camera -> bool
    detected: bool

    @property
    def ground_truth_any(self) -> bool:
        return any(self.ground_truth.values())

    @property
    def agrees(self) -> bool:
        return self.detected == self.ground_truth_any


@dataclass(frozen=True)
class PaperBound:
    """The paper's bound (V-D): every expected point found, depth error within 2 mm and the error along
    each image axis within 1 mm (maxima, millimetres)."""

    depth_max_mm: float
    xy_per_axis_max_mm: float
    all_points: bool
    depth_limit_mm: float = PAPER_DEPTH_MM
    xy_limit_mm: float = PAPER_XY_MM

    @property
    def met(self) -> bool:
        return bool(self.depth_max_mm <= self.depth_limit_mm and self.xy_per_axis_max_mm <= self.xy_limit_mm
                    and self.all_points)


@dataclass(frozen=True)
class Goals:
    """The bench's accuracy goals (millimetres): depth RMS, per-axis lateral RMS, boundary mean."""

    depth_rms_mm: float
    xy_per_axis_rms_mm: float
    boundary_mean_mm: float
    depth_rms_goal_mm: float = GOAL_DEPTH_RMS_MM
    xy_per_axis_rms_goal_mm: float = GOAL_XY_RMS_MM
    boundary_mean_goal_mm: float = GOAL_BOUNDARY_MEAN_MM

    @property
    def met(self) -> bool:
        return bool(self.depth_rms_mm <= self.depth_rms_goal_mm and self.xy_per_axis_rms_mm <= self.xy_per_axis_rms_goal_mm
                    and self.boundary_mean_mm <= self.boundary_mean_goal_mm)


@dataclass(frozen=True)
class Score:
    """Every metric of one reconstruction against the truth. Parts are None where the reconstruction
    has nothing to score (no point with a known true feature, no boundary, no surface). Its codec in
    ``bench.io.codecs.evaluation`` gives score.json's layout (units in every key)."""

    points: PointErrors | None
    matching: Matching
    boundary_3d: BoundaryScore | None
    boundary_image: BoundaryScore | None
    surface: SurfaceScore | None
    false_boundary: FalseBoundaryVerdict
    paper_bound: PaperBound | None
    goals: Goals | None
    # the centres of squares the method found cut and set apart (not in ``points``, the bound or
    # the goals): their errors against the true centres; None when it set none apart
    cut_points: PointErrors | None = None
    cut_count: int = 0
    # ``coverage_frac``: left plate pixels whose true ray hits the surface mesh (None: no mesh or no true rays)
    coverage: PixelCoverage | None = None
    # each centre's and surface vertex's error (None: not measured)
    per_point: PerPointErrors | None = field(default=None, compare=False)


def score_reconstruction(truth: SampleTruth, rec: ReconstructionData) -> Score:
    """All metrics of one reconstruction (``Score``; score.json is its codec in ``bench.io.codecs.evaluation``)."""
    for name, arr in (("points", rec.points), ("boundary", rec.boundary)):
        if arr.size and not np.all(np.isfinite(arr)):
            raise ScoreError(f"reconstruction {name} hold NaN or inf")
    true_pts = true_feature_points(truth.mesh, truth.projector, truth.feature_centers)
    vis = feature_visibility(truth.feature_maps, true_pts, truth.feature_ids)
    id_index = {int(i): k for k, i in enumerate(truth.feature_ids)}
    gid_l = feature_at_pixels(truth.feature_maps["left"], rec.uv_left)
    gid_r = feature_at_pixels(truth.feature_maps["right"], rec.uv_right)
    correct = (gid_l == gid_r) & (gid_l >= 0)

    def point_errors(P, uv_left) -> tuple[PointErrors | None, PerPointErrors | None]:
        """The points' errors against the true centre of the feature lighting their left pixel, and
        each point's error (None: no points)."""
        if not len(P):
            return None, None
        gid = feature_at_pixels(truth.feature_maps["left"], uv_left)
        known = np.array([g in id_index and np.all(np.isfinite(true_pts[id_index[g]])) for g in gid], bool)
        d_surf = point_to_surface_distance(P, truth.mesh)  # exact; trimesh's is off in metres
        true_known = true_pts[[id_index[g] for g in gid[known]]]
        each = d_surf.copy()
        each[known] = [np.linalg.norm(e) for e in P[known] - true_known]
        per_point = PerPointErrors(each, known)
        if not known.any():
            return None, per_point
        stats = score_points(P[known], true_known, truth.rig.left.R)
        return PointErrors(stats, float(np.sqrt(np.mean(d_surf ** 2))), float(d_surf.max())), per_point
    points, per_point = point_errors(rec.points, rec.uv_left)
    n_cut = 0 if rec.cut_points is None else len(rec.cut_points)
    cut_points = point_errors(rec.cut_points, rec.cut_uv_left)[0] if n_cut else None
    fb = rec.false_boundary
    matching = Matching(
        matched_count=int(len(rec.points)), correct_match_count=int(correct.sum()),
        label_correct_rate_frac=float(np.mean(rec.feature_id == gid_l)) if len(gid_l) else 0.0,
        detected_count={k: int(v) for k, v in fb.detected.items()},
        visible_count={cam: len(ids) for cam, ids in vis.seen.items()},
        visible_in_both_count=len(vis.visible_in_both()), expected_count_gt=len(vis.on_plate),
        expected_count_method=int(fb.expected))
    boundary_3d = boundary_image = None
    if len(rec.boundary) >= 3:
        boundary_3d = polyline_distance(rec.boundary, truth.boundary)
        boundary_image = contour_pixels_distance(truth.masks["left"], truth.rig.left.project(rec.boundary))
    surface = coverage = None
    surface_distance = None
    if rec.surface_vertices is not None and len(rec.surface_vertices):
        surface = score_surface(rec.surface_vertices, truth.mesh, sample_spacing_m=SURFACE_SAMPLE_SPACING_M)
        surface_distance = point_to_surface_distance(np.asarray(rec.surface_vertices, float), truth.mesh)
    if truth.points_left is not None:
        coverage = coverage_of_mesh(_surface_mesh(rec), truth.rig.left.center, truth.points_left,
                                    truth.masks["left"])
    verdict = FalseBoundaryVerdict({cam: bool(v.false_boundary) for cam, v in truth.visibility.items()},
                                   bool(fb.false_boundary_detected))
    paper_bound = goals = None
    if points is not None:
        paper_bound = PaperBound(_mm(points.stats.depth.max), _mm(points.xy_per_axis_max_m),
                                 points.count == matching.expected_count_gt)
        goals = Goals(_mm(points.stats.depth.rms), _mm(points.xy_per_axis_rms_m),
                      _mm(boundary_3d.mean_sym) if boundary_3d is not None else float("nan"))
    if per_point is not None or surface_distance is not None:
        per_point = PerPointErrors(np.zeros(0), np.zeros(0, bool)) if per_point is None else per_point
        per_point = replace(per_point, surface_distance_m=surface_distance)
    return Score(points, matching, boundary_3d, boundary_image, surface, verdict, paper_bound, goals, cut_points, n_cut,
                 coverage, per_point)


def _surface_mesh(rec: ReconstructionData):
    """The reconstruction's surface as a trimesh (world, metres); None without faces."""
    if rec.surface_vertices is None or rec.surface_faces is None or not len(rec.surface_faces):
        return None
    import trimesh  # noqa: PLC0415  (importing trimesh takes a second)

    return trimesh.Trimesh(np.asarray(rec.surface_vertices, np.float64), np.asarray(rec.surface_faces),
                           process=False)


def format_table(score: Score) -> str:
    """A readable summary of a Score (millimetres and pixels)."""
    lines = []
    m = score.matching
    if score.points is not None:
        s = score.points.stats
        lines.append(f"{'points':16s} {s.count} matched; depth RMS {_mm(s.depth.rms):.4f} mm, max "
                     f"{_mm(s.depth.max):.4f} mm; x/y RMS {_mm(s.x.rms):.4f}/{_mm(s.y.rms):.4f} mm "
                     f"(radial {_mm(s.xy_radial.rms):.4f} mm); 3D RMS {_mm(s.err3d.rms):.4f} mm")
    lines.append(f"{'matching':16s} correct {m.correct_match_count}/{m.matched_count}; visible L/R "
                 f"{m.visible_count.get('left')}/{m.visible_count.get('right')}; expected (truth) "
                 f"{m.expected_count_gt}, expected (method) {m.expected_count_method}")
    if score.boundary_3d is not None:
        b, bi = score.boundary_3d, score.boundary_image
        lines.append(f"{'boundary 3D':16s} mean {_mm(b.mean_sym):.4f} mm, RMS {_mm(b.rms_sym):.4f} mm, "
                     f"Hausdorff {_mm(b.hausdorff):.4f} mm")
        lines.append(f"{'boundary image':16s} mean {bi.mean_sym:.3f} px, Hausdorff {bi.hausdorff:.3f} px")
    if score.surface is not None:
        s = score.surface
        lines.append(f"{'surface':16s} RMS {_mm(s.dist.rms):.4g} mm, max {_mm(s.dist.max):.4g} mm, "
                     f"surface coverage {s.surface_coverage_frac:.4g} (share of the true plate's area within "
                     f"{_mm(s.coverage_radius_m):g} mm of it)")
    if score.coverage is not None:
        c = score.coverage
        lines.append(f"{'coverage':16s} {c.coverage_frac:.4g} ({c.estimated_px}/{c.plate_px} plate px of the left "
                     f"view whose ray hits the surface)")
    if score.cut_count:
        c = score.cut_points
        errs = "" if c is None else (f"; their depth max {_mm(c.stats.depth.max):.4f} mm, x/y max "
                                     f"{_mm(c.xy_per_axis_max_m):.4f} mm")
        lines.append(f"{'cut squares':16s} {score.cut_count} centres set apart (squares cut in either image by the "
                     f"plate's outline or the threshold), not in the points, the surface or the bound{errs}")
    fb = score.false_boundary
    lines.append(f"{'false boundary':16s} truth {fb.ground_truth_any}, detected {fb.detected}, "
                 f"{'agree' if fb.agrees else 'DISAGREE'}")
    if score.paper_bound is not None:
        pb, g = score.paper_bound, score.goals
        lines.append(f"{'paper bound':16s} depth <= {pb.depth_limit_mm:g} mm, x/y <= {pb.xy_limit_mm:g} mm, all "
                     f"points: {'MET' if pb.met else 'NOT MET'} (depth max {pb.depth_max_mm:.4f}, x/y max "
                     f"{pb.xy_per_axis_max_mm:.4f})")
        lines.append(f"{'goal':16s} depth RMS {g.depth_rms_mm:.4f} <= {g.depth_rms_goal_mm}, x/y RMS per axis "
                     f"{g.xy_per_axis_rms_mm:.4f} <= {g.xy_per_axis_rms_goal_mm}, boundary mean "
                     f"{g.boundary_mean_mm:.4f} <= {g.boundary_mean_goal_mm}: {'MET' if g.met else 'NOT MET'}")
    return "\n".join(lines)
