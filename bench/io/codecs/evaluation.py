"""Codecs of the `evaluation` types (see `bench.io.codecs`): score.json's parts and the field scores' layouts.

Values are held in metres (pixels for disparities and image boundaries); the forms carry the unit in
every key (mm, mm2, px, pct, frac, count). A reader fills what its form lacks with NaN (a figure),
0 (a count) or an empty array (per-point error vectors, which the forms do not hold).
"""
from __future__ import annotations

import math

import numpy as np

from platebench.bench.io.codecs.base import decode, decoder, encode
from platebench.evaluation.boundary_metrics import BOUNDARY_UNITS, BoundaryScore
from platebench.evaluation.dense import SparseDepthScore
from platebench.evaluation.detection import DetectionScore
from platebench.evaluation.disparity_metrics import Eth3dRegion, Eth3dScore, MiddleburyRegion, MiddleburyScore
from platebench.evaluation.field_scores import (
    MM,
    AbsErrors,
    DepthScore,
    DisparityScore,
    MeshScore,
    PointCloudScore,
    threshold_key,
)
from platebench.evaluation.pixel_coverage import PixelCoverage
from platebench.evaluation.point_metrics import MatchScore, PointScore
from platebench.evaluation.score import (
    GOAL_BOUNDARY_MEAN_MM,
    GOAL_DEPTH_RMS_MM,
    GOAL_XY_RMS_MM,
    BoundaryTruth,
    FalseBoundaryVerdict,
    Goals,
    Matching,
    PaperBound,
    PerPointErrors,
    PointErrors,
    Score,
)
from platebench.evaluation.stats import ErrorStats, stat_key
from platebench.evaluation.surface_metrics import SurfaceScore

__all__: list[str] = []

MM2 = 1e6  # square millimetres per square metre


def _thr_key(t: float) -> str:
    """0.5 -> '0_5', 1.0 -> '1_0', 4.0 -> '4_0' (a disparity threshold in a key)."""
    return f"{t:.1f}".replace(".", "_")


def _mm(x: float | None) -> float | None:
    return None if x is None else float(x) * MM


def _m(x_mm) -> float:
    """Metres from a file's millimetres (None: NaN)."""
    return math.nan if x_mm is None else float(x_mm) / MM


# ----------------------------------------------------------------------------- stats
@encode.register(ErrorStats)
def _(x: ErrorStats, prefix: str = "", unit_suffix: str = "mm", scale: float = MM) -> dict:
    """``{prefix}_mean_{unit}``, ``_rms_``, ``_max_``, ``_p95_`` (times ``scale``) and ``{prefix}_count``.

    Example: ``encode(stats, "depth")`` gives ``depth_mean_mm``, ``depth_rms_mm``, ``depth_max_mm``,
    ``depth_p95_mm``, ``depth_count`` from values in metres. ``unit_suffix="px", scale=1.0`` for pixel
    statistics. NaN (no values) stays NaN."""
    return {
        stat_key(prefix, "mean", unit_suffix): float(x.mean * scale),
        stat_key(prefix, "rms", unit_suffix): float(x.rms * scale),
        stat_key(prefix, "max", unit_suffix): float(x.max * scale),
        stat_key(prefix, "p95", unit_suffix): float(x.p95 * scale),
        stat_key(prefix, "count"): int(x.count),
    }


@decoder(ErrorStats)
def _(d: dict, prefix: str = "", unit_suffix: str = "mm", scale: float = MM, count: int | None = None) -> ErrorStats:
    """The inverse of the encoder (values divided by ``scale``; missing or None: NaN); ``count``: when the
    dict carries none of its own under ``{prefix}_count``."""
    def value(name):
        v = d.get(stat_key(prefix, name, unit_suffix))
        return math.nan if v is None else float(v) / scale
    n = d.get(stat_key(prefix, "count"), count)
    return ErrorStats(value("mean"), value("rms"), value("max"), value("p95"), int(n or 0))


