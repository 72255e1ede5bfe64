"""The paper's closed sensing loop (sections II, IV-B, V-B, VI) with a simulated robot, made to
say when it is not sure.

1. Stage 1: a far pose, a rough boundary (passive stereo). Stage 2: the pose of the paper's
   exploring strategy, the precise boundary. Stage 3: the projector on its centre line, active
   stereo, the paper's counting test and Fig. 2 symptom (reported as they are).
2. Verification views (every plate; not cures): the stage-2 pose turned about the boundary centre
   (``reconstruction.strategy.planner``). Each measures the outline by passive stereo.
3. The verdict (``reconstruction.strategy.multiview.verify``): outline points confirmed by a second,
   turned pose; pieces that close into one loop mean a verified boundary. The detectors of a false
   boundary at stage 2 are reported one by one (``reconstruction.strategy.detectors``).
4. While not verified: ``planner.decide`` picks the paper's cure 1 or 2 or a further pose, checked
   against the reconstructed surface model, or stops with the reason.

Decisions are pure functions of measurements in ``reconstruction.strategy``; this module renders,
and holds the ground truth for scoring only: each step's ``gt_visibility`` and, at the end, the
visibility of the true boundary from the final poses (a point counts when a pose's left (right)
camera sees it and that pose's measured outline passes through it in its left image), the
accuracy and the outcome class (``OUTCOMES``). Records are frozen dataclasses; ``to_dict`` makes
``sensing.json``. Light: the passive area light rides with the sensor (``Lighting.follows_rig``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from platebench.bench.config import SampleConfig
from platebench.bench.io.atomic import write_json
from platebench.bench.io.recon_files import image_checksums, write_reconstruction
from platebench.bench.io.sample_files import write_sample
from platebench.bench.run.render import RenderedSample, ground_truth_at, render_images
from platebench.bench.run.score import score_in_memory
from platebench.evaluation.boundary_metrics import points_to_polyline_distance
from platebench.evaluation.metrics_row import MetricsRow
from platebench.evaluation.surface_metrics import score_surface
from platebench.plates import build_plate
from platebench.reconstruction.paper.boundary_plane import BoundaryPlane
from platebench.reconstruction.paper.false_boundary import FalseBoundaryTest
from platebench.reconstruction.paper.outline_stereo import match_outlines
from platebench.reconstruction.paper.pipeline import passive_stereo, projector_feature_rays, reconstruct
from platebench.reconstruction.paper.plate_region import ReconstructionError, plate_mask
from platebench.reconstruction.strategy.detectors import (
    DetectorResult,
    end_tangents,
    occluding_contour,
    paper_tests,
    viewpoint_consistency,
)
from platebench.reconstruction.strategy.multiview import BoundaryVerdict, ViewOutline, verify
from platebench.reconstruction.strategy.planner import (
    MAX_VIEWS,
    Decision,
    PlannedView,
    candidate_views,
    decide,
    paper_cure_views,
    sensing_axes,
    verification_views,
)
from platebench.reconstruction.strategy.poses import (
    PoseError,
    Reach,
    SensorPose,
    ensure_in_view,
    most_bent_direction,
    stage1_pose,
    stage2_pose,
    validate_pose,
)
from platebench.reconstruction.strategy.surface_model import SurfaceModel, view_membrane
from platebench.scenes.render.ground_truth import GroundTruthCaster, combined_visibility
from platebench.scenes.scene_spec import scene_for_pose

OUTCOMES = ("cured", "honest", "silent", "clean", "false_alarm", "unconfirmed")
OUTCOME_TEXT = {
    "cured": "the stage-2 pose hid part of the boundary; the final poses see all of it and the loop verified it",
    "honest": "part of the boundary is still hidden and the loop says so",
    "silent": "part of the boundary is still hidden and the loop says it is verified (the defect)",
    "clean": "nothing was hidden and nothing was raised",
    "false_alarm": "nothing was hidden, but the loop applied a cure or did not verify the boundary",
    "unconfirmed": "the stage-2 pose hid part of the boundary; the final poses see all of it, but the "
                   "loop could not confirm it (says so: not wrong, not cured)",
}
HIDDEN_BELOW = 0.995  # ground truth "hides part of the boundary": a camera sees less than this fraction
TRIANGULATED_PX = 3.0  # a true boundary point lies on a pose's measured outline within this (left image)
PASSIVE = ("left_passive", "right_passive")
ACTIVE = ("left_active", "right_active")


def outcome_class(hidden_first: bool, hidden_final: bool, verified: bool, cured_or_raised: bool) -> str:
    """The outcome class of a sensing run (``OUTCOME_TEXT``) from ground truth's "hidden" at the stage-2
    pose and at the end, the loop's verdict, and whether it applied a cure or raised a flag."""
    if hidden_final:
        return "silent" if verified else "honest"
    if hidden_first:
        return "cured" if verified else "unconfirmed"
    return "false_alarm" if cured_or_raised else "clean"


