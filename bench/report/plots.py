"""Report plots (matplotlib, Agg): each function draws one figure and writes it as a PNG.

Every function takes plain data (table rows as dicts, a results frame, study rows, file
paths), draws on its own ``matplotlib.figure.Figure`` (no pyplot, so no global figure state
and no display), writes the PNG atomically (``bench.io.atomic.write_bytes``) and returns the
path. Missing columns or empty inputs give a figure that says so rather than an exception.
Labels of metrics come from ``evaluation.metrics_row.metric_label``, of parameters and axes
from ``bench.config.axes.parameter_label``; a flag is a bool (``values.flag``).

Units: errors in millimetres, bend angles in degrees, sensing distances in metres,
fractions in 0..1 (as the table columns name them).

Methods take their colours from one map (``bench.report.colours.method_colours``): a plot that
shows methods takes ``colours`` ({method: colour}, the report's map) and, without one, colours the
methods it shows in sorted order, so that a method has one colour in every figure.

No empty panels: a plot that can lose a panel takes ``left_out`` (a ``LeftOut``) and draws only the
panels with something to show, saying in ``left_out.panels`` which it dropped and why (one line
each); when nothing at all is left to show, ``left_out.figure`` says why, and the report shows
that line instead of the figure (``bench.report.page.Page.plot``). Called without ``left_out``, such
a plot still writes a figure that says it has nothing to show.
"""
from __future__ import annotations

import io
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from platebench.bench.config.axes import parameter_label
from platebench.bench.io.atomic import write_bytes
from platebench.bench.io.sweep_records import BEND_COLUMN, TRUTH_COLUMN
from platebench.bench.report.colours import colour_of
from platebench.bench.report.summary import FAILURE_KINDS, axis_stats, precision_recall
from platebench.bench.report.values import finite as _num
from platebench.bench.report.values import flag as _flag
from platebench.evaluation.metrics_row import METRIC_FIELDS, metric_label, metric_unit
from platebench.evaluation.stats import ErrorStats

__all__ = ["plot_error_vs_bend", "plot_detection_vs_bend", "plot_hidden_fraction_vs_bend",
           "plot_cure_success_vs_bend", "plot_l_formula", "plot_error_map", "plot_method_comparison",
           "plot_metric_vs_axis", "ErrorMapData", "error_map_data", "scored_per_point", "NOT_EVALUATED", "bend_bins",
           "compare_error_figure", "plot_output_error_map", "output_error_map_file",
           "output_file", "plot_accuracy_study", "LeftOut", "drawn"]

DPI = 100
_DIRECTION_STYLE = {"up": "-", "down": "--"}
_FLAG_LABELS = {"detected": "detected (either symptom)", "counting_test": "counting test",
                "arrays_disagree": "arrays disagree (Fig. 2)", "false_boundary_detected": "detected"}
# error metrics (mm) a method-comparison bar chart shows, in the results table's order; each is a group of
# bars of its own (the methods that report it), so that sparse and dense figures are never side by side
_BAR_METRICS = tuple(n for n, f in METRIC_FIELDS.items() if f.metadata["unit"] == "mm")
_MIN_COLOUR_RANGE_MM = 1e-3  # a colour scale spans at least this (mm): an exact method's zero errors still get one


@dataclass
class LeftOut:
    """What a plot left out (module doc): ``panels``, one line per panel dropped for having nothing to
    show; ``figure``, why the whole figure has nothing to show (None while it shows something)."""

    panels: list = field(default_factory=list)
    figure: str | None = None

    def panel(self, line: str) -> None:
        if line not in self.panels:
            self.panels.append(line)


def drawn(fn, *args, **kwargs) -> tuple[Path | None, LeftOut]:
    """``fn(*args, **kwargs)`` (a plot function of this module, or one with the same contract), with a
    fresh ``LeftOut`` where it takes one: (the PNG's path, what it left out); the path is None, and no
    PNG is left behind, when the figure has nothing to show (``LeftOut.figure`` says why)."""
    import inspect  # noqa: PLC0415
    left = LeftOut()
    if "left_out" in inspect.signature(fn).parameters:
        kwargs = {**kwargs, "left_out": left}
    path = Path(fn(*args, **kwargs))
    if left.figure is not None:
        path.unlink(missing_ok=True)
        return None, left
    return path, left


def _nothing(left_out: LeftOut | None, why: str) -> None:
    """Record that the whole figure has nothing to show (when the caller asked)."""
    if left_out is not None:
        left_out.figure = why


# ----------------------------------------------------------------------------- helpers
def _figure(w: float, h: float):
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: PLC0415
    from matplotlib.figure import Figure  # noqa: PLC0415
    fig = Figure(figsize=(w, h), dpi=DPI)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path) -> Path:
    """Render ``fig`` to PNG bytes and write them atomically; returns the path."""
    path = Path(path)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, metadata={"Software": None})
    write_bytes(path, buf.getvalue())
    return path


def _bend_key(v) -> float | None:
    x = _num(v)
    return None if x is None else round(x, 6)


def _bend(row) -> float | None:
    """A row's bend angle (degrees, rounded as ``_bend_key``; None when it has none)."""
    return _bend_key(row.get(BEND_COLUMN))


def _empty(ax, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, fontsize=10, color="0.35",
            wrap=True)
    ax.set_xticks([])
    ax.set_yticks([])


def _ok(row) -> bool:
    s = row.get("status")
    return s is None or str(s) == "ok"


def _groups(rows, keys):
    out: dict = {}
    for r in rows:
        out.setdefault(tuple(r.get(k) for k in keys), []).append(r)
    return out


def _colors(n: int):
    from matplotlib import colormaps  # noqa: PLC0415
    cmap = colormaps["tab10"]
    return [cmap(i % 10) for i in range(max(n, 1))]


def _positive_span(values) -> bool:
    """Log scale helps: positive values spanning more than two decades."""
    v = np.asarray([x for x in values if x is not None and x > 0], float)
    return v.size >= 2 and v.max() / v.min() > 30


