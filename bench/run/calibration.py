"""Calibration experiment (paper IV-A): render calibration images, calibrate, compare with the truth.

1. Stereo cameras: a ChArUco board (``scenes.render.board_renderer``) in 20 poses (flat, tilted
   15-35 degrees about both image axes, rolled, shifted, 0.36-0.50 m away) seen by both
   cameras through the same lens, sensor and noise as the samples -> ``reconstruction.calibration``:
   per-camera ``calibrateCamera`` (distortion fixed to zero, and free with k3 fixed, both
   reported), joint ``stereoCalibrate``, world registration from pose 0, which lies flat in
   the plate's plane z = 0 centred on the rig's target (its world placement is known, as the
   paper's target block's). The estimate handed to the pipeline takes the free distortion
   model when the images call for it (``distortion_is_needed``; ``distortion_model`` forces
   either), so the pipeline then undistorts its images with the estimated lens.
2. Structured light: a white flat target (0.3 x 0.3 m) at known heights
   ``target_z_m`` under the projector, rendered by the real ``PlateRenderer`` (active
   images) -> square centres triangulated with the *estimated* stereo calibration ->
   one least-squares line per projected feature.

   The target moves (z = -3, 0, +3 cm by default) and the rig and projector stay put,
   rather than the reverse: the fitted rays are then directly in the world frame in which
   the pipeline uses them, with no pose of the moved rig to estimate and undo (which
   would add its error to the rays). The renderer's lights are scaled for a surface at
   z = 0, so a target at z = -3 cm receives (0.40/0.43)^2 = 0.87 of that irradiance:
   harmless for thresholded square centroids.
3. Errors against the truth: focal length (px, %), principal point (px), baseline (mm),
   rotation between the cameras (deg), world registration (mm, deg), and per feature ray
   the angle (mrad) and the distance (mm) between the estimated and true rays at the
   plate's plane z = 0.

``estimated_calibration(cfg)`` gives (rig estimate, feature rays, report) for the
pipeline; ``compare_reconstruction(cfg)`` runs the reference experiment's
reconstruction with the estimated and with the true calibration and scores both.
Units: metres and radians in code; the report's keys name their units.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
import trimesh

from platebench.bench.config import SampleConfig
from platebench.bench.io.codecs import encode
from platebench.bench.io.calibration_records import (
    CalibrationEstimate,
    CalibrationReport,
    CalibrationSetup,
    CalibrationTimings,
    CameraFigures,
    IntrinsicsErrors,
    RayFigures,
    StereoFigures,
    TargetPlaneFigures,
)
from platebench.bench.io.images import DatasetError
from platebench.bench.io.sample_files import read_json
from platebench.bench.run.render import render_sample
from platebench.bench.run.score import recon_data, truth_from_sample
from platebench.evaluation.calibration_errors import RayErrors, rms_max, rotation_angle_rad  # noqa: F401
from platebench.evaluation.calibration_errors import ray_errors as _ray_errors
from platebench.evaluation.score import Score, score_reconstruction
from platebench.errors import UserValueError
from platebench.reconstruction.calibration import (
    StereoCalibration,
    calibrate_camera,
    detect_charuco,
    distortion_explained_px,
    distortion_is_needed,
    stereo_calibrate,
)
from platebench.reconstruction.calibration.stereo import UNDISTORT_CRITERIA
from platebench.reconstruction.paper.false_boundary import FeatureRays
from platebench.reconstruction.paper.pipeline import (
    PipelineOptions,
    projector_feature_rays,
    reconstruct,
)
from platebench.reconstruction.paper.structured_light import StructuredLightCalibration, calibrate_structured_light
from platebench.scenes.naming import image_seed
from platebench.scenes.render.board_renderer import (
    BoardRenderer,
    BoardSpec,
    calibration_poses,
)
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.rig import StereoRig
from platebench.scenes.scene_spec import RenderSettings

DEFAULT_TARGET_Z_M = (-0.03, 0.0, 0.03)
TARGET_SIZE_M = 0.3
PLATE_PLANE_Z_M = 0.0


@dataclass(frozen=True, eq=False)
class FlatTarget:
    """The white calibration plane, shaped as what ``PlateRenderer`` needs of a plate (``mesh``)."""

    mesh: trimesh.Trimesh
    z_m: float

    @classmethod
    def at(cls, z_m: float, size_m: float = TARGET_SIZE_M, center=(0.0, 0.0)) -> "FlatTarget":
        a = size_m / 2.0
        cx, cy = center
        v = np.array([[cx - a, cy - a, z_m], [cx + a, cy - a, z_m], [cx + a, cy + a, z_m], [cx - a, cy + a, z_m]])
        return cls(trimesh.Trimesh(v, np.array([[0, 1, 2], [0, 2, 3]]), process=False), float(z_m))


@dataclass(frozen=True)
class CalibrationImages:
    """Everything rendered for a calibration: board pairs (8-bit) and target active pairs (8-bit)."""

    board: BoardSpec
    poses: tuple
    board_images: tuple  # ({"left": uint8, "right": uint8}, ...) per pose
    target_z_m: tuple
    target_images: tuple  # ((left uint8, right uint8), ...) per target height
    timings_s: dict = field(default_factory=dict)


@dataclass(frozen=True)
class CalibrationResult:
    """The calibrations (estimated) and their comparison with the truth."""

    cameras: dict  # "fixed_distortion"/"free_distortion" -> {"left": CameraCalibration, "right": ...}
    stereo: dict  # "fixed_distortion"/"free_distortion" -> StereoCalibration
    structured_light: StructuredLightCalibration  # rays from the estimated stereo (the chosen model)
    structured_light_true_stereo: StructuredLightCalibration  # same images, true stereo: the method's own error
    rig_estimate: StereoRig
    report: CalibrationReport
    distortion_model: str = "fixed_distortion"  # the model of the estimate: a key of ``stereo``

    @property
    def rays(self) -> FeatureRays:
        return self.structured_light.rays


# -- rendering -----------------------------------------------------------------------
def render_calibration_images(cfg: SampleConfig, board: BoardSpec = BoardSpec(),
                              target_z_m=DEFAULT_TARGET_Z_M, progress=None,
                              renderer: PlateRenderer | None = None) -> tuple[CalibrationImages, PlateRenderer]:
    """Render the board poses (BoardRenderer) and the target heights (the real PlateRenderer)."""
    step = progress or (lambda name: None)
    scene = cfg.scene.build()
    rig = scene.rig
    timings = {}
    t = time.perf_counter()
    poses = tuple(calibration_poses(rig, board))
    br = BoardRenderer(rig, board, cfg.variant, cfg.sensor, scene.aperture_radius_m,
                       scene.focus_m if scene.aperture_radius_m > 0 else None)
    board_images = tuple(br.render_poses(poses, cfg.render, progress=step))
    timings["board_render_s"] = time.perf_counter() - t
    t = time.perf_counter()
    targets = [FlatTarget.at(z) for z in target_z_m]
    if renderer is None:
        renderer = PlateRenderer(scene, targets[0], cfg.variant)
    else:
        renderer.set_scene(scene)
    pairs = []
    for k, target in enumerate(targets):
        renderer.set_plate(target)
        pair = []
        for cam in ("left", "right"):
            step(f"target z={target.z_m * 1e3:+.0f} mm {cam}")
            s = RenderSettings(cfg.render.spp, (cfg.render.seed * 97 + 1000 + k) % 2**31)
            pair.append(cfg.sensor.digitize(renderer.render(cam, "active", s), seed=image_seed(s.seed, cam, "active")))
        pairs.append(tuple(pair))
    timings["target_render_s"] = time.perf_counter() - t
    return CalibrationImages(board, poses, board_images, tuple(float(z) for z in target_z_m), tuple(pairs),
                             timings), renderer


# -- calibrating ------------------------------------------------------------------------
DISTORTION_MODELS = ("auto", "fixed", "free")


def calibrate_from_images(images: CalibrationImages, width: int, height: int, pattern,
                          registration_view: int = 0, distortion_model: str = "auto"
                          ) -> tuple[dict, dict, StructuredLightCalibration, str]:
    """Run the calibrations on rendered images (no truth used): cameras, stereo (both distortion
    models), the rays from the chosen model's stereo, and the chosen model's key
    (``"fixed_distortion"``/``"free_distortion"``). ``distortion_model``: "auto" (the images
    decide: ``distortion_is_needed``), "fixed" (pinhole) or "free" (k1, k2, p1, p2)."""
    if distortion_model not in DISTORTION_MODELS:
        raise UserValueError(f"distortion model {distortion_model!r} is not allowed: choose one of "
                             f"{', '.join(DISTORTION_MODELS)}")
    cv_board = images.board.board()
    dets = {c: [detect_charuco(p[c], cv_board) for p in images.board_images] for c in ("left", "right")}
    size = (width, height)
    reg = images.poses[registration_view]
    cameras, stereo = {}, {}
    for key, fix in (("fixed_distortion", True), ("free_distortion", False)):
        cams = {c: calibrate_camera(dets[c], size, fix_distortion=fix) for c in ("left", "right")}
        cameras[key] = cams
        stereo[key] = stereo_calibrate(dets["left"], dets["right"], cams["left"], cams["right"], size,
                                       registration_view, (reg.R_wb, reg.p_wb))
    if distortion_model == "auto":
        free = distortion_is_needed(cameras["fixed_distortion"], cameras["free_distortion"])
    else:
        free = distortion_model == "free"
    chosen = "free_distortion" if free else "fixed_distortion"
    sl = calibrate_structured_light(images.target_images, stereo[chosen], pattern)
    return cameras, stereo, sl, chosen


# -- errors against the truth ----------------------------------------------------------
def ray_errors(est: FeatureRays, true: FeatureRays, plane_z_m: float = PLATE_PLANE_Z_M) -> RayErrors:
    """``evaluation.calibration_errors.ray_errors`` at the plate's plane z = ``PLATE_PLANE_Z_M`` by default."""
    return _ray_errors(est, true, plane_z_m)