# ----------------------------------------------------------------------------- coverage, detection
@encode.register(PixelCoverage)
def _(x: PixelCoverage) -> dict:
    """Keys ``plate_px``, ``estimated_px``, ``coverage_frac``."""
    return {"plate_px": x.plate_px, "estimated_px": x.estimated_px, "coverage_frac": x.coverage_frac}


@decoder(PixelCoverage)
def _(d: dict) -> PixelCoverage:
    return PixelCoverage(int(d.get("plate_px") or 0), int(d.get("estimated_px") or 0))


@encode.register(DetectionScore)
def _(x: DetectionScore) -> dict:
    return {"true_positive": x.true_positive, "false_positive": x.false_positive,
            "false_negative": x.false_negative, "true_negative": x.true_negative,
            "precision": x.precision, "recall": x.recall}


# ----------------------------------------------------------------------------- points, boundaries, surfaces
@encode.register(PointScore)
def _(x: PointScore) -> dict:
    """Keys: ``{depth,x,y,xy_radial,err3d}_{mean,rms,max,p95}_mm``, ``{depth,x,y}_mean_signed_mm``, ``count``."""
    out: dict = {}
    for name in ("depth", "x", "y", "xy_radial", "err3d"):
        d = encode(getattr(x, name), name, "mm", MM)
        d.pop(f"{name}_count")
        out.update(d)
    out["depth_mean_signed_mm"] = x.depth_bias_signed * MM
    out["x_mean_signed_mm"] = x.x_bias_signed * MM
    out["y_mean_signed_mm"] = x.y_bias_signed * MM
    out["count"] = x.count
    return out


@decoder(PointScore)
def _(d: dict) -> PointScore:
    """Metres; the per-point errors are not in the form: an empty (0, 3) array."""
    n = int(d.get("count") or 0)

    def signed(name):
        v = d.get(f"{name}_mean_signed_mm")
        return math.nan if v is None else float(v) / MM
    stats = {name: decode(ErrorStats, d, name, "mm", MM, n) for name in ("depth", "x", "y", "xy_radial", "err3d")}
    errors = np.zeros((0, 3))
    errors.setflags(write=False)
    return PointScore(**stats, depth_bias_signed=signed("depth"), x_bias_signed=signed("x"),
                      y_bias_signed=signed("y"), count=n, errors_cam=errors)


@encode.register(MatchScore)
def _(x: MatchScore) -> dict:
    return {
        "expected_count": x.expected,
        "visible_count": x.visible,
        "reported_count": x.reported,
        "duplicate_count": x.duplicate,
        "detected_visible_count": x.detected_visible,
        "detected_not_visible_count": x.detected_not_visible,
        "missed_count": x.missed,
        "correct_count": x.correct,
        "wrong_count": x.wrong,
        "correct_match_rate_frac": x.correct_match_rate,
        "detection_rate_frac": x.detection_rate,
        "correct_visible_rate_frac": x.correct_visible_rate,
    }


@encode.register(BoundaryScore)
def _(x: BoundaryScore) -> dict:
    """Keys (mm for metres, px for pixels): ``est_to_gt_{mean,rms,max,p95}_mm``, ``est_to_gt_count``,
    ``gt_to_est_*``, ``mean_sym_mm``, ``rms_sym_mm``, ``hausdorff_mm``, ``length_est_mm``,
    ``length_gt_mm``, ``sample_spacing_mm``."""
    suf, scale = BOUNDARY_UNITS[x.unit]
    out = {}
    out.update(encode(x.est_to_gt, "est_to_gt", suf, scale))
    out.update(encode(x.gt_to_est, "gt_to_est", suf, scale))
    out[f"mean_sym_{suf}"] = x.mean_sym * scale
    out[f"rms_sym_{suf}"] = x.rms_sym * scale
    out[f"hausdorff_{suf}"] = x.hausdorff * scale
    out[f"length_est_{suf}"] = x.length_est * scale
    out[f"length_gt_{suf}"] = x.length_gt * scale
    out[f"sample_spacing_{suf}"] = x.sample_spacing * scale
    return out


