"""Self-contained HTML reports of sweep datasets, false-boundary studies and method comparisons.

``write_report(input_dir, out_dir=None)`` looks in ``input_dir`` for

* a sweep DATASET (``bench/dataset.py``): ``manifest.json`` (format ``platebench-sweep``)
  and/or ``results.parquet`` / ``results.csv`` (one row per sample and method), else the
  per-sample ``samples/<id>/result.json`` files; reconstructions under
  ``samples/<id>/recon/<method>/`` and the sample under ``samples/<id>/sample/``;
* a false-boundary STUDY (``platebench study false-boundary``): ``study.json`` (rows,
  l_formula, smallest_hiding_bend_deg, precision_recall), else ``study.csv`` (rows only);
* ``compare.json`` files of ``platebench compare`` (in ``input_dir`` or a few levels
  below it, and in a dataset's ``samples/<id>/sample/compare/``);

and, when ``input_dir`` itself holds no dataset and no study, in its immediate
subdirectories. It writes ``OUT/index.html`` (default ``OUT = input_dir/report``):
one HTML file with inline CSS and every plot embedded as a base64 PNG data URI (no
scripts, no external assets or links), and the same plots as ``OUT/plots/*.png``.
Whatever is present is reported; a missing column, file or section is left out with a
note, never an exception. Units: errors in mm, bends in degrees, distances in m.

Writes are atomic: the plots directory is staged and renamed into place, then
``index.html`` is written to a temporary name and renamed. ``OUT`` must be new, empty,
or an earlier report (its ``index.html`` carries ``<meta name="generator"
content="platebench report">``): a report never writes into another directory.
"""
from __future__ import annotations

import base64
import csv
import datetime as _dt
import html
import json
import math
import statistics
from dataclasses import dataclass, field
from pathlib import Path

from platebench.bench.io.atomic import staged_directory, sweep_stale, write_text
from platebench.errors import UserValueError

__all__ = ["write_report", "detect_inputs", "load_results", "load_study", "method_summary", "swept_axes",
           "ReportInputError", "GENERATOR"]

GENERATOR = "platebench report"
MAX_ERROR_MAPS = 4
MAX_TABLE_ROWS = 200
MAX_COMPARES = 12
_SKIP_DIRS = {"report", "samples", "sample", "recon", "images", "gt", "plots"}


class ReportInputError(UserValueError):
    """The input directory holds nothing to report, or the output directory cannot be used."""


# ----------------------------------------------------------------------------- detection
@dataclass
class Inputs:
    root: Path
    datasets: list = field(default_factory=list)
    studies: list = field(default_factory=list)
    compares: list = field(default_factory=list)

    @property
    def empty(self) -> bool:
        return not (self.datasets or self.studies or self.compares)


def _read_json(path: Path):
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError, UnicodeDecodeError):
        return None


def is_dataset(d: Path) -> bool:
    d = Path(d)
    if (d / "results.csv").is_file() or (d / "results.parquet").is_file():
        return True
    m = _read_json(d / "manifest.json") if (d / "manifest.json").is_file() else None
    return isinstance(m, dict) and m.get("format") == "platebench-sweep"


def is_study(d: Path) -> bool:
    d = Path(d)
    return (d / "study.json").is_file() or (d / "study.csv").is_file()


def detect_inputs(input_dir: Path) -> Inputs:
    """Datasets, studies and compare.json files under ``input_dir`` (see module doc)."""
    root = Path(input_dir)
    inp = Inputs(root)
    if not root.is_dir():
        return inp
    cands = [root]
    if not (is_dataset(root) or is_study(root)):
        try:
            cands += sorted(p for p in root.iterdir() if p.is_dir() and not p.name.startswith(".")
                            and p.name not in _SKIP_DIRS)[:100]
        except OSError:
            pass
    for d in cands:
        if is_dataset(d):
            inp.datasets.append(d)
        if is_study(d):
            inp.studies.append(d)
    found = []
    for pattern in ("compare.json", "*/compare.json", "*/*/compare.json"):
        found += sorted(root.glob(pattern))
    for ds in inp.datasets:
        found += sorted((ds / "samples").glob("*/sample/compare/compare.json"))
        found += sorted((ds / "samples").glob("*/compare/compare.json"))
    seen = set()
    for p in found:
        rp = p.resolve()
        if rp in seen or "report" in p.relative_to(root).parts[:-1]:
            continue
        doc = _read_json(p)
        if isinstance(doc, dict) and isinstance(doc.get("methods"), dict):
            seen.add(rp)
            inp.compares.append(p)
    return inp


# ----------------------------------------------------------------------------- reading
def _column_types() -> dict:
    try:
        from platebench.bench.sweep.dataset import COLUMNS  # noqa: PLC0415
        return dict(COLUMNS)
    except Exception:  # noqa: BLE001  (the dataset module being edited: infer types)
        return {}


def _convert(text, kind: str | None):
    if text is None:
        return None
    if not isinstance(text, str):
        return text
    s = text.strip()
    if s == "":
        return None
    if kind == "str":
        return text
    low = s.lower()
    if kind == "bool" or (kind is None and low in ("true", "false")):
        return {"true": True, "false": False, "1": True, "0": False}.get(low, None)
    if kind in ("int", "float", None):
        try:
            v = float(s)
        except ValueError:
            return text if kind is None else None
        if kind == "int" and v.is_integer():
            return int(v)
        if kind is None and v.is_integer() and not any(c in s for c in ".eEn"):
            return int(v)
        return v
    return text


def _read_csv_rows(path: Path, types: dict | None = None) -> list[dict]:
    types = types or {}
    with open(path, newline="") as f:
        return [{k: _convert(v, types.get(k)) for k, v in r.items() if k is not None} for r in csv.DictReader(f)]


def load_results(dataset: Path) -> tuple[list[dict], str]:
    """The results table as a list of row dicts, and where it came from (parquet, csv,
    result.json files, or '' when none)."""
    d = Path(dataset)
    pq = d / "results.parquet"
    if pq.is_file():
        try:
            import pyarrow.parquet as pqm  # noqa: PLC0415
            rows = pqm.read_table(pq).to_pylist()
            return rows, "results.parquet"
        except Exception:  # noqa: BLE001  (unreadable: fall back to the CSV)
            pass
    if (d / "results.csv").is_file():
        try:
            return _read_csv_rows(d / "results.csv", _column_types()), "results.csv"
        except (OSError, csv.Error, UnicodeDecodeError):
            pass
    rows = []
    try:
        from platebench.bench.sweep.dataset import rows_of_result  # noqa: PLC0415
        for p in sorted((d / "samples").glob("*/result.json")):
            res = _read_json(p)
            if isinstance(res, dict) and isinstance(res.get("rows"), list):
                try:
                    rows += rows_of_result(res)
                except Exception:  # noqa: BLE001  (a malformed result: skip it)
                    continue
    except Exception:  # noqa: BLE001
        return [], ""
    return rows, "samples/*/result.json" if rows else ""


