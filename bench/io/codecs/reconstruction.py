"""Codecs of the `reconstruction` types (see `bench.io.codecs`): the paper pipeline's parts of
recon.json and calibration.json (world frame, metres unless the key says otherwise), the
calibration's estimate, and the sensing loop's parts of sensing.json (millimetres and degrees
where the key says so)."""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from platebench.bench.io.codecs.base import decoder, encode
from platebench.reconstruction.calibration.stereo import CameraCalibration, StereoCalibration
from platebench.reconstruction.paper.false_boundary import FalseBoundaryTest, FeatureRays
from platebench.reconstruction.paper.pipeline import CutSquares
from platebench.reconstruction.paper.square_matching import Fig6Check
from platebench.reconstruction.paper.structured_light import StructuredLightCalibration
from platebench.reconstruction.strategy.active_views import ActivePoints
from platebench.reconstruction.strategy.bending import BendingCurve
from platebench.reconstruction.strategy.detectors import DetectorResult
from platebench.reconstruction.strategy.multiview import BoundaryVerdict, Gap, PoseSpread, UnconfirmedRun
from platebench.reconstruction.strategy.multiview import SPREAD_REPORT_DISTANCE_M
from platebench.reconstruction.strategy.planner import Decision, PlannedView
from platebench.reconstruction.strategy.poses import SensorPose
from platebench.reconstruction.strategy.registration import PoseShifts

M_TO_MM = 1e3  # metres to millimetres (and radians to milliradians)


# -- the paper's pipeline ------------------------------------------------------------
@encode.register(FeatureRays)
def _(x: FeatureRays) -> dict:
    return {"ray_origins_m": x.origins.tolist(), "ray_directions": x.directions.tolist(),
            "ids": x.ids.tolist()}


@decoder(FeatureRays)
def _(d: Mapping[str, Any]) -> FeatureRays:
    """The rays of their form (or of a structured-light calibration's, which holds them)."""
    return FeatureRays(np.array(d["ray_origins_m"], float), np.array(d["ray_directions"], float),
                       np.array(d["ids"], int))


@encode.register(FalseBoundaryTest)
def _(x: FalseBoundaryTest) -> dict:
    return {"detected": x.detected, "expected": x.expected, "expected_ids": list(x.expected_ids),
            "counting_test": x.counting_test, "arrays_disagree": x.arrays_disagree,
            "false_boundary_detected": x.false_boundary_detected, "cut_squares": dict(x.cut)}


@decoder(FalseBoundaryTest)
def _(d) -> FalseBoundaryTest:
    """recon.json's ``false_boundary`` section. A key the section lacks reads as: no squares detected,
    ``expected`` -1 (unknown), the test's flag ``false_boundary_detected`` (False) as the counting test's,
    arrays that agree, no cut squares."""
    flagged = bool(d.get("false_boundary_detected", False))
    return FalseBoundaryTest({str(k): int(v) for k, v in (d.get("detected") or {}).items()}, int(d.get("expected", -1)),
                             tuple(int(i) for i in d.get("expected_ids") or ()), bool(d.get("counting_test", flagged)),
                             bool(d.get("arrays_disagree", False)),
                             {str(k): int(v) for k, v in (d.get("cut_squares") or {}).items()})


@encode.register(StructuredLightCalibration)
def _(x: StructuredLightCalibration) -> dict:
    """The rays' form, the fit's residuals and the common point (metres), and each target plane."""
    return {**encode(x.rays), "residual_rms_m": x.residual_rms_m.tolist(),
            "projector_center_m": x.projector_center.tolist(), "center_miss_m": x.center_miss_m.tolist(),
            "planes": [{"offset_m": p.plane_offset_m, "normal": p.plane_normal.tolist(),
                        "flatness_rms_m": p.flatness_rms_m} for p in x.planes]}


@encode.register(Fig6Check)
def _(x: Fig6Check) -> dict:
    return {"condition_1_ok": x.condition_1_ok, "condition_2_ok": x.condition_2_ok,
            "violations": list(x.violations)}


@encode.register(CutSquares)
def _(x: CutSquares) -> dict:
    return {"count": len(x), "feature_id": [int(i) for i in x.feature_id], "reasons": list(x.reasons)}


# -- calibration ---------------------------------------------------------------------
@encode.register(CameraCalibration)
def _(x: CameraCalibration) -> dict:
    return {"K": x.K.tolist(), "dist_k1_k2_p1_p2_k3": x.dist.tolist(), "rms_px": x.rms_px,
            "per_view_rms_px": x.per_view_rms_px.tolist(), "views": list(x.views),
            "fix_distortion": x.fix_distortion}


@encode.register(StereoCalibration)
def _(x: StereoCalibration) -> dict:
    return {"K_left": x.K_left.tolist(), "K_right": x.K_right.tolist(),
            "dist_left": x.dist_left.tolist(), "dist_right": x.dist_right.tolist(),
            "R_right_from_left": x.R.tolist(), "T_right_from_left_m": np.ravel(x.T).tolist(),
            "baseline_m": x.baseline_m, "R_world_left": x.R_world.tolist(),
            "t_world_left_m": np.ravel(x.t_world).tolist(), "width": x.width, "height": x.height,
            "stereo_rms_px": x.rms_px, "registration_rms_m": x.registration_rms_m,
            "triangulation_model": x.model,
            "conventional_deviation": x.conventional_deviation()}


