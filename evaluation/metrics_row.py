"""One results-table row of metrics: the columns every method's row shares, with their units.

``MetricsRow`` is the single definition of the metric columns of ``results.csv`` /
``results.parquet`` (``bench.sweep.dataset`` adds the sample's parameters and timings around
it). Each field's metadata gives its unit and a human label, for tables and plots. A method
fills what applies to it and leaves the rest None; method-specific figures (a dense method's
Middlebury/ETH3D metrics, ...) go in ``extra`` (name -> number or bool, units in the names)
and become further columns, labelled by the families of ``EXTRA_FAMILIES``.

One column, one meaning. Sparse figures (at the paper's square centres: a few dozen points) and
dense ones (over every plate pixel of a depth or disparity map) have different names:
``centres_depth_rms_mm`` is the RMS depth error of the matched square centres, ``depth_rms_mm``
the RMS depth error over the plate's pixels with an estimate. A table or plot that compares
methods compares one column.

``coverage_frac`` is the share of the left view's plate pixels (the truth's plate mask) that have an
estimate, 0..1, for every kind of method (``evaluation.pixel_coverage``: a map's valid pixels, a
cloud's projected points, a mesh's true rays that hit it). The share of the true plate's area within
a lateral radius of an estimate is another figure, ``surface_coverage_frac`` (an extra column).

``from_score`` flattens the paper pipeline's typed ``Score``; the other kinds' scores
(``evaluation.field_scores``) are flattened by the bench (``bench.run.outputs.score_row``).

Registered metrics. A further figure of every scored sample is one ``Metric`` given to
``register_metric``: its column name, label, unit, kind and how it is computed from a score. Every
row built from a score (``MetricsRow.from_score``, ``bench.run.outputs.score_row``) then holds
its value among the extra columns (``registered_figures``), so it appears in a sweep's results table
after the shared columns, and ``metric_label``/``metric_unit``/``is_metric`` know it.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field, fields
from typing import Any, Callable, Mapping

from platebench.errors import RegistrationError

__all__ = ["MetricsRow", "METRIC_FIELDS", "EXTRA_FAMILIES", "metric_unit", "metric_label", "is_metric",
           "Metric", "METRICS", "register_metric", "registered_figures"]


def _m(unit: str, label: str, kind: str = "float"):
    return field(default=None, metadata={"unit": unit, "label": label, "kind": kind})


@dataclass(frozen=True)
class MetricsRow:
    centres_depth_rms_mm: float | None = _m("mm", "depth RMS at the square centres")
    centres_depth_max_mm: float | None = _m("mm", "depth max at the square centres")
    depth_rms_mm: float | None = _m("mm", "depth RMS over the plate's pixels")
    depth_max_mm: float | None = _m("mm", "depth max over the plate's pixels")
    depth_median_mm: float | None = _m("mm", "depth median over the plate's pixels")
    xy_radial_rms_mm: float | None = _m("mm", "x/y radial RMS at the square centres")
    xy_per_axis_rms_mm: float | None = _m("mm", "x/y RMS per axis at the square centres")
    err3d_rms_mm: float | None = _m("mm", "3D error RMS at the square centres")
    boundary_mean_mm: float | None = _m("mm", "boundary mean")
    boundary_hausdorff_mm: float | None = _m("mm", "boundary Hausdorff")
    surface_rms_mm: float | None = _m("mm", "surface RMS (estimate to the true surface)")
    coverage_frac: float | None = _m("fraction", "coverage (share of the plate's pixels with an estimate)")
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
            kind = METRICS[k].kind if k in METRICS else "bool" if isinstance(v, bool) else "float"
            clean[k] = _clean(v, kind)
        object.__setattr__(self, "extra", clean)

    def columns(self) -> dict:
        """Column name -> value (None where unknown): the shared columns, then ``extra``."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "extra"}
        out.update(self.extra)
        return out

    @classmethod
    def from_score(cls, score, **overrides) -> "MetricsRow":
        """Flatten the paper pipeline's ``evaluation.score.Score``: ``coverage_frac`` from its pixel
        coverage (``Score.coverage``), its surface coverage as the extra ``surface_coverage_frac``."""
        p, b, s = score.points, score.boundary_3d, score.surface
        mm = 1e3
        cov = getattr(score, "coverage", None)
        extra = {**({"surface_coverage_frac": s.surface_coverage_frac} if s else {}),
                 **registered_figures(score), **dict(overrides.pop("extra", None) or {})}
        return cls(
            centres_depth_rms_mm=p.stats.depth.rms * mm if p else None,
            centres_depth_max_mm=p.stats.depth.max * mm if p else None,
            xy_radial_rms_mm=p.stats.xy_radial.rms * mm if p else None,
            xy_per_axis_rms_mm=p.xy_per_axis_rms_m * mm if p else None,
            err3d_rms_mm=p.stats.err3d.rms * mm if p else None,
            boundary_mean_mm=b.mean_sym * mm if b else None,
            boundary_hausdorff_mm=b.hausdorff * mm if b else None,
            surface_rms_mm=s.dist.rms * mm if s else None,
            coverage_frac=cov.coverage_frac if cov is not None else None,
            matched_count=score.matching.matched_count,
            correct_match_count=score.matching.correct_match_count,
            expected_count_gt=score.matching.expected_count_gt,
            false_boundary_gt=score.false_boundary.ground_truth_any,
            false_boundary_detected=score.false_boundary.detected,
            paper_bound_met=score.paper_bound.met if score.paper_bound else None,
            extra=extra, **overrides)


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
METRIC_KINDS = ("float", "int", "bool")


