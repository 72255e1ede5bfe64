"""The typed records that carry figures from the sensing loop, the study and ``compare`` to the
command line and the report, and their file form.

Each record is a frozen dataclass whose field names are its JSON keys and CSV columns, units in
the names (``_mm`` millimetres, ``_frac`` a fraction 0..1, ``_pct`` percent, ``_s`` seconds,
``_m`` metres, ``_deg`` degrees; counts bare). ``to_dict`` writes a record, ``from_dict`` reads
one back; both are called only where a file is written or read. Inside the package the figures
travel as these records and are read as attributes: a misspelt attribute is an error, where a
misspelt key of a dict is a silent None.

Figures the run did not produce are None (never NaN in a file).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any, Mapping

__all__ = ["Stage3Accuracy", "MergedFigures", "record_from_dict", "final_figures"]


def _value(v):
    """None for a missing, NaN or infinite number; else the value."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def record_from_dict(cls, d: Mapping[str, Any] | None, renamed: Mapping[str, str] | None = None):
    """A ``cls`` record from its dict form: every field from the key of its name (missing keys: the
    field's default); ``renamed``: old key -> field name, for files written before a figure was
    renamed. Unknown keys are ignored (a newer writer's figures)."""
    d = dict(d or {})
    for old, new in (renamed or {}).items():
        if old in d and new not in d:
            d[new] = d.pop(old)
    names = {f.name for f in fields(cls) if f.init}
    return cls(**{k: _value(v) for k, v in d.items() if k in names})


def _dict(record) -> dict:
    return {f.name: _value(getattr(record, f.name)) for f in fields(record)}


@dataclass(frozen=True)
class Stage3Accuracy:
    """The stage-3 reconstruction (the paper's method) scored against ground truth: depth RMS at its
    square centres, the centres scored, boundary mean distance, surface RMS and coverage, the
    paper's bound and the bench's goals (``evaluation.score``)."""

    centres_depth_rms_mm: float | None = None
    points_scored: int = 0
    boundary_mean_mm: float | None = None
    surface_rms_mm: float | None = None
    coverage_frac: float | None = None
    paper_bound_met: bool | None = None
    goals_met: bool | None = None

    def to_dict(self) -> dict:
        return _dict(self)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "Stage3Accuracy":
        return record_from_dict(cls, d, {"surface_coverage": "coverage_frac"})


@dataclass(frozen=True)
class MergedFigures:
    """The merged multi-view reconstruction (``active_views.MergedReconstruction``) scored against
    ground truth (``bench.run.sensing.scoring.merged_accuracy``): its boundary (points, mean
    symmetric and one-way distance to the true boundary, the share of the true boundary's length
    within 2 mm), its square centres (count, RMS and maximum distance to the true surface) and its
    surface (samples, RMS distance to the true surface, coverage of the true surface within 2 mm).
    None where the merged result has no such part."""

    poses: int = 0
    boundary_points: int = 0
    points: int = 0
    boundary_mean_mm: float | None = None
    boundary_est_to_gt_mean_mm: float | None = None
    boundary_covered_frac: float | None = None
    points_rms_mm: float | None = None
    points_max_mm: float | None = None
    surface_rms_mm: float | None = None
    coverage_frac: float | None = None
    surface_points: int = 0

    def to_dict(self) -> dict:
        return _dict(self)

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "MergedFigures":
        return record_from_dict(cls, d, {"surface_coverage": "coverage_frac"})


def final_figures(final: Mapping[str, Any]) -> tuple[Stage3Accuracy | None, MergedFigures]:
    """The figures of sensing.json's ``final`` section: (stage 3's accuracy, None when stage 3
    reconstructed nothing; the merged reconstruction's figures)."""
    acc = final.get("accuracy")
    return (Stage3Accuracy.from_dict(acc) if isinstance(acc, Mapping) else None,
            MergedFigures.from_dict(final.get("merged") if isinstance(final.get("merged"), Mapping) else {}))