def load_study(study_dir: Path) -> dict:
    """study.json as a dict (rows, l_formula, smallest_hiding_bend_deg, precision_recall), or the
    rows of study.csv when there is no readable study.json."""
    d = Path(study_dir)
    doc = _read_json(d / "study.json") if (d / "study.json").is_file() else None
    if isinstance(doc, dict):
        doc.setdefault("rows", [])
        if not isinstance(doc["rows"], list):
            doc["rows"] = []
        doc["rows"] = [r for r in doc["rows"] if isinstance(r, dict)]
        doc["_source"] = "study.json"
        return doc
    if (d / "study.csv").is_file():
        try:
            return {"rows": _read_csv_rows(d / "study.csv", {"direction": "str", "status": "str", "error": "str"}),
                    "_source": "study.csv"}
        except (OSError, csv.Error, UnicodeDecodeError):
            pass
    return {"rows": [], "_source": ""}


# ----------------------------------------------------------------------------- summaries
_KNOWN_METRICS = ("depth_rms_mm", "depth_median_mm", "depth_max_mm", "xy_rms_mm", "err3d_rms_mm",
                  "boundary_mean_mm", "boundary_hausdorff_mm", "surface_rms_mm", "coverage_frac",
                  "matched_count", "correct_match_count", "expected_count_gt", "false_boundary_gt",
                  "false_boundary_detected", "paper_bound_met",
                  "time_render_s", "time_recon_s", "time_eval_s", "time_total_s")
_PARAM_SUFFIXES = ("_m", "_deg", "_px", "_e", "_dn")


def _is_num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(float(v))


def metric_columns(rows: list[dict]) -> list[str]:
    """Metric columns present with at least one value: the known ones in order, then any other
    numeric column whose name carries a metric unit (_mm, _frac, _count, _s)."""
    present = {k for r in rows for k, v in r.items() if v is not None}
    out = [k for k in _KNOWN_METRICS if k in present]
    extra = sorted(k for k in present if k not in out and k.endswith(("_mm", "_frac", "_count", "_s"))
                   and not k.endswith(_PARAM_SUFFIXES) and any(_is_num(r.get(k)) for r in rows))
    return out + extra


def _ok(r) -> bool:
    return str(r.get("status") or "ok") == "ok"


def method_summary(rows: list[dict]) -> dict:
    """{method: {"rows": n, "ok": n, "failed": n, "metrics": {metric: {"mean", "median", "n", "kind"}}}}
    over the rows with status ok; booleans give the fraction true as "mean" (kind "rate")."""
    out: dict = {}
    metrics = metric_columns(rows)
    for r in rows:
        m = str(r.get("method") or "-")
        e = out.setdefault(m, {"rows": 0, "ok": 0, "failed": 0, "metrics": {}})
        e["rows"] += 1
        e["ok" if _ok(r) else "failed"] += 1
    for m, e in out.items():
        mrows = [r for r in rows if str(r.get("method") or "-") == m and _ok(r)]
        for k in metrics:
            vals = [r.get(k) for r in mrows if r.get(k) is not None]
            bools = [v for v in vals if isinstance(v, bool)]
            nums = [float(v) for v in vals if _is_num(v)]
            if bools and len(bools) >= len(nums):
                e["metrics"][k] = {"mean": sum(bools) / len(bools), "median": None, "n": len(bools), "kind": "rate",
                                   "true": sum(bools)}
            elif nums:
                e["metrics"][k] = {"mean": statistics.fmean(nums), "median": statistics.median(nums), "n": len(nums),
                                   "kind": "value"}
    return out


# ----------------------------------------------------------------------------- HTML helpers
def _esc(x) -> str:
    return html.escape(str(x), quote=True)


def _fmt(v, digits: int = 4) -> str:
    if v is None:
        return "&ndash;"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "&ndash;"
        if math.isinf(v):
            return "&infin;" if v > 0 else "&minus;&infin;"
        if v == 0:
            return "0"
        if abs(v) >= 1e5 or abs(v) < 1e-3:
            return f"{v:.{digits - 1}e}"
        return f"{v:.{digits}g}"
    return _esc(v)


def _num(v) -> float | None:
    if isinstance(v, bool) or v is None:
        return None
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _table(headers, rows, cls: str = "", header_rows: list | None = None) -> str:
    """An HTML table; cells already formatted (HTML) strings."""
    out = [f'<div class="tw"><table class="{cls}">', "<thead>"]
    for hr in header_rows or []:
        out.append("<tr>" + "".join(hr) + "</tr>")
    out.append("<tr>" + "".join(f"<th>{h}</th>" for h in headers) + "</tr></thead><tbody>")
    for r in rows:  # a row is a list of cells, or a string of ready-made cells
        out.append("<tr>" + (r if isinstance(r, str) else "".join(f"<td>{c}</td>" for c in r)) + "</tr>")
    out.append("</tbody></table></div>")
    return "\n".join(out)


def _kv_table(items) -> str:
    rows = "".join(f"<tr><th>{_esc(k)}</th><td>{v}</td></tr>" for k, v in items)
    return f'<div class="tw"><table class="kv"><tbody>{rows}</tbody></table></div>'


def _packages_table(pk: dict, per_row: int = 4) -> str:
    cells = [f"<th>{_esc(k)}</th><td>{_esc(v if v is not None else 'not installed')}</td>" for k, v in pk.items()]
    cells += ["<th></th><td></td>"] * (-len(cells) % per_row)
    rows = "".join("<tr>" + "".join(cells[i:i + per_row]) + "</tr>" for i in range(0, len(cells), per_row))
    return f'<div class="tw"><table class="kv pk"><tbody>{rows}</tbody></table></div>'


class _Plots:
    """Plots made into the staged plots directory; each embedded as a data URI."""

    def __init__(self, stage: Path):
        self.stage = stage
        self.names: list[str] = []
        self.notes: list[str] = []

    def make(self, name: str, fn, *args, caption: str = "", **kwargs) -> str:
        path = self.stage / f"{name}.png"
        try:
            fn(*args, path, **kwargs)
        except Exception as e:  # noqa: BLE001  (one bad plot never stops the report)
            msg = f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"
            return f'<p class="note">plot {_esc(name)} could not be drawn: {_esc(msg)}</p>'
        self.names.append(path.name)
        data = base64.b64encode(path.read_bytes()).decode("ascii")
        return (f'<figure><img alt="{_esc(name)}" src="data:image/png;base64,{data}">'
                f"<figcaption>{caption}</figcaption></figure>")