@decoder(BoundaryScore)
def _(d: dict, unit: str = "m") -> BoundaryScore:
    """A boundary in ``unit`` ("m": keys in mm, "px")."""
    suf, scale = BOUNDARY_UNITS[unit]

    def value(name):
        v = d.get(f"{name}_{suf}")
        return math.nan if v is None else float(v) / scale
    return BoundaryScore(decode(ErrorStats, d, "est_to_gt", suf, scale), decode(ErrorStats, d, "gt_to_est", suf, scale),
                         value("mean_sym"), value("rms_sym"), value("hausdorff"), value("length_est"),
                         value("length_gt"), value("sample_spacing"), unit)


@encode.register(SurfaceScore)
def _(x: SurfaceScore) -> dict:
    """Keys: ``dist_{mean,rms,max,p95}_mm``, ``dist_count``, ``surface_coverage_frac``, ``covered_area_mm2``,
    ``plate_area_mm2``, ``gt_sample_count``, ``coverage_point_count``, ``sample_spacing_mm``,
    ``coverage_radius_mm``, ``coverage_max_distance_mm`` (None = no limit)."""
    out = encode(x.dist, "dist", "mm", MM)
    out.update(
        {
            "surface_coverage_frac": x.surface_coverage_frac,
            "covered_area_mm2": x.covered_area_m2 * MM2,
            "plate_area_mm2": x.plate_area_m2 * MM2,
            "gt_sample_count": x.gt_sample_count,
            "coverage_point_count": x.points_used_for_coverage,
            "sample_spacing_mm": x.sample_spacing_m * MM,
            "coverage_radius_mm": x.coverage_radius_m * MM,
            "coverage_max_distance_mm": None if x.max_distance_m is None else x.max_distance_m * MM,
        }
    )
    return out


@decoder(SurfaceScore)
def _(d: dict) -> SurfaceScore:
    """Metres and m^2; the key ``coverage_frac`` is read as ``surface_coverage_frac`` where the form holds
    no ``surface_coverage_frac``."""
    def value(key, scale=MM):
        v = d.get(key)
        return math.nan if v is None else float(v) / scale
    coverage = "coverage_frac" if "surface_coverage_frac" not in d and "coverage_frac" in d \
        else "surface_coverage_frac"
    return SurfaceScore(decode(ErrorStats, d, "dist", "mm", MM), value(coverage, 1.0),
                        value("covered_area_mm2", MM2), value("plate_area_mm2", MM2),
                        int(d.get("gt_sample_count") or 0), int(d.get("coverage_point_count") or 0),
                        value("sample_spacing_mm"), value("coverage_radius_mm"),
                        None if d.get("coverage_max_distance_mm") is None
                        else float(d["coverage_max_distance_mm"]) / MM)


@encode.register(SparseDepthScore)
def _(x: SparseDepthScore) -> dict:
    out = {"points": x.points, "points_on_plate": x.points_on_plate,
           "centres_depth_median_mm": x.centres_depth_median_mm,
           "centres_depth_rms_mm": x.centres_depth_rms_mm, "centres_depth_max_mm": x.centres_depth_max_mm}
    if x.surface_rms_mm is not None:
        out.update(surface_rms_mm=x.surface_rms_mm, surface_max_mm=x.surface_max_mm)
    if x.coverage is not None:
        out.update(encode(x.coverage))
    return out


# ----------------------------------------------------------------------------- disparity benchmarks
@encode.register(MiddleburyRegion)
def _(x: MiddleburyRegion, prefix: str = "mb") -> dict:
    p = f"{prefix}_{x.region}_"
    out = {f"{p}bad_{_thr_key(t)}_pct": v for t, v in x.bad_pct}
    out[f"{p}invalid_pct"] = x.invalid_pct
    out[f"{p}avgerr_px"] = x.avgerr
    out[f"{p}rms_px"] = x.rms
    out.update({f"{p}a{q}_px": v for q, v in x.quantiles})
    out[f"{p}gt_count"] = x.gt_count
    out[f"{p}valid_count"] = x.valid_count
    return out


