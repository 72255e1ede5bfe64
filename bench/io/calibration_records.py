"""The calibration's report (``platebench calibrate``, ``bench.run.calibration``) as typed records,
and its file form (calibration.json).

Each part is a frozen dataclass whose field names are its JSON keys, units in the names (``_px``
pixels, ``_pct`` percent, ``_mm`` millimetres, ``_m`` metres, ``_deg`` degrees, ``_mrad``
milliradians, ``_um`` micrometres, ``_s`` seconds); ``to_dict`` writes it and ``from_dict`` reads
it back (``bench.io.records.Record``). A camera's figures are keyed by the lens model the
calibration fitted (``"fixed_distortion"``: no distortion, ``"free_distortion"``: k1, k2, p1, p2)
and then by camera (``"left"``, ``"right"``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from platebench.bench.io.codecs import decode
from platebench.bench.io.records import Record, records_from
from platebench.reconstruction.calibration.stereo import StereoCalibration
from platebench.reconstruction.paper.false_boundary import FeatureRays

__all__ = ["IntrinsicsErrors", "CameraFigures", "StereoFigures", "TargetPlaneFigures", "RayFigures",
           "CalibrationSetup", "CalibrationEstimate", "CalibrationTimings", "CalibrationReport", "LENS_MODELS"]

LENS_MODELS = ("fixed_distortion", "free_distortion")


@dataclass(frozen=True)
class IntrinsicsErrors(Record):
    """An estimated camera matrix K against the true one: the estimate (px) and its errors (estimate
    minus truth, px and percent of the truth; the principal point's distance, px)."""

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    fx_error_px: float
    fy_error_px: float
    fx_error_pct: float
    fy_error_pct: float
    cx_error_px: float
    cy_error_px: float
    principal_point_error_px: float


@dataclass(frozen=True)
class CameraFigures(IntrinsicsErrors):
    """One camera's own calibration (``cv2.calibrateCamera``) against the truth: its intrinsics'
    errors, reprojection RMS (px), the views it used, the estimated and true distortion (OpenCV k1,
    k2, p1, p2, k3), the largest shift (px) each applies inside the image, and the largest
    disagreement (px) of the estimated lens model with the true one."""

    reprojection_rms_px: float = float("nan")
    views_used: int = 0
    dist_k1_k2_p1_p2_k3: tuple = ()
    true_dist_k1_k2_p1_p2_k3: tuple = ()
    max_distortion_displacement_px: float = float("nan")
    true_max_distortion_displacement_px: float = float("nan")
    lens_model_error_max_px: float = float("nan")


@dataclass(frozen=True)
class StereoFigures(Record):
    """The stereo calibration (``cv2.stereoCalibrate`` and the world registration) against the true
    rig: baseline (m) and its error (mm, %), the rotation between the cameras and the direction of
    their translation (deg), f x baseline (%), reprojection RMS (px), registration residual (mm),
    the left camera's centre (mm, per axis and its norm) and rotation (deg), each camera's K
    (``IntrinsicsErrors``), and how far the estimate is from conventional geometry
    (``StereoCalibration.conventional_deviation``)."""

    baseline_m: float
    baseline_error_mm: float
    baseline_error_pct: float
    rotation_between_cameras_error_deg: float
    translation_direction_error_deg: float
    f_times_baseline_error_pct: float
    stereo_reprojection_rms_px: float
    registration_residual_rms_mm: float
    left_center_error_mm: tuple
    left_center_error_norm_mm: float
    left_rotation_error_deg: float
    K_left: IntrinsicsErrors
    K_right: IntrinsicsErrors
    conventional_deviation: Mapping[str, float] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "StereoFigures":
        d = dict(d)
        return super().from_dict({**d, "K_left": IntrinsicsErrors.from_dict(d.get("K_left")),
                                  "K_right": IntrinsicsErrors.from_dict(d.get("K_right"))})


@dataclass(frozen=True)
class TargetPlaneFigures(Record):
    """One height of the white target plane: its known and measured height (mm, world z), the
    depth error (mm), its measured tilt (deg) and flatness RMS (um)."""

    known_z_mm: float
    measured_z_mm: float
    depth_error_mm: float
    tilt_deg: float
    flatness_rms_um: float


@dataclass(frozen=True)
class RayFigures(Record):
    """The projector's fitted feature rays against the true ones, per feature (``ids``): the angle
    between the rays (mrad), the distance of their cuts with the plate's plane z = 0 (mm), each
    line fit's residual (um); the rays' common point against the projector's centre (mm, per axis
    and norm), the rays' RMS miss of that point (mm); each target height (``TargetPlaneFigures``);
    the RMS and maximum of the angle and the distance."""

    ids: tuple
    angle_error_mrad: tuple
    distance_at_plate_plane_mm: tuple
    line_fit_residual_um: tuple
    projector_center_error_mm: tuple
    projector_center_error_norm_mm: float
    ray_miss_of_common_center_rms_mm: float
    target_planes: tuple[TargetPlaneFigures, ...]
    angle_error_rms_mrad: float
    angle_error_max_mrad: float
    distance_at_plate_plane_rms_mm: float
    distance_at_plate_plane_max_mm: float

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "RayFigures":
        d = dict(d)
        return super().from_dict({**d, "target_planes": tuple(TargetPlaneFigures.from_dict(p)
                                                              for p in d.get("target_planes") or ())})


@dataclass(frozen=True)
class CalibrationSetup(Record):
    """What was calibrated: the image size and true focal lengths (px), baseline and sensing
    distance (m), samples per pixel and seed of the renders, the ChArUco board and its poses (their
    own file forms, ``scenes.render.board_renderer``), the pose that registers the world, the target
    plane's heights and size (m), the plate's plane (world z, m)."""

    width_px: int
    height_px: int
    f_px: float
    fy_px: float
    baseline_m: float
    distance_m: float
    spp: int
    seed: int
    board: Mapping[str, Any]
    board_poses: tuple
    registration_pose: str
    target_z_m: tuple
    target_size_m: float
    plate_plane_z_m: float


@dataclass(frozen=True)
class CalibrationEstimate(Record):
    """The calibration handed to the pipeline: the stereo calibration of the chosen lens model
    (``distortion_model``, chosen by ``distortion_model_choice``: auto, fixed or free), the
    structured light's fitted rays (a ``StructuredLightCalibration``'s form,
    ``bench/io/codecs/reconstruction.py``), each camera's reprojection RMS (px) per lens model and
    the share of the board corners' displacement (px RMS) the free model explains, per camera."""

    stereo: StereoCalibration
    rays: Mapping[str, Any]
    distortion_model: str | None = None  # None: a calibration.json from before the lens model was chosen
    distortion_model_choice: str | None = None
    reprojection_rms_px: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    distortion_explained_px: Mapping[str, float] = field(default_factory=dict)

    @property
    def feature_rays(self) -> FeatureRays:
        """The fitted feature rays (world frame)."""
        return decode(FeatureRays, self.rays)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "CalibrationEstimate":
        d = dict(d)
        return super().from_dict({**d, "stereo": decode(StereoCalibration, d["stereo"])})


@dataclass(frozen=True)
class CalibrationTimings(Record):
    """Seconds spent rendering the board poses and the target heights, calibrating, and in all."""

    board_render_s: float
    target_render_s: float
    calibrate_s: float
    total_s: float


@dataclass(frozen=True)
class CalibrationReport(Record):
    """The calibration against the truth (calibration.json without its ``units`` and
    ``reconstruction`` sections): the set-up; each camera per lens model (``CameraFigures``); the
    stereo pair per lens model (``StereoFigures``); the projector's rays fitted with the estimated
    stereo calibration and with the true one (the structured light's own error); the estimate the
    pipeline gets; the true calibration (its own file form); the timings."""

    config: CalibrationSetup
    cameras: Mapping[str, Mapping[str, CameraFigures]]
    stereo: Mapping[str, StereoFigures]
    projector_rays: RayFigures
    projector_rays_true_stereo: RayFigures
    estimate: CalibrationEstimate
    truth: Mapping[str, Any]
    timings_s: CalibrationTimings

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "CalibrationReport":
        d = dict(d)
        return super().from_dict({
            **d, "config": CalibrationSetup.from_dict(d.get("config")),
            "cameras": {k: records_from(CameraFigures, v) for k, v in (d.get("cameras") or {}).items()},
            "stereo": records_from(StereoFigures, d.get("stereo")),
            "projector_rays": RayFigures.from_dict(d.get("projector_rays") or {}),
            "projector_rays_true_stereo": RayFigures.from_dict(d.get("projector_rays_true_stereo") or {}),
            "estimate": CalibrationEstimate.from_dict(d.get("estimate") or {}),
            "timings_s": CalibrationTimings.from_dict(d.get("timings_s"))})
