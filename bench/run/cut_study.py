"""The cut-squares study: the paper's pipeline on oblique bends, where the plate's outline or a
grazing light cuts projected squares (``reconstruction.paper.squares``: ``Square.cut``), scored
against ground truth with the cut squares' centres set apart (the pipeline's default) and kept
(``PipelineOptions.keep_cut_squares``, as the paper has them).

Each centre is compared with the true centre of the feature lighting its left pixel (the
projector's ray through the feature's centre, cut with the plate mesh), its error split in the
left camera's frame as the paper's bound reads it (depth within 2 mm, x/y within 1 mm); a centre
on no feature is outside the bound. Ground truth is the referee only. World frame, metres; the
rows and the table in millimetres and degrees.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from platebench.bench.config import SampleConfig, with_overrides
from platebench.bench.io.atomic import write_json
from platebench.bench.io.cut_records import CutRow, CutStudy, CutTotals
from platebench.bench.io.outputs import output_dir
from platebench.bench.run.render import render_sample
from platebench.bench.run.score import truth_from_sample
from platebench.evaluation.score import PAPER_DEPTH_MM, PAPER_XY_MM
from platebench.evaluation.truth import feature_at_pixels, true_feature_points
from platebench.reconstruction.paper.pipeline import PipelineOptions, projector_feature_rays, reconstruct
from platebench.reconstruction.paper.plate_region import ReconstructionError

CUT_BENDS_DEG = (40.0, 60.0, 90.0, 120.0)
CUT_AXES_DEG = (20.0, 30.0, 45.0, 60.0, 75.0)
CUT_DISTANCES_M = (0.40, 0.45, 0.50)


def centre_errors_mm(sample, points: np.ndarray, uv_left: np.ndarray) -> np.ndarray:
    """(M,2) (depth, larger of the x and y errors) in millimetres of each centre (M,3) against the
    true centre of the feature lighting its left pixel ``uv_left`` (M,2); NaN on no feature."""
    t = truth_from_sample(sample)
    true = true_feature_points(t.mesh, t.projector, t.feature_centers)
    index = {int(i): k for k, i in enumerate(t.feature_ids)}
    out = np.full((len(points), 2), np.nan)
    for k, g in enumerate(feature_at_pixels(t.feature_maps["left"], uv_left)):
        if int(g) in index and np.all(np.isfinite(true[index[int(g)]])):
            e = t.rig.left.R @ (np.asarray(points[k]) - true[index[int(g)]])
            out[k] = abs(e[2]) * 1e3, max(abs(e[0]), abs(e[1])) * 1e3
    return out


def outside_bound(errors_mm: np.ndarray) -> np.ndarray:
    """(M,) True where a centre breaks the paper's bound (``evaluation.score.PAPER_DEPTH_MM``,
    ``PAPER_XY_MM``) or lies on no feature (NaN)."""
    e = np.asarray(errors_mm, float).reshape(-1, 2)
    return ~((e[:, 0] <= PAPER_DEPTH_MM) & (e[:, 1] <= PAPER_XY_MM))


def cut_row(cfg: SampleConfig, renderer=None) -> tuple[CutRow, object]:
    """One plate: rendered, reconstructed with the cut squares set apart and kept, each centre
    scored (``centre_errors_mm``). Returns (row, renderer)."""
    s, renderer = render_sample(cfg, renderer)
    sc = s.scene
    rays = projector_feature_rays(sc.projector.camera, sc.projector.pattern)
    d = cfg.plate.deformation
    plate = dict(bend_deg=round(float(np.degrees(d.angle_rad)), 6), direction=d.direction,
                 axis_deg=round(float(np.degrees(d.axis_rad)), 6), distance_m=cfg.scene.distance_m)
    try:
        rec = reconstruct(s.digital, sc.rig, rays, sc.projector.pattern)
        kept_all = reconstruct(s.digital, sc.rig, rays, sc.projector.pattern, PipelineOptions(keep_cut_squares=True))
    except ReconstructionError as e:
        return CutRow(**plate, error=str(e).splitlines()[0]), renderer
    kept = centre_errors_mm(s, rec.points, rec.uv_left)
    before = centre_errors_mm(s, kept_all.points, kept_all.uv_left)
    cut = centre_errors_mm(s, rec.cut.points, rec.cut.uv_left)
    return CutRow(**plate, centres=len(kept_all.points), kept=len(rec.points), cut=len(rec.cut),
                  cut_by_outline=sum("outline" in r for r in rec.cut.reasons),
                  cut_by_threshold=sum("threshold" in r and "outline" not in r for r in rec.cut.reasons),
                  outside_before=int(outside_bound(before).sum()), outside_kept=int(outside_bound(kept).sum()),
                  outside_cut=int(outside_bound(cut).sum()),
                  kept_depth_max_mm=float(np.nanmax(kept[:, 0])) if len(kept) else None,
                  kept_xy_max_mm=float(np.nanmax(kept[:, 1])) if len(kept) else None), renderer


def run_cut_study(base: SampleConfig, bends_deg=CUT_BENDS_DEG, axes_deg=CUT_AXES_DEG, distances_m=CUT_DISTANCES_M,
                  progress=None, settings: dict | None = None) -> CutStudy:
    """``cut_row`` on every bend convex and concave about every axis at every distance; the rows and
    the totals (cut_study.json's record; ``settings``: what it ran with, as the command was given it)."""
    t0 = time.perf_counter()
    rows, renderer = [], None
    for b in bends_deg:
        for direction in ("down", "up"):
            for ax in axes_deg:
                for dist in distances_m:
                    cfg = with_overrides(base, bend_deg=float(b), bend_direction=direction, bend_axis_deg=float(ax),
                                         distance_m=float(dist))
                    row, renderer = cut_row(cfg, renderer)
                    rows.append(row)
                    if progress is not None:
                        progress(row)
    return CutStudy(tuple(rows), CutTotals.of(rows), time.perf_counter() - t0, dict(settings or {}))


def write_cut_study(out: Path, base: SampleConfig, overwrite: bool = False, progress=None, settings: dict | None = None,
                    **axes) -> CutStudy:
    """Run the study (``run_cut_study``) and write ``out/cut_study.json`` (complete or not at all)."""
    with output_dir(out, "cut-squares study", overwrite=overwrite) as stage:
        study = run_cut_study(base, progress=progress, settings=settings, **axes)
        write_json(stage / "cut_study.json", study.to_dict())
    return study


def table_lines(study: CutStudy) -> list[str]:
    """The per-plate table and the totals as text lines."""
    out = [f"{'plate':32s} {'centres':>7s} {'kept':>4s} {'cut':>3s} {'outside before':>14s} {'kept':>4s} "
           f"{'cut':>3s} {'kept depth/xy max mm':>21s}"]
    for r in study.rows:
        name = f"{r.bend_deg:g} {r.direction} axis {r.axis_deg:g} at {r.distance_m:g} m"
        if not r.ok:
            out.append(f"{name:32s} error: {r.error}")
            continue
        worst = "-" if r.kept_depth_max_mm is None else f"{r.kept_depth_max_mm:.2f} / {r.kept_xy_max_mm:.2f}"
        out.append(f"{name:32s} {r.centres:7d} {r.kept:4d} {r.cut:3d} {r.outside_before:14d} "
                   f"{r.outside_kept:4d} {r.outside_cut:3d} {worst:>21s}")
    t = study.totals
    out.append(f"totals: {t.plates} plates ({t.errors} failed); {t.centres} matched centres, {t.cut} set apart "
               f"as cut ({t.cut_by_outline} by the outline, {t.cut_by_threshold} by the threshold alone); outside the "
               f"paper's bound (depth {PAPER_DEPTH_MM:g} mm, x/y {PAPER_XY_MM:g} mm) or on no square: {t.outside_before} "
               f"with the cut ones kept (on {t.plates_outside_before} plates), {t.outside_kept} of the kept (on "
               f"{t.plates_outside_kept} plates), {t.outside_cut} of those set apart")
    out.append(f"time: {study.time_s:.0f} s")
    return out


__all__ = ["run_cut_study", "write_cut_study", "cut_row", "centre_errors_mm", "outside_bound", "table_lines",
           "CUT_BENDS_DEG", "CUT_AXES_DEG", "CUT_DISTANCES_M"]
