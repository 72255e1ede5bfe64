"""Statistics of a results table (pandas group-bys): per method, per bend, per level of a swept axis.

Input: the typed frame of ``inputs.load_results`` (flags True/False/None, numbers floats with
NaN missing). A row counts as *ok* when its status is "ok" (or absent). Failures are counted
in three separate kinds, none hiding another:

* ``crashed``: status "failed" (the method raised);
* ``bound_violated``: ``paper_bound_met`` is False (the paper's bound, V-D: every expected
  point found, depth error within 2 mm, x/y within 1 mm), over the rows that have a verdict;
* ``mismatched``: ``correct_match_count < matched_count`` (a point matched to the wrong
  square), over the rows that report both counts.

Units: as the column names say (mm, s, fractions 0..1); bends in degrees.
"""
from __future__ import annotations

import math

import numpy as np
import pandas as pd

from platebench.bench.config.axes import PARAMETERS, axis_column
from platebench.bench.io.codecs import encode
from platebench.bench.io.sweep_records import BEND_COLUMN, TRUTH_COLUMN
from platebench.bench.report.inputs import FLAG_COLUMNS, NUMBER_COLUMNS, TEXT_COLUMNS
from platebench.bench.report.values import flag
from platebench.evaluation.detection import detection_score
from platebench.evaluation.metrics_row import METRIC_FIELDS
from platebench.plates.spec import FAMILIES

__all__ = ["ok_mask", "metric_columns", "extra_metric_columns", "method_order", "method_summary",
           "failure_flags", "failure_table", "by_bend", "axis_levels", "axis_stats", "swept_axes",
           "precision_recall", "FAILURE_KINDS", "CATEGORY_ORDER", "REPLICATE_AXES"]

# (column of failure_flags, denominator column, label)
# The depth errors a sweep's methods report, one meaning each: at the paper's square centres (sparse) and
# over the plate's pixels (dense maps). Tables and plots compare methods within one of them, never across.
DEPTH_METRICS = ("centres_depth_rms_mm", "depth_rms_mm")
FAILURE_KINDS = (("crashed", "rows", "crashed (status failed)"),
                 ("bound_violated", "bound_known", "paper's bound violated"),
                 ("mismatched", "match_known", "points mismatched"))
# natural order of categorical axes (anything else: alphabetical, after these)
CATEGORY_ORDER = {
    "noise": ("none", "low", "medium", "high", "custom"),
    "direction": ("up", "down"),
    "material": ("diffuse", "roughconductor"),
    "family": tuple(FAMILIES),  # plates.spec: the families in their own order
}
REPLICATE_AXES = ("seed",)  # varied to repeat a measurement: pooled, never plotted against
_KNOWN = set(TEXT_COLUMNS) | set(NUMBER_COLUMNS) | set(FLAG_COLUMNS)


def ok_mask(frame: pd.DataFrame) -> pd.Series:
    """Rows whose status is "ok" (or that carry no status)."""
    if "status" not in frame.columns:
        return pd.Series(True, index=frame.index)
    return frame["status"].isna() | frame["status"].eq("ok")


def _has_values(frame: pd.DataFrame, c: str) -> bool:
    return c in frame.columns and bool(frame[c].notna().any())


def extra_metric_columns(frame: pd.DataFrame) -> list[str]:
    """Method-specific metric columns (Middlebury/ETH3D figures, a plug-in's own): the numeric or flag
    columns that the results table places right after the shared metric columns (before the
    timings), that no registry names, and where some row has a value."""
    cols = list(frame.columns)
    shared = [i for i, c in enumerate(cols) if c in METRIC_FIELDS]
    if not shared:
        return []
    start = max(shared) + 1
    end = next((i for i in range(start, len(cols)) if cols[i] in _KNOWN), len(cols))
    return [c for c in cols[start:end] if _has_values(frame, c)
            and (pd.api.types.is_numeric_dtype(frame[c]) or is_flag_column(frame[c]))]


def metric_columns(frame: pd.DataFrame) -> list[str]:
    """The shared metric columns (``METRIC_FIELDS`` order) with a value, then the extra ones."""
    return [c for c in METRIC_FIELDS if _has_values(frame, c)] + extra_metric_columns(frame)


def is_flag_column(col: pd.Series) -> bool:
    known = col.dropna()
    return bool(len(known)) and bool(known.map(lambda v: flag(v) is not None).all())


def method_order(methods) -> list[str]:
    """The paper's pipeline first, then the others alphabetically."""
    return sorted({str(m) for m in methods}, key=lambda m: (m != "paper", m))