@dataclass(frozen=True)
class Metric:
    """A registered metric: one column of every row scored from then on.

    ``name``: the column's name, its unit in the suffix (``_mm``, ``_px``, ``_pct``, ``_frac``,
    ``_count``; a flag has none). ``label``: the figure in words, without the unit. ``unit``: as
    ``metric_unit`` gives it ("mm", "px", "%", "fraction", "count", "" for a flag). ``compute``:
    score -> value, given the method's score (``evaluation.score.Score`` for the paper's pipeline,
    ``evaluation.field_scores``' scores for depth maps, disparity maps, clouds and meshes); None where
    the metric does not apply to that score (the row then has no such column), its errors propagate.
    ``kind``: "float", "int" or "bool", the type the value is stored as."""

    name: str
    label: str
    unit: str
    compute: Callable[[Any], Any]
    kind: str = "float"


# every registered metric by name, in registration order (``register_metric``)
METRICS: dict[str, Metric] = {}


def register_metric(metric: Metric) -> Metric:
    """Add ``metric`` to ``METRICS``; returns it. TypeError when it is not a ``Metric`` with a
    callable ``compute`` and a kind of ``METRIC_KINDS``; ``RegistrationError`` (a ValueError) when its
    name is empty, a shared column, of a family of ``EXTRA_FAMILIES`` (a figure the scores already give)
    or registered already."""
    if not isinstance(metric, Metric) or not callable(metric.compute) or metric.kind not in METRIC_KINDS:
        raise TypeError(f"{metric!r} is not a Metric with a callable compute and a kind of {', '.join(METRIC_KINDS)}")
    name = metric.name
    if not isinstance(name, str) or not name or name in METRIC_FIELDS or name == "extra" \
            or _family(name) is not None or name in METRICS:
        raise RegistrationError(f"metric name {name!r} is not allowed: a new, non-empty name (not a shared column, "
                         "an extra column's family or a registered metric)")
    METRICS[name] = metric
    return metric


def registered_figures(score) -> dict[str, Any]:
    """Name -> value of every registered metric that applies to ``score`` (``Metric.compute`` not
    None), in registration order."""
    out = {}
    for m in METRICS.values():
        value = m.compute(score)
        if value is not None:
            out[m.name] = value
    return out


# The extra columns' families: (pattern of the name, label, unit). Names are built by
# ``evaluation.field_scores`` (``AbsErrors.to_dict``, ``DepthScore``, ``PointCloudScore``, ``MeshScore``),
# ``evaluation.disparity_metrics`` (``mb_*``, ``eth_*``) and the plug-ins (``method_*``: their own figures).
_REGION = {"all": "all pixels with known truth", "nonocc": "non-occluded pixels"}
_BENCH = {"mb": "Middlebury", "eth": "ETH3D"}
_STAT = {"mean": "mean", "median": "median", "rms": "RMS", "max": "max"}
_ERRS = {"depth": "depth error over the plate's pixels", "dist": "distance of the points to the true surface",
         "accuracy": "accuracy (estimate to the true surface)",
         "completeness": "completeness (true surface to estimate)"}