def _image_grid(width: int, height: int) -> np.ndarray:
    uu, vv = np.meshgrid(np.linspace(0, width - 1, 33), np.linspace(0, height - 1, 25))
    return np.column_stack([uu.ravel(), vv.ravel()]).astype(np.float64)


def _max_distortion_px(K: np.ndarray, dist: np.ndarray, width: int, height: int) -> float:
    """Largest displacement (px) the distortion model (K, OpenCV coefficients) applies inside the image."""
    pts = _image_grid(width, height)
    und = cv2.undistortPoints(pts.reshape(-1, 1, 2), K, dist, P=K, criteria=UNDISTORT_CRITERIA).reshape(-1, 2)
    return float(np.max(np.linalg.norm(und - pts, axis=1)))


def _lens_model_error_px(K: np.ndarray, dist: np.ndarray, true_cam) -> float:
    """Largest disagreement (px) inside the image between an estimated lens (K, distortion) and the
    true camera's: each pixel's true ray, projected through the estimate (the estimate's whole
    intrinsic model, K included, against the truth)."""
    pts = _image_grid(true_cam.width, true_cam.height)
    xy = true_cam.normalised(pts)
    est, _ = cv2.projectPoints(np.column_stack([xy, np.ones(len(xy))]), np.zeros(3), np.zeros(3), K, dist)
    return float(np.max(np.linalg.norm(est.reshape(-1, 2) - pts, axis=1)))