def _gt_vis(vis: dict) -> dict:
    return {c: {"visible_fraction": float(v.visible_fraction), "false_boundary": bool(v.false_boundary)}
            for c, v in vis.items()}


def hidden(gt_visibility: dict) -> bool:
    """Ground truth hides part of the boundary from a camera (fraction below ``HIDDEN_BELOW``)."""
    return min(v["visible_fraction"] for v in gt_visibility.values()) < HIDDEN_BELOW


@dataclass(frozen=True)
class SensingOptions:
    workspace_radius_m: float = 0.15  # stage 1 covers a disc of this radius around the workspace centre
    working_distance_m: float = 0.40  # cameras focused here: stage 2 comes no closer
    # Stage 3 places the projector on its centre line at this distance from the boundary centre;
    # None: at the cameras' distance (a fixed far projector shrinks its squares when cameras move).
    projector_distance_m: float | None = None
    max_cures: int = 6  # cure poses at most
    max_views: int = MAX_VIEWS  # measuring poses at most (stage 2, verification, cures)
    verification: bool = True  # False: the paper's loop alone (stages 1-3, no verification views)
    write_stages: bool = True
    reach: Reach = field(default_factory=Reach)
    # For scoring only: cast ground truth's boundary visibility from every pose the loop could reach
    # (its verification views and cure candidates) to say whether a reachable set sees the boundary.
    ground_truth_reach: bool = False


@dataclass(frozen=True)
class StageRecord:
    """Stage 1 or 2: a pose and its passive boundary."""

    stage: int
    pose: SensorPose
    boundary_points: int
    boundary_method: str
    gt_visibility: dict
    boundary_plane: BoundaryPlane | None = None

    def to_dict(self) -> dict:
        d = {"stage": self.stage, "pose": self.pose.to_dict(), "boundary_points": self.boundary_points,
             "boundary_method": self.boundary_method, "gt_visibility": self.gt_visibility}
        if self.boundary_plane is not None:
            d["boundary_plane"] = {"normal": self.boundary_plane.normal.tolist(),
                                   "point_m": self.boundary_plane.point.tolist()}
        return d


@dataclass(frozen=True)
class ActiveRecord:
    """Stage 3: the projector's pose, the paper's false-boundary test, the matching."""

    pose: SensorPose
    projector_pose: SensorPose
    false_boundary: FalseBoundaryTest | None
    matched: int
    unmatched: tuple
    gt_visibility: dict
    error: str | None = None

    @property
    def stage(self) -> int:
        return 3

    def to_dict(self) -> dict:
        return {"stage": 3, "pose": self.pose.to_dict(), "projector_pose": self.projector_pose.to_dict(),
                "false_boundary": None if self.false_boundary is None else self.false_boundary.to_dict(),
                "matched": self.matched, "unmatched": list(self.unmatched), "gt_visibility": self.gt_visibility,
                "error": self.error}


@dataclass(frozen=True)
class ViewRecord:
    """A verification view or a cure: the planned pose and what its passive stereo measured."""

    view: PlannedView
    outline_points: int
    outline_method: str
    gt_visibility: dict
    error: str | None = None

    def to_dict(self) -> dict:
        return {"stage": "view", **self.view.to_dict(), "outline_points": self.outline_points,
                "outline_method": self.outline_method, "gt_visibility": self.gt_visibility, "error": self.error}


