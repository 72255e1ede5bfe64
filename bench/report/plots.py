"""Report plots (matplotlib, Agg): each function draws one figure and writes it as a PNG.

Every function takes plain data (table rows as dicts, study rows, file paths), draws on
its own ``matplotlib.figure.Figure`` (no pyplot, so no global figure state and no
display), writes the PNG atomically (``bench.atomic.write_bytes``) and returns the path.
Missing columns or empty inputs give a figure that says so rather than an exception.

Units: errors in millimetres, bend angles in degrees, sensing distances in metres,
fractions in 0..1 (as the table columns name them).
"""
from __future__ import annotations

import io
import math
from pathlib import Path

import numpy as np

from platebench.bench.io.atomic import write_bytes

__all__ = ["plot_error_vs_bend", "plot_detection_vs_bend", "plot_hidden_fraction_vs_bend",
           "plot_cure_success_vs_bend", "plot_l_formula", "plot_error_map", "plot_method_comparison",
           "plot_metric_vs_axis", "axis_levels", "axis_stats", "row_failed", "axis_label",
           "error_map_data", "bend_bins", "precision_recall_counts", "METRIC_LABELS", "AXIS_LABELS",
           "CATEGORY_ORDER"]

DPI = 100
METRIC_LABELS = {
    "depth_rms_mm": "depth RMS (mm)", "depth_max_mm": "depth max (mm)", "depth_median_mm": "depth median (mm)",
    "xy_rms_mm": "x/y RMS (mm)", "err3d_rms_mm": "3D error RMS (mm)", "boundary_mean_mm": "boundary mean (mm)",
    "boundary_hausdorff_mm": "boundary Hausdorff (mm)", "surface_rms_mm": "surface RMS (mm)",
    "coverage_frac": "coverage (fraction of plate)",
}
AXIS_LABELS = {
    "roughness": "roughness (GGX alpha)", "noise": "sensor noise preset", "bend_deg": "bend angle (deg)",
    "distance_m": "sensing distance (m)", "material": "material", "spp": "samples per pixel",
    "width_px": "camera width (px)", "height_px": "camera height (px)", "direction": "bend direction",
    "family": "deformation family", "tilt_deg": "tilt (deg)", "azimuth_deg": "azimuth (deg)",
    "axis_deg": "bend axis (deg)", "metal": "metal", "albedo": "albedo", "baseline_m": "baseline (m)",
    "f_px": "focal length (px)", "full_well_e": "full well (e-)", "read_noise_dn": "read noise (DN)",
    "bit_depth": "bit depth", "aperture_radius_m": "aperture radius (m)",
}
# natural order of categorical axes (anything else: alphabetical, after these)
CATEGORY_ORDER = {
    "noise": ("none", "low", "medium", "high", "custom"),
    "direction": ("up", "down"),
    "material": ("diffuse", "roughconductor"),
    "family": ("flat", "cylinder", "fold", "twist", "dome", "dent"),
}
_DIRECTION_STYLE = {"up": "-", "down": "--"}
_FLAG_LABELS = {"detected": "detected (either symptom)", "counting_test": "counting test",
                "arrays_disagree": "arrays disagree (Fig. 2)", "false_boundary_detected": "detected"}


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


def _num(v) -> float | None:
    """A finite float, or None (None, NaN, inf, '', non-numbers)."""
    if v is None or isinstance(v, str) and not v.strip():
        return None
    if isinstance(v, bool):
        return float(v)
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def _flag(v) -> bool | None:
    """True / False / None (unknown) from bools, 0/1, 'true'/'false' strings."""
    if v is None:
        return None
    if isinstance(v, (bool, np.bool_)):
        return bool(v)
    if isinstance(v, str):
        s = v.strip().lower()
        if s in ("true", "1", "yes"):
            return True
        if s in ("false", "0", "no"):
            return False
        return None
    x = _num(v)
    return None if x is None else bool(x)


def _bend_key(v) -> float | None:
    x = _num(v)
    return None if x is None else round(x, 6)


def _empty(ax, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes, fontsize=10, color="0.35",
            wrap=True)
    ax.set_xticks([])
    ax.set_yticks([])


