"""The sweep-dataset section: overview, per-method tables, failures by kind, plots against every
swept axis, error maps, and the samples with links and thumbnails.

Each function builds one part as plain data for ``templates/dataset.html``; statistics come
from ``summary`` (pandas group-bys), plots from ``plots``. Units: errors in mm, bends in
degrees, fractions 0..1, times in s (as the column names say).
"""
from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from platebench.bench.config.axes import PARAMETERS, parameter_label
from platebench.bench.io.layout import RECON, method_folder
from platebench.bench.io.sweep_records import BEND_COLUMN, VERDICT_COLUMN
from platebench.bench.report import plots as P
from platebench.bench.report import summary as S
from platebench.bench.report.experiment import scored_errors
from platebench.bench.report.inputs import load_recon, load_results, read_manifest, records, sample_folder
from platebench.bench.report.page import Page
from platebench.bench.report.values import fmt
from platebench.evaluation.metrics_row import METRIC_FIELDS, metric_label, metric_unit

__all__ = ["dataset_section", "MAX_TABLE_ROWS", "MAX_ERROR_MAPS", "MAX_THUMB_SAMPLES", "MAX_AXIS_PLOTS"]

MAX_TABLE_ROWS = 200
MAX_ERROR_MAPS = 4  # per method
MAX_THUMB_SAMPLES = 40
MAX_AXIS_PLOTS = 8
_THUMB_IMAGES = ("left_passive", "left_active")
_PARAMETERS = {p.name: p for p in PARAMETERS}
_DESCRIBE = ("bend_deg", "direction", "family", "material", "roughness", "distance_m", "noise")


def dataset_section(page: Page, ds: Path, prefix: str) -> dict:
    """Everything the page shows of one sweep dataset (see the module doc)."""
    manifest = read_manifest(ds)
    frame, source = load_results(ds)
    spec = manifest.get("spec") or {}
    name = spec.get("name") or ds.name
    sec = {"kind": "dataset", "name": name, "rel": page.rel(ds), "source": source, **_overview(manifest, frame)}
    if frame is None or frame.empty:
        sec["empty"] = True
        sec["headline"] = _headline(name, sec, None)
        return sec
    summ = S.method_summary(frame)
    key = _key_table(frame, summ)
    sec.update(empty=False, key_table=key, metric_table=_metric_table(frame, summ),
               extra_table=_extra_table(frame, summ), failure_table=_failure_table(frame),
               headline={**_headline(name, sec, frame),
                         "table": {**key, "title": "", "caption": "Medians per method over its rows with status ok; "
                                                                 "every metric in the dataset's section."}})
    sec["plots"] = [page.plot(f"{prefix}method_comparison", P.plot_method_comparison, _bar_table(summ),
                              title=f"{name}: median over samples per method",
                              caption="Median of each error metric over the sweep's rows with status ok, per "
                                      "method (the table above gives the means too). One group of bars per "
                                      "metric, with the methods that report it: depth at the square centres (the "
                                      "paper's sparse points) and depth over the plate's pixels (dense maps) are "
                                      "separate groups, never compared. Errors in millimetres (log scale when they "
                                      "span decades); right panel: coverage as a fraction of the plate (0..1), "
                                      "where the method reports it.")]
    sec.update(_bend_part(page, frame, name, prefix))
    sec["axes"] = _axes_part(page, frame, manifest, name, prefix)
    sec["error_maps"] = _error_maps(page, ds, frame, prefix)
    sec["samples"], sec["samples_note"] = _samples(page, ds, frame, prefix, manifest)
    sec["failures"] = _failures(frame)
    return sec