def _intrinsics_errors(K: np.ndarray, K_true: np.ndarray) -> dict:
    """The fields of ``IntrinsicsErrors`` (px, %) of the estimate ``K`` against ``K_true``."""
    return dict(fx_px=float(K[0, 0]), fy_px=float(K[1, 1]), cx_px=float(K[0, 2]), cy_px=float(K[1, 2]),
                fx_error_px=float(K[0, 0] - K_true[0, 0]), fy_error_px=float(K[1, 1] - K_true[1, 1]),
                fx_error_pct=float((K[0, 0] / K_true[0, 0] - 1) * 100),
                fy_error_pct=float((K[1, 1] / K_true[1, 1] - 1) * 100),
                cx_error_px=float(K[0, 2] - K_true[0, 2]), cy_error_px=float(K[1, 2] - K_true[1, 2]),
                principal_point_error_px=float(np.hypot(K[0, 2] - K_true[0, 2], K[1, 2] - K_true[1, 2])))


def _stereo_errors(st: StereoCalibration, rig: StereoRig) -> StereoFigures:
    true = StereoCalibration.from_rig(rig)
    C_est = -st.R_world.T @ st.t_world
    return StereoFigures(
        baseline_m=float(st.baseline_m),
        baseline_error_mm=float((st.baseline_m - rig.baseline_m) * 1e3),
        baseline_error_pct=float((st.baseline_m / rig.baseline_m - 1) * 100),
        rotation_between_cameras_error_deg=float(np.degrees(rotation_angle_rad(st.R, true.R))),
        translation_direction_error_deg=float(np.degrees(np.arccos(np.clip(
            np.dot(st.T, true.T) / (np.linalg.norm(st.T) * np.linalg.norm(true.T)), -1, 1)))),
        f_times_baseline_error_pct=float((st.K_left[0, 0] * st.baseline_m / (rig.left.K[0, 0] * rig.baseline_m) - 1)
                                         * 100),
        stereo_reprojection_rms_px=float(st.rms_px),
        registration_residual_rms_mm=float(st.registration_rms_m * 1e3),
        left_center_error_mm=tuple(((C_est - rig.left.center) * 1e3).tolist()),
        left_center_error_norm_mm=float(np.linalg.norm(C_est - rig.left.center) * 1e3),
        left_rotation_error_deg=float(np.degrees(rotation_angle_rad(st.R_world, rig.left.R))),
        K_left=IntrinsicsErrors(**_intrinsics_errors(st.K_left, rig.left.K)),
        K_right=IntrinsicsErrors(**_intrinsics_errors(st.K_right, rig.right.K)),
        conventional_deviation=st.conventional_deviation())


