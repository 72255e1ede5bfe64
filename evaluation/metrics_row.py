"""One results-table row of metrics: the columns every method's row shares, with their units.

``MetricsRow`` is the single definition of the metric columns of ``results.csv`` /
``results.parquet`` (``bench.sweep.dataset`` adds the sample's parameters and timings around
it). Each field's metadata gives its unit and a human label, for tables and plots. A method
fills what applies to it and leaves the rest None; method-specific figures (a dense method's
Middlebury/ETH3D metrics, ...) go in ``extra`` (name -> number or bool, units in the names)
and become further columns.

``from_score`` flattens the paper pipeline's typed ``Score``; the other kinds' scores
(``evaluation.field_scores``) build theirs with ``metrics_row()``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, Mapping

__all__ = ["MetricsRow", "METRIC_FIELDS", "metric_unit", "metric_label"]


def _m(unit: str, label: str, kind: str = "float"):
    return field(default=None, metadata={"unit": unit, "label": label, "kind": kind})


@dataclass(frozen=True)
class MetricsRow:
    depth_rms_mm: float | None = _m("mm", "depth RMS")
    depth_max_mm: float | None = _m("mm", "depth max")
    depth_median_mm: float | None = _m("mm", "depth median")
    xy_radial_rms_mm: float | None = _m("mm", "x/y radial RMS")
    xy_per_axis_rms_mm: float | None = _m("mm", "x/y RMS per axis")
    err3d_rms_mm: float | None = _m("mm", "3D error RMS")
    boundary_mean_mm: float | None = _m("mm", "boundary mean")
    boundary_hausdorff_mm: float | None = _m("mm", "boundary Hausdorff")
    surface_rms_mm: float | None = _m("mm", "surface RMS")
    coverage_frac: float | None = _m("fraction", "coverage of the plate")
    matched_count: int | None = _m("count", "points matched", "int")
    correct_match_count: int | None = _m("count", "points matched correctly", "int")
    expected_count_gt: int | None = _m("count", "points expected (truth)", "int")
    false_boundary_gt: bool | None = _m("", "false boundary (truth)", "bool")
    false_boundary_detected: bool | None = _m("", "false boundary detected", "bool")
    paper_bound_met: bool | None = _m("", "paper's bound met", "bool")
    extra: Mapping[str, Any] = field(default_factory=dict, metadata={"unit": "", "label": "", "kind": "extra"})

    def __post_init__(self):
        for f in fields(self):
            if f.name == "extra":
                continue
            object.__setattr__(self, f.name, _clean(getattr(self, f.name), f.metadata["kind"]))
        clean = {}
        for k, v in dict(self.extra).items():
            if k in METRIC_NAMES or not isinstance(k, str) or not k:
                raise ValueError(f"extra metric name {k!r} is not allowed: a new, non-empty name (not one of "
                                 f"the shared columns)")
            clean[k] = _clean(v, "bool" if isinstance(v, bool) else "float")
        object.__setattr__(self, "extra", clean)

    def columns(self) -> dict:
        """Column name -> value (None where unknown): the shared columns, then ``extra``."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "extra"}
        out.update(self.extra)
        return out

    @classmethod
    def from_score(cls, score, **overrides) -> "MetricsRow":
        """Flatten the paper pipeline's ``evaluation.score.Score``."""
        p, b, s = score.points, score.boundary_3d, score.surface
        mm = 1e3
        return cls(
            depth_rms_mm=p.stats.depth.rms * mm if p else None,
            depth_max_mm=p.stats.depth.max * mm if p else None,
            xy_radial_rms_mm=p.stats.xy_radial.rms * mm if p else None,
            xy_per_axis_rms_mm=p.xy_per_axis_rms_m * mm if p else None,
            err3d_rms_mm=p.stats.err3d.rms * mm if p else None,
            boundary_mean_mm=b.mean_sym * mm if b else None,
            boundary_hausdorff_mm=b.hausdorff * mm if b else None,
            surface_rms_mm=s.dist.rms * mm if s else None,
            coverage_frac=s.coverage_frac if s else None,
            matched_count=score.matching.matched_count,
            correct_match_count=score.matching.correct_match_count,
            expected_count_gt=score.matching.expected_count_gt,
            false_boundary_gt=score.false_boundary.ground_truth_any,
            false_boundary_detected=score.false_boundary.detected,
            paper_bound_met=score.paper_bound.met if score.paper_bound else None,
            **overrides)


def _clean(v, kind: str):
    """None for missing/NaN/inf; else the value as its column's type."""
    if v is None:
        return None
    if kind == "bool":
        return bool(v)
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    if not math.isfinite(x):
        return None
    return int(round(x)) if kind == "int" else x


METRIC_FIELDS = {f.name: f for f in fields(MetricsRow) if f.name != "extra"}
METRIC_NAMES = tuple(METRIC_FIELDS)


def metric_unit(name: str) -> str:
    """Unit of a metric column ('' for flags, counts say 'count'); from the name for extra columns."""
    if name in METRIC_FIELDS:
        return METRIC_FIELDS[name].metadata["unit"]
    for suffix, unit in (("_mm", "mm"), ("_px", "px"), ("_pct", "%"), ("_frac", "fraction"), ("_count", "count")):
        if name.endswith(suffix):
            return unit
    return ""


def metric_label(name: str) -> str:
    """Human label with unit, e.g. 'depth RMS (mm)'."""
    if name in METRIC_FIELDS:
        label, unit = METRIC_FIELDS[name].metadata["label"], METRIC_FIELDS[name].metadata["unit"]
    else:  # an extra column: its name without the unit suffix, then the unit
        unit = metric_unit(name)
        suffix = {"mm": "_mm", "px": "_px", "%": "_pct", "fraction": "_frac", "count": "_count"}.get(unit, "")
        label = (name[: -len(suffix)] if suffix and name.endswith(suffix) else name).replace("_", " ")
    return f"{label} ({unit})" if unit and unit not in ("count",) else label