# ----------------------------------------------------------------------------- overview
def _overview(manifest: dict, frame: pd.DataFrame | None) -> dict:
    """Cards (samples, ok, failed, pending, rows, methods), facts of the sweep, package versions."""
    spec = manifest.get("spec") or {}
    counts = manifest.get("counts") or {}
    if frame is not None and not frame.empty:
        per_sample = S.ok_mask(frame).groupby(frame["sample_id"]).all()
        methods = S.method_order(frame["method"].dropna())
        n_rows = len(frame)
    else:
        per_sample, methods, n_rows = pd.Series(dtype=bool), [], 0
    total = counts.get("total", len(per_sample))
    ok = counts.get("ok", int(per_sample.sum()))
    failed = counts.get("failed", int((~per_sample).sum()))
    pending = counts.get("pending", max(0, (total or 0) - (ok or 0) - (failed or 0)))
    cards = [{"label": "samples", "value": total}, {"label": "ok", "value": ok, "status": "good"},
             {"label": "failed", "value": failed, "status": "bad" if failed else ""},
             {"label": "pending", "value": pending}, {"label": "table rows", "value": n_rows},
             {"label": "methods", "value": ", ".join(methods) or "-"}]
    facts = [(k, v) for k, v in (
        ("sweep mode", spec.get("mode")),
        ("axes", ", ".join(f"{k} = {json.dumps(v)}" for k, v in (spec.get("axes") or {}).items())),
        ("executor", ", ".join(f"{k} {v}" for k, v in (manifest.get("executor") or {}).items())),
        ("Mitsuba variant", ", ".join(sorted(set(frame["variant"].dropna().astype(str))))
         if frame is not None and "variant" in frame.columns else None),
        ("state", manifest.get("state") and " ".join(
            [manifest["state"]] + ([f"({manifest['state_note']})"] if manifest.get("state_note") else []))),
        ("created", manifest.get("created_utc")),
        ("updated", manifest.get("updated_utc"))) if v]
    packages = [(k, v if v is not None else "not installed") for k, v in (manifest.get("packages") or {}).items()]
    return {"description": spec.get("description") or "", "cards": cards, "facts": facts, "packages": packages,
            "spec_text": manifest.get("spec_text") or "", "counts": {"total": total, "ok": ok, "failed": failed}}


# ----------------------------------------------------------------------------- method tables
def _count(v) -> int | None:
    """A count as an integer (a mean of counts rounded to the nearest whole one)."""
    return None if v is None or v != v else int(round(v))


def _stat_cells(s: dict | None, count: bool = False) -> list:
    """Mean, median and n of one metric of one method; a count's mean and median as whole numbers."""
    if s is None:
        return [None, None, 0]
    if s["kind"] == "rate":
        return [f"{s['true']} yes", None, s["n"]]
    if count:
        return [_count(s["mean"]), _count(s["median"]), s["n"]]
    return [s["mean"], s["median"], s["n"]]


def _row_label(metric: str) -> str:
    """A metric's label with its unit; a count says so ("... (count)")."""
    return metric_label(metric) + (" (count)" if metric_unit(metric) == "count" else "")


def _grouped(metrics: list[str], methods: list[str], summ: dict, title: str, caption: str) -> dict:
    return {"title": title, "caption": caption, "cls": "",
            "groups": [{"label": "", "span": 1}] + [{"label": m, "span": 3} for m in methods],
            "columns": ["metric"] + ["mean", "median", "n"] * len(methods),
            "rows": [[_row_label(k)] + sum((_stat_cells(summ[m]["metrics"].get(k), metric_unit(k) == "count")
                                            for m in methods), [])
                     for k in metrics]}


# the figures users compare across methods, per method, in the headline (median over the ok rows), in column
# order: before the failure rate, then after it
KEY_FIGURES = ("depth_rms_mm", "centres_depth_rms_mm", "coverage_frac")
KEY_FIGURES_AFTER = ("boundary_mean_mm",)
TIME_COLUMN = "time_recon_s"  # the method's own time per sample (s)