def _rays_report(sl: StructuredLightCalibration, true_rays: FeatureRays, true_center: np.ndarray,
                 target_z_m) -> RayFigures:
    e = ray_errors(sl.rays, true_rays)
    angle_rms, angle_max = rms_max(e.angle_rad * 1e3)
    dist_rms, dist_max = rms_max(e.distance_at_plane_m * 1e3)
    return RayFigures(
        ids=tuple(e.ids.tolist()),
        angle_error_mrad=tuple((e.angle_rad * 1e3).tolist()),
        distance_at_plate_plane_mm=tuple((e.distance_at_plane_m * 1e3).tolist()),
        line_fit_residual_um=tuple((sl.residual_rms_m * 1e6).tolist()),
        projector_center_error_mm=tuple(((sl.projector_center - true_center) * 1e3).tolist()),
        projector_center_error_norm_mm=float(np.linalg.norm(sl.projector_center - true_center) * 1e3),
        ray_miss_of_common_center_rms_mm=rms_max(sl.center_miss_m * 1e3)[0],
        target_planes=tuple(TargetPlaneFigures(known_z_mm=z * 1e3, measured_z_mm=float(np.mean(p.points[:, 2]) * 1e3),
                                               depth_error_mm=float((np.mean(p.points[:, 2]) - z) * 1e3),
                                               tilt_deg=float(np.degrees(np.arccos(min(1.0, abs(p.plane_normal[2]))))),
                                               flatness_rms_um=p.flatness_rms_m * 1e6)
                            for z, p in zip(target_z_m, sl.planes)),
        angle_error_rms_mrad=angle_rms, angle_error_max_mrad=angle_max,
        distance_at_plate_plane_rms_mm=dist_rms, distance_at_plate_plane_max_mm=dist_max)