# ----------------------------------------------------------------------------- error vs bend
def plot_error_vs_bend(rows, path, metrics=("centres_depth_rms_mm", "depth_rms_mm", "boundary_mean_mm"),
                       series=("method", "direction"),
                       title: str | None = None, colours: dict | None = None, left_out: LeftOut | None = None) -> Path:
    """One panel per metric with a value (others left out): error (mm) against bend angle (deg), one
    series per method and direction; a method has its colour (``colours``, module doc) and the
    direction its line style.

    Each sample is a dot; the line joins the medians at each bend. Rows whose status is
    not "ok" are drawn as red crosses on the bottom edge (a failure at that bend)."""
    rows = list(rows or [])
    shown = [m for m in metrics if any(_num(r.get(m)) is not None for r in rows)]
    if not shown:
        _nothing(left_out, "no row has an error value")
    metrics = shown or list(metrics[:1])
    fig = _figure(5.2 * len(metrics), 4.0)
    axes = fig.subplots(1, len(metrics), squeeze=False)[0]
    present = [k for k in series if any(r.get(k) not in (None, "") for r in rows)]
    series = [k for k in present if len({str(r.get(k)) for r in rows}) > 1] or present[:1]
    if "method" in present and "method" not in series:  # a method keeps its colour even when it is the only one
        series = ["method", *series]
    groups = _groups(rows, series)
    d_at = series.index("direction") if "direction" in series else None
    m_at = series.index("method") if "method" in series else None

    def colour_key(key):  # one colour per series apart from the direction (line style), if anything else varies
        rest = tuple(x for i, x in enumerate(key) if i != d_at)
        return rest if rest else key

    ckeys = sorted({colour_key(g) for g in groups}, key=lambda k: tuple(str(x) for x in k))
    if m_at is not None:  # colours by method, from the one map
        methods = sorted({str(k[m_at]) for k in groups})
        colors = {ck: colour_of(colours, g[m_at], methods) for g in groups for ck in [colour_key(g)]}
    else:
        colors = dict(zip(ckeys, _colors(len(ckeys))))
    for ax, metric in zip(axes, metrics):
        drawn, allv = False, []
        for key in sorted(groups, key=lambda k: tuple(str(x) for x in k)):
            grp = groups[key]
            pts = [(_bend(r), _num(r.get(metric))) for r in grp if _ok(r)]
            pts = [(b, v) for b, v in pts if b is not None and v is not None]
            label = _series_label(key, tuple(series)).replace(", ", " / ") if key else metric
            color = colors.get(colour_key(key), "C0")
            ls = _DIRECTION_STYLE.get(str(key[d_at]) if d_at is not None else "", "-")
            fails = sorted({_bend(r) for r in grp if not _ok(r)} - {None})
            if pts:
                b, v = np.array(pts).T
                allv.extend(v.tolist())
                ax.plot(b, v, "o", color=color, ms=3.5, alpha=0.45)
                ub = np.unique(b)
                med = [np.median(v[b == x]) for x in ub]
                ax.plot(ub, med, ls, color=color, marker="o", ms=5, lw=1.6, label=label)
                drawn = True
            if fails:
                ax.plot(fails, [0.0] * len(fails), "x", color="red", ms=8, mew=2, clip_on=False,
                        transform=ax.get_xaxis_transform(), label=f"{label}: failed")
                drawn = True
        if not drawn:
            _empty(ax, f"no {metric_label(metric)} values")
            continue
        if _positive_span(allv):
            ax.set_yscale("log")
        ax.set_xlabel("bend angle (deg)")
        ax.set_ylabel(metric_label(metric))
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(title or "Error against bend angle (dots: samples, line: median per bend)", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


# ----------------------------------------------------------------------------- detection
def bend_bins(bends, max_bins: int = 10) -> np.ndarray:
    """Bin edges over bend angles (deg): one bin per distinct value when there are few, else equal widths."""
    b = np.unique(np.asarray([x for x in bends if x is not None], float))
    if b.size == 0:
        return np.array([0.0, 1.0])
    if b.size == 1:
        return np.array([b[0] - 0.5, b[0] + 0.5])
    if b.size <= max_bins:
        mids = 0.5 * (b[1:] + b[:-1])
        return np.concatenate([[b[0] - (mids[0] - b[0])], mids, [b[-1] + (b[-1] - mids[-1])]])
    return np.linspace(b[0], np.nextafter(b[-1], np.inf), max_bins + 1)


def plot_detection_vs_bend(rows, path, flags=("detected", "counting_test", "arrays_disagree"),
                           gt_key: str = TRUTH_COLUMN, max_bins: int = 10, title: str | None = None,
                           left_out: LeftOut | None = None) -> Path:
    """Precision and recall of each detection flag against ground truth, per bend-angle bin.

    Grey bars (right axis): fraction of cases in the bin with a ground-truth false boundary.
    Precision is undefined (gap) in a bin with no positive verdict, recall in a bin with no
    ground-truth positive. A panel undefined in every bin is left out (``left_out``, module doc)."""
    rows = [r for r in (rows or []) if _bend(r) is not None and _flag(r.get(gt_key)) is not None]
    flags = [f for f in flags if any(_flag(r.get(f)) is not None for r in rows)]
    if not rows or not flags:
        _nothing(left_out, "no case has both a ground-truth and a detection verdict")
        fig = _figure(9.0, 4.4)
        for ax in fig.subplots(1, 2, sharex=True):
            _empty(ax, "no cases with both a ground-truth and a detection verdict")
        fig.tight_layout()
        return _save(fig, path)
    bends = [_bend(r) for r in rows]
    edges = bend_bins(bends, max_bins)
    idx = np.clip(np.digitize(bends, edges) - 1, 0, len(edges) - 2)
    centres = 0.5 * (edges[1:] + edges[:-1])
    width = np.diff(edges)
    bins = [[r for r, i in zip(rows, idx) if i == k] for k in range(len(centres))]
    gt_frac = np.array([np.mean([bool(_flag(r.get(gt_key))) for r in b]) if b else np.nan for b in bins])
    n = np.array([len(b) for b in bins])
    curves = {what: [np.array([np.nan if v is None else v for v in
                               (precision_recall(b, f, gt_key)[what] for b in bins)], float) for f in flags]
              for what in ("precision", "recall")}
    why = {"precision": "no positive verdict in any bin", "recall": "no ground-truth false boundary in any bin"}
    panels = [w for w in ("precision", "recall") if any(np.isfinite(y).any() for y in curves[w])]
    for w in ("precision", "recall"):
        if w not in panels and left_out is not None:
            left_out.panel(f"{w} panel left out: {w} is undefined in every bin ({why[w]})")
    if not panels:
        _nothing(left_out, "precision and recall are undefined in every bin (no positive verdict and no "
                           "ground-truth false boundary)")
    on = panels or ["precision", "recall"]
    fig = _figure(4.5 * len(on) + (0.5 if len(on) == 1 else 0.0), 4.4)
    axs = fig.subplots(1, len(on), sharex=True, squeeze=False)[0]
    for ax, what in zip(axs, on):
        tw = ax.twinx()
        tw.bar(centres, gt_frac, width=0.85 * width, color="0.85", zorder=0)
        tw.set_ylim(0, 1.05)
        tw.set_ylabel("fraction with GT false boundary", color="0.45", fontsize=8)
        tw.tick_params(axis="y", colors="0.45", labelsize=7)
        ax.set_zorder(tw.get_zorder() + 1)
        ax.patch.set_visible(False)
        for j, (f, y) in enumerate(zip(flags, curves[what])):
            dodge = (j - (len(flags) - 1) / 2) * 0.06 * width  # overlapping flags stay visible
            ax.plot(centres + dodge, y, marker="os^v"[j % 4], lw=1.5, ms=5, label=_FLAG_LABELS.get(f, f), color=f"C{j}")
        if what not in panels:
            ax.text(0.5, 0.5, f"{what} undefined everywhere:\n{why[what]}", ha="center", va="center",
                    transform=ax.transAxes, fontsize=9, color="0.35")
        crowded = width.min() < 0.06 * (edges[-1] - edges[0])  # narrow bins: vertical labels
        for c, k in zip(centres, n):
            ax.annotate(f"n={k}", (c, 1.0), xycoords=("data", "axes fraction"), xytext=(0, 3),
                        textcoords="offset points", ha="center", va="bottom", fontsize=6, color="0.4",
                        rotation=90 if crowded else 0, annotation_clip=False)
        ax.set_ylim(-0.03, 1.03)
        ax.set_xlabel("bend angle (deg, bin centre)")
        ax.set_ylabel(what)
        ax.grid(True, alpha=0.3)
        ax.set_title(f"detection {what} per bend bin", fontsize=9, pad=22 if crowded else 14)
    handles, labels = axs[-1].get_legend_handles_labels()
    fig.suptitle(title or "False-boundary detection against ground truth", fontsize=10)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    return _save(fig, path)


# ----------------------------------------------------------------------------- study: hidden fraction
def _hidden(r) -> float | None:
    vals = [_num(r.get(k)) for k in ("hidden_frac_left", "hidden_frac_right")]
    vals = [v for v in vals if v is not None]
    return max(vals) if vals else None


def _detected_any(r) -> bool | None:
    """The pipeline's false-boundary verdict ("detected"), else any of the symptom flags."""
    if _flag(r.get("detected")) is not None:
        return _flag(r.get("detected"))
    vals = [_flag(r.get(k)) for k in ("false_boundary_detected", "counting_test", "arrays_disagree")]
    vals = [v for v in vals if v is not None]
    return any(vals) if vals else None


def _series_label(key: tuple, names: tuple) -> str:
    units = {"aspect": "aspect ", "distance_m": "", "axis_deg": "axis "}
    suffix = {"distance_m": " m", "axis_deg": " deg"}
    parts = []
    for k, v in zip(names, key):
        x = _num(v) if not isinstance(v, str) else None
        parts.append(f"{units.get(k, '')}{x:g}{suffix.get(k, '')}" if x is not None
                     else str(v if v is not None else "-"))
    return ", ".join(parts)


def plot_hidden_fraction_vs_bend(rows, path, smallest_hiding: dict | None = None, series=("direction",),
                                 title: str | None = None) -> Path:
    """Top: fraction of the true boundary hidden from the worse camera (0..1) against bend (deg),
    one line per series (direction, and aspect / distance when they vary). Bottom: per case, ground
    truth (a false boundary exists) and the pipeline's verdict: filled = yes, hollow = no, grey
    x = no verdict (reconstruction failed)."""
    rows = [r for r in (rows or []) if _bend(r) is not None]
    series = tuple(series) or ("direction",)
    keyf = lambda r: tuple(r.get(k) for k in series)  # noqa: E731
    keys = sorted({keyf(r) for r in rows}, key=lambda k: tuple(str(x) for x in k))
    n_events = 2 * max(len(keys), 1)
    fig = _figure(9.0, 4.0 + 0.22 * n_events)
    gs = fig.add_gridspec(2, 1, height_ratios=[3.0, 0.3 + 0.25 * n_events], hspace=0.08)
    ax = fig.add_subplot(gs[0])
    ev = fig.add_subplot(gs[1], sharex=ax)
    if not rows:
        _empty(ax, "no study cases")
        ev.set_axis_off()
        return _save(fig, path)
    colors = dict(zip(keys, _colors(len(keys))))
    markers = "os^vD<>p"
    for j, key in enumerate(keys):
        grp = sorted((r for r in rows if keyf(r) == key), key=lambda r: _bend(r))
        label = _series_label(key, series)
        pts = [(_bend(r), _hidden(r)) for r in grp]
        pts = [(b, h) for b, h in pts if h is not None]
        if pts:
            b, h = np.array(pts).T
            ax.plot(b, h, "-", marker=markers[j % len(markers)], color=colors[key], ms=4, lw=1.4,
                    label=f"{label}: worse camera")
        for side, mk in (("left", "<"), ("right", ">")):
            p2 = [(_bend(r), _num(r.get(f"hidden_frac_{side}"))) for r in grp]
            p2 = [(b, h) for b, h in p2 if h is not None]
            if p2 and len(keys) <= 4:
                b, h = np.array(p2).T
                ax.plot(b, h, mk, color=colors[key], ms=4, alpha=0.4, mfc="none")
    for d, hb in sorted((smallest_hiding or {}).items()):
        hb = _num(hb)
        if hb is None:
            continue
        c = next((colors[k] for k in keys if "direction" in series and str(k[series.index("direction")]) == d), "0.3")
        ax.axvline(hb, color=c, ls=":", lw=1.2)
        ax.annotate(f"first hiding bend ({d}) {hb:.1f} deg", (hb, 0.98), xycoords=("data", "axes fraction"),
                    xytext=(-3, 0), textcoords="offset points", rotation=90, va="top", ha="right", fontsize=7,
                    color=c)
    ax.set_ylabel("hidden fraction of true boundary (0..1)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    ax.tick_params(labelbottom=False)
    labels = []
    for j, key in enumerate(keys):
        name = _series_label(key, series)
        for k, (what, get) in enumerate((("GT false boundary", lambda r: _flag(r.get(TRUTH_COLUMN))),
                                         ("detected", _detected_any))):
            y = j * 2 + k
            labels.append((y, f"{name}: {what}"))
            for r in rows:
                if keyf(r) != key:
                    continue
                b, v = _bend(r), get(r)
                if v is None:
                    ev.plot(b, y, "x", color="0.5", ms=6)
                else:
                    ev.plot(b, y, "o" if k == 0 else "s", ms=6, color=colors[key], mfc=colors[key] if v else "white")
    ev.set_yticks([y for y, _ in labels])
    ev.set_yticklabels([t for _, t in labels], fontsize=7)
    ev.set_ylim(-0.6, len(labels) - 0.4)
    ev.invert_yaxis()
    ev.set_xlabel("bend angle (deg)")
    ev.grid(True, axis="x", alpha=0.3)
    fig.suptitle(title or "How much of the true boundary the default pose hides, by bend", fontsize=10)
    fig.subplots_adjust(left=0.26 if len(series) > 1 else 0.2, right=0.97, top=0.93, bottom=0.08)
    return _save(fig, path)


# ----------------------------------------------------------------------------- study: cures
def plot_cure_success_vs_bend(rows, path, title: str | None = None, left_out: LeftOut | None = None) -> Path:
    """Cases with a ground-truth false boundary: left, fraction of cases each cure removes it
    (the boundary fully visible at the new pose) per bend; right, hidden fraction (0..1) before
    and after each cure."""
    rows = [r for r in (rows or []) if _bend(r) is not None and _flag(r.get(TRUTH_COLUMN))]
    cures = [("cure1", "cure 1: orient (look along the tangent)"), ("cure2", "cure 2: move back")]
    fig = _figure(10.0, 4.0)
    a1, a2 = fig.subplots(1, 2, sharex=True)
    tried = [r for r in rows if any(_flag(r.get(f"{c}_removed")) is not None for c, _ in cures)]
    if not tried:
        _nothing(left_out, "no case with a ground-truth false boundary has a cure result")
        for ax in (a1, a2):
            _empty(ax, "no case with a ground-truth false boundary and a cure result")
        fig.tight_layout()
        return _save(fig, path)
    bends = sorted({_bend(r) for r in tried})
    for j, (c, label) in enumerate(cures):
        rate, ns = [], []
        for b in bends:
            vals = [_flag(r.get(f"{c}_removed")) for r in tried if _bend(r) == b]
            vals = [v for v in vals if v is not None]
            rate.append(np.mean(vals) if vals else np.nan)
            ns.append(len(vals))
        off = (j - 0.5) * 0.6
        a1.plot(np.array(bends) + off, rate, "o-", ms=6, lw=1.4, color=f"C{j}", label=label)
        pts = [(_bend(r), _num(r.get(f"{c}_hidden_frac"))) for r in tried]
        pts = sorted(((b, h) for b, h in pts if h is not None), key=lambda t: t[0])
        if pts:
            b, h = np.array(pts).T
            a2.plot(b + off, h, "o", ms=5, color=f"C{j}", label=f"after {c}")
    for b, k in zip(bends, [sum(1 for r in tried if _bend(r) == b) for b in bends]):
        a1.annotate(f"n={k}", (b, 1.0), xycoords=("data", "axes fraction"), xytext=(0, 3),
                    textcoords="offset points", ha="center", fontsize=6, color="0.4", annotation_clip=False)
    before = sorted(((_bend(r), _hidden(r)) for r in tried if _hidden(r) is not None),
                    key=lambda t: t[0])
    if before:
        b, h = np.array(before).T
        a2.plot(b, h, "k_", ms=12, mew=2, label="before (default pose)")
    a1.set_ylim(-0.05, 1.05)
    a1.set_ylabel("fraction of cases cured (0..1)")
    a1.set_title("cure success rate", fontsize=9, pad=14)
    a2.set_ylabel("hidden fraction of true boundary (0..1)")
    a2.set_title("hidden boundary before / after", fontsize=9, pad=14)
    for ax in (a1, a2):
        ax.set_xlabel("bend angle (deg)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    fig.suptitle(title or "The paper's two cures, checked by ground-truth visibility", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


# ----------------------------------------------------------------------------- study: L formula
def plot_l_formula(rows, path, title: str | None = None, left_out: LeftOut | None = None) -> Path:
    """Left: the L formula's predicted rig distance (m) and the ground-truth distance of complete
    visibility (m) against bend (deg), for both baselines. Right: ground truth against prediction
    (m) with the identity line. ``rows``: ``bench.io.records.LFormulaRow``s."""
    rows = [r for r in (rows or []) if _bend_key(r.bend_deg) is not None]
    fig = _figure(10.0, 4.2)
    a1, a2 = fig.subplots(1, 2)
    series = [(lambda r: r.gt_distance_baseline_along_axis_m, "GT, baseline along the bend axis", "s"),
              (lambda r: r.gt_distance_baseline_along_bend_m, "GT, baseline along the bend", "^")]
    pred = [(_bend_key(r.bend_deg), _num(r.predicted_distance_m)) for r in rows]
    pred = sorted((b, p) for b, p in pred if p is not None)
    if not pred:
        _nothing(left_out, "no L-formula row has a predicted distance")
        for ax in (a1, a2):
            _empty(ax, "no L-formula rows")
        fig.tight_layout()
        return _save(fig, path)
    b, p = np.array(pred).T
    a1.plot(b, p, "k-o", ms=4, lw=1.6, label="predicted: L + height of AB")
    lo = hi = None
    for j, (gt, label, mk) in enumerate(series):
        pts = sorted(((_bend_key(r.bend_deg), _num(gt(r)), _num(r.predicted_distance_m)) for r in rows),
                     key=lambda t: t[0])
        good = [(x, g, q) for x, g, q in pts if g is not None and q is not None]
        # an infinite distance: never fully visible (None: not computed)
        never = sorted({_bend_key(r.bend_deg) for r in rows if gt(r) is not None and _num(gt(r)) is None})
        if good:
            x, g, q = np.array(good).T
            a1.plot(x, g, mk + "--", ms=5, lw=1.2, color=f"C{j}", label=label)
            a2.plot(q, g, mk, ms=6, color=f"C{j}", label=label)
            lo = min(lo if lo is not None else np.inf, q.min(), g.min())
            hi = max(hi if hi is not None else -np.inf, q.max(), g.max())
        if never:
            a1.plot(never, [1.0] * len(never), mk, color=f"C{j}", mfc="none", ms=7, clip_on=False,
                    transform=a1.get_xaxis_transform(), label=f"{label}: never fully visible")
    a1.set_xlabel("bend angle (deg)")
    a1.set_ylabel("rig distance above plate centre (m)")
    a1.grid(True, alpha=0.3)
    a1.legend(fontsize=7, loc="best")
    a1.set_title("predicted vs ground-truth distance", fontsize=9)
    if lo is not None:
        pad = 0.05 * (hi - lo if hi > lo else 1.0)
        a2.plot([lo - pad, hi + pad], [lo - pad, hi + pad], color="0.5", lw=1, label="GT = predicted")
        a2.set_xlim(lo - pad, hi + pad)
        a2.set_ylim(lo - pad, hi + pad)
        a2.set_aspect("equal", adjustable="box")
        a2.legend(fontsize=7, loc="upper left")
    else:
        _empty(a2, "no finite ground-truth distance")
        if left_out is not None:
            left_out.panel("ground truth against prediction: no finite ground-truth distance to plot")
    a2.set_xlabel("predicted distance (m)")
    a2.set_ylabel("ground-truth distance (m)")
    a2.grid(True, alpha=0.3)
    a2.set_title("ground truth against prediction", fontsize=9)
    fig.suptitle(title or "The paper's L formula: distance at which the whole boundary is visible", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


# ----------------------------------------------------------------------------- method comparison
def plot_method_comparison(table: dict, path, metrics=None, title: str | None = None, colours: dict | None = None,
                           left_out: LeftOut | None = None) -> Path:
    """Grouped bars: one group per error metric (mm, log scale when values span decades), with a bar
    for each method that reports it (one column, one meaning: a group never mixes the paper's
    square centres with a dense map's pixels); a second panel for coverage (fraction of the plate,
    0..1) when present. A method has its colour (``colours``, module doc); a panel with no value is
    left out (``left_out``).

    ``table``: {method: {metric: value}} (e.g. the mean over a sweep's samples, or compare.json)."""
    table = {str(m): dict(v or {}) for m, v in (table or {}).items()}
    methods = list(table)
    if metrics is None:
        metrics = _BAR_METRICS
    # the shared columns in fractions (coverage) go to the second panel, by their unit (``MetricsRow``)
    fractions = [k for k in METRIC_FIELDS if metric_unit(k) == "fraction"]
    err_metrics = [k for k in metrics if k not in fractions
                   and any(_num(t.get(k)) is not None for t in table.values())]
    cov = "coverage_frac"  # the share of the plate's pixels with an estimate (``evaluation.pixel_coverage``)
    has_cov = any(_num(t.get(cov)) is not None for t in table.values())
    colors = [colour_of(colours, m, methods) for m in methods]
    if not methods or not (err_metrics or has_cov):
        _nothing(left_out, "no method reports an error in mm or a coverage")
    elif not err_metrics and left_out is not None:
        left_out.panel("error panel left out: no method reports an error in mm")
    if has_cov and not err_metrics:
        fig = _figure(4.0, 4.2)
        ax, axc = None, fig.add_subplot(111)
    elif has_cov:
        fig = _figure(9.5, 4.2)
        gs = fig.add_gridspec(1, 2, width_ratios=[3, 1.2])
        ax, axc = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    else:
        fig = _figure(7.5, 4.2)
        ax, axc = fig.add_subplot(111), None
    if ax is None:
        pass
    elif not methods or not err_metrics:
        _empty(ax, "no method metrics to compare")
    else:
        w = 0.8 / len(methods)
        x = np.arange(len(err_metrics))
        allv = []
        for j, m in enumerate(methods):
            v = np.array([np.nan if _num(table[m].get(k)) is None else _num(table[m].get(k)) for k in err_metrics])
            allv.extend(v[np.isfinite(v)].tolist())
            bars = ax.bar(x + (j - (len(methods) - 1) / 2) * w, np.where(np.isfinite(v), v, 0), w, color=colors[j],
                          label=m)
            for rect, val in zip(bars, v):
                if np.isfinite(val):
                    ax.annotate(f"{val:.3g}", (rect.get_x() + rect.get_width() / 2, rect.get_height()),
                                xytext=(0, 2), textcoords="offset points", ha="center", fontsize=6, rotation=90)
        if _positive_span(allv):
            ax.set_yscale("log")
        ax.set_xticks(x)
        ax.set_xticklabels([metric_label(k).replace(" (mm)", "") for k in err_metrics], rotation=20, ha="right",
                           fontsize=8)
        ax.set_ylabel("error (mm)")
        ax.margins(y=0.15)
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    if axc is not None:
        vals = [(m, _num(table[m].get(cov))) for m in methods]
        for j, (m, v) in enumerate(vals):
            if v is not None:
                axc.bar(j, v, color=colors[j])
                axc.annotate(f"{v:.2f}", (j, v), xytext=(0, 2), textcoords="offset points", ha="center", fontsize=7)
        axc.set_xticks(range(len(methods)))
        axc.set_xticklabels(methods, rotation=30, ha="right", fontsize=8)
        axc.set_ylim(0, 1.1)
        axc.set_ylabel("coverage (share of plate pixels, 0..1)")
        axc.grid(True, axis="y", alpha=0.3)
    fig.suptitle(title or "Method comparison", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


# ----------------------------------------------------------------------------- metric against a swept axis
@dataclass(frozen=True)
class _XAxis:
    """Where the levels of a swept axis go on the x axis, and each method's small sideways offset
    (so that equal values, such as a failure rate of 0, stay visible)."""

    levels: list
    xs: np.ndarray
    numeric: bool
    logx: bool
    step: float
    methods: tuple

    @classmethod
    def of(cls, stats: dict) -> "_XAxis":
        xs = np.array([lv["x"] for lv in stats["levels"]], float)
        numeric = stats["numeric"]
        logx = bool(numeric and xs.min() > 0 and xs.max() / xs.min() > 20)
        if numeric and len(xs) > 1:
            step = 0.012 * ((np.log10(xs.max() / xs.min()) if logx else xs.max() - xs.min()) or 1.0)
        else:
            step = 0.06 if not numeric else 0.01 * (abs(xs[0]) or 1.0)
        return cls(stats["levels"], xs, numeric, logx, float(step), tuple(stats["methods"]))

    def x(self, level_x: float, method: str) -> float:
        d = (self.methods.index(method) - (len(self.methods) - 1) / 2) * self.step
        return level_x * 10 ** d if self.logx else level_x + d

    def format(self, ax, label: str) -> None:
        if self.logx:
            ax.set_xscale("log")
        if not self.numeric or len(self.levels) <= 12:
            ax.set_xticks(self.xs)
            ax.set_xticklabels([lv["label"] for lv in self.levels], fontsize=8,
                               rotation=30 if any(len(lv["label"]) > 6 for lv in self.levels) else 0)
            if self.logx:
                ax.xaxis.set_minor_formatter(_null_formatter())
        lo, hi = float(self.xs.min()), float(self.xs.max())
        if not self.numeric:
            ax.set_xlim(lo - 0.5, hi + 0.5)
        elif self.logx:
            f = (hi / lo) ** 0.06
            ax.set_xlim(lo / f, hi * f)
        else:
            pad = 0.06 * (hi - lo) if hi > lo else 0.1 * (abs(lo) or 1.0)
            ax.set_xlim(lo - pad, hi + pad)
        ax.set_xlabel(label)


def _any_failure(cell: dict) -> bool:
    return any(cell[kind] for kind, _, _ in FAILURE_KINDS)


def _draw_metric_panel(ax, st: dict, xa: _XAxis, style: dict) -> None:
    """Median of the metric per level and method (line), the samples (faint dots), a hollow median
    marker where some rows at that level failed in any way, a cross on the bottom edge where no
    row of the method gave a value."""
    allv, drawn = [], False
    for m in xa.methods:
        cells = [(lv, st["cells"].get((m, lv["key"]))) for lv in xa.levels]
        cells = [(xa.x(lv["x"], m), c) for lv, c in cells if c is not None]
        if not any(c["values"] for _, c in cells):
            continue  # the method never gives this metric: nothing to draw
        color, marker = style[m]
        med = [(x, c["median"], _any_failure(c)) for x, c in cells if c["median"] is not None]
        dots = [(x, v) for x, c in cells for v in c["values"]]
        none_x = [x for x, c in cells if c["median"] is None]
        allv += [v for _, v in dots]
        if len(dots) > len(med):
            ax.plot(*zip(*dots), marker, color=color, ms=3, alpha=0.35, mfc="none")
        ax.plot([x for x, _, _ in med], [y for _, y, _ in med], "-", marker=marker, color=color, ms=6, lw=1.7,
                label=m)
        hollow = [(x, y) for x, y, bad in med if bad]
        if hollow:
            ax.plot(*zip(*hollow), marker, color=color, ms=6, mfc="white", mew=1.5)
        if none_x:
            ax.plot(none_x, [0.0] * len(none_x), "x", color=color, ms=9, mew=2, clip_on=False,
                    transform=ax.get_xaxis_transform(), label=f"{m}: no value")
        drawn = True
    label = metric_label(st["metric"])
    if not drawn:
        _empty(ax, f"no {label} values")
        return
    pos = [v for v in allv if v > 0]
    if len(pos) >= 2 and max(pos) / min(pos) > 10:
        ax.set_yscale("log")
        ax.grid(True, which="minor", axis="y", alpha=0.1)
    ax.set_ylabel(label + ", median")
    ax.set_title(f"{label} (line: median, dots: samples)", fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="best")


def _draw_rate_panel(ax, st: dict, xa: _XAxis, style: dict, kind: str, denominator: str, title: str) -> None:
    """The fraction (0..1) of each method's rows at each level that failed in one way, "k/n" printed
    where k > 0; a method without a single row that can say (no verdict) is left out."""
    stacked: dict = {}  # labels at the same point go one above the other
    drawn = False
    for m in xa.methods:
        pts = [(xa.x(lv["x"], m), lv["key"], st["cells"].get((m, lv["key"]))) for lv in xa.levels]
        pts = [(x, key, c[kind], c[denominator]) for x, key, c in pts if c is not None and c[denominator]]
        if not pts:
            continue
        color, marker = style[m]
        ax.plot([p[0] for p in pts], [k / n for _, _, k, n in pts], "-", marker=marker, color=color, ms=6, lw=1.5,
                label=m)
        for x, key, k, n in pts:
            if k:
                at = (key, round(k / n, 6))
                j = stacked[at] = stacked.get(at, -1) + 1
                ax.annotate(f"{k}/{n}", (x, k / n), xytext=(4, 3 + 9 * j), textcoords="offset points", fontsize=7,
                            color=color)
        drawn = True
    ax.set_title(f"{title} (fraction of rows)", fontsize=9)
    if not drawn:
        _empty(ax, f"no row can say: {title}")
        return
    ax.set_ylim(-0.05, 1.08)
    ax.set_ylabel("rate (0..1)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="best")


def plot_metric_vs_axis(frame, axis: str, path, metrics=("centres_depth_rms_mm",), title: str | None = None,
                        pooled: dict | None = None, max_levels: int = 10, colours: dict | None = None,
                        left_out: LeftOut | None = None) -> Path:
    """A results frame against one swept ``axis`` (a results column): per metric, the median over
    samples at each level, one line per method (``_draw_metric_panel``); then one panel per kind
    of failure (``summary.FAILURE_KINDS``: crashed, paper's bound violated, points mismatched),
    each method's rate at each level (``_draw_rate_panel``).

    Numeric axes are drawn on their values (log x when all are positive and span more than a
    factor 20), categorical ones (noise none < low < medium < high, ...) as ordered categories.
    ``pooled`` ({column: [labels]}) names the other axes that vary and are pooled into each
    point; it goes under the title. Methods have their colours (``colours``, module doc); a panel with
    nothing to show (a metric no row gives, a kind of failure no row can say) is left out
    (``left_out``)."""
    metrics = [m for m in metrics if m in frame.columns and frame[m].notna().any()] or list(metrics[:1])
    stats = [axis_stats(frame, axis, m, max_levels) for m in metrics]
    if not stats[0]["levels"]:
        _nothing(left_out, f"no row has a value of {parameter_label(axis)}")
    else:  # the panels with something to show
        keep = [st for st in stats if any(c["values"] for c in st["cells"].values())]
        for st in stats:
            if st not in keep and left_out is not None:
                left_out.panel(f"{metric_label(st['metric'])} panel left out: no row gives a value")
        kinds = [k for k in FAILURE_KINDS if any(c[k[1]] for c in stats[0]["cells"].values())]
        for _, _, label in FAILURE_KINDS:
            if label not in [k[2] for k in kinds] and left_out is not None:
                left_out.panel(f"'{label}' panel left out: no row of any method can say")
        if keep or kinds:
            return _metric_vs_axis_panels(stats[0], keep, kinds, axis, path, title, pooled, colours)
        _nothing(left_out, f"no row gives a value of {', '.join(metric_label(m) for m in metrics)}")
    fig = _figure(11.0, 4.2)
    fig.suptitle(_axis_title(axis, title, pooled), fontsize=10)
    _empty(fig.add_subplot(111), f"no rows with a value of {parameter_label(axis)}")
    fig.tight_layout()
    return _save(fig, path)


def _axis_title(axis: str, title: str | None, pooled: dict | None) -> str:
    head = title or f"Error and failures against {parameter_label(axis)}"
    if pooled:
        head += "\n(pooled over " + "; ".join(f"{parameter_label(k)}: {', '.join(map(str, v))}"
                                               for k, v in pooled.items()) + ")"
    return head


def _metric_vs_axis_panels(first: dict, stats: list, kinds: list, axis: str, path, title, pooled, colours) -> Path:
    """``plot_metric_vs_axis``'s figure: a panel per metric of ``stats``, then per kind of failure of ``kinds``."""
    n_panels = len(stats) + len(kinds)
    rows = -(-n_panels // 2)
    fig = _figure(11.0, 3.5 * rows + 0.7)
    axes = fig.subplots(rows, 2, squeeze=False).ravel()
    for ax in axes[n_panels:]:
        ax.set_axis_off()
    label_x = parameter_label(axis)
    fig.suptitle(_axis_title(axis, title, pooled), fontsize=10)
    xa = _XAxis.of(first)
    style = {m: (colour_of(colours, m, xa.methods), mk) for m, mk in zip(xa.methods, "osD^v<>p*h" * 3)}
    for ax, st in zip(axes, stats):
        _draw_metric_panel(ax, st, xa, style)
    for ax, (kind, denominator, label) in zip(axes[len(stats):], kinds):
        _draw_rate_panel(ax, first, xa, style, kind, denominator, label)
    for ax in axes[:n_panels]:
        xa.format(ax, label_x)
    fig.tight_layout()
    return _save(fig, path)


def _null_formatter():
    from matplotlib.ticker import NullFormatter  # noqa: PLC0415
    return NullFormatter()


# ----------------------------------------------------------------------------- error map
@dataclass(frozen=True, eq=False)
class ErrorMapData:
    """What the error map shows (world frame, metres; errors in millimetres): the true outline (N,3;
    None: not in the sample), the reconstructed boundary (M,3; None: none), the reconstructed
    surface's vertices (V,3), faces (F,3) and each vertex's exact distance to the true mesh (V,; all
    None: no surface), the square centres (P,3), their error (P,) and its kind per centre (P,:
    "3d", the 3D error against the true centre, or "surface", the distance to the true surface where
    the identity is unknown), and the centres' feature ids."""

    gt_boundary: np.ndarray | None
    rec_boundary: np.ndarray | None
    centres: np.ndarray
    feature_id: np.ndarray | None = None
    surface_vertices: np.ndarray | None = None
    surface_faces: np.ndarray | None = None
    surface_dist_mm: np.ndarray | None = None
    centre_err_mm: np.ndarray = field(default_factory=lambda: np.zeros(0))
    centre_kind: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype="<U7"))


NOT_EVALUATED = "not evaluated (run 'platebench evaluate')"


def error_map_data(sample_dir, recon_dir, per_point=None) -> ErrorMapData:
    """What the error map shows (``ErrorMapData``), from a sample directory, a reconstruction
    directory and the per-point errors its score.json holds (``per_point``: the parsed
    ``evaluation.score.PerPointErrors``, metres; millimetres out): the GT outline, the reconstructed
    surface's vertices and faces with their exact distance to the GT mesh, the reconstructed
    boundary, and the square centres with their 3D error against the true centre, or, where the
    identity is unknown, their distance to the true surface (``centre_kind`` says which). Raises
    ``ValueError`` (``NOT_EVALUATED``) when ``per_point`` is None or does not fit the reconstruction
    (``scored_per_point``), and what reading the files raises (``OSError``, ``DatasetError``)."""
    from platebench.bench.io.images import read_npy  # noqa: PLC0415
    from platebench.bench.io.recon_files import load_reconstruction  # noqa: PLC0415

    sample_dir, recon_dir = Path(sample_dir), Path(recon_dir)
    gt_boundary = read_npy(sample_dir / "boundary.npy", (None, 3)) if (sample_dir / "boundary.npy").is_file() \
        else None
    rec = load_reconstruction(recon_dir)
    has_surface = rec.surface is not None and len(rec.surface.vertices) > 0
    per = scored_per_point(per_point, len(rec.points), len(rec.surface.vertices) if has_surface else 0)
    out = dict(gt_boundary=gt_boundary, rec_boundary=rec.boundary if len(rec.boundary) else None, centres=rec.points,
               feature_id=rec.feature_id)
    mm = 1e3
    if has_surface:
        out.update(surface_vertices=np.asarray(rec.surface.vertices, float),
                   surface_faces=np.asarray(rec.surface.faces, int), surface_dist_mm=per.surface_distance_m * mm)
    if len(rec.points):
        out.update(centre_err_mm=per.centre_error_m * mm,
                   centre_kind=np.where(per.centre_known, "3d", "surface").astype("<U7"))
    return ErrorMapData(**out)


def scored_per_point(per_point, n_points: int, n_vertices: int):
    """``per_point`` (the ``evaluation.score.PerPointErrors`` of a parsed score.json, metres) when it
    holds errors for ``n_points`` centres and ``n_vertices`` surface vertices; a reconstruction
    without centres or surface needs none. Raises ``ValueError`` (``NOT_EVALUATED``) when it is None
    (not evaluated) or scores another reconstruction. The report never scores."""
    from platebench.evaluation.score import PerPointErrors  # noqa: PLC0415

    if per_point is None:
        if n_points == 0 and n_vertices == 0:
            return PerPointErrors(np.zeros(0), np.zeros(0, bool))
        raise ValueError(NOT_EVALUATED)
    surf = per_point.surface_distance_m
    if len(per_point.centre_error_m) != n_points or (len(surf) if surf is not None else 0) != n_vertices:
        raise ValueError(f"score.json scores another reconstruction: {NOT_EVALUATED}")
    return per_point


def _outline(ax, d: ErrorMapData) -> None:
    """The true boundary (black), closed, in mm."""
    if d.gt_boundary is not None and len(d.gt_boundary):
        b = np.vstack([d.gt_boundary, d.gt_boundary[:1]]) * 1e3
        ax.plot(b[:, 0], b[:, 1], "k-", lw=1.2, label="true boundary")


def _draw_surface_panel(fig, ax, d: ErrorMapData) -> None:
    """The reconstructed surface coloured by its distance to the true mesh (mm), both boundaries."""
    from matplotlib.tri import Triangulation  # noqa: PLC0415
    if d.surface_vertices is not None and len(d.surface_faces):
        v = d.surface_vertices * 1e3
        dist = d.surface_dist_mm
        vmax = float(np.percentile(dist, 99)) if dist.size else 1.0
        im = ax.tripcolor(Triangulation(v[:, 0], v[:, 1], d.surface_faces), dist, shading="gouraud",
                          cmap="viridis", vmin=0.0, vmax=max(vmax, _MIN_COLOUR_RANGE_MM))
        fig.colorbar(im, ax=ax, fraction=0.046, pad=0.03, label="distance to true surface (mm)")
        st = ErrorStats.from_abs(dist, name="surface distance")
        ax.set_title(f"surface: RMS {st.rms:.3f} mm, max {st.max:.3f} mm ({len(v)} vertices)", fontsize=9)
    else:
        ax.set_title("no reconstructed surface", fontsize=9)
    _outline(ax, d)
    if d.rec_boundary is not None:
        rb = np.vstack([d.rec_boundary, d.rec_boundary[:1]]) * 1e3
        ax.plot(rb[:, 0], rb[:, 1], "--", color="red", lw=1.1, label="reconstructed boundary")
    ax.legend(fontsize=7, loc="upper right", ncol=2, framealpha=0.85)


def _draw_centres_panel(fig, ax, d: ErrorMapData) -> None:
    """The square centres coloured by their 3D error against the true centres (mm; diamonds: identity
    unknown, distance to the surface), values printed above each when there are few."""
    _outline(ax, d)
    pts, err, kind = d.centres, d.centre_err_mm, d.centre_kind
    if not len(pts):
        ax.set_title("no triangulated square centres", fontsize=9)
        return
    p = pts * 1e3
    style = dict(cmap="plasma", vmin=0, vmax=max(float(err.max()), _MIN_COLOUR_RANGE_MM), s=70, edgecolors="k",
                 linewidths=0.6,
                 zorder=3)
    three = kind == "3d"
    sc = []
    if three.any():
        sc.append(ax.scatter(p[three, 0], p[three, 1], c=err[three], label="3D error vs true centre", **style))
    if (~three).any():
        sc.append(ax.scatter(p[~three, 0], p[~three, 1], c=err[~three], marker="D",
                             label="identity unknown: distance to surface", **style))
    fig.colorbar(sc[0], ax=ax, fraction=0.046, pad=0.03, label="square-centre error (mm)")
    if len(p) <= 40:
        for (x, y, _), e in zip(p, err):
            ax.annotate(f"{e:.2f}", (x, y), xytext=(0, 7), textcoords="offset points", ha="center", fontsize=6)
    rms = ErrorStats.from_abs(err[three], name="centre error").rms if three.any() else float("nan")
    ax.set_title(f"square centres: {len(p)} points, 3D RMS {rms:.3f} mm", fontsize=9)
    ax.legend(fontsize=7, loc="upper right", ncol=2, framealpha=0.85)


def _same_window(axes, d: ErrorMapData) -> None:
    """The same window on every panel, equal scales, world X/Y in mm, headroom for the legend."""
    xy = [a[:, :2] for a in (d.gt_boundary, d.rec_boundary, d.surface_vertices, d.centres)
          if a is not None and len(a)]
    for ax in axes:
        if xy:
            pts = np.vstack(xy) * 1e3
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            pad = 0.08 * max(float((hi - lo).max()), 1.0)
            ax.set_xlim(lo[0] - pad, hi[0] + pad)
            ax.set_ylim(lo[1] - pad, hi[1] + pad + 0.22 * max(float(hi[1] - lo[1]), 1.0))
        ax.set_xlabel("world X (mm)")
        ax.set_ylabel("world Y (mm)")
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, alpha=0.25)


def plot_error_map(sample_dir, recon_dir, path, title: str | None = None, data: ErrorMapData | None = None,
                   per_point=None) -> Path:
    """Error map over the plate, top view in world X/Y (mm): left, the reconstructed surface
    coloured by its exact distance to the ground-truth mesh (mm), with the true boundary (black)
    and the reconstructed one (red dashed); right, the triangulated square centres coloured by
    their 3D error (mm) over the true outline. Drawn from ``data``, or else from the scored
    per-point errors ``per_point`` (the parsed score.json's, ``error_map_data``). Without them
    (not evaluated), or with files that cannot be read, a figure saying so."""
    fig = _figure(11.0, 4.6)
    a1, a2 = fig.subplots(1, 2)
    try:
        d = data if data is not None else error_map_data(sample_dir, recon_dir, per_point)
    except (OSError, ValueError) as e:  # missing or damaged sample / reconstruction files
        for ax in (a1, a2):
            _empty(ax, f"error map unavailable: {str(e).splitlines()[0][:120]}")
        fig.tight_layout()
        return _save(fig, path)
    _draw_surface_panel(fig, a1, d)
    _draw_centres_panel(fig, a2, d)
    _same_window((a1, a2), d)
    where = f"{Path(recon_dir).resolve().parent.name}/{Path(recon_dir).name}"
    fig.suptitle(title or f"Error map of {where} against {Path(sample_dir).name}'s ground truth (top view)",
                 fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


OUTPUT_MAP_CAPTION = ("a disparity or depth map: the left view cropped to the plate, coloured by the signed depth "
                      "error Z_est - Z_gt (mm; a disparity through Z = f B / (d + doffs)), plate pixels without an "
                      "estimate dark grey; a point cloud or mesh: a top view in world X/Y (mm) of its points "
                      "(vertices) coloured by their exact distance to the true surface (mm), the true outline black.")


def output_file(where) -> tuple[str, Path] | None:
    """(kind, file) of a method's output: ``where`` is the file itself (its kind from its name or
    suffix) or a reconstruction directory holding one of ``method_outputs.OUTPUT_FILES``."""
    from platebench.bench.io.method_outputs import OUTPUT_FILES  # noqa: PLC0415

    where = Path(where)
    if where.is_dir():
        return next(((k, where / n) for k, n in OUTPUT_FILES.items() if (where / n).is_file()), None)
    if not where.is_file():
        return None
    by_name = {n: k for k, n in OUTPUT_FILES.items()}
    if where.name in by_name:
        return by_name[where.name], where
    suffix = where.suffix.lower()
    kind = {".pfm": "disparity", ".exr": "depth", ".npy": "depth", ".csv": "points"}.get(suffix)
    return (kind, where) if kind else None


def output_error_map_file(where) -> Path:
    """The scored error map (``bench.io.error_map_files.ERROR_MAP_FILE``) of a method's output: ``where``
    is a reconstruction directory or its output file (``method_outputs.OUTPUT_FILES``; the error map
    in that directory), the error map file itself, or a score document ``F.score.json`` that
    ``platebench evaluate`` wrote (``F.error_map.npz`` beside it)."""
    from platebench.bench.io.error_map_files import ERROR_MAP_FILE, error_map_beside  # noqa: PLC0415
    from platebench.bench.io.method_outputs import OUTPUT_FILES  # noqa: PLC0415

    where = Path(where)
    if where.is_dir():
        return where / ERROR_MAP_FILE
    if where.name in OUTPUT_FILES.values():
        return where.parent / ERROR_MAP_FILE
    return where if where.suffix == ".npz" else error_map_beside(where)


def plot_output_error_map(sample_dir, where, path, kind: str | None = None, title: str | None = None) -> Path:
    """Error map of another method's output against a sample's ground truth, drawn from its scored error
    map (``output_error_map_file(where)``, written when the output was scored; ``kind``: the kind the
    panel names, default the file's).

    Disparity and depth maps: the left view, cropped to the plate, coloured by the signed depth
    error Z_est - Z_gt (mm; a disparity through Z = f B / (d + doffs)); plate pixels without an
    estimate dark grey. Point clouds and meshes: a top view in world X/Y (mm) of the points (the
    mesh's vertices) coloured by their exact distance to the true surface (mm), the true outline
    (``sample_dir``'s boundary.npy) in black. A missing or damaged error map gives a figure saying so."""
    from platebench.bench.io.error_map_files import read_error_map  # noqa: PLC0415

    fig = _figure(7.5, 5.4)
    ax = fig.add_subplot(111)
    file = output_error_map_file(where)
    try:
        if not file.is_file():
            raise ValueError(f"{file.name} missing")
        m = read_error_map(file)
        kind = kind or m.kind
        if m.is_map:
            err, mask = m.error_m.astype(np.float64) * 1e3, m.plate
            if not mask.any():
                raise ValueError(f"{file.name}: no plate pixel")
            vs, us = np.nonzero(mask)
            v0, v1 = max(vs.min() - 5, 0), min(vs.max() + 6, mask.shape[0])
            u0, u1 = max(us.min() - 5, 0), min(us.max() + 6, mask.shape[1])
            a = np.abs(err[np.isfinite(err)])
            lim = max(float(np.percentile(a, 95)) if a.size else 1.0, _MIN_COLOUR_RANGE_MM)
            ax.imshow(np.where(mask, 0.45, 0.05)[v0:v1, u0:u1], cmap="gray", vmin=0, vmax=1, interpolation="nearest")
            im = ax.imshow(err[v0:v1, u0:u1], cmap="coolwarm", vmin=-lim, vmax=lim, interpolation="nearest")
            fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04, label="Z_est - Z_gt (mm)")
            ax.set_title(f"left view, {kind}: depth error over the plate's pixels, median "
                         f"{m.median_m * 1e3:.3g} / RMS {m.rms_m * 1e3:.3g} mm, coverage "
                         f"{m.coverage_frac:.3f}", fontsize=8)
            ax.set_xticks([])
            ax.set_yticks([])
        else:
            P, dist = m.points_m, m.distance_m * 1e3
            boundary = Path(sample_dir) / "boundary.npy"
            if boundary.is_file():
                b = np.load(boundary) * 1e3
                ax.plot(np.r_[b[:, 0], b[:1, 0]], np.r_[b[:, 1], b[:1, 1]], "k-", lw=1.0)
            lim = max(float(np.percentile(dist, 95)) if dist.size else 1.0, _MIN_COLOUR_RANGE_MM)
            sc = ax.scatter(P[:, 0] * 1e3, P[:, 1] * 1e3, c=dist, s=2, cmap="viridis", vmin=0, vmax=lim)
            fig.colorbar(sc, ax=ax, fraction=0.046, pad=0.04, label="distance to the true surface (mm)")
            ax.set_aspect("equal")
            ax.set_xlabel("world X (mm)")
            ax.set_ylabel("world Y (mm)")
            ax.set_title(f"{kind} ({len(P)} shown): distance to the true surface, median "
                         f"{m.median_m * 1e3:.3g} / RMS {m.rms_m * 1e3:.3g} mm", fontsize=8)
    except (OSError, ValueError) as e:  # missing or damaged files (DatasetError is a ValueError)
        _empty(ax, f"error map unavailable: {str(e).splitlines()[0][:120]}")
    import textwrap  # noqa: PLC0415
    ax.set_title(textwrap.fill(ax.get_title(), 80), fontsize=8)
    head = title or f"Error of {Path(where).name} against {Path(sample_dir).name}'s ground truth"
    fig.suptitle(textwrap.fill(head, 90), fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


def compare_error_figure(cmp) -> bytes:
    """PNG: signed depth error (mm) per dense method (a disparity or depth output) on the plate's bounding
    box, drawn from each row's ``error_map`` (a depth error map, scored with its output by
    ``bench.run.compare``); point clouds and meshes are not drawn."""
    import io  # noqa: PLC0415

    dense = [r for r in cmp.rows if r.kind in ("disparity", "depth") and r.error_map is not None]
    n = max(len(dense), 1)
    fig = _figure(3.6 * n, 4.4)
    axes = fig.subplots(1, n, squeeze=False)
    mask = cmp.gt_mask
    vs, us = np.nonzero(mask)
    if vs.size:
        m = 5
        v0, v1 = max(vs.min() - m, 0), min(vs.max() + m + 1, mask.shape[0])
        u0, u1 = max(us.min() - m, 0), min(us.max() + m + 1, mask.shape[1])
    else:
        v0, v1, u0, u1 = 0, mask.shape[0], 0, mask.shape[1]
    for ax, r in zip(axes[0], dense):
        err = r.error_map.error_m * 1e3  # NaN off the plate and where there is no estimate
        a = np.abs(err[np.isfinite(err)])
        lim = float(np.percentile(a, 95)) if a.size else 1.0
        lim = max(lim, _MIN_COLOUR_RANGE_MM)
        back = np.where(mask, 0.45, 0.05)[v0:v1, u0:u1]
        ax.imshow(back, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        im = ax.imshow(err[v0:v1, u0:u1], cmap="coolwarm", vmin=-lim, vmax=lim, interpolation="nearest")
        f = r.figures
        ax.set_title(f"{r.name}\nmed {f.depth_median_mm:.3f} / RMS {f.depth_rms_mm:.3f} mm\n"
                     f"cov {100 * f.coverage_frac:.1f} %, {r.n_images} img/cam", fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
        fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04, label="Z_est - Z_gt (mm)")
    fig.suptitle(f"{cmp.sample_dir}: left-camera depth error (dark grey: plate pixel without estimate)", fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()



# ----------------------------------------------------------------------------- accuracy study
def plot_accuracy_study(study, path) -> Path:
    """The accuracy study (``bench.run.accuracy``, an ``AccuracyStudy``): per target, each draw's worst
    corner with every source on beside the paper's bound (top), and the error budget: the median worst
    corner of each budget row with its 5-95 % spread over the draws (bottom). Millimetres."""
    targets = list(study.summary)
    paper = study.paper
    fig = _figure(6.5 * max(len(targets), 1), 9.0)
    if not targets:
        ax = fig.add_subplot(1, 1, 1)
        ax.text(0.5, 0.5, "no trials", ha="center", va="center")
        ax.set_axis_off()
        return _save(fig, path)
    grid = fig.add_gridspec(2, len(targets), height_ratios=[1.0, 1.6])
    for j, target in enumerate(targets):
        summary = study.summary[target]
        top = fig.add_subplot(grid[0, j])
        allc = [c for c, v in summary.items() if v.kind == "all"]
        trials = [r for r in study.rows if r.target == target and allc and r.config == allc[0] and r.ok]
        for k, (worst, label, color, bound) in enumerate(((lambda r: r.worst_depth_mm, "depth", "C0", paper.depth_mm),
                                                           (lambda r: r.worst_xy_mm, "x/y", "C1", paper.xy_mm))):
            v = np.array([worst(r) for r in trials], float)
            x = np.full(v.size, float(k)) + np.linspace(-0.25, 0.25, max(v.size, 1))[:v.size]
            top.plot(x, v, "o", color=color, ms=4, alpha=0.7)
            if v.size:
                top.hlines(np.median(v), k - 0.35, k + 0.35, color=color, lw=2)
            if bound:
                top.hlines(bound, k - 0.45, k + 0.45, color="k", ls="--", lw=1)
                top.text(k + 0.46, bound, f"paper {bound:g}", va="center", fontsize=8)
        top.set_xticks([0, 1], ["depth", "x/y"])
        top.set_xlim(-0.6, 1.9)
        top.set_ylabel("worst corner of a trial (mm)")
        top.set_title(f"{target}: every source on, {len(trials)} draws (bar: median)", fontsize=10)
        ax = fig.add_subplot(grid[1, j])
        labels = list(summary)
        y = np.arange(len(labels))
        for k, (m, color, dy) in enumerate((("depth", "C0", -0.18), ("xy", "C1", 0.18))):
            stats = [summary[c].stats(m) for c in labels]
            med = np.array([np.nan if s is None else s.worst_median_mm for s in stats], float)
            lo = np.array([np.nan if s is None else s.worst_quantiles_mm.get("q05", np.nan) for s in stats], float)
            hi = np.array([np.nan if s is None else s.worst_quantiles_mm.get("q95", np.nan) for s in stats], float)
            ax.barh(y + dy, med, height=0.34, color=color, label="depth" if m == "depth" else "x/y")
            ax.errorbar(med, y + dy, xerr=[np.nan_to_num(med - lo), np.nan_to_num(hi - med)], fmt="none",
                        ecolor="k", lw=0.8, capsize=2)
        for bound, style in ((paper.depth_mm, "--"), (paper.xy_mm, ":")):
            if bound:
                ax.axvline(bound, color="k", ls=style, lw=1)
        ax.set_yticks(y, labels, fontsize=8)
        ax.invert_yaxis()
        ax.set_xlabel("worst corner, median over draws (mm); whiskers 5-95 %\npaper: -- depth, : x/y")
        ax.set_title(f"{target}: error budget", fontsize=10)
        ax.legend(fontsize=8, loc="lower right")
    rz = study.settings.realism.name
    fig.suptitle(f"Accuracy test (paper V-D) under realism {rz}", fontsize=11)
    fig.tight_layout()
    return _save(fig, path)