def _key_table(frame: pd.DataFrame, summ: dict) -> dict:
    """Per method: the median depth RMS over the plate's pixels and at the square centres (mm; two
    columns, never one), coverage (0..1), the failure rate (rows crashed of rows), the median
    boundary mean (mm) and the median time (s); a column no method fills is left out."""
    def filled(names):
        return [k for k in names if any(k in e["metrics"] for e in summ.values())]
    before, after = filled(KEY_FIGURES), filled(KEY_FIGURES_AFTER)
    ok = frame[S.ok_mask(frame)]
    times = ok.groupby("method")[TIME_COLUMN].median() if TIME_COLUMN in ok.columns else pd.Series(dtype=float)
    has_time = bool(times.notna().any())
    rows = []
    for m, e in summ.items():
        share = f" ({100 * e['failed'] / e['rows']:.0f} %)" if e["rows"] else ""
        line = [m] + [(e["metrics"].get(k) or {}).get("median") for k in before] \
            + [f"{e['failed']} / {e['rows']}{share}"] + [(e["metrics"].get(k) or {}).get("median") for k in after]
        if has_time:
            t = times.get(m)
            line.append(None if t is None or pd.isna(t) else float(t))
        rows.append(line)
    cols = ["method"] + [f"median {metric_label(k)}" for k in before] + ["failed / rows"] \
        + [f"median {metric_label(k)}" for k in after] + (["median time (s)"] if has_time else [])
    return {"title": "Key figures", "cls": "", "groups": [], "columns": cols, "rows": rows,
            "caption": "Per method, over its rows with status ok: the median of each figure users compare (depth "
                       "RMS over the plate's pixels and at the square centres are separate columns, never "
                       "compared with each other), and the rows that failed (status failed) of all its rows. "
                       "Every metric, with means and counts, is in the full table below."}


def _metric_table(frame: pd.DataFrame, summ: dict) -> dict:
    """Mean, median and n of every shared metric column per method (ok rows)."""
    shared = [k for k in S.metric_columns(frame) if k in METRIC_FIELDS]
    return _grouped(shared, list(summ), summ, "Method comparison",
                    "Mean, median and number of values of each metric over the rows with status ok (units in "
                    "the labels; for yes/no columns: how many rows say yes, out of n).")


def _extra_table(frame: pd.DataFrame, summ: dict) -> dict | None:
    """The method-specific metric columns (Middlebury/ETH3D, a plug-in's own), for the methods
    that give them."""
    extra = S.extra_metric_columns(frame)
    methods = [m for m in summ if any(k in summ[m]["metrics"] for k in extra)]
    if not extra or not methods:
        return None
    return _grouped(extra, methods, summ, "Method-specific metrics",
                    "Metrics only some methods report (their own names and units: _pct per cent, _px pixels, "
                    "_mm millimetres), over the rows with status ok.")


def _rate(k: int, n: int) -> str | None:
    return f"{k} / {n}" if n else None


def _failure_table(frame: pd.DataFrame) -> dict:
    """Per method: rows, crashes, bound violations and mismatches, each out of the rows that can say."""
    t = S.failure_table(frame, frame["method"].astype(str))
    rows = [[m, int(t.loc[m, "rows"])] + [_rate(int(t.loc[m, k]), int(t.loc[m, d])) for k, d, _ in S.FAILURE_KINDS]
            for m in S.method_order(t.index)]
    return {"title": "Failures by kind", "cls": "", "groups": [],
            "caption": "Counted separately: crashed = status failed (the method raised); paper's bound violated "
                       "= paper_bound_met is false (V-D: every expected point found, depth within 2 mm, x/y "
                       "within 1 mm), out of the rows with a verdict; points mismatched = fewer points matched "
                       "correctly than matched (correct_match_count < matched_count), out of the rows that "
                       "report both. A dash: no row of the method can say.",
            "columns": ["method", "rows"] + [label for _, _, label in S.FAILURE_KINDS], "rows": rows}


def _bar_table(summ: dict) -> dict:
    return {m: {k: v["median"] for k, v in e["metrics"].items() if v["kind"] == "value"} for m, e in summ.items()}