@encode.register(MiddleburyScore)
def _(x: MiddleburyScore) -> dict:
    """Keys ``mb_{all,nonocc}_{bad_0_5_pct, bad_1_0_pct, bad_2_0_pct, bad_4_0_pct, invalid_pct, avgerr_px,
    rms_px, a50_px, a90_px, a95_px, a99_px, gt_count, valid_count}``."""
    out = encode(x.all, "mb")
    if x.nonocc is not None:
        out.update(encode(x.nonocc, "mb"))
    return out


@encode.register(Eth3dRegion)
def _(x: Eth3dRegion, prefix: str = "eth") -> dict:
    p = f"{prefix}_{x.region}_"
    out = {f"{p}coverage_frac": x.coverage}
    out.update({f"{p}bad_{_thr_key(t)}_pct": v for t, v in x.bad_pct})
    out[f"{p}avgerr_px"] = x.avgerr
    out[f"{p}rms_px"] = x.rms
    out.update({f"{p}a{q}_px": v for q, v in x.quantiles})
    out[f"{p}gt_count"] = x.gt_count
    out[f"{p}est_count"] = x.est_count
    return out


@encode.register(Eth3dScore)
def _(x: Eth3dScore) -> dict:
    """Keys ``eth_{all,nonocc}_{coverage_frac, bad_0_5_pct, bad_1_0_pct, bad_2_0_pct, bad_4_0_pct, avgerr_px,
    rms_px, a50_px, a90_px, a95_px, a99_px, gt_count, est_count}``."""
    out = encode(x.all, "eth")
    if x.nonocc is not None:
        out.update(encode(x.nonocc, "eth"))
    return out


# ----------------------------------------------------------------------------- field scores
@encode.register(AbsErrors)
def _(x: AbsErrors, prefix: str) -> dict:
    """``{prefix}_{mean,median,rms,max}_mm``, ``{prefix}_a{50,90,95,99}_mm``, ``{prefix}_mean_signed_mm``
    (signed errors only), ``{prefix}_count``."""
    out = {f"{prefix}_mean_mm": x.mean_m * MM, f"{prefix}_median_mm": x.median_m * MM,
           f"{prefix}_rms_mm": x.rms_m * MM, f"{prefix}_max_mm": x.max_m * MM}
    out.update({f"{prefix}_a{q}_mm": v * MM for q, v in x.quantiles_m})
    if x.signed_mean_m is not None:
        out[f"{prefix}_mean_signed_mm"] = x.signed_mean_m * MM
    out[f"{prefix}_count"] = x.count
    return out


@encode.register(DepthScore)
def _(x: DepthScore) -> dict:
    out = {"plate_px": x.plate_px, "estimated_px": x.estimated_px, "off_plate_px": x.off_plate_px,
           "coverage_frac": x.coverage_frac}
    out.update(encode(x.errors, "depth"))
    out.update({f"depth_bad_{threshold_key(t)}_mm_pct": v for t, v in x.bad_pct})
    return out


@encode.register(DisparityScore)
def _(x: DisparityScore) -> dict:
    """The implied depth's keys (``DepthScore``'s form) at the top, ``middlebury`` and ``eth3d`` sections
    (keys ``mb_*``/``eth_*``)."""
    out = {"doffs_px": x.doffs_px, "nonocc_px": x.nonocc_px}
    out.update(encode(x.depth))
    out["middlebury"] = encode(x.middlebury)
    out["eth3d"] = encode(x.eth3d)
    return out


@encode.register(PointCloudScore)
def _(x: PointCloudScore) -> dict:
    out = {"points_count": x.count, "points_dropped_count": x.dropped_count}
    out.update(encode(x.distance, "dist"))
    c = x.surface
    out.update({"outlier_threshold_mm": x.outlier_threshold_m * MM, "outlier_count": x.outlier_count,
                "outlier_frac": x.outlier_frac, **encode(x.coverage),
                "surface_coverage_frac": c.surface_coverage_frac,
                "coverage_radius_mm": c.coverage_radius_m * MM, "covered_area_mm2": c.covered_area_m2 * MM2,
                "plate_area_mm2": c.plate_area_m2 * MM2, "sample_spacing_mm": c.sample_spacing_m * MM})
    return out