def run_calibration(cfg: SampleConfig = SampleConfig(), board: BoardSpec = BoardSpec(),
                    target_z_m=DEFAULT_TARGET_Z_M, progress=None,
                    renderer: PlateRenderer | None = None,
                    distortion_model: str = "auto") -> tuple[CalibrationResult, PlateRenderer]:
    """Render, calibrate and compare with the truth. Returns the result and the plate renderer
    (reuse it for samples of the same scene: its kernels are compiled). ``distortion_model``:
    the estimate's lens model ("auto": chosen from the images; "fixed"; "free")."""
    t0 = time.perf_counter()
    scene = cfg.scene.build()
    rig, projector = scene.rig, scene.projector
    images, renderer = render_calibration_images(cfg, board, target_z_m, progress, renderer)
    t = time.perf_counter()
    W, H = rig.left.width, rig.left.height
    cameras, stereo, sl, chosen = calibrate_from_images(images, W, H, projector.pattern,
                                                        distortion_model=distortion_model)
    sl_true = calibrate_structured_light(images.target_images, rig, projector.pattern)
    t_cal = time.perf_counter() - t
    true_rays = projector_feature_rays(projector.camera, projector.pattern)
    setup = CalibrationSetup(width_px=W, height_px=H, f_px=rig.left.f_px, fy_px=float(rig.left.K[1, 1]),
                             baseline_m=rig.baseline_m, distance_m=cfg.scene.distance_m, spp=cfg.render.spp,
                             seed=cfg.render.seed, board=encode(board),
                             board_poses=tuple(encode(p) for p in images.poses),
                             registration_pose=images.poses[0].name, target_z_m=tuple(images.target_z_m),
                             target_size_m=TARGET_SIZE_M, plate_plane_z_m=PLATE_PLANE_Z_M)
    camera_figures = {}
    for key in cameras:
        camera_figures[key] = {}
        for cam, cal in cameras[key].items():
            true_cam = rig.cameras[cam]
            true_dist = np.zeros(5) if true_cam.distortion is None else true_cam.distortion.as_opencv()
            camera_figures[key][cam] = CameraFigures(
                **_intrinsics_errors(cal.K, true_cam.K), reprojection_rms_px=cal.rms_px, views_used=len(cal.views),
                dist_k1_k2_p1_p2_k3=tuple(cal.dist.tolist()), true_dist_k1_k2_p1_p2_k3=tuple(true_dist.tolist()),
                max_distortion_displacement_px=_max_distortion_px(cal.K, cal.dist, W, H),
                true_max_distortion_displacement_px=_max_distortion_px(true_cam.K, true_dist, W, H),
                lens_model_error_max_px=_lens_model_error_px(cal.K, cal.dist, true_cam))
    estimate = CalibrationEstimate(
        stereo=stereo[chosen], rays=encode(sl), distortion_model=chosen, distortion_model_choice=distortion_model,
        reprojection_rms_px={k: {c: cal.rms_px for c, cal in cams.items()} for k, cams in cameras.items()},
        distortion_explained_px={c: distortion_explained_px(cameras["fixed_distortion"][c],
                                                            cameras["free_distortion"][c]) for c in ("left", "right")})
    truth = {"left": encode(rig.left), "right": encode(rig.right), "baseline_m": rig.baseline_m,
             "projector": encode(projector),
             "rays": {"origins_m": true_rays.origins.tolist(), "directions": true_rays.directions.tolist(),
                      "ids": true_rays.ids.tolist()}}
    report = CalibrationReport(
        setup, camera_figures, {key: _stereo_errors(stereo[key], rig) for key in cameras},
        _rays_report(sl, true_rays, projector.camera.center, images.target_z_m),
        _rays_report(sl_true, true_rays, projector.camera.center, images.target_z_m), estimate, truth,
        CalibrationTimings(**images.timings_s, calibrate_s=t_cal, total_s=time.perf_counter() - t0))
    result = CalibrationResult(cameras, stereo, sl, sl_true, stereo[chosen].to_rig(), report, chosen)
    return result, renderer