# ----------------------------------------------------------------------------- bend
def _bend_part(page: Page, frame: pd.DataFrame, name: str, prefix: str) -> dict:
    """Error and detection against the bend angle, when the sweep has more than one bend."""
    if BEND_COLUMN not in frame.columns or frame[BEND_COLUMN].round(6).nunique() < 2:
        return {"bend_plots": [], "bend_table": None, "detection": None}
    rows = records(frame)
    plots = [page.plot(f"{prefix}error_vs_bend", P.plot_error_vs_bend, rows, title=f"{name}: error against bend angle",
                       caption="One panel per figure, each comparing only the methods that report it: depth RMS "
                               "error at the square centres (mm; the paper's sparse points), depth RMS error over "
                               "the plate's pixels (mm; dense maps) and mean symmetric boundary distance (mm), "
                               "against the bend angle (degrees), one colour per method, solid = bend up, dashed = "
                               "bend down; dots are samples, lines join the median per bend; red crosses on the "
                               "bottom edge mark failed rows at that bend.")]
    detection = None
    det = frame[frame[VERDICT_COLUMN].notna()] if VERDICT_COLUMN in frame.columns \
        else frame.iloc[:0]
    if len(det):
        plots.append(page.plot(f"{prefix}detection_vs_bend", P.plot_detection_vs_bend, records(det),
                               flags=(VERDICT_COLUMN,),
                               title=f"{name}: false-boundary detection against ground truth",
                               caption="Precision and recall (0..1) of the pipeline's false-boundary verdict "
                                       "against ground-truth boundary visibility, per bend-angle bin (degrees, n = "
                                       "cases in the bin); grey bars: fraction of cases in the bin with a "
                                       "ground-truth false boundary. A gap means undefined (no positive verdict, "
                                       "or no ground-truth positive, in that bin)."))
        detection = S.precision_recall(det, VERDICT_COLUMN)
    return {"bend_plots": plots, "bend_table": _bend_table(frame), "detection": detection}


def _bend_table(frame: pd.DataFrame) -> dict | None:
    """Median depth RMS and boundary mean (mm) and the failures per bend and method."""
    t = S.by_bend(frame)
    bends = sorted(set(t.index.get_level_values(0)))
    if len(bends) > 40:
        return None
    methods = S.method_order(t.index.get_level_values(1))
    shown = [k for k in (*S.DEPTH_METRICS, "boundary_mean_mm") if k in t.columns]
    cols = [f"median {metric_label(k)}" for k in shown] + ["ok / rows", "bound violated", "mismatched"]
    rows = []
    for b in bends:
        line = [b]
        for m in methods:
            if (b, m) not in t.index:
                line += [None] * len(cols)
                continue
            c = t.loc[(b, m)]
            line += [c[k] for k in shown] + [f"{int(c['rows'] - c['crashed'])} / {int(c['rows'])}",
                                             _rate(int(c["bound_violated"]), int(c["bound_known"])),
                                             _rate(int(c["mismatched"]), int(c["match_known"]))]
        rows.append(line)
    return {"title": "By bend angle", "cls": "",
            "caption": "Median per bend angle (degrees) and method over the rows with status ok (errors in mm), "
                       "and the failures by kind (see the table of failures).",
            "groups": [{"label": "", "span": 1}] + [{"label": m, "span": len(cols)} for m in methods],
            "columns": ["bend (deg)"] + cols * len(methods), "rows": rows}


