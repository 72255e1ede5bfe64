"""The paper's accuracy test (section V-D) as a Monte Carlo study, with an error budget.

The paper measured, with passive stereo, the corners of a square on the hand/eye target block at about
40 cm and reported the error in the block's frame: depth (z) within 2 mm, x and y within 1 mm. One
trial here does the same under a realism preset (``bench.config.realism``):

* ``block``: the target block's central square (``hardware_robot.TARGET``), white on a dark ground,
  at the world origin turned by the cell's yaw, seen by the commanded rig 0.40 m above it. One draw
  (``bench.run.realism.realise``) places the camera where the robot really puts it for each view,
  with the estimates of the mount, the block's pose and the intrinsics; the passive pair is rendered
  from the poses really taken and digitised by the camera's sensor. The paper's pipeline pieces find
  the square (``reconstruction.paper.plate_region``: Tsai's moment-preserving threshold, contour
  following) and its corners (``block_corners``: the intersections of lines fitted to its edges, or,
  with ``AccuracySettings.corners`` "pixels", the vertices of its binary outline's polygon on the
  pixel grid, as the paper's own method found them); its corners are
  triangulated in the commanded conventional geometry (``triangulate_rectified``: Z = f B / d) into
  the world, and taken into the block's frame through the block pose the calibration estimated.
  Error = measured minus true corner in the block frame: depth = z, and x, y.
* ``plate``: the reference experiment's plate and its 16 projected squares under the same draws; the
  paper's pipeline up to the square centres (``pipeline.passive_stereo`` for the plate regions,
  ``pipeline.square_stereo``: squares, arrays, matching, triangulation; the surface is not needed) on
  the four images, every square centre compared with the true one (its projector ray's hit on the
  plate), in the world frame (the plate's). Which true centre a measured one is, is read in the left
  image (``MATCH_SPACING_FRACTION``): the robot's error moves the measured centres in space by up to
  centimetres, more than the squares' spacing, but not where the camera really posed sees them.

A draw whose estimates cannot be used (a calibration that fits a lens folding over inside the image,
views that do not determine the mount) is recorded as failed with the reason, in every target.

Scoring (``evaluation.accuracy``: the matching, the statistics and the paper's bound). Per trial: the
worst corner (or centre) in depth and in x/y (the larger of |x| and |y|), because the paper's "within"
is one trial's worst. Over the draws: the median of those worst values and its quantiles, and over all
corners of all draws the RMS, the 95th percentile and the maximum.

Error budget (``budget_configs``): no source, each source alone, every source, and every source but
one, all on the same draws (each source draws the same numbers whichever others are on).

Cost: the calibration views are simulated (their corners projected, with the corner noise measured
once on rendered target images: ``RealismSetup.prepare``), so a draw costs one IK per robot move and
two (block) or four (plate) renders. The renders' Monte Carlo noise sits at the edges the block's
corners are fitted to (pixel coverage sampled ``spp`` times): it is part of the "no source" row, the
floor every other row stands on, and shrinks with ``spp`` (docs/findings/real-rigs.md gives the
floor at spp 4, 16, 64). Units: metres in code and JSON keys ending _m; millimetres only in
keys ending _mm.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, replace
from typing import Mapping

import numpy as np
import trimesh

from platebench.bench.config import SampleConfig
from platebench.bench.config.hardware_robot import CELL, ROBOTS, TARGET
from platebench.bench.config.presets import with_realism
from platebench.bench.config.realism import SOURCES, Realism
from platebench.bench.io.accuracy_records import (
    AccuracyCamera,
    AccuracyPaper,
    AccuracyRobot,
    AccuracySettings,
    AccuracyStudy,
    AccuracyTargetBlock,
    AccuracyTrial,
    ConfigSummary,
    ErrorStats,
)
from platebench.bench.io.codecs import encode
from platebench.bench.run.realism import RealismSetup, realise
from platebench.bench.run.render import render_images
from platebench.evaluation.accuracy import (
    MATCH_SPACING_FRACTION,
    PAPER_DEPTH_MM,
    PAPER_XY_MM,
    TrialScore,
    identify_in_image,
    nearest_order,
    score_trial,
    summarise_trials,
)
from platebench.evaluation.truth import true_feature_points
from platebench.plates import build_plate
from platebench.reconstruction.paper.pipeline import passive_stereo, square_stereo
from platebench.reconstruction.calibration.hand_eye import HandEyeError
from platebench.reconstruction.calibration.stereo import CalibrationError
from platebench.reconstruction.calibration.undistort import undistort_views
from platebench.reconstruction.paper.passive_boundary import outline_edges
from platebench.reconstruction.paper.plate_region import ReconstructionError, extract_plate_region, order_corners
from platebench.scenes.camera import triangulate_rectified
from platebench.scenes.naming import IMAGE_NAMES
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.robot import invert_pose
from platebench.scenes.scene_spec import RenderSettings

__all__ = ["TARGETS", "CORNER_METHODS", "block_corners", "AccuracySettings", "BudgetConfig", "budget_configs",
           "run_accuracy_study", "SquareTarget", "summarise", "dominant_sources", "accuracy_csv"]

TARGETS = ("block", "plate")
CORNER_METHODS = ("edges", "pixels")  # how the block's corners are located (``block_corners``)


@dataclass(frozen=True)
class BudgetConfig:
    """One row of the error budget: a label, its kind (none / alone / all_but / all) and the realism."""

    label: str
    kind: str
    realism: Realism


def budget_configs(realism: Realism, budget: bool = True) -> list[BudgetConfig]:
    """The budget's configurations of ``realism``'s sources: none, each alone, all but each, all
    (``budget`` False: all only)."""
    on = list(realism.sources)
    if not on:
        return [BudgetConfig("no source", "none", realism)]
    allc = BudgetConfig("all sources", "all", realism)
    if not budget:
        return [allc]
    out = [BudgetConfig("no source", "none", realism.with_sources([], f"{realism.name}: no source"))]
    out += [BudgetConfig(f"{s} alone", "alone", realism.only(s)) for s in on]
    if len(on) > 1:
        out += [BudgetConfig(f"all but {s}", "all_but", realism.without(s)) for s in on]
    return out + [allc]


@dataclass(frozen=True, eq=False)
class SquareTarget:
    """The measured square as the renderer wants a plate: a white square mesh (what ``PlateRenderer``
    needs of a plate: ``mesh``) of the target block's square, on the block's top face in the world."""

    mesh: trimesh.Trimesh
    corners_world: np.ndarray  # (4, 3)

    @classmethod
    def of(cls, T_world_block: np.ndarray, corners_block: np.ndarray) -> "SquareTarget":
        c = corners_block @ T_world_block[:3, :3].T + T_world_block[:3, 3]
        return cls(trimesh.Trimesh(c, np.array([[0, 1, 2], [0, 2, 3]]), process=False), c)


# -- one trial -------------------------------------------------------------------------
def block_corners(image: np.ndarray, name: str, method: str = "edges") -> np.ndarray:
    """(4,2) the square's corners (TL, TR, BR, BL) in ``image`` (pixels) by ``method``
    (``CORNER_METHODS``): "edges", the intersections of the lines fitted to its four edges
    (``passive_boundary.outline_edges``: sub-pixel); "pixels", the vertices of the polygon
    ``approxPolyDP`` fits to its binary outline (Tsai's threshold, border following), which lie on
    outline pixels: the paper's contour following and corner detection (its [11], Cabrelli and
    Molter's representation of binary images), with no sub-pixel step."""
    if method not in CORNER_METHODS:
        raise ValueError(f"corner method {method!r} is not one of {', '.join(CORNER_METHODS)}")
    region = extract_plate_region(image, name)
    return region.corners.astype(float) if method == "pixels" else outline_edges(image, region).corners


def _block_trial(cfg: SampleConfig, acq, renderer: PlateRenderer, seed: int, corner_method: str = "edges") -> TrialScore:
    scene = cfg.scene.build().with_rig(acq.taken)
    square = SquareTarget.of(acq.T_world_block, TARGET.square_block())
    renderer.set_scene(scene)
    renderer.set_plate(square)
    settings = RenderSettings(cfg.render.spp, seed)
    images = {f"{cam}_passive": cfg.sensor.digitize(renderer.render(cam, "passive", settings),
                                                    seed=(seed * 7919 + len(cam)) % 2 ** 31) for cam in ("left", "right")}
    images, told = undistort_views(images, acq.told)  # through the lens the method is told, as the pipeline does
    corners = {}
    for cam in ("left", "right"):
        corners[cam] = block_corners(images[f"{cam}_passive"], f"{cam}_passive", corner_method)  # TL, TR, BR, BL
    ul, ur = corners["left"], corners["right"]
    p_world = triangulate_rectified(ul[:, 0], 0.5 * (ul[:, 1] + ur[:, 1]), ur[:, 0], told.left, told.baseline_m)
    T_block_world = invert_pose(acq.T_world_block_est)
    p_block = p_world @ T_block_world[:3, :3].T + T_block_world[:3, 3]
    # the true corners in the order the images give them (TL, TR, BR, BL in the true left image)
    true_uv = acq.taken.left.project(square.corners_world)
    order = nearest_order(true_uv, order_corners(true_uv))
    return score_trial(p_block - TARGET.square_block()[order], 4)


def _plate_trial(cfg: SampleConfig, acq, renderer: PlateRenderer, plate, seed: int) -> TrialScore:
    base = cfg.scene.build()
    scene = base.with_rig(acq.taken)
    proj = base.projector
    c = replace(cfg, render=RenderSettings(cfg.render.spp, seed))
    _, digital, _, _ = render_images(c, renderer, scene, plate, IMAGE_NAMES)
    passive = passive_stereo(digital["left_passive"], digital["right_passive"], acq.told)
    rec = square_stereo(digital, {k: passive.regions[k].mask for k in ("left", "right")}, acq.told)
    centres = np.array([f.center for f in proj.pattern.features], float).reshape(-1, 2)
    truth = true_feature_points(plate.mesh, proj.camera, centres)
    truth = truth[np.all(np.isfinite(truth), axis=1)]
    if len(truth) < 2:
        raise ReconstructionError(f"{len(truth)} of the projector's square centres hit the plate (2 at least "
                                  "to compare)")
    if not len(rec.points):
        raise ReconstructionError("no square centre measured")
    # the square's identity from where it appears: the true centres seen by the camera really posed, in the
    # pixels the method works in (undistorted with the told lens onto the told intrinsics' pinhole), against
    # the measured centres' left pixels; each true centre taken by its nearest measured one only
    # (``evaluation.accuracy.identify_in_image``)
    seen = replace(acq.taken.left, K=acq.told.left.K).pinhole
    match = identify_in_image(rec.uv_left, seen.project(truth), MATCH_SPACING_FRACTION)
    if not match.ok.any():
        raise ReconstructionError(f"no measured square centre appears within {MATCH_SPACING_FRACTION:g} of the "
                                  f"centres' spacing ({match.spacing_px:.1f} px) of a true one in the left image")
    return score_trial(rec.points[match.ok] - truth[match.index[match.ok]], int(match.ok.sum()))


def _trial_row(target: str, conf: BudgetConfig, seed: int, out: TrialScore | None, error: str | None,
               time_s: float | None, acquisition) -> AccuracyTrial:
    row = dict(target=target, config=conf.label, kind=conf.kind, realism=conf.realism.name,
               sources=" ".join(conf.realism.sources), seed=seed, time_s=time_s, acquisition=acquisition)
    if out is None:
        return AccuracyTrial(**row, status="failed", error=error)
    mm = 1e3
    return AccuracyTrial(**row, status="ok", error=None, points=int(out.points),
                         worst_depth_mm=out.worst_depth_m * mm, worst_xy_mm=out.worst_xy_m * mm,
                         rms_depth_mm=out.rms_depth_m * mm, rms_xy_mm=out.rms_xy_m * mm,
                         mean_depth_mm=out.mean_depth_m * mm,
                         errors_mm=tuple(map(tuple, np.round(out.errors_m * mm, 5).tolist())))


# -- statistics ------------------------------------------------------------------------
def _error_stats(s) -> ErrorStats:
    """An ``evaluation.accuracy.WorstCaseStats`` (millimetres) as the study's record."""
    return ErrorStats(worst_median_mm=s.worst_median, worst_quantiles_mm=dict(s.worst_quantiles), rms_mm=s.rms,
                      p95_mm=s.p95, max_mm=s.max, within_paper_frac=s.within_bound_frac, mean_signed_mm=s.mean_signed)


def summarise(rows: list[AccuracyTrial], kind: str = "", sources: tuple = ()) -> ConfigSummary:
    """Statistics of one configuration's trials (``evaluation.accuracy.summarise_trials``;
    millimetres), of a budget row of ``kind`` with ``sources`` on."""
    ok = [r for r in rows if r.ok]
    if not ok:
        return ConfigSummary(kind, tuple(sources), len(rows), len(rows))
    s = summarise_trials([r.worst_depth_mm for r in ok], [r.worst_xy_mm for r in ok], [r.errors_mm for r in ok],
                         PAPER_DEPTH_MM, PAPER_XY_MM)
    return ConfigSummary(kind, tuple(sources), len(rows), len(rows) - len(ok), depth=_error_stats(s.depth),
                         xy=_error_stats(s.xy))


# -- the study ---------------------------------------------------------------------------
def run_accuracy_study(settings: AccuracySettings, progress=None) -> AccuracyStudy:
    """Run every budget configuration on every target for every draw; the study (accuracy.json's
    record). ``progress(trial)`` is called after each trial with its ``AccuracyTrial``."""
    t0 = time.perf_counter()
    rz = settings.realism
    start = SampleConfig(render=RenderSettings(settings.spp, settings.seed0), variant=settings.variant)
    base = with_realism(start, rz)
    confs = budget_configs(rz, settings.budget)
    noise_cache: dict = {}  # corner noise per camera (lens, aperture, sensor): measured once
    renderers: dict = {}  # one renderer per scene structure (a thin lens, a distorting lens): kernels kept
    unit_robots: dict = {}  # robot -> its error model at unit scales (``RealismSetup.unit_robot_model``): built once
    plate = build_plate(base.plate) if "plate" in settings.targets else None
    rows, setups = [], {}
    for conf in confs:
        cfg = with_realism(start, conf.realism)
        scene = cfg.scene.build()
        rig = scene.rig
        key = json.dumps([encode(cfg.scene), encode(cfg.sensor)], sort_keys=True)
        robot = conf.realism.robot
        if robot is not None and robot not in unit_robots:
            unit_robots[robot] = RealismSetup.unit_robot_model(robot)
        unit = unit_robots.get(robot)
        if conf.realism.estimates and key not in noise_cache:
            noise_cache[key] = RealismSetup.prepare(conf.realism, cfg, unit_robot=unit).corner_noise_px
        setup = RealismSetup.prepare(conf.realism, cfg, corner_noise_px=noise_cache.get(key, 0.0), unit_robot=unit)
        setups[conf.label] = setup
        rkey = (scene.aperture_radius_m > 0, rig.left.distortion is not None, rig.left.K[0, 0] != rig.left.K[1, 1])
        if rkey not in renderers:
            renderers[rkey] = PlateRenderer(scene, plate or SquareTarget.of(np.eye(4), TARGET.square_block()),
                                            settings.variant)
        renderer = renderers[rkey]
        for k in range(settings.draws):
            seed = settings.seed0 + k
            try:
                acq = realise(setup, rig, seed)
            except (CalibrationError, HandEyeError) as e:  # the draw's estimates cannot be used: said, not hidden
                for target in settings.targets:
                    row = _trial_row(target, conf, seed, None, str(e).splitlines()[0], 0.0, None)
                    rows.append(row)
                    if progress:
                        progress(row)
                continue
            for target in settings.targets:
                t = time.perf_counter()
                try:
                    out = _block_trial(cfg, acq, renderer, seed, settings.corners) if target == "block" else \
                        _plate_trial(cfg, acq, renderer, plate, seed)
                    error = None
                except ReconstructionError as e:
                    out, error = None, str(e).splitlines()[0]
                row = _trial_row(target, conf, seed, out, error, time.perf_counter() - t, acq.report)
                rows.append(row)
                if progress:
                    progress(row)
    summary = {t: {c.label: summarise([r for r in rows if r.target == t and r.config == c.label], c.kind,
                                      c.realism.sources)
                   for c in confs} for t in settings.targets}
    return AccuracyStudy(
        settings=settings,
        paper=AccuracyPaper(PAPER_DEPTH_MM, PAPER_XY_MM, base.scene.distance_m,
                            "one trial's worst corner of a square on the hand/eye target block, in the block's frame "
                            "(paper section V-D)"),
        camera=_camera(base),
        target_block=AccuracyTargetBlock(TARGET.squares_x, TARGET.squares_y, TARGET.square_m, CELL.target_yaw_rad),
        robot=None if rz.robot is None else _robot(rz.robot, setups[confs[-1].label]),
        corner_noise_px={c.label: setups[c.label].corner_noise_px for c in confs if c.realism.estimates},
        sources={s: SOURCES[s] for s in rz.sources}, summary=summary, rows=tuple(rows),
        time_s=time.perf_counter() - t0)


def _camera(cfg: SampleConfig) -> AccuracyCamera:
    scene = cfg.scene.build()
    left = scene.rig.left
    return AccuracyCamera(
        name=cfg.realism.camera, width_px=left.width, height_px=left.height, fx_px=float(left.K[0, 0]),
        fy_px=float(left.K[1, 1]), baseline_m=scene.rig.baseline_m, distance_m=cfg.scene.distance_m,
        distortion_k1_k2_p1_p2_k3=None if left.distortion is None else tuple(left.distortion.as_opencv().tolist()),
        aperture_radius_m=scene.aperture_radius_m, line_jitter_px=cfg.sensor.line_jitter_px,
        full_well_e=cfg.sensor.full_well_e, read_noise_dn=cfg.sensor.read_noise_dn, bit_depth=cfg.sensor.bit_depth)


def _robot(name: str, setup: RealismSetup) -> AccuracyRobot:
    m = setup.robot_model
    if m is None:
        return AccuracyRobot(name, ROBOTS[name].description)
    return AccuracyRobot(name, ROBOTS[name].description, joint_sigma_rad=m.joint_sigma_rad,
                         kinematic_sigma_angle_rad=m.sigma_angle_rad, kinematic_sigma_length_m=m.sigma_length_m)


def dominant_sources(summary: Mapping[str, ConfigSummary], measure: str = "depth") -> list[tuple[str, float]]:
    """Sources ranked by what each adds alone to the method's own floor (median worst error of the
    source alone minus that of no source, mm), largest first."""
    floor = next((s.stats(measure).worst_median_mm for s in summary.values()
                  if s.kind == "none" and s.stats(measure) is not None), 0.0)
    alone = [(c.replace(" alone", ""), s.stats(measure).worst_median_mm - floor) for c, s in summary.items()
             if s.kind == "alone" and s.stats(measure) is not None]
    return sorted(alone, key=lambda t: -t[1])


CSV_FIELDS = ("target", "config", "kind", "realism", "sources", "seed", "status", "points", "worst_depth_mm",
              "worst_xy_mm", "rms_depth_mm", "rms_xy_mm", "mean_depth_mm", "time_s", "error")


def accuracy_csv(rows: list[AccuracyTrial]) -> str:
    """One line per trial: the realism preset, the draw's seed and the errors (mm)."""
    import csv  # noqa: PLC0415
    import io  # noqa: PLC0415

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_FIELDS, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        d = r.to_dict()
        w.writerow({k: d.get(k) for k in CSV_FIELDS})
    return buf.getvalue()