_CSS = """
body{font-family:-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;margin:0;color:#1d2330;background:#f4f5f7;
 line-height:1.45;font-size:14px}
main{max-width:1180px;margin:0 auto;padding:20px 28px 60px;background:#fff;box-shadow:0 0 8px rgba(0,0,0,.08)}
header{border-bottom:3px solid #2f5d8a;margin-bottom:12px}
h1{font-size:24px;margin:8px 0 4px;color:#1f3f60} h2{font-size:19px;margin:28px 0 8px;color:#1f3f60;
 border-bottom:1px solid #d5dbe3;padding-bottom:3px} h3{font-size:15px;margin:18px 0 6px;color:#2f4a66}
h4{font-size:13.5px;margin:16px 0 4px;color:#2f4a66}
p.meta{color:#5b6675;margin:2px 0 10px;font-size:13px} p.note{color:#7a5a00;background:#fff8e1;padding:4px 8px;
 border-left:3px solid #e0b000;font-size:13px}
nav{font-size:13px;background:#f0f3f7;padding:6px 10px;border-radius:4px} nav a{margin-right:14px;color:#2f5d8a}
.tw{overflow-x:auto;margin:6px 0 12px} table{border-collapse:collapse;font-size:12.5px}
th,td{border:1px solid #d5dbe3;padding:3px 7px;text-align:right;vertical-align:top}
th{background:#e9eef4;font-weight:600} td:first-child,th:first-child{text-align:left}
tbody tr:nth-child(even){background:#f8f9fb}
table.kv td,table.kv th,table.err th{text-align:left} table.pk th{font-weight:500;background:#f0f3f7}
td.c{text-align:center} table.cases{font-size:11.5px} table.cases th,table.cases td{padding:2px 5px}
table.err td{text-align:left} table.err td.msg{max-width:620px;word-break:break-word;
 font-family:Menlo,Consolas,monospace;font-size:11.5px}
.cards{display:flex;flex-wrap:wrap;gap:10px;margin:8px 0 12px}
.card{border:1px solid #d5dbe3;border-radius:6px;padding:8px 14px;min-width:110px;background:#fafbfc}
.card .v{font-size:22px;font-weight:600;color:#1f3f60} .card .k{font-size:12px;color:#5b6675}
.card.bad .v{color:#b3261e} .card.good .v{color:#1e7b34}
figure{margin:14px 0 20px;text-align:center} figure img{max-width:100%;height:auto;border:1px solid #e1e5ea}
figcaption{font-size:12.5px;color:#4a5463;text-align:left;max-width:980px;margin:4px auto 0}
details{margin:6px 0} pre{background:#f4f6f8;padding:8px;font-size:11.5px;overflow-x:auto}
.yes{color:#1e7b34;font-weight:600} .no{color:#b3261e}
"""


def _card(label: str, value, cls: str = "") -> str:
    return f'<div class="card {cls}"><div class="v">{value}</div><div class="k">{_esc(label)}</div></div>'


def _yn(v) -> str:
    if v is None:
        return "&ndash;"
    return '<span class="yes">yes</span>' if v else '<span class="no">no</span>'


def _flag(v):
    if isinstance(v, str):
        return {"true": True, "false": False}.get(v.strip().lower())
    if isinstance(v, (bool, int)) and not isinstance(v, float):
        return bool(v)
    return None


# ----------------------------------------------------------------------------- dataset section
def _metric_label(k: str) -> str:
    from platebench.bench.report.plots import METRIC_LABELS  # noqa: PLC0415
    return METRIC_LABELS.get(k, k)