@encode.register(MeshScore)
def _(x: MeshScore) -> dict:
    out = {"faces_count": x.faces_count, "sample_spacing_mm": x.sample_spacing_m * MM}
    out.update(encode(x.accuracy, "accuracy"))
    out.update(encode(x.completeness, "completeness"))
    out["overall_mm"] = x.overall_m * MM
    if x.coverage is not None:
        out.update(encode(x.coverage))
    for t, p, r, f in x.thresholds:
        k = threshold_key(t * MM)
        out[f"precision_{k}_mm_pct"] = 100.0 * p
        out[f"recall_{k}_mm_pct"] = 100.0 * r
        out[f"fscore_{k}_mm_pct"] = 100.0 * f
    return out


# ----------------------------------------------------------------------------- score.json
@encode.register(PointErrors)
def _(x: PointErrors) -> dict:
    d = encode(x.stats)
    d["to_surface_rms_mm"] = _mm(x.to_surface_rms_m)
    d["to_surface_max_mm"] = _mm(x.to_surface_max_m)
    return d


@decoder(PointErrors)
def _(d: dict) -> PointErrors:
    return PointErrors(decode(PointScore, d), _m(d.get("to_surface_rms_mm")), _m(d.get("to_surface_max_mm")))


@encode.register(PerPointErrors)
def _(x: PerPointErrors) -> dict:
    out = {"centre_error_mm": [float(v) for v in np.asarray(x.centre_error_m) * MM],
           "centre_identity_known": [bool(k) for k in x.centre_known]}
    if x.surface_distance_m is not None:
        out["surface_vertex_distance_mm"] = [float(v) for v in np.asarray(x.surface_distance_m) * MM]
    return out


@decoder(PerPointErrors)
def _(d: dict) -> PerPointErrors:
    surf = d.get("surface_vertex_distance_mm")
    return PerPointErrors(np.asarray(d.get("centre_error_mm") or [], float) / MM,
                          np.asarray(d.get("centre_identity_known") or [], bool),
                          None if surf is None else np.asarray(surf, float) / MM)


@encode.register(Matching)
def _(x: Matching) -> dict:
    return {"matched_count": x.matched_count, "correct_match_count": x.correct_match_count,
            "correct_match_rate_frac": x.correct_match_rate_frac,
            "label_correct_rate_frac": x.label_correct_rate_frac,
            "detected_count": dict(x.detected_count), "visible_count": dict(x.visible_count),
            "visible_in_both_count": x.visible_in_both_count, "expected_count_gt": x.expected_count_gt,
            "expected_count_method": x.expected_count_method}


@decoder(Matching)
def _(d: dict) -> Matching:
    return Matching(int(d.get("matched_count") or 0), int(d.get("correct_match_count") or 0),
                    float(d.get("label_correct_rate_frac") or 0.0), dict(d.get("detected_count") or {}),
                    dict(d.get("visible_count") or {}), int(d.get("visible_in_both_count") or 0),
                    int(d.get("expected_count_gt") or 0), int(d.get("expected_count_method", -1)))


@encode.register(FalseBoundaryVerdict)
def _(x: FalseBoundaryVerdict) -> dict:
    return {"ground_truth": dict(x.ground_truth), "ground_truth_any": x.ground_truth_any,
            "detected": x.detected, "agrees": x.agrees}


@decoder(FalseBoundaryVerdict)
def _(d: dict) -> FalseBoundaryVerdict:
    return FalseBoundaryVerdict({k: bool(v) for k, v in (d.get("ground_truth") or {}).items()},
                                bool(d.get("detected")))


