"""The paper's closed sensing loop (sections II, IV-B, V-B) with a simulated robot.

Decisions (poses, the false-boundary test, the cures) are the pure functions of
``reconstruction.exploring`` and ``reconstruction.pipeline``; this module renders at
each chosen pose, runs the method, and records every pose, decision and reason in
``sensing.json``. Each stage's sample (with ground truth, for scoring only) and
reconstruction are written under DIR/stageN[_k]/.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from platebench.bench.config import SampleConfig
from platebench.bench.io.atomic import write_json
from platebench.bench.io.recon_files import image_checksums, write_reconstruction
from platebench.bench.io.sample_files import write_sample
from platebench.bench.run.render import render_sample
from platebench.bench.run.score import score_in_memory
from platebench.evaluation.metrics_row import MetricsRow
from platebench.reconstruction.paper.pipeline import (
    passive_stereo,
    projector_feature_rays,
    reconstruct,
)
from platebench.reconstruction.strategy.exploring import (
    PoseError,
    SensorPose,
    cure_move_back,
    cure_orient,
    ensure_in_view,
    most_bending_curves,
    most_bent_direction,
    stage1_pose,
    stage2_pose,
    tangent_intersection_distance,
    validate_pose,
)
from platebench.scenes.scene_spec import scene_for_pose


@dataclass(frozen=True)
class SensingOptions:
    workspace_radius_m: float = 0.15  # stage 1 covers a disc of this radius around the workspace centre
    working_distance_m: float = 0.40  # cameras focused here: stage 2 comes no closer
    # Stage 3 places the projector (a separate device: the paper's overhead projector) on its centre
    # line at this distance from the boundary centre; None: at the cameras' distance. A fixed
    # projector shrinks its squares in the images when a cure moves the cameras back (5 px at
    # 0.59 m, 640 px images: too small to extract), so None is the default.
    projector_distance_m: float | None = None
    max_cures: int = 4
    write_stages: bool = True


@dataclass
class SensingLog:
    """Everything the loop did, in order (becomes sensing.json)."""

    steps: list = field(default_factory=list)

    def add(self, **kw) -> None:
        self.steps.append(kw)


def _visibility(sample) -> dict:
    return {c: {"visible_fraction": v.visible_fraction, "false_boundary": v.false_boundary}
            for c, v in sample.visibility.items()}


def _accuracy(sample, rec) -> dict:
    """The final reconstruction scored against ground truth (millimetres)."""
    score = score_in_memory(sample, rec)
    row = MetricsRow.from_score(score)
    return {"depth_rms_mm": row.depth_rms_mm, "points_scored": score.points.count if score.points else 0,
            "boundary_mean_mm": row.boundary_mean_mm, "surface_rms_mm": row.surface_rms_mm,
            "surface_coverage": row.coverage_frac, "paper_bound_met": row.paper_bound_met,
            "goals_met": score.goals.met if score.goals else None}


def run_sensing(cfg: SampleConfig, out: Path | None, options: SensingOptions = SensingOptions(),
                feature_rays=None, progress=None) -> dict:
    """Run stages 1-3 and the cures on the plate of ``cfg``; returns the sensing summary.

    ``feature_rays``: a function scene -> FeatureRays (default: the projector's true K, R, t;
    the calibration module supplies estimated rays).
    """
    step = progress or (lambda name: None)
    base = cfg.scene.build()
    cam = base.rig.left
    pcam = base.projector.camera
    B = base.rig.baseline_m
    rays_for = feature_rays or (lambda scene: projector_feature_rays(scene.projector.camera, scene.projector.pattern))
    log = SensingLog()
    renderer = None
    t0 = time.perf_counter()

    def render_at(pose: SensorPose, name: str, projector: SensorPose | None = None):
        nonlocal renderer
        pc = None if projector is None else projector.center
        pt = None if projector is None else projector.target
        scene = scene_for_pose(pose.center, pose.target, pose.baseline_dir, base, projector_center=pc,
                               projector_target=pt)
        step(f"{name}: render")
        sample, renderer = render_sample(cfg, renderer, scene=scene)
        if out is not None and options.write_stages:
            write_sample(Path(out) / name / "sample", sample, overwrite=True)
        return sample

    # -- stage 1: far pose, rough boundary -----------------------------------------
    pose = stage1_pose(np.zeros(3), options.workspace_radius_m, cam, B)
    s1 = render_at(pose, "stage1")
    step("stage1: passive stereo")
    p1 = passive_stereo(s1.digital["left_passive"], s1.digital["right_passive"], s1.scene.rig)
    log.add(stage=1, pose=pose.to_dict(), boundary_points=len(p1.boundary),
            boundary_plane={"normal": p1.plane.normal.tolist(), "point_m": p1.plane.point.tolist()},
            gt_visibility=_visibility(s1))

    # -- stage 2: pose from the rough boundary, precise boundary ------------------------
    pose = stage2_pose(p1.boundary, p1.plane, cam, B, options.working_distance_m)
    validate_pose(pose, p1.boundary, p1.plane, cam, B)
    cures = 0
    final = None
    while True:
        tag = "" if cures == 0 else f"_cure{cures}"
        s2 = render_at(pose, f"stage2{tag}")
        step("stage2: passive stereo")
        p2 = passive_stereo(s2.digital["left_passive"], s2.digital["right_passive"], s2.scene.rig)
        log.add(stage=2, cure=cures, pose=pose.to_dict(), boundary_points=len(p2.boundary),
                gt_visibility=_visibility(s2))
        # -- stage 3: the projector's centre ray through the boundary centre, perpendicular to the
        # boundary plane (paper V-B); the cameras stay where stage 2 (or the cure) put them.
        pd = options.projector_distance_m or pose.distance_m
        proj_pose = SensorPose(p2.plane.point + p2.plane.normal * pd, p2.plane.point.copy(), pose.baseline_dir,
                               "stage 3: projector centre ray through the boundary centre, perpendicular to "
                               "the boundary plane")
        proj_pose = ensure_in_view(proj_pose, p2.boundary, pcam, 0.0)
        validate_pose(proj_pose, p2.boundary, p2.plane, pcam, 0.0)
        s3 = render_at(pose, f"stage3{tag}", projector=proj_pose)
        step("stage3: active stereo")
        rays = rays_for(s3.scene)
        rec = reconstruct(s3.digital, s3.scene.rig, rays, s3.scene.projector.pattern)
        if out is not None and options.write_stages:
            write_reconstruction(Path(out) / f"stage3{tag}" / "recon", rec, Path(out) / f"stage3{tag}" / "sample",
                                 image_checksums(s3.digital), overwrite=True)
        fb = rec.false_boundary
        log.add(stage=3, cure=cures, pose=pose.to_dict(), projector_pose=proj_pose.to_dict(),
                false_boundary=fb.to_dict(), matched=len(rec.points), unmatched=list(rec.unmatched),
                gt_visibility=_visibility(s3))
        final = (s3, rec, pose)
        if not fb.false_boundary_detected:
            break
        if cures >= options.max_cures:
            log.add(decision="stop", reason=f"false boundary still detected after {cures} cures")
            break
        # -- a cure ------------------------------------------------------------------------
        bent = most_bent_direction(rec.boundary, rec.boundary_plane, rec.points)
        curves = most_bending_curves(rec.boundary, rec.boundary_source, rec.boundary_plane, bent)
        curve = max(curves, key=tangent_intersection_distance)
        L = tangent_intersection_distance(curve)
        missing = fb.expected - min(fb.detected.values())
        oriented = cure_orient(curve, pose)
        off_axis = np.degrees(np.arccos(np.clip(oriented.view_dir @ pose.view_dir, -1, 1)))
        turn = np.degrees(np.arccos(np.clip(abs(oriented.baseline_dir @ pose.baseline_dir), -1, 1)))
        if not np.isfinite(L):
            log.add(decision="stop", curve=curve.to_dict(), L_m=L,
                    reason=f"no cure: an end tangent of the most bending curve turns past 90 deg from its chord "
                           f"(a = {np.degrees(curve.a_rad):.0f}, b = {np.degrees(curve.b_rad):.0f} deg): the "
                           f"plate curls over itself and no pose on the chord's side sees both ends")
            break
        if L <= 0:
            log.add(decision="stop", curve=curve.to_dict(), L_m=L,
                    reason=f"no cure: the most bending curve is concave (L = {L * 1e3:.0f} mm <= 0); both cures "
                           f"reveal the falling ends of a convex bend, and a concave bend hides its boundary "
                           f"under its own rims (past 180 deg) from every pose on the chord's side")
            break
        if cures == 0 and (off_axis > 2.0 or turn > 10.0):
            method, new = 1, oriented
        else:
            method, new = 2, cure_move_back(curve, pose, missing, fb.expected)
        new = ensure_in_view(new, rec.boundary, cam, B)
        try:
            validate_pose(new, rec.boundary, rec.boundary_plane, cam, B)
        except PoseError as e:
            log.add(decision="stop", reason=f"cure refused: {e}")
            break
        log.add(decision="cure", method=method, reason=new.reason, curve=curve.to_dict(),
                L_m=L, missing_squares=int(missing),
                centre_line_change_deg=float(off_axis), baseline_turn_deg=float(turn))
        pose = new
        cures += 1
    s3, rec, final_pose = final
    summary = {"config": cfg.to_dict(), "steps": log.steps, "cures": cures,
               "final": {"pose": final_pose.to_dict(), "false_boundary": rec.false_boundary.to_dict(),
                         "matched": int(len(rec.points)), "gt_visibility": _visibility(s3),
                         "accuracy": _accuracy(s3, rec),
                         "stage_dir": f"stage3{'' if cures == 0 else f'_cure{cures}'}"},
               "time_s": time.perf_counter() - t0}
    if out is not None:
        write_json(Path(out) / "sensing.json", summary)
    return summary


def with_bend(cfg: SampleConfig, bend_deg: float, direction: str) -> SampleConfig:
    """``cfg`` with a cylindrical bend (degrees, 'up' or 'down')."""
    from platebench.plates import CylindricalBend  # noqa: PLC0415
    return replace(cfg, plate=replace(cfg.plate, deformation=CylindricalBend(np.radians(bend_deg), direction)))