def _dataset_section(ds: Path, root: Path, plots: _Plots, prefix: str, anchor: str) -> str:
    from platebench.bench.report import plots as P  # noqa: PLC0415
    manifest = _read_json(ds / "manifest.json")
    manifest = manifest if isinstance(manifest, dict) else {}
    rows, source = load_results(ds)
    spec = manifest.get("spec") or {}
    name = spec.get("name") or ds.name
    rel = _rel(ds, root)
    h = [f'<h2 id="{anchor}">Sweep dataset: {_esc(name)}</h2>',
         f'<p class="meta">directory {_esc(rel)}; table read from {_esc(source or "nothing (no results yet)")}'
         + (f"; state {_esc(manifest.get('state'))}" if manifest.get("state") else "")
         + (f"; updated {_esc(manifest.get('updated_utc'))}" if manifest.get("updated_utc") else "") + "</p>"]
    if spec.get("description"):
        h.append(f"<p>{_esc(spec['description'])}</p>")
    # -- summary -----------------------------------------------------------------
    counts = manifest.get("counts") or {}
    sample_status: dict = {}
    for r in rows:
        sid = str(r.get("sample_id"))
        sample_status[sid] = sample_status.get(sid, True) and _ok(r)
    n_total = counts.get("total", len(sample_status))
    n_ok = counts.get("ok", sum(sample_status.values()))
    n_failed = counts.get("failed", sum(not v for v in sample_status.values()))
    n_pending = counts.get("pending", max(0, (n_total or 0) - (n_ok or 0) - (n_failed or 0)))
    methods = sorted({str(r.get("method")) for r in rows if r.get("method") is not None})
    h.append('<h3>Summary</h3><div class="cards">'
             + _card("samples", _fmt(n_total)) + _card("ok", _fmt(n_ok), "good")
             + _card("failed", _fmt(n_failed), "bad" if n_failed else "") + _card("pending", _fmt(n_pending))
             + _card("table rows", _fmt(len(rows))) + _card("methods", _esc(", ".join(methods) or "-"))
             + "</div>")
    items = []
    if spec.get("mode"):
        items.append(("sweep mode", _esc(spec.get("mode"))))
    if spec.get("axes"):
        items.append(("axes", _esc(", ".join(f"{k} = {json.dumps(v)}" for k, v in spec["axes"].items()))))
    ex = manifest.get("executor") or {}
    if ex:
        items.append(("executor", _esc(", ".join(f"{k} {v}" for k, v in ex.items()))))
    variants = sorted({str(r.get("variant")) for r in rows if r.get("variant")})
    if variants:
        items.append(("Mitsuba variant", _esc(", ".join(variants))))
    if manifest.get("created_utc"):
        items.append(("created", _esc(manifest["created_utc"])))
    if items:
        h.append(_kv_table(items))
    pk = manifest.get("packages") or {}
    if pk:
        h.append("<h3>Package versions</h3>" + _packages_table(pk))
    if manifest.get("spec_text"):
        h.append(f"<details><summary>sweep spec (TOML)</summary><pre>{_esc(manifest['spec_text'])}</pre></details>")
    if not rows:
        h.append('<p class="note">no results table and no per-sample results yet: nothing to tabulate.</p>')
        return "\n".join(h)
    # -- method comparison table --------------------------------------------------
    summ = method_summary(rows)
    mlist = list(summ)
    metrics = [k for k in metric_columns(rows) if any(k in summ[m]["metrics"] for m in mlist)]
    h.append("<h3>Method comparison</h3><p class=\"meta\">Mean, median and number of values of each metric over "
             "the rows with status ok (units in the names: mm, s, fractions 0..1; for yes/no columns: how many "
             "rows say yes, out of n).</p>")
    top = ['<th rowspan="2">metric</th>'] + [f'<th colspan="3">{_esc(m)}</th>' for m in mlist]
    sub = sum((["mean", "median", "n"] for _ in mlist), [])
    body = ["<td>rows ok / failed</td>" + "".join(
        f'<td colspan="3" class="c">{summ[m]["ok"]} / {summ[m]["failed"]}</td>' for m in mlist)]
    for k in metrics:
        line = [f"{_esc(k)}"]
        for m in mlist:
            s = summ[m]["metrics"].get(k)
            if s is None:
                line += ["&ndash;", "&ndash;", "0"]
            elif s["kind"] == "rate":
                line += [f"{s['true']} yes", "&ndash;", str(s["n"])]
            else:
                line += [_fmt(s["mean"]), _fmt(s["median"]), str(s["n"])]
        body.append(line)
    h.append(_table(sub, body, "", header_rows=[top]))
    # -- plots -----------------------------------------------------------------
    bar_table = {m: {k: v["median"] for k, v in summ[m]["metrics"].items() if v["kind"] == "value"} for m in mlist}
    h.append("<h3>Plots</h3>")
    h.append(plots.make(f"{prefix}method_comparison", P.plot_method_comparison, bar_table,
                        title=f"{name}: median over samples per method",
                        caption="Median of each error metric over the sweep's successful rows, per method (the "
                                "table above gives the means too). Bars: "
                                "errors in millimetres (log scale when they span decades); right panel: coverage "
                                "as a fraction of the plate (0..1), where the method reports it."))
    bends = {round(b, 6) for b in (_num(r.get("bend_deg")) for r in rows) if b is not None}
    det_rows = [r for r in rows if r.get("false_boundary_detected") is not None]
    if len(bends) > 1:  # (one bend for every sample: the per-bend plots would be one column of dots)
        h.append(plots.make(f"{prefix}error_vs_bend", P.plot_error_vs_bend, rows,
                            title=f"{name}: error against bend angle",
                            caption="Depth RMS error of the square centres / dense depth (mm, left) and mean "
                                    "symmetric boundary distance (mm, right) against the bend angle (degrees), "
                                    "one colour per method, solid = bend up, dashed = bend down; dots are samples, "
                                    "lines join the median per bend; red crosses on the bottom edge mark failed "
                                    "rows at that bend."))
        if det_rows:
            h.append(plots.make(f"{prefix}detection_vs_bend", P.plot_detection_vs_bend, det_rows,
                                flags=("false_boundary_detected",),
                                title=f"{name}: false-boundary detection against ground truth",
                                caption="Precision and recall (0..1) of the pipeline's false-boundary verdict "
                                        "against ground-truth boundary visibility, per bend-angle bin (degrees, "
                                        "n = cases in the bin); grey bars: fraction of cases in the bin with a "
                                        "ground-truth false boundary. A gap means undefined (no positive verdict, "
                                        "or no ground-truth positive, in that bin)."))
    if bends and det_rows:
        pr = P.precision_recall_counts(det_rows, "false_boundary_detected")
        h.append("<p>False-boundary detection over the whole sweep: " + ", ".join(
            f"{k.replace('_', ' ')} {_fmt(v, 3)}" for k, v in pr.items()) + ".</p>")
    if len(bends) > 1:
        h.append(_by_bend_table(rows, metrics))
    # -- each swept axis: depth RMS and failure rate per method ------------------
    h.append(_axes_section(rows, manifest, plots, prefix, name))
    # -- error maps -----------------------------------------------------------
    maps = _pick_error_maps(ds, rows)
    if maps:
        h.append("<h3>Per-sample error maps</h3>")
        for r, recon in maps:
            sid, meth = str(r.get("sample_id")), str(r.get("method"))
            desc = ", ".join(f"{k} {_fmt(r.get(k))}" for k in ("bend_deg", "direction", "family", "material",
                                                                "roughness", "distance_m", "noise")
                             if r.get(k) is not None)
            h.append(plots.make(f"{prefix}error_map_{_safe(sid)}_{_safe(meth)}", P.plot_error_map,
                                recon.parent.parent / "sample", recon,
                                title=f"sample {sid}, {meth}: {desc}",
                                caption=f"Sample {_esc(sid)} ({_esc(desc)}), method {_esc(meth)}; top view of the "
                                        "plate in world X/Y (mm). Left: the reconstructed surface coloured by its "
                                        "exact distance to the ground-truth mesh (mm), black = true boundary, "
                                        "red dashed = reconstructed boundary. Right: the triangulated square "
                                        "centres coloured by their 3D error against the true centres (mm), "
                                        "values printed above each."))
    # -- failures -------------------------------------------------------------
    fails = [r for r in rows if not _ok(r)]
    h.append(f"<h3>Failures ({len(fails)})</h3>")
    if fails:
        cols = [c for c in ("sample_id", "method", "bend_deg", "direction", "family", "material") if
                any(r.get(c) is not None for r in fails)]
        body = [[_fmt(r.get(c)) for c in cols] + [_esc(r.get("status")), f'<span>{_esc(r.get("error") or "")}</span>']
                for r in fails[:MAX_TABLE_ROWS]]
        t = _table(cols + ["status", "error"], body, "err")
        h.append(t.replace("<td><span>", '<td class="msg"><span>'))
        if len(fails) > MAX_TABLE_ROWS:
            h.append(f'<p class="note">{len(fails) - MAX_TABLE_ROWS} more failed rows: see results.csv</p>')
    else:
        h.append("<p>No failed rows.</p>")
    return "\n".join(h)