@dataclass(frozen=True)
class FinalRecord:
    """The end of the run: the loop's verdict (no ground truth), and its scores against ground truth."""

    pose: SensorPose
    stage_dir: str
    false_boundary: FalseBoundaryTest | None
    matched: int
    boundary_verified: bool
    verdict_reason: str
    unverified_parts: tuple
    poses: tuple
    gt_visibility: dict
    gt_visibility_first: dict
    accuracy: dict | None
    merged: dict
    outcome: str
    gt_reachable_visibility: dict | None = None  # union over every reachable candidate pose (scoring only)

    @property
    def hidden_first(self) -> bool:
        """Ground truth: the stage-2 pose hides part of the boundary."""
        return hidden(self.gt_visibility_first)

    @property
    def hidden_final(self) -> bool:
        """Ground truth: the final poses (together) still miss part of the boundary."""
        return hidden(self.gt_visibility)

    @property
    def gt_reachable(self) -> bool | None:
        """Ground truth: the reachable candidate poses together see the whole boundary (None: not cast)."""
        return None if self.gt_reachable_visibility is None else not hidden(self.gt_reachable_visibility)

    def to_dict(self) -> dict:
        return {"pose": self.pose.to_dict(), "stage_dir": self.stage_dir,
                "false_boundary": None if self.false_boundary is None else self.false_boundary.to_dict(),
                "matched": self.matched, "boundary_verified": self.boundary_verified,
                "verdict": self.verdict_reason, "unverified_parts": list(self.unverified_parts),
                "poses": list(self.poses), "gt_visibility": self.gt_visibility,
                "gt_visibility_first": self.gt_visibility_first, "accuracy": self.accuracy, "merged": self.merged,
                "outcome": self.outcome, "outcome_text": OUTCOME_TEXT[self.outcome],
                "gt_hidden_first": self.hidden_first, "gt_hidden_final": self.hidden_final,
                "gt_reachable_visibility": self.gt_reachable_visibility, "gt_reachable": self.gt_reachable}


@dataclass(frozen=True)
class SensingResult:
    """Everything the loop did, typed; ``to_dict`` is sensing.json."""

    config: SampleConfig
    steps: tuple
    detectors: tuple[DetectorResult, ...]
    verification_views: tuple[PlannedView, ...]
    cure_views: tuple[PlannedView, ...]
    verdict: BoundaryVerdict
    final: FinalRecord
    notes: tuple[str, ...]
    time_s: float
    views: tuple[ViewOutline, ...] = ()  # every measuring pose's outline (not in sensing.json: multiview.npz)

    @property
    def cures(self) -> int:
        return len(self.cure_views)

    def to_dict(self) -> dict:
        return {"config": self.config.to_dict(), "steps": [s.to_dict() for s in self.steps],
                "detectors": {d.name: d.to_dict() for d in self.detectors},
                "verification_views": [v.to_dict() for v in self.verification_views],
                "cures": self.cures, "cure_views": [v.to_dict() for v in self.cure_views],
                "verdict": self.verdict.to_dict(), "notes": list(self.notes),
                "final": self.final.to_dict(), "time_s": self.time_s}


def _accuracy(sample, rec) -> dict:
    """The stage-3 reconstruction (the paper's method) scored against ground truth (millimetres)."""
    score = score_in_memory(sample, rec)
    row = MetricsRow.from_score(score)
    return {"depth_rms_mm": row.depth_rms_mm, "points_scored": score.points.count if score.points else 0,
            "boundary_mean_mm": row.boundary_mean_mm, "surface_rms_mm": row.surface_rms_mm,
            "surface_coverage": row.coverage_frac, "paper_bound_met": row.paper_bound_met,
            "goals_met": score.goals.met if score.goals else None}