def _label_of(metric: str) -> str:
    return METRIC_LABELS.get(metric, metric)


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
def plot_error_vs_bend(rows, path, metrics=("depth_rms_mm", "boundary_mean_mm"), series=("method", "direction"),
                       title: str | None = None) -> Path:
    """One panel per metric: error (mm) against bend angle (deg), one series per method and direction.

    Each sample is a dot; the line joins the medians at each bend. Rows whose status is
    not "ok" are drawn as red crosses on the bottom edge (a failure at that bend)."""
    rows = list(rows or [])
    metrics = [m for m in metrics if any(_num(r.get(m)) is not None for r in rows)] or list(metrics[:1])
    fig = _figure(5.2 * len(metrics), 4.0)
    axes = fig.subplots(1, len(metrics), squeeze=False)[0]
    present = [k for k in series if any(r.get(k) not in (None, "") for r in rows)]
    series = [k for k in present if len({str(r.get(k)) for r in rows}) > 1] or present[:1]
    groups = _groups(rows, series)
    d_at = series.index("direction") if "direction" in series else None

    def colour_key(key):  # one colour per series apart from the direction (line style), if anything else varies
        rest = tuple(x for i, x in enumerate(key) if i != d_at)
        return rest if rest else key

    ckeys = sorted({colour_key(g) for g in groups}, key=lambda k: tuple(str(x) for x in k))
    colors = dict(zip(ckeys, _colors(len(ckeys))))
    for ax, metric in zip(axes, metrics):
        drawn, allv = False, []
        for key in sorted(groups, key=lambda k: tuple(str(x) for x in k)):
            grp = groups[key]
            pts = [(_bend_key(r.get("bend_deg")), _num(r.get(metric))) for r in grp if _ok(r)]
            pts = [(b, v) for b, v in pts if b is not None and v is not None]
            label = _series_label(key, tuple(series)).replace(", ", " / ") if key else metric
            color = colors.get(colour_key(key), "C0")
            ls = _DIRECTION_STYLE.get(str(key[d_at]) if d_at is not None else "", "-")
            fails = sorted({_bend_key(r.get("bend_deg")) for r in grp if not _ok(r)} - {None})
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
            _empty(ax, f"no {_label_of(metric)} values")
            continue
        if _positive_span(allv):
            ax.set_yscale("log")
        ax.set_xlabel("bend angle (deg)")
        ax.set_ylabel(_label_of(metric))
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
    return np.linspace(b[0], b[-1] + 1e-9, max_bins + 1)


def precision_recall_counts(rows, flag: str, gt_key: str = "false_boundary_gt") -> dict:
    """TP/FP/FN/TN, precision and recall of ``flag`` against ``gt_key`` over rows where both are known."""
    tp = fp = fn = tn = 0
    for r in rows:
        g, d = _flag(r.get(gt_key)), _flag(r.get(flag))
        if g is None or d is None:
            continue
        tp += g and d
        fp += d and not g
        fn += g and not d
        tn += (not g) and (not d)
    return {"true_positive": tp, "false_positive": fp, "false_negative": fn, "true_negative": tn,
            "precision": tp / (tp + fp) if tp + fp else None, "recall": tp / (tp + fn) if tp + fn else None}