def _by_bend_table(rows: list[dict], metrics: list[str]) -> str:
    """Median depth RMS and boundary mean (mm) and ok/total rows per bend and method."""
    groups: dict = {}
    for r in rows:
        b = _num(r.get("bend_deg"))
        if b is not None:
            groups.setdefault((round(b, 6), str(r.get("method") or "-")), []).append(r)
    bends = sorted({b for b, _ in groups})
    if not bends or len(bends) > 40:
        return ""
    mlist = sorted({m for _, m in groups})
    show = [k for k in ("depth_rms_mm", "boundary_mean_mm") if k in metrics]
    top = ['<th rowspan="2">bend (deg)</th>'] + [f'<th colspan="{len(show) + 1}">{_esc(m)}</th>' for m in mlist]
    sub = sum(([f"median {k}" for k in show] + ["ok / rows"] for _ in mlist), [])
    body = []
    for b in bends:
        line = [_fmt(b)]
        for m in mlist:
            grp = groups.get((b, m), [])
            for k in show:
                vals = [_num(r.get(k)) for r in grp if _ok(r) and _num(r.get(k)) is not None]
                line.append(_fmt(statistics.median(vals)) if vals else "&ndash;")
            line.append(f"{sum(_ok(r) for r in grp)} / {len(grp)}")
        body.append(line)
    return ("<h3>By bend angle</h3><p class=\"meta\">Median per bend angle (degrees) and method, over rows with "
            "status ok; errors in mm.</p>" + _table(sub, body, "", header_rows=[top]))


# ----------------------------------------------------------------------------- swept axes
# result columns a sweep may vary, looked at even when the manifest names no axis
_AXIS_CANDIDATES = ("roughness", "noise", "bend_deg", "distance_m", "material", "spp", "resolution", "width_px")
# spec axis (or last part of a dotted path) -> result columns that carry it, first varying one wins
_SPEC_AXIS_COLUMNS = {"resolution": ("width_px", "height_px"), "alpha": ("roughness",), "angle_rad": ("bend_deg",),
                      "axis_rad": ("axis_deg",), "width": ("width_px",), "height": ("height_px",),
                      "noise": ("noise", "read_noise_dn", "full_well_e"), "kind": ("material",)}
_REPLICATE_AXES = ("seed",)  # varied to repeat a measurement: pooled, never plotted against
MAX_AXIS_PLOTS = 8


def _levels(rows: list[dict], col: str) -> list[str]:
    from platebench.bench.report.plots import axis_levels  # noqa: PLC0415
    if not any(col in r for r in rows):
        return []
    return [lv["label"] for lv in axis_levels(rows, col)[0]]


def swept_axes(manifest: dict, rows: list[dict]) -> tuple[list[str], dict]:
    """The results columns a sweep varies: its spec's axes (as results columns: ``resolution`` is
    width_px, ``scene.material.alpha`` is roughness, a custom ``noise`` table its sensor keys), then
    those of ``_AXIS_CANDIDATES`` that take more than one value. Returns (axes to plot in that
    order, {column: level labels} of every varying column, replicate axes such as seed included)."""
    spec_axes = list(((manifest or {}).get("spec") or {}).get("axes") or {})
    varying: dict = {}
    order: list[str] = []
    for k in spec_axes:
        leaf = str(k).split(".")[-1]
        for col in _SPEC_AXIS_COLUMNS.get(leaf, (leaf,)):
            lv = _levels(rows, col)
            if len(lv) > 1:
                varying.setdefault(col, lv)
                order.append(col)
                break
    for col in _AXIS_CANDIDATES:
        col = _SPEC_AXIS_COLUMNS.get(col, (col,))[0]
        lv = _levels(rows, col)
        if len(lv) > 1:
            varying.setdefault(col, lv)
            order.append(col)
    if "width_px" in varying and "height_px" in varying:  # one resolution axis, not two
        order = [c for c in order if c != "height_px"]
    plotted = [c for c in dict.fromkeys(order) if c not in _REPLICATE_AXES]
    return plotted, varying


def _axes_section(rows: list[dict], manifest: dict, plots: _Plots, prefix: str, name: str) -> str:
    """Per swept axis: depth RMS (median) and failure rate per method, a plot and a table."""
    from platebench.bench.report import plots as P  # noqa: PLC0415
    axes, varying = swept_axes(manifest, rows)
    if not axes:
        return ""
    metric = "depth_rms_mm"
    h = ["<h3>Against the swept axes</h3>",
         "<p class=\"meta\">For each swept axis: the median depth RMS error (mm) over the samples at each value, "
         "per method, and the failure rate (fraction 0..1 of the method's rows at that value, with the count): a "
         "row counts as failed when its status is failed, when it gives no depth RMS, or, for the paper's "
         "pipeline, when it matched fewer squares than ground truth puts on the plate. Medians are over the rows "
         "with status ok and a value (an incomplete paper row included).</p>"]
    if not any(_num(r.get(metric)) is not None for r in rows):
        h.append('<p class="note">no row has a depth RMS: nothing to plot against the swept axes.</p>')
        return "\n".join(h)
    for axis in axes[:MAX_AXIS_PLOTS]:
        label = P.axis_label(axis)
        others = {k: v for k, v in varying.items() if k != axis and not (axis == "width_px" and k == "height_px")}
        pooled_txt = ("Other swept axes vary too, and every point pools their samples: "
                      + "; ".join(f"{_esc(P.axis_label(k))} ({_esc(', '.join(v))})" for k, v in others.items()) + "."
                      if others else "No other swept axis varies.")
        st = P.axis_stats(rows, axis, metric)
        h.append(f"<h4>{_esc(label)}</h4>")
        h.append(plots.make(f"{prefix}vs_{_safe(axis)}", P.plot_metric_vs_axis, rows, axis,
                            metrics=(metric,), pooled=others or None,
                            title=f"{name}: depth RMS and failure rate against {label}",
                            caption=f"Left: median depth RMS error (mm) against {_esc(label)}, one line per method "
                                    "(small hollow dots: the samples; log scale when they span more than a decade; a "
                                    "hollow median marker: some rows at that value count as failed, see the right "
                                    "panel; a cross on the bottom edge: no row of the method gave a value "
                                    "there). Right: failure rate "
                                    "(0..1) per method, with k/n printed where some failed: status failed, no "
                                    "depth RMS, or for the paper's pipeline fewer squares matched than ground "
                                    "truth puts on the plate. Methods are offset sideways a little so that equal "
                                    f"values stay visible. {pooled_txt}"))
        h.append(_axis_table(st, label))
        if st["no_value"]:
            h.append(f'<p class="note">{st["no_value"]} rows have no {_esc(label)} (the axis does not apply '
                     "to them) and are left out here.</p>")
    if len(axes) > MAX_AXIS_PLOTS:
        h.append(f'<p class="note">{len(axes) - MAX_AXIS_PLOTS} more swept axes not shown: '
                 f'{_esc(", ".join(axes[MAX_AXIS_PLOTS:]))}</p>')
    return "\n".join(h)