def estimated_calibration(cfg: SampleConfig = SampleConfig(), **kw) -> tuple[StereoRig, FeatureRays,
                                                                             CalibrationReport]:
    """(conventional rig estimate, estimated feature rays, report) for ``cfg``'s scene."""
    result, _ = run_calibration(cfg, **kw)
    return result.rig_estimate, result.rays, result.report


# -- the reference experiment with estimated vs true calibration --------------------------
def compare_reconstruction(cfg: SampleConfig = SampleConfig(), result: CalibrationResult | None = None,
                           renderer: PlateRenderer | None = None, progress=None) -> dict[str, Score]:
    """Reconstruct ``cfg``'s sample (default: the reference experiment) with the true calibration,
    with the estimated one (rig + rays), and with the true rig + estimated rays; score each.
    Returns {"true": Score, "estimated": Score, "true_rig_estimated_rays": Score}."""
    if result is None:
        result, renderer = run_calibration(cfg, progress=progress, renderer=renderer)
    sample, renderer = render_sample(cfg, renderer, progress)
    scene = sample.scene
    pattern = scene.projector.pattern
    truth = truth_from_sample(sample)
    true_rays = projector_feature_rays(scene.projector.camera, pattern)
    runs = {"true": (scene.rig, true_rays), "estimated": (result.rig_estimate, result.rays),
            "true_rig_estimated_rays": (scene.rig, result.rays)}
    scores = {}
    for name, (rig, rays) in runs.items():
        if progress:
            progress(f"reconstruct ({name} calibration)")
        r = reconstruct(sample.digital, rig, rays, pattern, PipelineOptions())
        scores[name] = score_reconstruction(truth, recon_data(r))
    return scores


def load_estimated_calibration(path: Path) -> tuple[StereoRig, FeatureRays]:
    """The estimated conventional rig and projector feature rays stored in a calibration.json
    written by ``platebench calibrate`` (so the pipeline can run on estimated calibration)."""
    path = Path(path)
    doc = read_json(path)  # missing, not a regular file, too large, not JSON: one line naming it
    try:
        est = CalibrationEstimate.from_dict(doc["estimate"])
        rays = est.feature_rays
    except (KeyError, ValueError, TypeError, json.JSONDecodeError) as e:
        raise DatasetError(f"{path}: not a platebench calibration ({type(e).__name__}: {e})") from None
    return est.stereo.to_rig(), rays


def progress_steps(cfg: SampleConfig, target_z_m, reconstruction: bool, board: BoardSpec = BoardSpec()) -> int:
    """The steps ``run_calibration`` (and, with ``reconstruction``, ``compare_reconstruction``) report to
    their ``progress`` callback: each camera's render of each board pose and of each target height, then
    the reference sample's renders and its reconstructions."""
    n_poses = len(calibration_poses(cfg.scene.build().rig, board))
    return 2 * n_poses + 2 * len(target_z_m) + (6 + 3 if reconstruction else 0)


def calibration_json(result: CalibrationResult, comparison: dict | None = None) -> dict:
    """calibration.json: the report (``CalibrationReport.to_dict``), its units, and per calibration of
    ``comparison`` (``compare_reconstruction``) the reference reconstruction's metrics row and score."""
    from platebench.evaluation.metrics_row import MetricsRow  # noqa: PLC0415

    out = result.report.to_dict()
    out["units"] = ("metres, radians, pixels unless a key names another unit; camera dicts (K, R, t) in the "
                    "OpenCV convention of calib.json (x_cam = R x_world + t, t in metres)")
    if comparison is not None:
        out["reconstruction"] = {name: {"metrics": MetricsRow.from_score(s).columns(), "score": encode(s)}
                                 for name, s in comparison.items()}
    return out