# ----------------------------------------------------------------------------- swept axes
def _axes_part(page: Page, frame: pd.DataFrame, manifest: dict, name: str, prefix: str) -> dict:
    """Per swept axis: a plot of each depth RMS (at the square centres, over the plate's pixels: one panel
    each, with the methods that report it) and the three failure rates per method, and a table."""
    axes, varying = S.swept_axes(manifest, frame)
    metrics = [m for m in S.DEPTH_METRICS if m in frame.columns and frame[m].notna().any()]
    out = {"items": [], "note": "", "more": axes[MAX_AXIS_PLOTS:]}
    if not axes:
        return out
    if not metrics:
        out["note"] = "no row has a depth RMS: nothing to plot against the swept axes."
        return out
    for axis in axes[:MAX_AXIS_PLOTS]:
        label = parameter_label(axis)
        others = {k: v for k, v in varying.items() if k != axis}
        pooled = ("Other swept axes vary too, and every point pools their samples: "
                  + "; ".join(f"{parameter_label(k)} ({', '.join(v)})" for k, v in others.items()) + "."
                  if others else "No other swept axis varies.")
        stats = [S.axis_stats(frame, axis, m) for m in metrics]
        what = " and ".join(f"{metric_label(m).replace(' (mm)', '')} (a panel of its own)" for m in metrics)
        fig = page.plot(f"{prefix}vs_{_safe(axis)}", P.plot_metric_vs_axis, frame, axis, metrics=tuple(metrics),
                        pooled=others or None, title=f"{name}: depth RMS and failures against {label}",
                        caption=f"Top: the median {what}, in mm, against {label}, one line per method that "
                                "reports it "
                                "(small hollow dots: the samples; log scale when they span more than a decade; a "
                                "hollow median marker: some rows at that value failed in one of the three ways; a "
                                "cross on the bottom edge: no row of the method gave a value there). The other "
                                "panels: the rate (0..1) of each kind of failure per method, k/n printed where "
                                "some failed: crashed (status failed), the paper's bound violated, points "
                                "mismatched; a method that cannot say is left out of a panel. Methods are offset "
                                f"sideways a little so that equal values stay visible. {pooled}")
        out["items"].append({"label": label, "plot": fig, "table": _axis_table(stats, label),
                             "no_value": stats[0]["no_value"]})
    return out


def _axis_table(stats: list[dict], label: str) -> dict:
    """Median depth RMS (mm: each depth metric in its own column) and the failures (k / n per kind) per
    method and value of the axis."""
    st = stats[0]
    cols = [f"median {metric_label(s['metric'])}" for s in stats] + ["crashed", "bound violated", "mismatched"]
    rows = []
    for lv in st["levels"]:
        line = [lv["label"]]
        for m in st["methods"]:
            c = st["cells"].get((m, lv["key"]))
            line += [None] * len(cols) if c is None else \
                [(s["cells"].get((m, lv["key"])) or {}).get("median") for s in stats] \
                + [_rate(c[k], c[d]) for k, d, _ in S.FAILURE_KINDS]
        rows.append(line)
    return {"title": "", "caption": "", "cls": "axis",
            "groups": [{"label": "", "span": 1}] + [{"label": m, "span": len(cols)} for m in st["methods"]],
            "columns": [label] + cols * len(st["methods"]), "rows": rows}


# ----------------------------------------------------------------------------- error maps
def _recon_dir(ds: Path, sample_id: str, method: str) -> Path:
    return sample_folder(ds, sample_id) / RECON / method_folder(method)


def _has_map_files(recon: Path) -> bool:
    """Whether a method's folder holds what its error map is drawn from (the paper's points.csv, or
    another method's output file, whose scored ``error_map.npz`` the map reads: a folder without it gets
    the "unavailable" figure) beside its sample."""
    if not (recon.parent.parent / "sample" / "plate.ply").is_file():
        return False
    return (recon / "points.csv").is_file() or P.output_file(recon) is not None