def merged_accuracy(plate, verdict: BoundaryVerdict, model: SurfaceModel, measured_surface=None) -> dict:
    """The merged multi-view result against ground truth (millimetres): the merged boundary's mean
    (symmetric) distance to the true boundary, its one-way distance, the fraction of the true
    boundary within 2 mm of it; the measured surface (``measured_surface``, (S,3): the stage-3
    interpolated surface and points, with the merged boundary) RMS distance to the true surface and
    its coverage (true surface within 2 mm of it); and the surface model's own RMS (the poses'
    outline membranes, which the planner uses for normals and ray casting: a coarse model, not a
    measurement)."""
    out = {"boundary_points": int(len(verdict.merged))}
    B = np.asarray(plate.boundary, float)
    if len(verdict.merged):
        est_gt = points_to_polyline_distance(verdict.merged, B)
        gt_est = cKDTree(verdict.merged).query(B)[0]
        out.update(boundary_mean_mm=float(0.5 * (est_gt.mean() + gt_est.mean()) * 1e3),
                   boundary_est_to_gt_mean_mm=float(est_gt.mean() * 1e3),
                   boundary_covered_frac=float(np.mean(gt_est <= 2e-3)))
    parts = [np.asarray(p, float).reshape(-1, 3) for p in (measured_surface, verdict.merged) if p is not None]
    S = np.vstack(parts) if parts else np.zeros((0, 3))
    if len(S):
        s = score_surface(S, plate.mesh, sample_spacing_m=1e-3, coverage_radius_m=2e-3, max_distance_m=1e-3)
        out.update(surface_rms_mm=float(s.dist.rms * 1e3), surface_coverage=float(s.coverage_frac),
                   surface_points=int(len(S)))
    M = model.samples
    if len(M):
        M = M[::max(1, len(M) // 4000)]
        s = score_surface(M, plate.mesh, sample_spacing_m=2e-3, coverage_radius_m=2e-3, max_distance_m=1e-3)
        out.update(model_surface_rms_mm=float(s.dist.rms * 1e3), model_surface_coverage=float(s.coverage_frac))
    return out


def run_sensing(cfg: SampleConfig, out: Path | None, options: SensingOptions = SensingOptions(),
                feature_rays=None, progress=None) -> SensingResult:
    """Run stages 1-3, the verification views and the cures on the plate of ``cfg``.

    ``feature_rays``: a function scene -> FeatureRays (default: the projector's true K, R, t; the
    calibration module supplies estimated rays). With ``out``: stage 3's sample and reconstruction
    under ``out/stage3``, ``sensing.json`` and ``multiview.npz`` (every pose's outline, its confirmed
    points, the merged boundary, and the true boundary for plots)."""
    step = progress or (lambda name: None)
    t0 = time.perf_counter()
    built = cfg.scene.build()
    base = replace(built, lighting=replace(built.lighting, follows_rig=True))
    plate = build_plate(cfg.plate)
    cam, pcam, B = base.rig.left, base.projector.camera, base.rig.baseline_m
    rays_for = feature_rays or (lambda scene: projector_feature_rays(scene.projector.camera, scene.projector.pattern))
    state = {"renderer": None}
    steps, notes = [], []

    def render(pose: SensorPose, names, projector: SensorPose | None = None):
        scene = scene_for_pose(pose.center, pose.target, pose.baseline_dir, base,
                               projector_center=None if projector is None else projector.center,
                               projector_target=None if projector is None else projector.target)
        rad, dig, vis, state["renderer"] = render_images(cfg, state["renderer"], scene, plate, names)
        return scene, rad, dig, vis

    # -- stage 1 ------------------------------------------------------------------------------
    pose1 = stage1_pose(np.zeros(3), options.workspace_radius_m, cam, B)
    step("stage 1: render")
    s1, _, d1, v1 = render(pose1, PASSIVE)
    p1 = passive_stereo(d1["left_passive"], d1["right_passive"], s1.rig)
    steps.append(StageRecord(1, pose1, len(p1.boundary), p1.stereo.method, _gt_vis(v1), p1.plane))
    # -- stage 2 ------------------------------------------------------------------------------
    pose2 = stage2_pose(p1.boundary, p1.plane, cam, B, options.working_distance_m)
    validate_pose(pose2, p1.boundary, p1.plane, cam, B)
    step("stage 2: render")
    s2, r2, d2, v2 = render(pose2, PASSIVE)
    p2 = passive_stereo(d2["left_passive"], d2["right_passive"], s2.rig)
    steps.append(StageRecord(2, pose2, len(p2.boundary), p2.stereo.method, _gt_vis(v2)))
    # -- stage 3 (paper V-B): the projector's centre ray through the boundary centre along the normal --
    pd = options.projector_distance_m or pose2.distance_m
    proj_pose = SensorPose(p2.plane.point + p2.plane.normal * pd, p2.plane.point.copy(), pose2.baseline_dir,
                           "stage 3: projector centre ray through the boundary centre, perpendicular to the "
                           "boundary plane")
    proj_pose = ensure_in_view(proj_pose, p2.boundary, pcam, 0.0)
    validate_pose(proj_pose, p2.boundary, p2.plane, pcam, 0.0)
    step("stage 3: render")
    s3, r3, d3, v3 = render(pose2, ACTIVE, projector=proj_pose)
    gt3, vis3 = ground_truth_at(state["renderer"])
    sample3 = RenderedSample(cfg, plate, s3, {**r2, **r3}, {**d2, **d3}, gt3, vis3, {}, state["renderer"].variant)
    rec, rec_error = None, None
    try:
        rec = reconstruct(sample3.digital, s3.rig, rays_for(s3), s3.projector.pattern)
    except ReconstructionError as e:
        rec_error = f"active stage failed: {e}"
        notes.append(rec_error)
    steps.append(ActiveRecord(pose2, proj_pose, None if rec is None else rec.false_boundary,
                              0 if rec is None else len(rec.points), () if rec is None else tuple(rec.unmatched),
                              _gt_vis(vis3), rec_error))
    if out is not None and options.write_stages:
        write_sample(Path(out) / "stage3" / "sample", sample3, overwrite=True)
        if rec is not None:
            write_reconstruction(Path(out) / "stage3" / "recon", rec, Path(out) / "stage3" / "sample",
                                 image_checksums(sample3.digital), overwrite=True)

    # -- the stage-2 pose's own outline, measured by the general outline stereo ----------------
    gt_views = []  # (name, left camera, visibility dict) for the ground-truth scoring only

    def outline_of(name: str, scene, digital) -> ViewOutline:
        m = {c: plate_mask(digital[f"{c}_passive"], f"{c}_passive") for c in ("left", "right")}
        st = match_outlines(digital["left_passive"], digital["right_passive"], m["left"], m["right"], scene.rig)
        return ViewOutline.from_stereo(name, st, scene.rig.center)

    first = outline_of("stage 2", s2, d2)
    views, poses = [first], [pose2]
    gt_views.append(("stage 2", s2.rig.left, v2, first))
    extra_uv = rec.uv_left if rec is not None else None
    extra_pts = rec.points if rec is not None else None
    membranes = [view_membrane(first, extra_uv, extra_pts)]
    bent = most_bent_direction(rec.boundary, rec.boundary_plane, rec.points) if rec is not None else \
        most_bent_direction(p2.boundary, p2.plane)
    g, e = sensing_axes(bent, (rec.boundary_plane if rec is not None else p2.plane).normal)
    measured = first.points

    def measure(view: PlannedView) -> None:
        step(f"{view.name}: render")
        sc, _, dg, vs = render(view.pose, PASSIVE)
        try:
            o = outline_of(view.name, sc, dg)
        except ReconstructionError as err:
            steps.append(ViewRecord(view, 0, "", _gt_vis(vs), f"passive stereo failed: {err}"))
            return
        steps.append(ViewRecord(view, len(o.points), o.method, _gt_vis(vs)))
        views.append(o)
        poses.append(view.pose)
        membranes.append(view_membrane(o))
        gt_views.append((view.name, sc.rig.left, vs, o))

    verif: list[PlannedView] = []
    if options.verification:
        verif, skipped = verification_views(pose2, g, e, options.reach, measured, cam, B)
        notes.extend(f"verification view left out: {s}" for s in skipped)
        for v in verif:
            measure(v)
    model = SurfaceModel.build(membranes)
    verdict = verify(views, model)
    stage2_cams = np.array([s2.rig.left.center, s2.rig.right.center])
    detectors = tuple(paper_tests(rec.false_boundary) if rec is not None else []) + (
        viewpoint_consistency(first, verdict), occluding_contour(first, model),
        end_tangents(rec, stage2_cams) if rec is not None else
        DetectorResult("end_tangents", None, None, "mm", "no stage-3 reconstruction"))

    # -- cures ----------------------------------------------------------------------------------
    cures: list[PlannedView] = []
    cands: list[PlannedView] = []
    if options.verification:
        measured = np.vstack([v.points for v in views])
        paper, note = paper_cure_views(rec, pose2, options.reach, measured, cam, B) if rec is not None else ([], "")
        if note:
            notes.append(note)
        cands = candidate_views(pose2, g, e, options.reach, measured, cam, B, paper)
        while True:
            d = decide(verdict, views, poses, cands, model, B, options.max_views)
            if d.kind == "view" and len(cures) >= options.max_cures:
                d = Decision("stop", None, f"{len(cures)} cures applied, the most allowed; " + verdict.reason,
                             d.gaps_targeted)
            steps.append(d)
            if d.kind != "view":
                break
            cures.append(d.view)
            measure(d.view)
            model = SurfaceModel.build(membranes)
            verdict = verify(views, model)
    else:
        steps.append(Decision("done" if verdict.verified else "stop", None,
                              "verification views off: " + verdict.reason))

    # -- the end: verdict, scores ---------------------------------------------------------------
    P = np.asarray(plate.boundary, float)
    masks = {"left": [], "right": []}
    for name, left_cam, vs, o in gt_views:
        uv = left_cam.project(P)
        ok = np.all(np.isfinite(uv), axis=1)
        tri = np.zeros(len(P), bool)
        tri[ok] = cKDTree(o.image_points).query(uv[ok])[0] <= TRIANGULATED_PX
        for c in ("left", "right"):
            masks[c].append(np.asarray(vs[c].visible, bool) & tri)
    gt_final = {c: combined_visibility(P, masks[c]) for c in ("left", "right")}
    gt_final = _gt_vis(gt_final)
    gt_first = _gt_vis(v2)
    # Not verified: the gaps, and the outline stretches no confirmed piece runs along. Verified: none
    # (outline stretches no other pose confirmed are then occluding contours; sensing.json's
    # verdict lists them all under "unconfirmed_outline").
    unverified = () if verdict.verified else tuple(
        [g_.to_dict() for g_ in verdict.gaps]
        + [{"what": f"{u.view}: {u.length_m * 1e3:.0f} mm of outline no other pose confirmed", **u.to_dict()}
           for u in verdict.unconfirmed if not u.covered])
    outcome = outcome_class(hidden(gt_first), hidden(gt_final), verdict.verified,
                            bool(cures) or not verdict.verified)
    reach_vis = None
    if options.ground_truth_reach:
        reach_poses = [p for p in poses] + [v.pose for v in verif] + [v.pose for v in cands]
        masks = {"left": [], "right": []}
        for p in reach_poses:
            state["renderer"].set_scene(scene_for_pose(p.center, p.target, p.baseline_dir, base))
            caster = GroundTruthCaster(state["renderer"])
            for c in ("left", "right"):
                masks[c].append(np.asarray(caster.boundary_visibility(c).visible, bool))
        reach_vis = _gt_vis({c: combined_visibility(P, masks[c]) for c in ("left", "right")})
    accuracy = _accuracy(sample3, rec) if rec is not None else None
    merged = merged_accuracy(plate, verdict, model, None if rec is None else np.vstack([rec.surface_vertices,
                                                                                        rec.points]))
    merged["poses"] = len(views)
    final = FinalRecord(pose2, "stage3", None if rec is None else rec.false_boundary,
                        0 if rec is None else len(rec.points), verdict.verified, verdict.reason, unverified,
                        tuple(v.name for v in views), gt_final, gt_first, accuracy, merged, outcome, reach_vis)
    result = SensingResult(cfg, tuple(steps), detectors, tuple(verif), tuple(cures), verdict, final, tuple(notes),
                           time.perf_counter() - t0, tuple(views))
    if out is not None:
        write_json(Path(out) / "sensing.json", result.to_dict())
        _write_multiview(Path(out) / "multiview.npz", views, verdict, P)
    return result


def _write_multiview(path: Path, views: list[ViewOutline], verdict: BoundaryVerdict, true_boundary) -> None:
    """The poses' outlines (points, pose index, confirmed), the merged boundary, the gaps and the true
    boundary (for plots), in metres."""
    conf = verdict.confirmed if verdict.confirmed else [np.zeros(len(v.points), bool) for v in views]
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, outline_points=np.vstack([v.points for v in views]),
                        outline_view=np.concatenate([np.full(len(v.points), k) for k, v in enumerate(views)]),
                        outline_confirmed=np.concatenate(conf), view_names=np.array([v.name for v in views]),
                        merged=verdict.merged, gaps=np.array([g.position_m for g in verdict.gaps]).reshape(-1, 3),
                        true_boundary=np.asarray(true_boundary))


def with_bend(cfg: SampleConfig, bend_deg: float, direction: str, axis_deg: float = 0.0) -> SampleConfig:
    """``cfg`` with a cylindrical bend (degrees, 'up' or 'down', axis in degrees)."""
    from platebench.plates import CylindricalBend  # noqa: PLC0415
    return replace(cfg, plate=replace(cfg.plate, deformation=CylindricalBend(np.radians(bend_deg), direction,
                                                                              np.radians(axis_deg))))


__all__ = ["SensingOptions", "SensingResult", "run_sensing", "outcome_class", "OUTCOMES", "OUTCOME_TEXT",
           "hidden", "merged_accuracy", "with_bend", "PoseError"]