@decoder(StereoCalibration)
def _(d: Mapping[str, Any]) -> StereoCalibration:
    """The calibration of its form (its derived figures, baseline and deviation, are computed again;
    the per-view RMS is not in the file)."""
    return StereoCalibration(
        np.array(d["K_left"], float), np.array(d["K_right"], float), np.array(d["dist_left"], float),
        np.array(d["dist_right"], float), np.array(d["R_right_from_left"], float),
        np.array(d["T_right_from_left_m"], float), np.array(d["R_world_left"], float),
        np.array(d["t_world_left_m"], float), int(d["width"]), int(d["height"]),
        float("nan") if d.get("stereo_rms_px") is None else float(d["stereo_rms_px"]),
        registration_rms_m=float("nan") if d.get("registration_rms_m") is None
        else float(d["registration_rms_m"]),
        model=str(d.get("triangulation_model", "general")))


# -- the sensing strategy ------------------------------------------------------------
@encode.register(SensorPose)
def _(x: SensorPose) -> dict:
    return {"center_m": x.center.tolist(), "target_m": x.target.tolist(),
            "view_dir": x.view_dir.tolist(), "baseline_dir": x.baseline_dir.tolist(),
            "distance_m": x.distance_m, "reason": x.reason}


@encode.register(PlannedView)
def _(x: PlannedView) -> dict:
    return {"name": x.name, "purpose": x.purpose, "method": x.method, "reason": x.reason,
            "pose": encode(x.pose)}


@encode.register(Decision)
def _(x: Decision) -> dict:
    return {"decision": x.kind, "reason": x.reason, "gaps_targeted": x.gaps_targeted,
            "gaps_predicted_seen": x.gaps_predicted_seen,
            **({"view": encode(x.view)} if x.view is not None else {})}


@encode.register(PoseSpread)
def _(x: PoseSpread) -> dict:
    """Millimetres and milliradians, with the matching distance the spread gives
    ``multiview.SPREAD_REPORT_DISTANCE_M`` from the camera."""
    return {"translation_rms_mm": round(x.translation_m * M_TO_MM, 4),
            "rotation_rms_mrad": round(x.rotation_rad * M_TO_MM, 4),
            "match_tol_mm_at_0.40_m": round(float(x.match_tol_m(SPREAD_REPORT_DISTANCE_M)) * M_TO_MM, 3)}


@encode.register(Gap)
def _(x: Gap) -> dict:
    return {"position_mm": (x.position_m * M_TO_MM).round(2).tolist(),
            "direction": x.direction.round(4).tolist(), "piece_from": x.view, "what": x.what}


@encode.register(UnconfirmedRun)
def _(x: UnconfirmedRun) -> dict:
    return {"view": x.view, "length_mm": round(x.length_m * M_TO_MM, 1),
            "start_mm": (x.start_m * M_TO_MM).round(1).tolist(), "end_mm": (x.end_m * M_TO_MM).round(1).tolist(),
            "covered_by_other_poses": x.covered}


@encode.register(BoundaryVerdict)
def _(x: BoundaryVerdict) -> dict:
    return {"boundary_verified": x.verified, "reason": x.reason, "components": x.components,
            "pieces": [{"view": p.view, "length_mm": round(p.length_m * M_TO_MM, 1), "closed": p.closed}
                       for p in x.pieces],
            "gaps": [encode(g) for g in x.gaps],
            "unconfirmed_outline": [encode(u) for u in x.unconfirmed],
            "refuted_points": int(sum(int(np.count_nonzero(r)) for r in x.refuted)),
            "merged_points": int(len(x.merged))}


@encode.register(PoseShifts)
def _(x: PoseShifts) -> dict:
    """View name -> [x, y, z] shift in millimetres (3 decimals)."""
    return {n: [round(float(v) * M_TO_MM, 3) for v in s] for n, s in x.shifts_m.items()}


@encode.register(DetectorResult)
def _(x: DetectorResult) -> dict:
    return {"fired": x.fired, "measure": x.measure, "unit": x.unit, "detail": x.detail}


@encode.register(BendingCurve)
def _(x: BendingCurve) -> dict:
    return {"A_m": x.A.tolist(), "B_m": x.B.tolist(), "chord_m": x.chord_m,
            "a_deg": float(np.degrees(x.a_rad)), "b_deg": float(np.degrees(x.b_rad))}


@encode.register(ActivePoints)
def _(x: ActivePoints) -> dict:
    return {"points": int(len(x.points)), "matched": x.matched, "rejected_off_ray": x.rejected,
            "row_spacing_mm": round(x.row_spacing_m * M_TO_MM, 2) if np.isfinite(x.row_spacing_m) else None,
            "ray_distance_max_mm": round(float(x.ray_distance_m.max()) * M_TO_MM, 3) if len(x.points) else None}
