"""A method's output scored, written and recorded: the bench's side of the method contract
(``reconstruction.methods``), the same for a method run in this process and for a plug-in.

``score_output`` scores an output kind against the truth with the metrics of its kind
(``evaluation.field_scores``); ``write_output`` writes it under ``bench.io.method_outputs.OUTPUT_FILES``;
``score_row`` is a score's row of the results table (the shared columns, every other figure of its
JSON form in ``extra``), ``metrics_row`` that row with the method's own metrics as ``method_<name>`` columns;
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
from platebench.bench.io.codecs import encode
from platebench.evaluation.field_scores import (
    DepthScore,
    DisparityScore,
    FieldTruth,
    MeshScore,
    PointCloudScore,
    score_depth,
    score_disparity,
    score_mesh,
    score_point_cloud,
)
from platebench.evaluation.metrics_row import METRIC_NAMES, MetricsRow, registered_figures
from platebench.reconstruction.methods import Depth, Disparity, Points

__all__ = ["score_output", "write_output", "score_row", "metrics_row", "score_document", "jsonable"]

MM = 1e3  # millimetres per metre


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


def score_row(score: DepthScore | DisparityScore | PointCloudScore | MeshScore) -> MetricsRow:
    """A field score's results-table row: the shared columns (``depth_*_mm`` or ``surface_rms_mm``, and
    ``coverage_frac``), every other number of its JSON form (``encode``; a disparity's ``middlebury``
    and ``eth3d`` sections flattened) in ``extra``, and the registered metrics' figures
    (``evaluation.metrics_row.registered_figures``)."""
    flat = {k: v for k, v in encode(score).items() if not isinstance(v, dict)}
    if isinstance(score, DisparityScore):
        flat.update(encode(score.middlebury))
        flat.update(encode(score.eth3d))
        depth = score.depth
    else:
        depth = score if isinstance(score, DepthScore) else None
    if depth is not None:
        e = depth.errors
        shared = {"depth_rms_mm": e.rms_m * MM, "depth_max_mm": e.max_m * MM, "depth_median_mm": e.median_m * MM,
                  "coverage_frac": depth.coverage_frac}
    elif isinstance(score, PointCloudScore):
        shared = {"surface_rms_mm": score.distance.rms_m * MM, "coverage_frac": score.coverage.coverage_frac}
    else:
        shared = {"surface_rms_mm": score.accuracy.rms_m * MM, "coverage_frac": score.coverage_frac}
    extra = {k: v for k, v in flat.items() if k not in METRIC_NAMES and k not in shared
             and isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)}
    extra.update(registered_figures(score))
    return MetricsRow(**shared, extra=extra)


def write_error_map(directory: Path, kind: str, truth: FieldTruth) -> Path:
    """Score the output file of ``kind`` in ``directory`` (``OUTPUT_FILES[kind]``, read back as written)
    as an error map against ``truth`` (``evaluation.error_maps.output_error_map``) and write it there as
    ``bench.io.error_map_files.ERROR_MAP_FILE``; returns its path. The readers' ``DatasetError`` and
    ``ValueError`` for a map of another shape than the truth's."""
    from platebench.bench.io.error_map_files import ERROR_MAP_FILE, StoredErrorMap  # noqa: PLC0415
    from platebench.bench.io.error_map_files import write_error_map as write_file  # noqa: PLC0415
    from platebench.bench.io.method_outputs import read_depth, read_disparity, read_mesh, read_points  # noqa: PLC0415
    from platebench.evaluation.error_maps import output_error_map  # noqa: PLC0415

    path = Path(directory) / OUTPUT_FILES[kind]
    values = {"disparity": read_disparity, "depth": read_depth, "points": read_points, "mesh": read_mesh}[kind](path)
    return write_file(Path(directory) / ERROR_MAP_FILE, StoredErrorMap.of(kind, output_error_map(kind, values, truth)))


def metrics_row(score, out) -> MetricsRow:
    """The score's row, with the method's own figures as ``method_<name>`` columns."""
    row = score_row(score)
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
           "score": encode(score)}
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