def _pick_error_maps(ds: Path, frame: pd.DataFrame) -> list[tuple[dict, Path]]:
    """For every method (the paper's pipeline first) whose folders hold a map's files: up to
    MAX_ERROR_MAPS (row, recon dir) of its ok rows, spread over the bend angles, plus its worst row
    by its own error figure (depth RMS at the centres or over the pixels, else surface RMS)."""
    ok = frame[S.ok_mask(frame) & frame["method"].notna()]
    out = []
    for m in S.method_order(ok["method"]):
        rows = ok[ok["method"] == m]
        if not any(_has_map_files(_recon_dir(ds, r.sample_id, m)) for r in rows.head(20).itertuples()):
            continue
        rows = rows.sort_values(["bend_deg", "sample_id"] if "bend_deg" in rows.columns else ["sample_id"])
        n = len(rows)
        k = min(MAX_ERROR_MAPS, n)
        order = {round(i * (n - 1) / max(k - 1, 1)) for i in range(k)}
        figure = next((c for c in (*S.DEPTH_METRICS, "surface_rms_mm") if c in rows.columns
                       and rows[c].notna().any()), None)
        if figure is not None:
            worst = int(rows[figure].fillna(-1.0).to_numpy().argmax())
            if worst not in order and len(order) >= MAX_ERROR_MAPS:
                order.discard(max(order))
            order.add(worst)
        picked = [records(rows.iloc[[i]])[0] for i in sorted(order)]
        out += [(r, _recon_dir(ds, r["sample_id"], m)) for r in picked
                if _has_map_files(_recon_dir(ds, r["sample_id"], m))]
    return out


_PAPER_MAP_CAPTION = ("top view of the plate in world X/Y (mm). Left: the reconstructed surface coloured by its exact "
                      "distance to the ground-truth mesh (mm), black = true boundary, red dashed = reconstructed "
                      "boundary. Right: the triangulated square centres coloured by their 3D error against the true "
                      "centres (mm), values printed above each.")
def _error_maps(page: Page, ds: Path, frame: pd.DataFrame, prefix: str) -> list[dict]:
    out = []
    for r, recon in _pick_error_maps(ds, frame):
        sid, meth = r["sample_id"], r["method"]
        problem = page.sample_problem(recon.parent.parent)
        if problem:
            page.leave_out(f"{problem}: the error map of sample {sid} is not shown")
            continue
        desc = ", ".join(_describe(k, r.get(k)) for k in _DESCRIBE if r.get(k) is not None)
        name, sample = f"{prefix}error_map_{_safe(sid)}_{_safe(meth)}", recon.parent.parent / "sample"
        if (recon / "points.csv").is_file():
            try:
                per_point = scored_errors(load_recon(recon)[1])
            except (OSError, ValueError) as e:  # a damaged recon.json or score.json
                page.leave_out(f"{str(e).splitlines()[0]}: the error map of sample {sid} is not shown")
                continue
            out.append(page.plot(name, P.plot_error_map, sample, recon, title=f"sample {sid}, {meth}: {desc}",
                                 per_point=per_point,
                                 caption=f"Sample {sid} ({desc}), method {meth}; {_PAPER_MAP_CAPTION}"))
        else:
            out.append(page.plot(name, P.plot_output_error_map, sample, recon, title=f"sample {sid}, {meth}: {desc}",
                                 caption=f"Sample {sid} ({desc}), method {meth}; {P.OUTPUT_MAP_CAPTION}"))
    return out


# ----------------------------------------------------------------------------- samples
def _samples(page: Page, ds: Path, frame: pd.DataFrame, prefix: str, manifest: dict) -> tuple[list, str]:
    """One entry per sample: its folder (relative link), the swept values, each method's status and
    depth RMS, and thumbnails of the left camera's images (the first MAX_THUMB_SAMPLES)."""
    axes, _ = S.swept_axes(manifest, frame)
    shown = axes or [c for c in _DESCRIBE if c in frame.columns][:3]
    methods = S.method_order(frame["method"].dropna())
    depth = {m: _depth_metric(frame, m) for m in methods}
    heads = {m: f"{m} ({_DEPTH_WHERE.get(depth[m], 'no depth figure')})" for m in methods}
    out = []
    for i, (sid, rows) in enumerate(frame.groupby("sample_id", sort=True)):
        folder = sample_folder(ds, sid)
        first = records(rows.iloc[[0]])[0]
        by_method = {r["method"]: r for r in records(rows)}
        sample = folder / "sample"
        thumbs = []
        if not folder.is_dir():
            page.leave_out(f"{folder}: the folder of sample {sid} is missing (the results table lists it)")
        elif not sample.is_dir() and any(r.get("status") == "ok" for r in by_method.values()):
            page.leave_out(f"{sample}: sample {sid} is done in the results table, but its sample folder is missing")
        elif i < MAX_THUMB_SAMPLES and sample.is_dir():
            thumbs = page.thumbnails(sample, _THUMB_IMAGES)
        out.append({"id": sid, "href": page.link(folder) if folder.is_dir() else None,
                    "values": [(parameter_label(c), first.get(c)) for c in shown],
                    "methods": [(heads[m], (by_method.get(m) or {}).get("status"),
                                 (by_method.get(m) or {}).get(depth[m]) if depth[m] else None,
                                 (by_method.get(m) or {}).get("paper_bound_met")) for m in methods],
                    "thumbs": thumbs})
    note = (f"thumbnails of the first {MAX_THUMB_SAMPLES} samples only" if len(out) > MAX_THUMB_SAMPLES else "")
    return out[:MAX_TABLE_ROWS], note


