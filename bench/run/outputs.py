"""A method's output scored, written and recorded: the bench's side of the method contract
(``reconstruction.methods``), the same for a method run in this process and for a plug-in.

``score_output`` scores an output kind against the truth with the metrics of its kind
(``evaluation.field_scores``); ``write_output`` writes it under ``bench.io.method_outputs.OUTPUT_FILES``;
``metrics_row`` is the results table's row (the method's own metrics as ``method_<name>`` columns);
``score_document`` is its ``score.json``.
"""
from __future__ import annotations

from pathlib import Path
from typing import Mapping

import numpy as np

from platebench.bench.io.method_outputs import (
    OUTPUT_FILES,
    write_depth,
    write_disparity,
    write_mesh,
    write_points,
)
from platebench.evaluation.field_scores import (
    FieldTruth,
    score_depth,
    score_disparity,
    score_mesh,
    score_point_cloud,
)
from platebench.evaluation.metrics_row import MetricsRow
from platebench.reconstruction.methods import Depth, Disparity, Points

__all__ = ["score_output", "write_output", "metrics_row", "score_document", "jsonable"]


def score_output(out, truth: FieldTruth, what: str | None = None):
    """Score an output kind against the truth (``evaluation.field_scores``)."""
    what = what or f"{out.kind} output"
    if isinstance(out, Disparity):
        return score_disparity(out.disparity, truth, what=what)
    if isinstance(out, Depth):
        return score_depth(out.depth, truth, what=what)
    if isinstance(out, Points):
        return score_point_cloud(out.points, truth, what=what)
    return score_mesh(out.mesh, truth, what=what)


def write_output(directory: Path, out) -> Path:
    """Write an output kind into ``directory`` under ``OUTPUT_FILES[kind]``; returns the path."""
    path = Path(directory) / OUTPUT_FILES[out.kind]
    {"disparity": lambda: write_disparity(path, out.disparity), "depth": lambda: write_depth(path, out.depth),
     "points": lambda: write_points(path, out.points), "mesh": lambda: write_mesh(path, out.mesh)}[out.kind]()
    return path


def metrics_row(score, out) -> MetricsRow:
    """The score's row, with the method's own figures as ``method_<name>`` columns."""
    row = score.metrics_row()
    own = {f"method_{k}": v for k, v in dict(out.metrics or {}).items()}
    if not own:
        return row
    cols = row.columns()
    base = {k: cols[k] for k in cols if k not in row.extra}
    return MetricsRow(**base, extra={**row.extra, **own})


def score_document(name: str, kind: str, score, sample_dir: Path, timings: dict | None = None,
                   own: Mapping | None = None) -> dict:
    """score.json of a scored output: method, kind, sample, units, the score (units in every key)."""
    doc = {"method": name, "kind": kind, "sample": str(Path(sample_dir)),
           "units": "mm for lengths, px for disparities, pct = percent, frac = fraction, count = number",
           "score": score.to_dict()}
    if own:
        doc["method_metrics"] = dict(own)
    if timings:
        doc["timings_s"] = timings
    return jsonable(doc)


def jsonable(o):
    """``o`` with numpy scalars as Python numbers and NaN/inf as None (strict JSON)."""
    if isinstance(o, Mapping):
        return {str(k): jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [jsonable(v) for v in o]
    if isinstance(o, (bool, np.bool_)):
        return bool(o)
    if isinstance(o, (float, np.floating)):
        return float(o) if np.isfinite(o) else None
    if isinstance(o, np.integer):
        return int(o)
    return o