@decoder(BoundaryTruth)
def _(d: dict) -> BoundaryTruth:
    """One camera's entry of gt/visibility.json (``scenes.render.ground_truth.BoundaryVisibility``'s form:
    ``false_boundary``, ``visible_fraction``; a fraction it lacks reads as NaN)."""
    v = d.get("visible_fraction")
    return BoundaryTruth(bool(d["false_boundary"]), math.nan if v is None else float(v))


@encode.register(PaperBound)
def _(x: PaperBound) -> dict:
    return {"depth_max_mm": x.depth_max_mm, "xy_per_axis_max_mm": x.xy_per_axis_max_mm,
            "all_points": x.all_points, "met": x.met}


@decoder(PaperBound)
def _(d: dict) -> PaperBound:
    return PaperBound(float(d["depth_max_mm"]), float(d["xy_per_axis_max_mm"]), bool(d["all_points"]))


@encode.register(Goals)
def _(x: Goals) -> dict:
    return {"depth_rms_mm": x.depth_rms_mm, "depth_rms_goal_mm": x.depth_rms_goal_mm,
            "xy_per_axis_rms_mm": x.xy_per_axis_rms_mm,
            "xy_per_axis_rms_goal_mm": x.xy_per_axis_rms_goal_mm,
            "boundary_mean_mm": x.boundary_mean_mm, "boundary_mean_goal_mm": x.boundary_mean_goal_mm,
            "met": x.met}


@decoder(Goals)
def _(d: dict) -> Goals:
    def mm(key):
        v = d.get(key)
        return math.nan if v is None else float(v)
    return Goals(mm("depth_rms_mm"), mm("xy_per_axis_rms_mm"), mm("boundary_mean_mm"),
                 d.get("depth_rms_goal_mm", GOAL_DEPTH_RMS_MM), d.get("xy_per_axis_rms_goal_mm", GOAL_XY_RMS_MM),
                 d.get("boundary_mean_goal_mm", GOAL_BOUNDARY_MEAN_MM))


@encode.register(Score)
def _(x: Score) -> dict:
    """score.json's ``score`` layout (units in every key)."""
    out: dict = {"points": encode(x.points) if x.points else {"count": 0},
                 "matching": encode(x.matching)}
    if x.coverage is not None:
        out["coverage"] = encode(x.coverage)
    for name in ("boundary_3d", "boundary_image", "surface"):
        part = getattr(x, name)
        if part is not None:
            out[name] = encode(part)
    out["false_boundary"] = encode(x.false_boundary)
    if x.paper_bound is not None:
        out["paper_bound"] = encode(x.paper_bound)
    if x.goals is not None:
        out["goals"] = encode(x.goals)
    if x.cut_count:
        out["cut_points"] = {"count": x.cut_count, **(encode(x.cut_points) if x.cut_points else {})}
    if x.per_point is not None:
        out["per_point"] = encode(x.per_point)
    return out


@decoder(Score)
def _(d: dict) -> Score:
    """score.json's layout read back as a ``Score``: the parts it holds (a part it lacks is None), values
    in metres again; each point's error vector is not in the file (empty arrays)."""
    def part(name, reader):
        body = d.get(name)
        return reader(body) if isinstance(body, dict) else None
    points = part("points", lambda b: decode(PointErrors, b) if b.get("count") else None)
    cut = d.get("cut_points") if isinstance(d.get("cut_points"), dict) else {}
    return Score(points, decode(Matching, d.get("matching") or {}),
                 part("boundary_3d", lambda b: decode(BoundaryScore, b)),
                 part("boundary_image", lambda b: decode(BoundaryScore, b, "px")),
                 part("surface", lambda b: decode(SurfaceScore, b)),
                 decode(FalseBoundaryVerdict, d.get("false_boundary") or {}),
                 part("paper_bound", lambda b: decode(PaperBound, b)), part("goals", lambda b: decode(Goals, b)),
                 decode(PointErrors, cut) if "depth_rms_mm" in cut else None, int(cut.get("count") or 0),
                 part("coverage", lambda b: decode(PixelCoverage, b)),
                 part("per_point", lambda b: decode(PerPointErrors, b)))
