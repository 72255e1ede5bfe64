"""A sweep sample's result as typed records, and their file forms: ``result.json`` (``SampleResult``)
and the rows of the results table (``table_rows``).

A worker returns a ``SampleResult`` (``bench.sweep.tasks``); the sweep process commits it, writing
``to_dict`` as ``samples/<id>/result.json`` (``bench.sweep.dataset.commit_sample``), and reads a
committed one back with ``from_dict`` (``validate_result``). Times are in seconds; ``metrics`` maps a
results-table column (``evaluation.metrics_row.MetricsRow.columns``, units in the names) to its
value, as the table holds it.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, Mapping

from platebench.bench.config.axes import parameter_columns
from platebench.bench.io.layout import RESULT_FORMAT, VERSION
from platebench.evaluation.metrics_row import METRIC_FIELDS, METRIC_NAMES

__all__ = ["SampleTimings", "MethodRun", "SampleResult", "table_rows", "sample_columns", "BEND_COLUMN",
           "TRUTH_COLUMN", "VERDICT_COLUMN"]

# results-table columns the report groups, counts and plots by: the bend angle (degrees), ground
# truth's false boundary and the method's false-boundary verdict
BEND_COLUMN = "bend_deg"
TRUTH_COLUMN = "false_boundary_gt"
VERDICT_COLUMN = "false_boundary_detected"


@dataclass(frozen=True)
class SampleTimings:
    """Seconds a sample's task spent: rendering (with this worker's renderer), writing the sample,
    and the whole task. None where the task did not get that far."""

    render_s: float | None = None
    write_s: float | None = None
    total_s: float | None = None

    def to_dict(self) -> dict:
        """The times the task measured (the keys of those it did not, left out)."""
        return {k: v for k, v in (("render_s", self.render_s), ("write_s", self.write_s),
                                  ("total_s", self.total_s)) if v is not None}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> "SampleTimings":
        d = d or {}
        return cls(d.get("render_s"), d.get("write_s"), d.get("total_s"))


@dataclass(frozen=True)
class MethodRun:
    """One method's run on a sample: its status ("ok" or "failed"), its error text, its metrics
    (results-table column -> value; empty when it failed) and, for a run that finished, the seconds
    of its reconstruction, its evaluation and the renders of its own pattern sequences."""

    method: str
    status: str
    error: str | None = None
    metrics: Mapping[str, Any] = field(default_factory=dict)
    time_recon_s: float | None = None
    time_eval_s: float | None = None
    time_render_extra_s: float | None = None

    @classmethod
    def failed(cls, method: str, error: str | None) -> "MethodRun":
        return cls(method, "failed", error, {})

    def to_dict(self) -> dict:
        """The row as result.json holds it: the times only for a run that finished ("ok")."""
        out = {"method": self.method, "status": self.status, "error": self.error, "metrics": dict(self.metrics)}
        if self.status == "ok":
            out.update(time_recon_s=self.time_recon_s, time_eval_s=self.time_eval_s,
                       time_render_extra_s=self.time_render_extra_s)
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "MethodRun":
        return cls(d.get("method"), d.get("status"), d.get("error"), dict(d.get("metrics") or {}),
                   d.get("time_recon_s"), d.get("time_eval_s"), d.get("time_render_extra_s"))


@dataclass(frozen=True)
class SampleResult:
    """One sweep sample's result (``result.json``, format ``RESULT_FORMAT``): its identity and
    configuration (``config``: a ``SampleConfig``'s form; ``params``: the spec's axis values), its
    status ("ok" or "failed"), the error that failed it and in which phase ("render", "method",
    "executor"), the renderer variant, ground truth's false boundary (True when part of the true
    boundary is hidden from a camera; None when not rendered), one ``MethodRun`` per method, the
    timings, the sha256 of every file of the sample directory (``files``) and of its images, the
    worker that made it (and the one that rendered it, in a two-stage sweep) and when it finished.

    Not in the file: ``stage`` (the attempt directory the worker wrote) and ``result_sha256`` (the
    committed result.json's checksum, for the manifest)."""

    sample_id: str
    index: int | None
    config_sha256: str | None
    status: str
    error: str | None = None
    phase: str | None = None
    params: Mapping[str, Any] = field(default_factory=dict)
    config: Mapping[str, Any] = field(default_factory=dict)
    pose: Mapping[str, Any] | None = None
    methods: tuple[str, ...] = ()
    variant: str | None = None
    false_boundary_gt: bool | None = None
    rows: tuple[MethodRun, ...] = ()
    timings: SampleTimings = field(default_factory=SampleTimings)
    files: Mapping[str, str] = field(default_factory=dict)
    images: Mapping[str, Any] = field(default_factory=dict)
    worker: Mapping[str, Any] | None = None
    finished_utc: str | None = None
    render_worker: Mapping[str, Any] | None = None
    stage: str | None = field(default=None, compare=False)
    result_sha256: str | None = field(default=None, compare=False)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def to_dict(self) -> dict:
        """result.json's layout (``stage`` and ``result_sha256`` left out; ``render_worker`` only
        when a render worker made the sample)."""
        out = {"format": RESULT_FORMAT, "version": VERSION, "sample_id": self.sample_id, "index": self.index,
               "config_sha256": self.config_sha256, "status": self.status, "error": self.error,
               "phase": self.phase, "params": self.params, "config": self.config, "pose": self.pose,
               "methods": list(self.methods), "variant": self.variant, "false_boundary_gt": self.false_boundary_gt,
               "rows": [r.to_dict() for r in self.rows], "timings_s": self.timings.to_dict(), "files": self.files,
               "images": self.images, "worker": self.worker, "finished_utc": self.finished_utc}
        if self.render_worker is not None:
            out["render_worker"] = self.render_worker
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "SampleResult":
        """A result.json's dict (``to_dict``) read back; the caller checks its format and version."""
        return cls(d.get("sample_id"), d.get("index"), d.get("config_sha256"), d.get("status"), d.get("error"),
                   d.get("phase"), d.get("params") or {}, d.get("config") or {}, d.get("pose"),
                   tuple(d.get("methods") or ()), d.get("variant"), d.get("false_boundary_gt"),
                   tuple(MethodRun.from_dict(r) for r in d.get("rows") or ()),
                   SampleTimings.from_dict(d.get("timings_s")), d.get("files") or {}, d.get("images") or {},
                   d.get("worker"), d.get("finished_utc"), d.get("render_worker"))


def sample_columns(config: Mapping[str, Any], pose: Mapping[str, Any] | None, params: Mapping[str, Any]) -> dict:
    """The parameter columns of a sample, from its full configuration (what was rendered)."""
    out = parameter_columns(config, pose)
    out["params_json"] = json.dumps(params, sort_keys=True, default=str)
    return out


def _sum(a, b):
    if a is None:
        return None
    return float(a) + float(b or 0.0)


def table_rows(res: SampleResult) -> list[dict]:
    """The results table's rows (one per method) of a sample's result: the parameter columns, the
    metrics (``METRIC_NAMES``, then a method's own), ground truth's false boundary, the times
    (``time_render_s``: the sample's render plus the method's own pattern renders; ``time_total_s``:
    the whole task), the variant and the worker."""
    base = {"sample_id": res.sample_id, "index": res.index}
    base.update(sample_columns(res.config, res.pose, res.params))
    w = res.worker or {}
    out = []
    for row in res.rows:
        r = dict(base)
        r.update({"method": row.method, "status": row.status, "error": row.error})
        metrics = row.metrics
        for k in METRIC_NAMES:
            r[k] = metrics.get(k)
        r.update({k: v for k, v in metrics.items() if k not in METRIC_FIELDS})  # a method's own metrics
        if r.get(TRUTH_COLUMN) is None:
            r[TRUTH_COLUMN] = res.false_boundary_gt
        r["time_render_s"] = _sum(res.timings.render_s, row.time_render_extra_s)
        r["time_recon_s"] = row.time_recon_s
        r["time_eval_s"] = row.time_eval_s
        r["time_total_s"] = res.timings.total_s
        r["variant"] = res.variant
        r["worker"] = f"{w.get('host')}:{w.get('pid')}" if w else None
        r["worker_maxrss_mb"] = w.get("maxrss_mb")
        out.append(r)
    return out