_DEPTH_WHERE = {"centres_depth_rms_mm": "at the square centres", "depth_rms_mm": "over the plate's pixels"}


def _depth_metric(frame: pd.DataFrame, method: str) -> str | None:
    """The depth RMS column a method's rows fill (``summary.DEPTH_METRICS``), or None."""
    rows = frame[frame["method"] == method]
    return next((k for k in S.DEPTH_METRICS if k in rows.columns and rows[k].notna().any()), None)


# ----------------------------------------------------------------------------- failures, headline
def _failures(frame: pd.DataFrame) -> dict:
    """The failed rows (status not ok) with their messages."""
    bad = frame[~S.ok_mask(frame)]
    cols = [c for c in ("sample_id", "method", "bend_deg", "direction", "family", "material")
            if c in bad.columns and bad[c].notna().any()]
    rows = [[r.get(c) for c in cols] + [r.get("status"), {"text": r.get("error") or "", "cls": "msg"}]
            for r in records(bad.head(MAX_TABLE_ROWS))]
    return {"count": len(bad), "more": max(0, len(bad) - MAX_TABLE_ROWS),
            "table": {"title": "", "caption": "", "cls": "err", "groups": [], "columns": cols + ["status", "error"],
                      "rows": rows}}


def _headline(name: str, sec: dict, frame: pd.DataFrame | None) -> dict:
    """One line per dataset for the page's headline: samples ok/failed, the paper's bound met in
    how many rows, crashes and mismatches, and the median depth RMS per method, grouped by what it
    measures (at the square centres; over the plate's pixels), so that the line compares like with like."""
    c = sec["counts"]
    parts = [f"{c['total']} samples, {c['ok']} ok, {c['failed']} failed"]
    bound = None
    if frame is not None and not frame.empty:
        f = S.failure_table(frame, frame["method"].astype(str))
        known, bad = int(f["bound_known"].sum()), int(f["bound_violated"].sum())
        if known:
            bound = bad == 0
            parts.append(f"paper's bound met in {known - bad} of {known} rows")
        parts.append(f"{int(f['crashed'].sum())} crashed, {int(f['mismatched'].sum())} with mismatched points")
        ok = frame[S.ok_mask(frame)]
        for k in S.DEPTH_METRICS:  # like with like: each depth figure with the methods that report it
            if k not in ok.columns:
                continue
            med = ok.groupby("method")[k].median()
            told = [f"{m} {fmt(float(med[m]), 3)} mm" for m in S.method_order(med.index) if pd.notna(med[m])]
            if told:
                parts.append(f"median {metric_label(k).replace(' (mm)', '')}: " + ", ".join(told))
    return {"label": f"Sweep {name} ({sec['rel']})", "text": "; ".join(parts), "met": bound}


def _describe(column: str, value) -> str:
    """'bend angle 120 deg' for a parameter column's value."""
    p = _PARAMETERS[column]
    return f"{p.label} {fmt(value)}" + (f" {p.unit}" if p.unit else "")


def _safe(s) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in str(s))[:60]