def _axis_table(st: dict, label: str) -> str:
    """Median depth RMS (mm) and failure rate (k/n) per method and value of the axis."""
    mlist = st["methods"]
    top = [f'<th rowspan="2">{_esc(label)}</th>'] + [f'<th colspan="2">{_esc(m)}</th>' for m in mlist]
    sub = sum((["median depth RMS (mm)", "failure rate"] for _ in mlist), [])
    body = []
    for lv in st["levels"]:
        line = [_esc(lv["label"])]
        for m in mlist:
            c = st["cells"].get((m, lv["key"]))
            if c is None:
                line += ["&ndash;", "&ndash;"]
                continue
            line.append(_fmt(c["median"]))
            line.append(f"{c['failure_rate']:.2f} ({c['failed']}/{c['rows']})")
        body.append(line)
    return _table(sub, body, "axis", header_rows=[top])


def _recon_dir(ds: Path, r: dict) -> Path:
    return ds / "samples" / str(r["sample_id"]) / "recon" / str(r["method"])


def _has_map_files(recon: Path) -> bool:
    return (recon / "points.csv").is_file() and (recon.parent.parent / "sample" / "plate.ply").is_file()


def _pick_error_maps(ds: Path, rows: list[dict]) -> list:
    """Up to MAX_ERROR_MAPS (row, recon dir) of ok rows of a method that writes points.csv (the
    paper's pipeline): spread over the bend angles, plus the worst depth RMS."""
    ok = [r for r in rows if _ok(r) and r.get("sample_id") is not None and r.get("method") is not None]
    by_method: dict = {}
    for r in ok:
        by_method.setdefault(str(r["method"]), []).append(r)
    cands = []
    for m, mrows in by_method.items():  # a method writes point files if some of its first rows have them
        if any(_has_map_files(_recon_dir(ds, r)) for r in mrows[:20]):
            cands += mrows
    if not cands:
        return []
    cands.sort(key=lambda r: (str(r.get("method")) != "paper", _num(r.get("bend_deg")) or 0.0, str(r.get("sample_id"))))
    n_first = sum(1 for r in cands if str(r.get("method")) == str(cands[0].get("method")))
    k = min(MAX_ERROR_MAPS, n_first)
    order = [round(i * (n_first - 1) / max(k - 1, 1)) for i in range(k)]
    worst = max(range(n_first), key=lambda i: _num(cands[i].get("depth_rms_mm")) or -1.0)
    if worst not in order:
        order = order[:-1] + [worst] if len(order) >= MAX_ERROR_MAPS else order + [worst]
    picked = []
    for i in sorted(set(order)):
        recon = _recon_dir(ds, cands[i])
        if _has_map_files(recon):
            picked.append((cands[i], recon))
    return picked


def _safe(s: str) -> str:
    return "".join(c if c.isalnum() or c in "-_" else "_" for c in s)[:60]


def _rel(p: Path, root: Path) -> str:
    try:
        r = Path(p).resolve().relative_to(Path(root).resolve())
        return str(r) if str(r) != "." else str(Path(root))
    except ValueError:
        return str(p)


# ----------------------------------------------------------------------------- study section
_CASE_COLUMNS = (("bend_deg", "bend (deg)"), ("direction", "dir"), ("axis_deg", "axis (deg)"),
                 ("aspect", "aspect L/W"), ("length_m", "length (m)"), ("width_m", "width (m)"),
                 ("distance_m", "distance (m)"), ("hidden_frac_left", "hidden L"), ("hidden_frac_right", "hidden R"),
                 ("false_boundary_gt", "GT false bnd"), ("status", "status"), ("detected", "detected"),
                 ("counting_test", "count test"), ("arrays_disagree", "arrays differ"),
                 ("squares_expected", "sq. exp."), ("squares_left", "sq. L"), ("squares_right", "sq. R"),
                 ("matched", "matched"), ("depth_rms_mm", "depth RMS (mm)"), ("xy_rms_mm", "x/y RMS (mm)"),
                 ("boundary_mean_mm", "bnd mean (mm)"), ("cure1_removed", "cure 1 ok"),
                 ("cure1_hidden_frac", "hidden after 1"), ("cure2_removed", "cure 2 ok"),
                 ("cure2_hidden_frac", "hidden after 2"), ("cure2_steps", "cure 2 steps"),
                 ("cure2_distance_m", "cure 2 dist (m)"), ("L_measured_m", "L measured (m)"), ("time_s", "time (s)"))
_BOOL_CASE = {"false_boundary_gt", "detected", "counting_test", "arrays_disagree", "cure1_removed", "cure2_removed"}


def _study_series(rows: list[dict]) -> tuple:
    """Direction, plus the case parameters that vary across the study (aspect, distance, axis)."""
    extra = tuple(k for k in ("aspect", "distance_m", "axis_deg")
                  if len({json.dumps(r.get(k), default=str) for r in rows}) > 1)
    return ("direction",) + extra