def plot_detection_vs_bend(rows, path, flags=("detected", "counting_test", "arrays_disagree"),
                           gt_key: str = "false_boundary_gt", max_bins: int = 10, title: str | None = None) -> Path:
    """Precision and recall of each detection flag against ground truth, per bend-angle bin.

    Grey bars (right axis): fraction of cases in the bin with a ground-truth false boundary.
    Precision is undefined (gap) in a bin with no positive verdict, recall in a bin with no
    ground-truth positive."""
    rows = [r for r in (rows or []) if _bend_key(r.get("bend_deg")) is not None and _flag(r.get(gt_key)) is not None]
    flags = [f for f in flags if any(_flag(r.get(f)) is not None for r in rows)]
    fig = _figure(9.0, 4.4)
    ax_p, ax_r = fig.subplots(1, 2, sharex=True)
    if not rows or not flags:
        for ax in (ax_p, ax_r):
            _empty(ax, "no cases with both a ground-truth and a detection verdict")
        fig.tight_layout()
        return _save(fig, path)
    bends = [_bend_key(r["bend_deg"]) for r in rows]
    edges = bend_bins(bends, max_bins)
    idx = np.clip(np.digitize(bends, edges) - 1, 0, len(edges) - 2)
    centres = 0.5 * (edges[1:] + edges[:-1])
    width = np.diff(edges)
    bins = [[r for r, i in zip(rows, idx) if i == k] for k in range(len(centres))]
    gt_frac = np.array([np.mean([bool(_flag(r.get(gt_key))) for r in b]) if b else np.nan for b in bins])
    n = np.array([len(b) for b in bins])
    for ax, what in ((ax_p, "precision"), (ax_r, "recall")):
        tw = ax.twinx()
        tw.bar(centres, gt_frac, width=0.85 * width, color="0.85", zorder=0)
        tw.set_ylim(0, 1.05)
        tw.set_ylabel("fraction with GT false boundary", color="0.45", fontsize=8)
        tw.tick_params(axis="y", colors="0.45", labelsize=7)
        ax.set_zorder(tw.get_zorder() + 1)
        ax.patch.set_visible(False)
        defined = False
        for j, f in enumerate(flags):
            vals = [precision_recall_counts(b, f, gt_key)[what] for b in bins]
            y = np.array([np.nan if v is None else v for v in vals], float)
            defined |= bool(np.isfinite(y).any())
            dodge = (j - (len(flags) - 1) / 2) * 0.06 * width  # overlapping flags stay visible
            ax.plot(centres + dodge, y, marker="os^v"[j % 4], lw=1.5, ms=5, label=_FLAG_LABELS.get(f, f), color=f"C{j}")
        if not defined:
            why = ("no positive verdict in any bin" if what == "precision" else
                   "no ground-truth false boundary in any bin")
            ax.text(0.5, 0.5, f"{what} undefined everywhere:\n{why}", ha="center", va="center",
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
    handles, labels = ax_r.get_legend_handles_labels()
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
        parts.append(f"{units.get(k, '')}{x:g}{suffix.get(k, '')}" if x is not None else str(v if v is not None else "-"))
    return ", ".join(parts)


def plot_hidden_fraction_vs_bend(rows, path, smallest_hiding: dict | None = None, series=("direction",),
                                 title: str | None = None) -> Path:
    """Top: fraction of the true boundary hidden from the worse camera (0..1) against bend (deg),
    one line per series (direction, and aspect / distance when they vary). Bottom: per case, ground
    truth (a false boundary exists) and the pipeline's verdict: filled = yes, hollow = no, grey
    x = no verdict (reconstruction failed)."""
    rows = [r for r in (rows or []) if _bend_key(r.get("bend_deg")) is not None]
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
        grp = sorted((r for r in rows if keyf(r) == key), key=lambda r: _bend_key(r["bend_deg"]))
        label = _series_label(key, series)
        pts = [(_bend_key(r["bend_deg"]), _hidden(r)) for r in grp]
        pts = [(b, h) for b, h in pts if h is not None]
        if pts:
            b, h = np.array(pts).T
            ax.plot(b, h, "-", marker=markers[j % len(markers)], color=colors[key], ms=4, lw=1.4,
                    label=f"{label}: worse camera")
        for side, mk in (("left", "<"), ("right", ">")):
            p2 = [(_bend_key(r["bend_deg"]), _num(r.get(f"hidden_frac_{side}"))) for r in grp]
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
        for k, (what, get) in enumerate((("GT false boundary", lambda r: _flag(r.get("false_boundary_gt"))),
                                         ("detected", _detected_any))):
            y = j * 2 + k
            labels.append((y, f"{name}: {what}"))
            for r in rows:
                if keyf(r) != key:
                    continue
                b, v = _bend_key(r["bend_deg"]), get(r)
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
def plot_cure_success_vs_bend(rows, path, title: str | None = None) -> Path:
    """Cases with a ground-truth false boundary: left, fraction of cases each cure removes it
    (the boundary fully visible at the new pose) per bend; right, hidden fraction (0..1) before
    and after each cure."""
    rows = [r for r in (rows or []) if _bend_key(r.get("bend_deg")) is not None and _flag(r.get("false_boundary_gt"))]
    cures = [("cure1", "cure 1: orient (look along the tangent)"), ("cure2", "cure 2: move back")]
    fig = _figure(10.0, 4.0)
    a1, a2 = fig.subplots(1, 2, sharex=True)
    tried = [r for r in rows if any(_flag(r.get(f"{c}_removed")) is not None for c, _ in cures)]
    if not tried:
        for ax in (a1, a2):
            _empty(ax, "no case with a ground-truth false boundary and a cure result")
        fig.tight_layout()
        return _save(fig, path)
    bends = sorted({_bend_key(r["bend_deg"]) for r in tried})
    for j, (c, label) in enumerate(cures):
        rate, ns = [], []
        for b in bends:
            vals = [_flag(r.get(f"{c}_removed")) for r in tried if _bend_key(r["bend_deg"]) == b]
            vals = [v for v in vals if v is not None]
            rate.append(np.mean(vals) if vals else np.nan)
            ns.append(len(vals))
        off = (j - 0.5) * 0.6
        a1.plot(np.array(bends) + off, rate, "o-", ms=6, lw=1.4, color=f"C{j}", label=label)
        pts = [(_bend_key(r["bend_deg"]), _num(r.get(f"{c}_hidden_frac"))) for r in tried]
        pts = sorted(((b, h) for b, h in pts if h is not None), key=lambda t: t[0])
        if pts:
            b, h = np.array(pts).T
            a2.plot(b + off, h, "o", ms=5, color=f"C{j}", label=f"after {c}")
    for b, k in zip(bends, [sum(1 for r in tried if _bend_key(r["bend_deg"]) == b) for b in bends]):
        a1.annotate(f"n={k}", (b, 1.0), xycoords=("data", "axes fraction"), xytext=(0, 3),
                    textcoords="offset points", ha="center", fontsize=6, color="0.4", annotation_clip=False)
    before = sorted(((_bend_key(r["bend_deg"]), _hidden(r)) for r in tried if _hidden(r) is not None),
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
def plot_l_formula(rows, path, title: str | None = None) -> Path:
    """Left: the L formula's predicted rig distance (m) and the ground-truth distance of complete
    visibility (m) against bend (deg), for both baselines. Right: ground truth against prediction
    (m) with the identity line."""
    rows = [r for r in (rows or []) if _bend_key(r.get("bend_deg")) is not None]
    fig = _figure(10.0, 4.2)
    a1, a2 = fig.subplots(1, 2)
    series = [("gt_distance_baseline_along_axis_m", "GT, baseline along the bend axis", "s"),
              ("gt_distance_baseline_along_bend_m", "GT, baseline along the bend", "^")]
    pred = [(_bend_key(r["bend_deg"]), _num(r.get("predicted_distance_m"))) for r in rows]
    pred = sorted((b, p) for b, p in pred if p is not None)
    if not pred:
        for ax in (a1, a2):
            _empty(ax, "no L-formula rows")
        fig.tight_layout()
        return _save(fig, path)
    b, p = np.array(pred).T
    a1.plot(b, p, "k-o", ms=4, lw=1.6, label="predicted: L + height of AB")
    lo = hi = None
    for j, (key, label, mk) in enumerate(series):
        pts = sorted(((_bend_key(r["bend_deg"]), _num(r.get(key)), _num(r.get("predicted_distance_m")))
                      for r in rows), key=lambda t: t[0])
        good = [(x, g, q) for x, g, q in pts if g is not None and q is not None]
        never = sorted({x for x, g, q in pts if g is None and _has(rows, x, key)})
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
    a2.set_xlabel("predicted distance (m)")
    a2.set_ylabel("ground-truth distance (m)")
    a2.grid(True, alpha=0.3)
    a2.set_title("ground truth against prediction", fontsize=9)
    fig.suptitle(title or "The paper's L formula: distance at which the whole boundary is visible", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def _has(rows, bend, key) -> bool:
    """Whether a row at ``bend`` has ``key`` present (None or inf = never visible, vs column missing)."""
    return any(_bend_key(r.get("bend_deg")) == bend and key in r for r in rows)


# ----------------------------------------------------------------------------- method comparison
def plot_method_comparison(table: dict, path, metrics=None, title: str | None = None) -> Path:
    """Grouped bars: one group per error metric (mm, log scale when values span decades), one bar
    per method; a second panel for coverage (fraction of the plate, 0..1) when present.

    ``table``: {method: {metric: value}} (e.g. the mean over a sweep's samples, or compare.json)."""
    table = {str(m): dict(v or {}) for m, v in (table or {}).items()}
    methods = list(table)
    if metrics is None:
        metrics = [k for k in ("depth_rms_mm", "depth_median_mm", "depth_max_mm", "xy_rms_mm", "err3d_rms_mm",
                               "surface_rms_mm", "boundary_mean_mm") if any(_num(t.get(k)) is not None
                                                                           for t in table.values())]
    err_metrics = [m for m in metrics if m != "coverage_frac"]
    has_cov = any(_num(t.get("coverage_frac")) is not None for t in table.values())
    fig = _figure(9.5 if has_cov else 7.5, 4.2)
    if has_cov:
        gs = fig.add_gridspec(1, 2, width_ratios=[3, 1.2])
        ax, axc = fig.add_subplot(gs[0]), fig.add_subplot(gs[1])
    else:
        ax, axc = fig.add_subplot(111), None
    if not methods or not err_metrics:
        _empty(ax, "no method metrics to compare")
    else:
        colors = _colors(len(methods))
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
        ax.set_xticklabels([_label_of(k).replace(" (mm)", "") for k in err_metrics], rotation=20, ha="right",
                           fontsize=8)
        ax.set_ylabel("error (mm)")
        ax.margins(y=0.15)
        ax.grid(True, axis="y", alpha=0.3)
        ax.legend(fontsize=7, loc="best")
    if axc is not None:
        vals = [(m, _num(table[m].get("coverage_frac"))) for m in methods]
        colors = _colors(len(methods))
        for j, (m, v) in enumerate(vals):
            if v is not None:
                axc.bar(j, v, color=colors[j])
                axc.annotate(f"{v:.2f}", (j, v), xytext=(0, 2), textcoords="offset points", ha="center", fontsize=7)
        axc.set_xticks(range(len(methods)))
        axc.set_xticklabels(methods, rotation=30, ha="right", fontsize=8)
        axc.set_ylim(0, 1.1)
        axc.set_ylabel("coverage (fraction of plate, 0..1)")
        axc.grid(True, axis="y", alpha=0.3)
    fig.suptitle(title or "Method comparison", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


# ----------------------------------------------------------------------------- metric against a swept axis
def axis_label(axis: str) -> str:
    return AXIS_LABELS.get(axis, axis)


def row_failed(row, metric: str = "depth_rms_mm") -> bool:
    """Whether a results row counts as a failure of its method: status not "ok", or no finite
    ``metric``, or (the paper's pipeline, the one method that reports both) fewer squares matched
    than ground truth puts on the plate (``matched_count < expected_count_gt``)."""
    if not _ok(row):
        return True
    if _num(row.get(metric)) is None:
        return True
    matched, expected = _num(row.get("matched_count")), _num(row.get("expected_count_gt"))
    return matched is not None and expected is not None and matched < expected


def _axis_value(row, axis):
    """A row's value on ``axis``: a finite float, a non-empty string, or None (unknown)."""
    v = row.get(axis)
    if v is None or isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, str):
        s = v.strip()
        if not s:
            return None
        x = _num(s)
        return x if x is not None else s
    if isinstance(v, (bool, np.bool_)):
        return str(bool(v)).lower()
    x = _num(v)
    return x if x is not None else str(v)


def axis_levels(rows, axis: str, max_levels: int = 10) -> tuple[list[dict], object, bool]:
    """The ordered levels of ``axis`` over ``rows``: ([{"key", "label", "x"}], key_of(row), numeric).

    Numeric axes: one level per distinct value (x = the value), or, with more than
    ``max_levels`` distinct values (random draws), equal-width bins (x = bin centre, label
    "lo to hi" joined by an en dash; empty bins left out). Categorical axes: one level per
    value in its natural order (``CATEGORY_ORDER``: noise none < low < medium < high), x = 0,
    1, ... ``key_of`` gives a row's level key, or None where the row has no value on the axis."""
    vals = [_axis_value(r, axis) for r in rows]
    known = [v for v in vals if v is not None]
    numeric = bool(known) and all(isinstance(v, float) for v in known)
    if not known:
        return [], (lambda r: None), False
    if numeric:
        uniq = sorted({round(v, 9) for v in known})
        if len(uniq) <= max_levels:
            levels = [{"key": u, "label": f"{u:g}", "x": u} for u in uniq]

            def key_of(r):
                v = _axis_value(r, axis)
                return round(v, 9) if isinstance(v, float) else None
            return levels, key_of, True
        edges = np.linspace(uniq[0], uniq[-1], max_levels + 1)

        def key_of(r):
            v = _axis_value(r, axis)
            if not isinstance(v, float):
                return None
            return int(np.clip(np.searchsorted(edges, v, side="right") - 1, 0, max_levels - 1))
        used = sorted({key_of(r) for r in rows} - {None})
        levels = [{"key": i, "label": f"{edges[i]:.3g}\u2013{edges[i + 1]:.3g}",
                   "x": float(0.5 * (edges[i] + edges[i + 1]))} for i in used]
        return levels, key_of, True
    def cat(v):
        return f"{v:g}" if isinstance(v, float) else str(v)

    order = CATEGORY_ORDER.get(axis, ())
    names = sorted({cat(v) for v in known}, key=lambda s: (order.index(s) if s in order else len(order), s))
    levels = [{"key": n, "label": n, "x": float(i)} for i, n in enumerate(names)]

    def key_of(r):
        v = _axis_value(r, axis)
        return None if v is None else cat(v)
    return levels, key_of, False


def _method_order(methods) -> list[str]:
    """The paper's pipeline first, then the peers alphabetically."""
    return sorted(set(methods), key=lambda m: (m != "paper", m))


def axis_stats(rows, axis: str, metric: str = "depth_rms_mm", max_levels: int = 10) -> dict:
    """Per method and level of ``axis``: rows, failures (``row_failed``), failure rate (0..1),
    and the median / values of ``metric`` over the rows with status ok and a finite value
    (a paper row that matched fewer squares than expected still gives its value here).

    Returns {"axis", "metric", "levels", "numeric", "methods", "cells": {(method, key): {...}},
    "no_value": rows without a value on the axis}."""
    rows = list(rows or [])
    levels, key_of, numeric = axis_levels(rows, axis, max_levels)
    cells: dict = {}
    no_value = 0
    for r in rows:
        k = key_of(r)
        if k is None:
            no_value += 1
            continue
        m = str(r.get("method") or "-")
        c = cells.setdefault((m, k), {"rows": 0, "failed": 0, "values": []})
        c["rows"] += 1
        c["failed"] += row_failed(r, metric)
        v = _num(r.get(metric)) if _ok(r) else None
        if v is not None:
            c["values"].append(v)
    for c in cells.values():
        c["failure_rate"] = c["failed"] / c["rows"] if c["rows"] else None
        c["median"] = float(np.median(c["values"])) if c["values"] else None
    methods = _method_order(m for m, _ in cells)
    return {"axis": axis, "metric": metric, "levels": levels, "numeric": numeric, "methods": methods,
            "cells": cells, "no_value": no_value}


def plot_metric_vs_axis(rows, axis: str, path, metrics=("depth_rms_mm",), title: str | None = None,
                        pooled: dict | None = None, max_levels: int = 10) -> Path:
    """One panel per metric: the median over samples (line) of the metric at each value of the
    swept ``axis``, one line per method, samples as faint dots, log y when the medians and samples
    span more than a decade; and a last panel: each method's failure rate (0..1) at each value
    (``row_failed`` on the first metric: status failed, no value, or for the paper's pipeline
    fewer squares matched than expected), with the count "k/n" printed where it is not zero. A
    hollow median marker: some of the rows at that value count as failed (the median is over
    those that gave a value); a cross on the bottom edge: none gave a value there.

    Numeric axes (roughness, bend_deg, ...) are drawn on their values (log x when all are positive and
    span more than a factor 20), categorical ones (noise none < low < medium < high, material, ...) as ordered
    categories. ``pooled`` ({axis: [values]}) names the other axes that vary and are pooled into
    each point; it goes under the title."""
    rows = list(rows or [])
    metrics = [m for m in metrics if any(_num(r.get(m)) is not None for r in rows)] or list(metrics[:1])
    n_panels = len(metrics) + 1
    fig = _figure(4.6 * n_panels + 0.6, 4.3)
    axes = fig.subplots(1, n_panels, squeeze=False)[0]
    stats = axis_stats(rows, axis, metrics[0], max_levels)
    levels = stats["levels"]
    label_x = axis_label(axis)
    if not levels:
        for ax in axes:
            _empty(ax, f"no rows with a value of {label_x}")
        fig.suptitle(title or f"Against {label_x}", fontsize=10)
        fig.tight_layout()
        return _save(fig, path)
    numeric = stats["numeric"]
    xs = np.array([lv["x"] for lv in levels], float)
    logx = numeric and xs.min() > 0 and xs.max() / xs.min() > 20
    methods = stats["methods"]
    colors = dict(zip(methods, _colors(len(methods))))
    markers = dict(zip(methods, "osD^v<>p*h" * 3))
    # a small sideways offset per method so that equal values (failure rate 0) stay visible
    if numeric and len(xs) > 1:
        span = (np.log10(xs.max() / xs.min()) if logx else xs.max() - xs.min()) or 1.0
        step = 0.012 * span
    else:
        step = 0.06 if not numeric else 0.01 * (abs(xs[0]) or 1.0)

    def shifted(x, j):
        d = (j - (len(methods) - 1) / 2) * step
        return x * 10 ** d if logx else x + d

    for ax, metric in zip(axes[:-1], metrics):
        st = stats if metric == metrics[0] else axis_stats(rows, axis, metric, max_levels)
        allv, drawn = [], False
        for j, m in enumerate(methods):
            if not any(c["values"] for (mm, _), c in st["cells"].items() if mm == m):
                continue  # the method never gives this metric: nothing to draw, no "no value" marks
            xm, med, bad, dots_x, dots_y, none_x = [], [], [], [], [], []
            for lv in levels:
                c = st["cells"].get((m, lv["key"]))
                if c is None:
                    continue
                x = shifted(lv["x"], j)
                if c["median"] is None:
                    none_x.append(x)
                    continue
                xm.append(x)
                med.append(c["median"])
                bad.append(c["failed"] > 0)
                dots_x += [x] * len(c["values"])
                dots_y += c["values"]
            allv += dots_y
            if dots_y and len(dots_y) > len(med):
                ax.plot(dots_x, dots_y, markers[m], color=colors[m], ms=3, alpha=0.35, mfc="none")
            if med:
                ax.plot(xm, med, "-", marker=markers[m], color=colors[m], ms=6, lw=1.7, label=m)
                hollow = [(x, y) for x, y, f in zip(xm, med, bad) if f]
                if hollow:  # a median over rows some of which count as failed (e.g. squares missing)
                    ax.plot(*zip(*hollow), markers[m], color=colors[m], ms=6, mfc="white", mew=1.5)
                drawn = True
            if none_x:
                ax.plot(none_x, [0.0] * len(none_x), "x", color=colors[m], ms=9, mew=2, clip_on=False,
                        transform=ax.get_xaxis_transform(), label=f"{m}: no value")
                drawn = True
        if not drawn:
            _empty(ax, f"no {_label_of(metric)} values")
            continue
        pos = [v for v in allv if v > 0]
        if len(pos) >= 2 and max(pos) / min(pos) > 10:
            ax.set_yscale("log")
        ax.set_ylabel(_label_of(metric) + ", median")
        ax.set_title(f"{_label_of(metric)} (line: median, dots: samples)", fontsize=9)
        ax.grid(True, alpha=0.3)
        if ax.get_yscale() == "log":
            ax.grid(True, which="minor", axis="y", alpha=0.1)
        ax.legend(fontsize=7, loc="best")
    axf = axes[-1]
    stacked: dict = {}  # labels at the same point go one above the other
    for j, m in enumerate(methods):
        pts = [(shifted(lv["x"], j), lv["key"], stats["cells"][(m, lv["key"])]) for lv in levels
               if (m, lv["key"]) in stats["cells"]]
        if not pts:
            continue
        axf.plot([p[0] for p in pts], [p[2]["failure_rate"] for p in pts], "-", marker=markers[m],
                 color=colors[m], ms=6, lw=1.5, label=m)
        for xx, key, c in pts:
            if c["failed"]:
                at = (key, round(c["failure_rate"], 6))
                k = stacked[at] = stacked.get(at, -1) + 1
                axf.annotate(f"{c['failed']}/{c['rows']}", (xx, c["failure_rate"]), xytext=(4, 3 + 9 * k),
                             textcoords="offset points", fontsize=7, color=colors[m])
    axf.set_ylim(-0.05, 1.08)
    axf.set_ylabel("failure rate (0..1)")
    axf.set_title("failure rate: failed, no value, or squares missing", fontsize=9)
    axf.grid(True, alpha=0.3)
    axf.legend(fontsize=7, loc="best")
    for ax in axes:
        if logx:
            ax.set_xscale("log")
        if not numeric or len(levels) <= 12:
            ax.set_xticks(xs)
            ax.set_xticklabels([lv["label"] for lv in levels], fontsize=8,
                               rotation=30 if any(len(lv["label"]) > 6 for lv in levels) else 0)
            if logx:
                ax.xaxis.set_minor_formatter(_null_formatter())
        if not numeric:
            ax.set_xlim(xs.min() - 0.5, xs.max() + 0.5)
        else:
            _pad_x(ax, xs, logx)
        ax.set_xlabel(label_x)
    sub = ""
    if pooled:
        sub = "pooled over " + "; ".join(f"{axis_label(k)}: {', '.join(_short(v) for v in vals)}"
                                          for k, vals in pooled.items())
    head = title or f"Depth error and failure rate against {label_x}"
    fig.suptitle(head + (f"\n({sub})" if sub else ""), fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def _short(v) -> str:
    x = _num(v) if not isinstance(v, str) else None
    return f"{x:g}" if x is not None else str(v)


def _null_formatter():
    from matplotlib.ticker import NullFormatter  # noqa: PLC0415
    return NullFormatter()


def _pad_x(ax, xs, logx: bool) -> None:
    lo, hi = float(xs.min()), float(xs.max())
    if logx:
        f = (hi / lo) ** 0.06
        ax.set_xlim(lo / f, hi * f)
    else:
        pad = 0.06 * (hi - lo) if hi > lo else 0.1 * (abs(lo) or 1.0)
        ax.set_xlim(lo - pad, hi + pad)



# ----------------------------------------------------------------------------- error map
def error_map_data(sample_dir, recon_dir) -> dict:
    """What the error map shows, from a sample directory and a reconstruction directory (metres in,
    millimetres out): the GT outline, the reconstructed surface's vertices and faces with their
    exact distance to the GT mesh, the reconstructed boundary, and the square centres with their
    3D error against the true centre (projector ray through the feature centre cut with the mesh;
    identity from the GT feature map at the left pixel), or, where the identity is unknown, their
    distance to the true surface (``centre_kind`` says which)."""
    import trimesh  # noqa: PLC0415

    from platebench.bench.io.images import read_png  # noqa: PLC0415
    from platebench.bench.io.recon_files import load_reconstruction  # noqa: PLC0415
    from platebench.evaluation.point_metrics import point_to_surface_distance  # noqa: PLC0415

    sample_dir, recon_dir = Path(sample_dir), Path(recon_dir)
    mesh = trimesh.load(sample_dir / "plate.ply", process=False, force="mesh")
    gt_boundary = np.load(sample_dir / "boundary.npy") if (sample_dir / "boundary.npy").is_file() else None
    rec = load_reconstruction(recon_dir)
    out = {"gt_boundary": gt_boundary, "rec_boundary": rec.boundary if len(rec.boundary) else None,
           "surface_vertices": None, "surface_faces": None, "surface_dist_mm": None,
           "centres": rec.points, "centre_err_mm": np.zeros(0), "centre_kind": np.zeros(0, dtype="<U7"),
           "feature_id": rec.feature_id}
    if rec.surface is not None and len(rec.surface.vertices):
        v = np.asarray(rec.surface.vertices, float)
        out.update(surface_vertices=v, surface_faces=np.asarray(rec.surface.faces, int),
                   surface_dist_mm=point_to_surface_distance(v, mesh) * 1e3)
    if len(rec.points):
        err = point_to_surface_distance(rec.points, mesh) * 1e3
        kind = np.full(len(rec.points), "surface", dtype="<U7")
        try:
            from platebench.bench.io.sample_files import load_calibration, load_pattern  # noqa: PLC0415
            from platebench.evaluation.truth import (  # noqa: PLC0415
                feature_at_pixels,
                true_feature_points,
            )
            calib = load_calibration(sample_dir)
            pattern = load_pattern(sample_dir)
            ids = np.array([f.id for f in pattern.features])
            centers = np.array([f.center for f in pattern.features], float).reshape(-1, 2)
            true_pts = true_feature_points(mesh, calib.projector_camera, centers)
            fmap = read_png(sample_dir / "gt" / "left_feature.png").astype(np.int32) - 1
            gid = feature_at_pixels(fmap, rec.uv_left)
            index = {int(i): k for k, i in enumerate(ids)}
            for k, g in enumerate(gid):
                j = index.get(int(g))
                if j is not None and np.all(np.isfinite(true_pts[j])):
                    err[k] = np.linalg.norm(rec.points[k] - true_pts[j]) * 1e3
                    kind[k] = "3d"
        except (OSError, ValueError, KeyError):  # no GT feature map / pattern: distances to the surface only
            pass
        out.update(centre_err_mm=err, centre_kind=kind)
    return out


def plot_error_map(sample_dir, recon_dir, path, title: str | None = None, data: dict | None = None) -> Path:
    """Error map over the plate, top view in world X/Y (mm): left, the reconstructed surface
    coloured by its exact distance to the ground-truth mesh (mm), with the true boundary (black)
    and the reconstructed one (white dashed); right, the triangulated square centres coloured by
    their 3D error (mm) over the true outline."""
    from matplotlib.tri import Triangulation  # noqa: PLC0415
    fig = _figure(11.0, 4.6)
    a1, a2 = fig.subplots(1, 2)
    try:
        d = data if data is not None else error_map_data(sample_dir, recon_dir)
    except (OSError, ValueError) as e:
        for ax in (a1, a2):
            _empty(ax, f"error map unavailable: {str(e).splitlines()[0][:120]}")
        fig.tight_layout()
        return _save(fig, path)

    def outline(ax, lw=1.2):
        if d["gt_boundary"] is not None and len(d["gt_boundary"]):
            b = np.vstack([d["gt_boundary"], d["gt_boundary"][:1]]) * 1e3
            ax.plot(b[:, 0], b[:, 1], "k-", lw=lw, label="true boundary")

    if d["surface_vertices"] is not None and len(d["surface_faces"]):
        v = d["surface_vertices"] * 1e3
        tri = Triangulation(v[:, 0], v[:, 1], d["surface_faces"])
        dist = d["surface_dist_mm"]
        vmax = float(np.percentile(dist, 99)) if dist.size else 1.0
        im = a1.tripcolor(tri, dist, shading="gouraud", cmap="viridis", vmin=0.0, vmax=max(vmax, 1e-3))
        fig.colorbar(im, ax=a1, fraction=0.046, pad=0.03, label="distance to true surface (mm)")
        a1.set_title(f"surface: RMS {np.sqrt(np.mean(dist ** 2)):.3f} mm, max {dist.max():.3f} mm "
                     f"({len(v)} vertices)", fontsize=9)
    else:
        a1.set_title("no reconstructed surface", fontsize=9)
    outline(a1)
    if d["rec_boundary"] is not None:
        rb = np.vstack([d["rec_boundary"], d["rec_boundary"][:1]]) * 1e3
        a1.plot(rb[:, 0], rb[:, 1], "--", color="red", lw=1.1, label="reconstructed boundary")
    a1.legend(fontsize=7, loc="upper right", ncol=2, framealpha=0.85)

    outline(a2)
    pts, err, kind = d["centres"], d["centre_err_mm"], d["centre_kind"]
    if len(pts):
        p = pts * 1e3
        vmax = max(float(err.max()), 1e-3)
        three = kind == "3d"
        sc = None
        if three.any():
            sc = a2.scatter(p[three, 0], p[three, 1], c=err[three], cmap="plasma", vmin=0, vmax=vmax, s=70,
                            edgecolors="k", linewidths=0.6, zorder=3, label="3D error vs true centre")
        if (~three).any():
            sc2 = a2.scatter(p[~three, 0], p[~three, 1], c=err[~three], cmap="plasma", vmin=0, vmax=vmax, s=70,
                             marker="D", edgecolors="k", linewidths=0.6, zorder=3,
                             label="identity unknown: distance to surface")
            sc = sc if sc is not None else sc2
        fig.colorbar(sc, ax=a2, fraction=0.046, pad=0.03, label="square-centre error (mm)")
        if len(p) <= 40:
            for (x, y, _), e in zip(p, err):
                a2.annotate(f"{e:.2f}", (x, y), xytext=(0, 7), textcoords="offset points", ha="center", fontsize=6)
        rms = float(np.sqrt(np.mean(err[three] ** 2))) if three.any() else float("nan")
        a2.set_title(f"square centres: {len(p)} points, 3D RMS {rms:.3f} mm", fontsize=9)
        a2.legend(fontsize=7, loc="upper right", ncol=2, framealpha=0.85)
    else:
        a2.set_title("no triangulated square centres", fontsize=9)
    xy = [a[:, :2] for a in (d["gt_boundary"], d["rec_boundary"], d["surface_vertices"], d["centres"])
          if a is not None and len(a)]
    if xy:
        xy = np.vstack(xy) * 1e3
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        pad = 0.08 * max(float((hi - lo).max()), 1.0)
        for ax in (a1, a2):  # the same window on both panels, equal scales; headroom for the legend
            ax.set_xlim(lo[0] - pad, hi[0] + pad)
            ax.set_ylim(lo[1] - pad, hi[1] + pad + 0.22 * max(float(hi[1] - lo[1]), 1.0))
    for ax in (a1, a2):
        ax.set_xlabel("world X (mm)")
        ax.set_ylabel("world Y (mm)")
        ax.set_aspect("equal", adjustable="box")
        ax.grid(True, alpha=0.25)
    where = f"{Path(recon_dir).resolve().parent.name}/{Path(recon_dir).name}"
    fig.suptitle(title or f"Error map of {where} against {Path(sample_dir).name}'s ground truth (top view)",
                 fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def compare_error_figure(cmp) -> bytes:
    """PNG: signed depth error (mm) per dense method on the plate's bounding box."""
    import io  # noqa: PLC0415

    dense = [r for r in cmp.rows if r.result is not None]
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
        res = r.result
        err = np.where(res.valid & mask, (res.depth.astype(np.float64) - cmp.gt_depth) * 1e3, np.nan)
        a = np.abs(err[np.isfinite(err)])
        lim = float(np.percentile(a, 95)) if a.size else 1.0
        lim = max(lim, 1e-3)
        back = np.where(mask, 0.45, 0.05)[v0:v1, u0:u1]
        ax.imshow(back, cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        im = ax.imshow(err[v0:v1, u0:u1], cmap="coolwarm", vmin=-lim, vmax=lim, interpolation="nearest")
        s = r.scores
        ax.set_title(f"{r.name}\nmed {s['depth_median_mm']:.3f} / RMS {s['depth_rms_mm']:.3f} mm\n"
                     f"cov {s['coverage_pct']:.1f} %, {r.n_images} img/cam", fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
        fig.colorbar(im, ax=ax, fraction=0.046, pad=0.04, label="Z_est - Z_gt (mm)")
    fig.suptitle(f"{cmp.sample_dir}: left-camera depth error (dark grey: plate pixel without estimate)", fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return buf.getvalue()