def method_summary(frame: pd.DataFrame) -> dict:
    """{method: {"rows", "ok", "failed", "metrics": {metric: {"mean", "median", "n", "kind"[, "true"]}}}}
    over each method's ok rows; a flag metric gives how many rows say yes ("true") of ``n``
    (kind "rate", "mean" the fraction). A metric no ok row of a method has is left out."""
    ok = ok_mask(frame)
    counts = ok.groupby(frame["method"]).agg(rows="size", ok="sum")
    good = frame[ok]
    metrics = metric_columns(frame)
    flags = [m for m in metrics if is_flag_column(frame[m])]
    nums = [m for m in metrics if m not in flags]
    stats = good.groupby("method")[nums].agg(["mean", "median", "count"]) if nums else None
    trues = good[flags].eq(True).groupby(good["method"]).sum() if flags else None
    known = good[flags].notna().groupby(good["method"]).sum() if flags else None
    out = {}
    for m in method_order(counts.index):
        e = {"rows": int(counts.loc[m, "rows"]), "ok": int(counts.loc[m, "ok"]), "metrics": {}}
        e["failed"] = e["rows"] - e["ok"]
        for k in metrics:
            if k in flags:
                n = int(known.loc[m, k]) if m in known.index else 0
                if n:
                    t = int(trues.loc[m, k])
                    e["metrics"][k] = {"mean": t / n, "median": None, "n": n, "kind": "rate", "true": t}
            elif stats is not None and m in stats.index and stats.loc[m, (k, "count")] > 0:
                e["metrics"][k] = {"mean": float(stats.loc[m, (k, "mean")]),
                                   "median": float(stats.loc[m, (k, "median")]),
                                   "n": int(stats.loc[m, (k, "count")]), "kind": "value"}
        out[m] = e
    return out


def failure_flags(frame: pd.DataFrame) -> pd.DataFrame:
    """Per row: crashed, bound_known, bound_violated, match_known, mismatched (booleans; see module doc)."""
    def col(name):
        return frame[name] if name in frame.columns else pd.Series(None, index=frame.index, dtype=object)
    bound = col("paper_bound_met").map(flag)
    matched, correct = pd.to_numeric(col("matched_count")), pd.to_numeric(col("correct_match_count"))
    match_known = matched.notna() & correct.notna()
    return pd.DataFrame({"crashed": ~ok_mask(frame),
                         "bound_known": bound.notna(), "bound_violated": bound.eq(False),
                         "match_known": match_known, "mismatched": match_known & (correct < matched)},
                        index=frame.index)


def failure_table(frame: pd.DataFrame, keys) -> pd.DataFrame:
    """Counts per group of ``keys`` (column names or aligned Series): rows, and the sums of
    ``failure_flags``' columns."""
    keys = [frame[k] if isinstance(k, str) else k for k in (keys if isinstance(keys, list) else [keys])]
    f = failure_flags(frame)
    f["rows"] = 1
    return f.groupby(keys if len(keys) > 1 else keys[0], sort=False).sum().astype(int)


def by_bend(frame: pd.DataFrame, metrics=(*DEPTH_METRICS, "boundary_mean_mm")) -> pd.DataFrame:
    """Per bend angle (deg, rounded to 1e-6) and method: the median of each metric over the ok rows,
    and the failure counts. Indexed by (bend_deg, method), bends ascending."""
    bend = frame[BEND_COLUMN].round(6).rename(BEND_COLUMN)
    ok = ok_mask(frame)
    metrics = [m for m in metrics if _has_values(frame, m)]
    med = frame[metrics].where(ok).groupby([bend, frame["method"]]).median()
    fails = failure_table(frame, [bend, frame["method"]])
    return med.join(fails).sort_index()


# ----------------------------------------------------------------------------- swept axes
def _axis_values(col: pd.Series) -> tuple[pd.Series, bool]:
    """A column as axis values: (floats or labels, NaN/None where unknown; numeric?)."""
    if pd.api.types.is_bool_dtype(col) or is_flag_column(col):
        return col.map(lambda v: None if flag(v) is None else str(bool(v)).lower()), False
    if pd.api.types.is_numeric_dtype(col):
        x = col.astype(float)
        return x.where(np.isfinite(x)), True
    known = col.map(lambda v: not _missing(v))
    num = pd.to_numeric(col.where(known), errors="coerce")
    if known.any() and num[known].notna().all():
        return num.where(np.isfinite(num)), True
    labels = [None if not k else (f"{v:g}" if isinstance(v, float) else str(v)) for v, k in zip(col, known)]
    return pd.Series(labels, index=col.index, dtype=object), False


def _missing(v) -> bool:
    return v is None or v is pd.NA or (isinstance(v, float) and math.isnan(v)) or (isinstance(v, str)
                                                                                    and not v.strip())


