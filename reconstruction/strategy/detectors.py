"""Detectors of a false boundary at the first measuring pose (stage 2), from measurements only.

Each answers one question, "does the stage-2 pose miss part of the true boundary?", and is
reported on its own so that its precision and recall against ground truth can be measured:

* ``counting_test``: the paper's test (IV-B), fewer whole squares in an image than projector rays
  inside the measured boundary.
* ``arrays_disagree``: the paper's Fig. 2 symptom, a horizontal square array with different counts
  in the two images.
* ``viewpoint_consistency``: a stretch of the stage-2 outline that no confirmed piece of another
  pose explains (a true edge stays put when the viewpoint moves; an occluding contour slides).
* ``occluding_contour``: along the stage-2 outline, the surface measured by the other poses has
  its normal perpendicular to the stage-2 viewing ray (the surface turns away there).
* ``end_tangents``: the paper's L formula on the measured most-bending curve: the stage-2 cameras
  are not beyond the point C where its end tangents meet (or a tangent turns past 90 degrees).

World frame, metres, radians. Nothing here reads ground truth.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from platebench.reconstruction.strategy.bending import measured_bending_curves, tangent_intersection_distance
from platebench.reconstruction.strategy.multiview import LINK_M, REPORT_MIN_M, BoundaryVerdict, ViewOutline, cyclic_runs
from platebench.reconstruction.strategy.poses import most_bent_direction
from platebench.reconstruction.strategy.surface_model import SurfaceModel

DETECTORS = ("counting_test", "arrays_disagree", "viewpoint_consistency", "occluding_contour", "end_tangents")
GRAZING_RAD = float(np.radians(10.0))  # occluding contour: the ray meets the measured surface this flat
L_MARGIN = 1.1  # end tangents: the cameras must be this much beyond C


@dataclass(frozen=True)
class DetectorResult:
    """One detector's verdict on the stage-2 pose: ``fired`` None when it could not be evaluated
    (``detail`` says why); ``measure`` in ``unit``."""

    name: str
    fired: bool | None
    measure: float | None
    unit: str
    detail: str


def paper_tests(false_boundary) -> list[DetectorResult]:
    """The paper's counting test and Fig. 2 symptom from the stage-3 ``FalseBoundaryTest``."""
    fb = false_boundary
    seen = min(fb.detected.values()) if fb.detected else 0
    return [DetectorResult("counting_test", bool(fb.counting_test), float(fb.expected - seen), "squares",
                           f"{fb.detected} whole squares against {fb.expected} rays inside the boundary"),
            DetectorResult("arrays_disagree", bool(fb.arrays_disagree), None, "",
                           "a horizontal array holds different counts left/right" if fb.arrays_disagree
                           else "every matched array holds the same count left and right")]


def _longest_run_m(view: ViewOutline, mask: np.ndarray) -> float:
    arc = view.arc_m
    return max((float(arc[r[:-1]].sum()) for r in cyclic_runs(mask)), default=0.0)


def viewpoint_consistency(first: ViewOutline, verdict: BoundaryVerdict) -> DetectorResult:
    """Fires when a stretch of at least REPORT_MIN_M of the first pose's outline is farther than
    LINK_M from every confirmed piece (its own confirmed pieces included)."""
    if not verdict.pieces:
        return DetectorResult("viewpoint_consistency", None, None, "mm", "no piece confirmed by two poses")
    tree = cKDTree(np.vstack([p.points for p in verdict.pieces]))
    far = tree.query(first.points)[0] > LINK_M
    run = _longest_run_m(first, far)
    return DetectorResult("viewpoint_consistency", run >= REPORT_MIN_M, run * 1e3, "mm",
                          f"longest stretch of the stage-2 outline no confirmed piece explains: {run * 1e3:.1f} mm")


def occluding_contour(first: ViewOutline, model: SurfaceModel) -> DetectorResult:
    """Fires when a stretch of at least REPORT_MIN_M of the first pose's outline meets the surface
    measured by the other poses at less than GRAZING_RAD (its normal perpendicular to the ray)."""
    n = model.normals_near(first.points, first.camera_center, exclude_view=first.name)
    ok = np.all(np.isfinite(n), axis=1)
    if ok.mean() < 0.2:
        return DetectorResult("occluding_contour", None, None, "mm",
                              "the other poses measured too little surface near the stage-2 outline")
    ray = first.points - first.camera_center
    ray /= np.linalg.norm(ray, axis=1, keepdims=True)
    graze = np.full(len(ray), np.pi / 2)
    graze[ok] = np.arcsin(np.clip(np.abs(np.einsum("ij,ij->i", n[ok], ray[ok])), 0, 1))
    run = _longest_run_m(first, graze < GRAZING_RAD)
    return DetectorResult("occluding_contour", run >= REPORT_MIN_M, run * 1e3, "mm",
                          f"longest stretch of the stage-2 outline seen within {np.degrees(GRAZING_RAD):.0f} deg of "
                          f"the measured surface: {run * 1e3:.1f} mm")


def end_tangents(rec, camera_centers: np.ndarray) -> DetectorResult:
    """The L formula on the stage-3 reconstruction's most bending curve: fires when a camera is not
    ``L_MARGIN`` x L beyond the chord AB, or an end tangent turns past 90 degrees (L infinite)."""
    try:
        bent = most_bent_direction(rec.boundary, rec.boundary_plane, rec.points)
        curves, how = measured_bending_curves(rec.boundary, rec.boundary_source, rec.boundary_plane, bent,
                                              rec.surface_vertices)
    except ValueError as e:
        return DetectorResult("end_tangents", None, None, "mm", f"no most bending curve: {e}")
    worst, detail = -np.inf, ""
    for c in curves:
        L = tangent_intersection_distance(c)
        mid = 0.5 * (c.A + c.B)
        up = c.normal
        for cam in np.atleast_2d(camera_centers):
            h = float((cam - mid) @ up)
            if not np.isfinite(L):
                short = np.inf
            else:
                short = L_MARGIN * L - h if L > 0 else -np.inf
            if short > worst:
                worst = short
                detail = (f"{how}: L = {L * 1e3:.0f} mm (a = {np.degrees(c.a_rad):.0f}, b = {np.degrees(c.b_rad):.0f} deg), "
                          f"cameras {h * 1e3:.0f} mm above AB")
    return DetectorResult("end_tangents", bool(worst > 0), None if not np.isfinite(worst) else float(worst * 1e3),
                          "mm", detail)