def _study_section(sd: Path, root: Path, plots: _Plots, prefix: str, anchor: str) -> str:
    from platebench.bench.report import plots as P  # noqa: PLC0415
    doc = load_study(sd)
    rows = doc.get("rows") or []
    h = [f'<h2 id="{anchor}">False-boundary study</h2>',
         f'<p class="meta">directory {_esc(_rel(sd, root))}; read from {_esc(doc.get("_source") or "nothing")}</p>']
    n_ok = sum(1 for r in rows if str(r.get("status") or "ok") == "ok")
    n_gt = sum(1 for r in rows if _flag(r.get("false_boundary_gt")))
    n_det = sum(1 for r in rows if _flag(r.get("detected")))
    t = [_num(r.get("time_s")) for r in rows]
    t = [x for x in t if x is not None]
    h.append('<div class="cards">' + _card("cases", len(rows)) + _card("reconstructed", n_ok, "good")
             + _card("failed", len(rows) - n_ok, "bad" if len(rows) - n_ok else "")
             + _card("GT false boundary", n_gt) + _card("detected", n_det)
             + (_card("total time (s)", f"{sum(t):.1f}") if t else "") + "</div>")
    cures = doc.get("cures")
    if isinstance(cures, dict) and cures:
        h.append("<p>Cures over the cases with a ground-truth false boundary: " + ", ".join(
            f"{_esc(k.replace('_removed_frac', ''))} removes it in {_fmt(v, 3)}"
            + (" of them" if v is not None else " (no such case)") for k, v in cures.items()) + " (fraction 0..1).</p>")
    for k in ("config", "settings", "parameters"):
        if isinstance(doc.get(k), dict) and doc[k]:
            h.append(f"<details><summary>study {k}</summary><pre>{_esc(json.dumps(doc[k], indent=1))}</pre></details>")
    # smallest hiding bend
    sh = doc.get("smallest_hiding_bend_deg")
    if isinstance(sh, dict) and sh:
        h.append("<h3>Smallest hiding bend</h3><p class=\"meta\">Smallest cylindrical bend (degrees) at which the "
                 "straight-down reference rig misses part of the true boundary (ground-truth visibility); "
                 "&ndash; = no bend up to 350 degrees hides it.</p>"
                 + _table(["direction", "smallest hiding bend (deg)"], [[_esc(k), _fmt(v)] for k, v in sh.items()]))
    # precision / recall
    pr = doc.get("precision_recall")
    if not isinstance(pr, dict) or not pr:
        pr = {f: P.precision_recall_counts(rows, f) for f in ("detected", "counting_test", "arrays_disagree")
              if any(r.get(f) is not None for r in rows)}
        src = "computed from the rows"
    else:
        src = "from study.json"
    if pr:
        keys = ("true_positive", "false_positive", "false_negative", "precision", "recall")
        h.append(f"<h3>Detection precision / recall</h3><p class=\"meta\">Each flag of the counting test against "
                 f"ground truth (a true-boundary point hidden from a camera), over the reconstructed cases ({src}); "
                 "precision and recall are fractions 0..1, &ndash; where undefined.</p>"
                 + _table(["flag"] + [k.replace("_", " ") for k in keys],
                          [[_esc(f)] + [_fmt((v or {}).get(k), 3) for k in keys] for f, v in pr.items()]))
    # L formula
    lf = [r for r in (doc.get("l_formula") or []) if isinstance(r, dict)]
    if lf:
        cols = [("bend_deg", "bend (deg)"), ("L_m", "L (m)"), ("predicted_distance_m", "predicted distance (m)"),
                ("gt_distance_baseline_along_axis_m", "GT distance, baseline along axis (m)"),
                ("ratio_gt_over_predicted_baseline_along_axis", "ratio GT / predicted (along axis)"),
                ("gt_distance_baseline_along_bend_m", "GT distance, baseline along bend (m)"),
                ("ratio_gt_over_predicted_baseline_along_bend", "ratio GT / predicted (along bend)")]
        cols = [c for c in cols if any(c[0] in r for r in lf)]
        h.append("<h3>L formula</h3><p class=\"meta\">The paper's sensing distance L (from the tangents at the ends of "
                 "the most-bent curve) plus the height of AB, against the ground-truth smallest rig distance at which "
                 "both cameras see the whole true boundary; distances in metres, &infin; = never fully visible.</p>"
                 + _table([t for _, t in cols], [[_fmt(r.get(k)) for k, _ in cols] for r in lf]))
    # plots
    if rows:
        h.append("<h3>Plots</h3>")
        h.append(plots.make(f"{prefix}hidden_fraction_vs_bend", P.plot_hidden_fraction_vs_bend, rows,
                            series=_study_series(rows),
                            smallest_hiding=sh if isinstance(sh, dict) else None,
                            caption="Top: fraction (0..1) of the true boundary hidden from the worse camera at the "
                                    "default pose against the bend angle (degrees), per bend direction; small "
                                    "hollow triangles: left (&lt;) and right (&gt;) camera; dotted verticals: "
                                    "smallest hiding bend. Bottom: per case, the ground truth (circles) and the "
                                    "pipeline's verdict (squares): filled = yes, hollow = no, grey x = no verdict "
                                    "(reconstruction failed)."))
        h.append(plots.make(f"{prefix}detection_vs_bend", P.plot_detection_vs_bend, rows,
                            caption="Precision and recall (0..1) of the false-boundary verdict and of each of its "
                                    "two symptoms (fewer squares than expected; the arrays of the two images "
                                    "disagree) against ground truth, per bend-angle bin (degrees, n = cases); grey "
                                    "bars: fraction of cases with a ground-truth false boundary. Gaps: undefined."))
        if any(r.get("cure1_removed") is not None or r.get("cure2_removed") is not None for r in rows):
            h.append(plots.make(f"{prefix}cure_success_vs_bend", P.plot_cure_success_vs_bend, rows,
                                caption="Cases with a ground-truth false boundary. Left: fraction of cases (0..1) in "
                                        "which each cure leaves the whole true boundary visible, by bend angle "
                                        "(degrees). Right: hidden fraction of the true boundary (0..1) before "
                                        "(black bars) and after each cure."))
        if any(_num(r.get(k)) is not None for r in rows for k in ("depth_rms_mm", "boundary_mean_mm")):
            h.append(plots.make(f"{prefix}error_vs_bend", P.plot_error_vs_bend, rows, series=_study_series(rows),
                                title="Study: error against bend angle",
                                caption="Depth RMS error of the square centres (mm) and mean boundary distance (mm) "
                                        "against the bend angle (degrees), solid/dashed per bend direction; red "
                                        "crosses mark cases whose reconstruction failed."))
    if lf:
        h.append(plots.make(f"{prefix}l_formula", P.plot_l_formula, lf,
                            caption="Left: the L formula's predicted rig distance (m) and the ground-truth distance "
                                    "of complete visibility (m) against the bend angle (degrees), for a baseline "
                                    "along the bend axis and along the bend. Right: ground truth against prediction "
                                    "(m); points above the grey line mean the formula is too close."))
    # case table
    if rows:
        cols = [(k, t) for k, t in _CASE_COLUMNS if any(r.get(k) is not None for r in rows)]
        const = [(k, t) for k, t in cols if k not in ("bend_deg", "direction") and len(rows) > 1
                 and len({json.dumps(r.get(k), default=str) for r in rows}) == 1]
        cols = [c for c in cols if c not in const]
        if const:
            h.append(f"<h3>Cases ({len(rows)})</h3><p class=\"meta\">All cases: " + ", ".join(
                f"{_esc(t)} {_yn(_flag(rows[0].get(k))) if k in _BOOL_CASE else _fmt(rows[0].get(k), 3)}"
                for k, t in const) + ".</p>")
        else:
            h.append(f"<h3>Cases ({len(rows)})</h3>")
        body = []
        for r in rows[:MAX_TABLE_ROWS]:
            body.append([_yn(_flag(r.get(k))) if k in _BOOL_CASE else _fmt(r.get(k), 3) for k, _ in cols])
        h.append(_table([_esc(t) for _, t in cols], body, "cases"))
        if len(rows) > MAX_TABLE_ROWS:
            h.append(f'<p class="note">{len(rows) - MAX_TABLE_ROWS} more cases: see study.csv</p>')
        errs = [r for r in rows if str(r.get("status") or "ok") != "ok" or r.get("cure_error")]
        if errs:
            body = [[_fmt(r.get("bend_deg")), _esc(r.get("direction") or ""), _esc(r.get("status") or ""),
                     f'<span>{_esc(r.get("error") or r.get("cure_error") or "")}</span>'] for r in errs]
            t = _table(["bend (deg)", "direction", "status", "error"], body, "err")
            h.append(f"<h3>Failures ({len(errs)})</h3>" + t.replace("<td><span>", '<td class="msg"><span>'))
    else:
        h.append('<p class="note">the study holds no case rows.</p>')
    return "\n".join(h)