def axis_levels(frame: pd.DataFrame, axis: str, max_levels: int = 10) -> tuple[list[dict], pd.Series, bool]:
    """The ordered levels of ``axis``: ([{"key", "label", "x"}], each row's level key (None where the
    row has no value), numeric).

    Numeric axes: one level per distinct value (x = the value), or, with more than ``max_levels``
    distinct values (random draws), equal-width bins (x = bin centre, label "lo–hi"; empty bins
    left out). Categorical axes: one level per value in its natural order (``CATEGORY_ORDER``:
    noise none < low < medium < high), x = 0, 1, ..."""
    empty = pd.Series(None, index=frame.index, dtype=object)
    if axis not in frame.columns:
        return [], empty, False
    vals, numeric = _axis_values(frame[axis])
    known = vals.dropna()
    if known.empty:
        return [], empty, False
    if numeric:
        rounded = vals.round(9)
        uniq = np.unique(rounded.dropna().to_numpy())
        if len(uniq) <= max_levels:
            return ([{"key": float(u), "label": f"{u:g}", "x": float(u)} for u in uniq],
                    rounded.astype(object).where(rounded.notna(), None), True)
        edges = np.linspace(uniq[0], uniq[-1], max_levels + 1)
        idx = np.clip(np.searchsorted(edges, vals.fillna(uniq[0]).to_numpy(), side="right") - 1, 0, max_levels - 1)
        keys = pd.Series(idx, index=frame.index, dtype=object).where(vals.notna(), None)
        used = sorted(set(keys.dropna()))
        return ([{"key": int(i), "label": f"{edges[i]:.3g}\u2013{edges[i + 1]:.3g}",
                  "x": float(0.5 * (edges[i] + edges[i + 1]))} for i in used], keys, True)
    order = CATEGORY_ORDER.get(axis, ())
    names = sorted(set(known), key=lambda s: (order.index(s) if s in order else len(order), s))
    return [{"key": n, "label": n, "x": float(i)} for i, n in enumerate(names)], vals, False


def axis_stats(frame: pd.DataFrame, axis: str, metric: str = DEPTH_METRICS[0], max_levels: int = 10) -> dict:
    """Per method and level of ``axis``: rows, the three failure counts with their denominators
    (``failure_flags``), and the median and values of ``metric`` over the ok rows with a value
    (a paper row that violates the bound still gives its value here).

    Returns {"axis", "metric", "levels", "numeric", "methods", "cells": {(method, key): {...}},
    "no_value": rows without a value on the axis}."""
    levels, keys, numeric = axis_levels(frame, axis, max_levels)
    has = keys.notna()
    sub, k = frame[has], keys[has].rename("_level")
    groups = [sub["method"].astype(str), k]
    fails = failure_table(sub, groups)
    value = sub[metric].where(ok_mask(sub)) if metric in sub.columns else pd.Series(np.nan, index=sub.index)
    vals = value.groupby(groups, sort=False).agg(lambda s: [float(v) for v in s.dropna()])
    cells = {}
    for (m, key), c in fails.iterrows():
        v = vals.loc[(m, key)] if (m, key) in vals.index else []
        cells[(m, key)] = {**{n: int(x) for n, x in c.items()}, "values": v,
                           "median": float(np.median(v)) if v else None}
    return {"axis": axis, "metric": metric, "levels": levels, "numeric": numeric,
            "methods": method_order(m for m, _ in cells), "cells": cells, "no_value": int((~has).sum())}


def _same_partition(frame: pd.DataFrame, a: str, b: str) -> bool:
    """Whether columns a and b split the rows the same way (one determines the other)."""
    pair = frame[[a, b]].astype(str)
    return bool(pair.groupby(a)[b].nunique().max() == 1 and pair.groupby(b)[a].nunique().max() == 1)


def _varies(frame: pd.DataFrame, col: str) -> bool:
    return col in frame.columns and len(axis_levels(frame, col)[0]) > 1


def swept_axes(manifest: dict, frame: pd.DataFrame) -> tuple[list[str], dict]:
    """The results columns a sweep varies: the columns carrying its spec's axes (``axis_column``:
    ``resolution`` is width_px, ``scene.material.alpha`` roughness), then any other parameter
    column that varies and does not merely follow one already chosen (height_px with width_px,
    a noise preset's read noise with the preset). Returns (columns to plot against, in that
    order; {column: level labels} of every varying column, replicate axes such as seed included)."""
    chosen: list[str] = []
    for name in ((manifest or {}).get("spec") or {}).get("axes") or {}:
        col = axis_column(str(name)) or (str(name) if str(name) in frame.columns else None)
        if col and col not in chosen and _varies(frame, col):
            chosen.append(col)
    for p in PARAMETERS:
        if p.name not in chosen and _varies(frame, p.name) \
                and not any(_same_partition(frame, c, p.name) for c in chosen):
            chosen.append(p.name)
    varying = {c: [lv["label"] for lv in axis_levels(frame, c)[0]] for c in chosen}
    return [c for c in chosen if c not in REPLICATE_AXES], varying


def precision_recall(rows, verdict: str, truth: str = TRUTH_COLUMN) -> dict:
    """TP/FP/FN/TN, precision and recall of the flag ``verdict`` against ``truth`` over the rows
    (dicts or a frame) where both are flags; precision/recall None where undefined
    (``evaluation.detection.detection_score``)."""
    frame = rows if isinstance(rows, pd.DataFrame) else pd.DataFrame(list(rows or []))
    if verdict not in frame.columns or truth not in frame.columns:
        return encode(detection_score([], []))
    return encode(detection_score(frame[truth].map(flag).tolist(), frame[verdict].map(flag).tolist()))