EXTRA_FAMILIES: tuple[tuple[str, str, str], ...] = (
    (r"(?P<e>depth|dist|accuracy|completeness)_(?P<s>mean|median|rms|max)_mm", "{E}, {S}", "mm"),
    (r"(?P<e>depth|dist|accuracy|completeness)_a(?P<q>\d+)_mm", "{E}, A{q} ({q} % of values below)", "mm"),
    (r"(?P<e>depth|dist|accuracy|completeness)_count", "{E}: values", "count"),
    (r"centres_depth_median_mm", "depth median at the square centres", "mm"),
    (r"depth_mean_signed_mm", "depth bias over the plate's pixels (mean signed error, + = too far)", "mm"),
    (r"depth_bad_(?P<t>\d+_\d+)_mm_pct", "estimated plate pixels with depth error > {t} mm", "%"),
    (r"plate_px", "plate pixels (left view)", "count"),
    (r"estimated_px", "plate pixels with an estimate", "count"),
    (r"off_plate_px", "estimates off the plate", "count"),
    (r"nonocc_px", "non-occluded plate pixels", "count"),
    (r"doffs_px", "disparity offset doffs", "px"),
    (r"(?P<b>mb|eth)_(?P<r>all|nonocc)_bad_(?P<t>\d+_\d+)_pct", "{B} bad {t} px, {R}", "%"),
    (r"mb_(?P<r>all|nonocc)_invalid_pct", "Middlebury invalid, {R}", "%"),
    (r"(?P<b>mb|eth)_(?P<r>all|nonocc)_avgerr_px", "{B} average error, {R}", "px"),
    (r"(?P<b>mb|eth)_(?P<r>all|nonocc)_rms_px", "{B} RMS error, {R}", "px"),
    (r"(?P<b>mb|eth)_(?P<r>all|nonocc)_a(?P<q>\d+)_px", "{B} A{q} error, {R}", "px"),
    (r"(?P<b>mb|eth)_(?P<r>all|nonocc)_gt_count", "{B} pixels scored, {R}", "count"),
    (r"mb_(?P<r>all|nonocc)_valid_count", "Middlebury valid estimates, {R}", "count"),
    (r"eth_(?P<r>all|nonocc)_est_count", "ETH3D estimated pixels, {R}", "count"),
    (r"eth_(?P<r>all|nonocc)_coverage_frac", "ETH3D coverage, {R}", "fraction"),
    (r"points_count", "points scored", "count"),
    (r"points_dropped_count", "points dropped (not finite)", "count"),
    (r"outlier_threshold_mm", "outlier threshold", "mm"),
    (r"outlier_count", "outliers (points beyond the threshold)", "count"),
    (r"outlier_frac", "outliers (share of the points)", "fraction"),
    (r"coverage_radius_mm", "coverage radius", "mm"),
    (r"surface_coverage_frac", "surface coverage (share of the true plate's area within the coverage radius of "
                               "the estimate)", "fraction"),
    (r"covered_area_mm2", "plate area covered", "mm^2"),
    (r"plate_area_mm2", "plate area", "mm^2"),
    (r"sample_spacing_mm", "surface sample spacing", "mm"),
    (r"faces_count", "mesh faces", "count"),
    (r"overall_mm", "DTU overall (mean of accuracy and completeness means)", "mm"),
    (r"(?P<k>precision|recall|fscore)_(?P<t>\d+_\d+)_mm_pct", "{K} at {t} mm", "%"),
    (r"method_(?P<n>.+)", "the method's own figure {n!r}", ""),
)
_FAMILIES = tuple((re.compile(p), label, unit) for p, label, unit in EXTRA_FAMILIES)


def _family(name: str):
    """(label, unit) of an extra column from ``EXTRA_FAMILIES``; None when no family matches."""
    for rx, label, unit in _FAMILIES:
        m = rx.fullmatch(name)
        if m:
            g = m.groupdict()
            words = dict(g)
            if "t" in g:
                words["t"] = g["t"].replace("_", ".")
            words.update(E=_ERRS.get(g.get("e", ""), ""), S=_STAT.get(g.get("s", ""), ""),
                         B=_BENCH.get(g.get("b", ""), ""), R=_REGION.get(g.get("r", ""), ""),
                         K={"precision": "precision", "recall": "recall", "fscore": "F-score"}.get(g.get("k", ""), ""))
            return label.format(**words), unit
    return None


def is_metric(name: str) -> bool:
    """Whether ``name`` is a metric column: a shared field, a registered metric or one of ``EXTRA_FAMILIES``."""
    return name in METRIC_FIELDS or name in METRICS or _family(name) is not None


def metric_unit(name: str) -> str:
    """Unit of a metric column ('' for flags, counts say 'count'): from its field, its family, or its name."""
    if name in METRIC_FIELDS:
        return METRIC_FIELDS[name].metadata["unit"]
    if name in METRICS:
        return METRICS[name].unit
    fam = _family(name)
    if fam is not None:
        return fam[1]
    for suffix, unit in (("_mm", "mm"), ("_px", "px"), ("_pct", "%"), ("_frac", "fraction"), ("_count", "count")):
        if name.endswith(suffix):
            return unit
    return ""


def metric_label(name: str) -> str:
    """Human label with unit, e.g. 'depth RMS over the plate's pixels (mm)': from the field's metadata,
    else from the registered metric (``METRICS``), else from the column's family (``EXTRA_FAMILIES``),
    else the name as it is."""
    if name in METRIC_FIELDS:
        label, unit = METRIC_FIELDS[name].metadata["label"], METRIC_FIELDS[name].metadata["unit"]
    elif name in METRICS:
        label, unit = METRICS[name].label, METRICS[name].unit
    elif (fam := _family(name)) is not None:
        label, unit = fam
    else:  # a column of no known family: its own name, verbatim
        label, unit = name, ""
    return f"{label} ({unit})" if unit and unit not in ("count",) else label