# ----------------------------------------------------------------------------- compare section
def _compare_section(path: Path, root: Path, plots: _Plots, prefix: str, anchor: str) -> str:
    from platebench.bench.report import plots as P  # noqa: PLC0415
    doc = _read_json(path) or {}
    methods = doc.get("methods") or {}
    h = [f'<h2 id="{anchor}">Method comparison: {_esc(_rel(path, root))}</h2>',
         f'<p class="meta">sample {_esc(doc.get("sample", "?"))}'
         + (f"; {_esc(doc['units'])}" if doc.get("units") else "") + "</p>"]
    cols = [("n_images", "images / camera"), ("depth_median_mm", "depth median (mm)"),
            ("depth_rms_mm", "depth RMS (mm)"), ("depth_p95_mm", "depth p95 (mm)"), ("depth_max_mm", "depth max (mm)"),
            ("coverage_pct", "coverage (%)"), ("points_on_plate", "points on plate"),
            ("surface_rms_mm", "surface RMS (mm)"), ("bad1", "Middlebury bad 1.0 (%)"), ("time_s", "time (s)"),
            ("render_s", "render (s)")]

    def cell(m, k):
        if k == "bad1":
            return ((m.get("middlebury") or {}).get("mb_all_bad_1_0_pct"))
        return m.get(k)

    cols = [c for c in cols if any(cell(m, c[0]) is not None for m in methods.values() if isinstance(m, dict))]
    body = [[_esc(n)] + [_fmt(cell(m, k)) for k, _ in cols] for n, m in methods.items() if isinstance(m, dict)]
    h.append(_table(["method"] + [t for _, t in cols], body))
    desc = [(n, m.get("description")) for n, m in methods.items() if isinstance(m, dict) and m.get("description")]
    if desc:
        h.append("<p class=\"meta\">" + "; ".join(f"<b>{_esc(n)}</b>: {_esc(d)}" for n, d in desc) + "</p>")
    for n in doc.get("notes") or []:
        h.append(f'<p class="note">{_esc(n)}</p>')
    table = {}
    for n, m in methods.items():
        if not isinstance(m, dict):
            continue
        e = {k: m.get(k) for k in ("depth_median_mm", "depth_rms_mm", "depth_max_mm", "surface_rms_mm")}
        cov = _num(m.get("coverage_pct"))
        e["coverage_frac"] = None if cov is None else cov / 100.0
        table[n] = e
    if table:
        h.append(plots.make(f"{prefix}compare", P.plot_method_comparison, table,
                            title=f"compare: {_rel(path, root)}",
                            caption="Depth error of each method on this sample (mm: median, RMS, max over plate "
                                    "pixels with an estimate, or over the paper's square centres; log scale when "
                                    "they span decades) and coverage of the plate (fraction 0..1, dense methods)."))
    return "\n".join(h)


# ----------------------------------------------------------------------------- the report
def _check_out_dir(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise ReportInputError(f"{out} exists and is not a directory")
    if out.is_dir():
        entries = [p for p in out.iterdir() if not p.name.startswith(".")]
        if not entries:
            return
        idx = out / "index.html"
        try:
            head = idx.read_text(errors="replace")[:2000] if idx.is_file() else ""
        except OSError:
            head = ""
        if f'content="{GENERATOR}"' not in head:
            raise ReportInputError(f"{out} is not empty and holds no PlateBench report: refusing to write into it "
                                   "(choose another --out)")


def _package_version() -> str:
    try:
        from importlib import metadata  # noqa: PLC0415
        return metadata.version("platebench")
    except Exception:  # noqa: BLE001
        return "?"


def write_report(input_dir, out_dir=None) -> Path:
    """Write the HTML report of whatever ``input_dir`` holds (see module doc); returns index.html's path.

    Raises ReportInputError (a ValueError, one line) when ``input_dir`` holds no dataset, no
    study and no compare.json, or when ``out_dir`` is a non-empty directory that is not a report."""
    root = Path(input_dir)
    if not root.is_dir():
        raise ReportInputError(f"{root}: directory is missing")
    inp = detect_inputs(root)
    if inp.empty:
        raise ReportInputError(f"{root} holds neither a sweep dataset (manifest.json / results.csv) nor a "
                               "false-boundary study (study.json / study.csv) nor a compare.json: nothing to report")
    out = Path(out_dir) if out_dir is not None else root / "report"
    _check_out_dir(out)
    out.mkdir(parents=True, exist_ok=True)
    sweep_stale(out)
    now = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    sections, toc = [], []
    with staged_directory(out / "plots", overwrite=True) as stage:
        plots = _Plots(stage)
        many = len(inp.datasets) + len(inp.studies) > 1
        for i, ds in enumerate(inp.datasets):
            anchor = f"dataset{i + 1}"
            prefix = f"{anchor}_" if many else "dataset_"
            sections.append(_dataset_section(ds, root, plots, prefix, anchor))
            toc.append((anchor, f"dataset {_rel(ds, root)}" if many else "sweep dataset"))
        for i, sd in enumerate(inp.studies):
            anchor = f"study{i + 1}"
            prefix = f"{anchor}_" if many else "study_"
            sections.append(_study_section(sd, root, plots, prefix, anchor))
            toc.append((anchor, f"study {_rel(sd, root)}" if many else "false-boundary study"))
        for i, cp in enumerate(inp.compares[:MAX_COMPARES]):
            anchor = f"compare{i + 1}"
            sections.append(_compare_section(cp, root, plots, f"compare{i + 1}_", anchor))
            toc.append((anchor, f"compare {_rel(cp.parent, root)}"))
        if len(inp.compares) > MAX_COMPARES:
            plots.notes.append(f"{len(inp.compares) - MAX_COMPARES} more compare.json files not shown")
    found = ", ".join(f"{n} {k}" for n, k in ((len(inp.datasets), "dataset(s)"), (len(inp.studies), "study(ies)"),
                                              (len(inp.compares), "compare.json file(s)")) if n)
    notes = "".join(f'<p class="note">{_esc(n)}</p>' for n in plots.notes)
    doc = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="generator" content="{GENERATOR}">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>PlateBench report: {_esc(root.resolve().name)}</title>
<style>{_CSS}</style></head>
<body><main>
<header><h1>PlateBench report</h1>
<p class="meta">input {_esc(root.resolve())} &middot; {_esc(found)} &middot; generated {_esc(now)} by platebench
{_esc(_package_version())} &middot; errors in mm, bend angles in degrees, distances in m</p></header>
<nav>{"".join(f'<a href="#{a}">{_esc(t)}</a>' for a, t in toc)}</nav>
{notes}
{"".join(sections)}
</main></body></html>
"""
    index = out / "index.html"
    write_text(index, doc)
    return index
