"""Interim study and sensing sections, from today's ``study.json`` and ``sensing.json``.

``study_section(study_dir, out_dir)`` and ``sensing_section(sensing_dir, out_dir)`` have the
signature and return the generic section dict (``bench.report.page``) of the functions
``bench.report.sensing`` will provide; ``html.py`` imports them from here until that module
lands, and from there after (a one-line change). Each writes its PNG plots into ``out_dir``
and returns plain data: title, key figures, tables as lists of dicts, plot file names with
captions, notes. Units: errors in mm, bends in degrees, distances in m, fractions 0..1.
"""
from __future__ import annotations

import json
from pathlib import Path

from platebench.bench.io.records import study_extras
from platebench.bench.io.report_records import SensingRun, SensingStep, StudyCase, boundary_hidden
from platebench.bench.report import plots as P
from platebench.bench.report.inputs import load_sensing, load_study
from platebench.bench.report.page import column_label
from platebench.bench.report.summary import precision_recall
from platebench.bench.report.values import finite, flag, fmt

__all__ = ["study_section", "sensing_section"]

# a study row's columns in table order, with the study's own short labels (others: page.column_label)
_CASE_COLUMNS = (("bend_deg", None), ("direction", None), ("axis_deg", None), ("aspect", "aspect L/W"),
                 ("length_m", None), ("width_m", None), ("distance_m", None), ("hidden_frac_left", "hidden L"),
                 ("hidden_frac_right", "hidden R"), ("false_boundary_gt", "GT false bnd"), ("status", "status"),
                 ("detected", "detected"), ("counting_test", "count test"), ("arrays_disagree", "arrays differ"),
                 ("squares_expected", "sq. exp."), ("squares_left", "sq. L"), ("squares_right", "sq. R"),
                 ("matched", "matched"), ("centres_depth_rms_mm", None), ("xy_radial_rms_mm", None),
                 ("boundary_mean_mm", None), ("cure1_removed", "cure 1 ok"), ("cure1_hidden_frac", "hidden after 1"),
                 ("cure2_removed", "cure 2 ok"), ("cure2_hidden_frac", "hidden after 2"),
                 ("cure2_steps", "cure 2 steps"), ("cure2_distance_m", "cure 2 dist (m)"),
                 ("L_measured_m", "L measured (m)"), ("time_s", "time (s)"))
_L_COLUMNS = (("bend_deg", None), ("L_m", "L (m)"), ("predicted_distance_m", "predicted distance (m)"),
              ("gt_distance_baseline_along_axis_m", "GT distance, baseline along axis (m)"),
              ("ratio_gt_over_predicted_baseline_along_axis", "ratio GT / predicted (along axis)"),
              ("gt_distance_baseline_along_bend_m", "GT distance, baseline along bend (m)"),
              ("ratio_gt_over_predicted_baseline_along_bend", "ratio GT / predicted (along bend)"))
_PR_FLAGS = ("detected", "counting_test", "arrays_disagree")


def _columns(spec, rows: list[dict]) -> list:
    """The columns of ``spec`` some row has, as table columns ({"key", "label"} or a bare key)."""
    return [{"key": k, "label": t} if t else k for k, t in spec if any(r.get(k) is not None for r in rows)]


def _series(rows: list[dict]) -> tuple:
    """Direction, plus the case parameters that vary across the study (aspect, distance, axis)."""
    return ("direction",) + tuple(k for k in ("aspect", "distance_m", "axis_deg")
                                  if len({json.dumps(r.get(k), default=str) for r in rows}) > 1)


def _study_figures(rows: list[dict]) -> list[dict]:
    cases = [StudyCase.from_dict(r) for r in rows]
    ok = [c for c in cases if (c.status or "ok") == "ok"]
    times = [t for t in (finite(c.time_s) for c in cases) if t is not None]
    figs = [{"label": "cases", "value": len(rows)}, {"label": "reconstructed", "value": len(ok), "status": "good"},
            {"label": "failed", "value": len(rows) - len(ok), "status": "bad" if len(rows) > len(ok) else ""},
            {"label": "GT false boundary", "value": sum(flag(c.false_boundary_gt) is True for c in cases)},
            {"label": "detected", "value": sum(flag(c.detected) is True for c in cases)}]
    outcomes = [c.outcome for c in cases if isinstance(c.outcome, str)]
    figs += [{"label": k, "value": outcomes.count(k)} for k in dict.fromkeys(outcomes)]
    if times:
        figs.append({"label": "total time", "value": round(sum(times), 1), "unit": "s"})
    return figs


def _study_tables(doc: dict, rows: list[dict]) -> list[dict]:
    tables = []
    sh, lf = study_extras(doc)
    if sh:
        tables.append({"title": "Smallest hiding bend",
                       "caption": "Smallest cylindrical bend (degrees) at which the straight-down reference rig "
                                  "misses part of the true boundary (ground-truth visibility); a dash: no bend up to "
                                  "350 degrees hides it.",
                       "rows": [{"direction": k, "smallest hiding bend (deg)": v} for k, v in sh.items()]})
    pr = doc.get("precision_recall")
    src = "from study.json"
    if not isinstance(pr, dict) or not pr:
        pr = {f: precision_recall(rows, f) for f in _PR_FLAGS if any(r.get(f) is not None for r in rows)}
        src = "computed from the rows"
    if pr:
        keys = ("true_positive", "false_positive", "false_negative", "precision", "recall")
        tables.append({"title": "Detection precision / recall",
                       "caption": "Each flag of the counting test against ground truth (a true-boundary point hidden "
                                  f"from a camera), over the reconstructed cases ({src}); precision and recall are "
                                  "fractions 0..1, a dash where undefined.",
                       "columns": ["flag", *keys],
                       "rows": [{"flag": f, **{k: (v or {}).get(k) for k in keys}} for f, v in pr.items()]})
    if lf:
        lf = [r.to_dict() for r in lf]  # the table's rows, by column
        tables.append({"title": "L formula", "columns": _columns(_L_COLUMNS, lf), "rows": lf,
                       "caption": "The paper's sensing distance L (from the tangents at the ends of the most-bent "
                                  "curve) plus the height of AB, against the ground-truth smallest rig distance at "
                                  "which both cameras see the whole true boundary; distances in metres, ∞ = never "
                                  "fully visible."})
    if rows:
        tables.append({"title": f"Cases ({len(rows)})", "columns": _columns(_CASE_COLUMNS, rows), "rows": rows})
    errs = [r for r in rows if (r.get("status") or "ok") != "ok" or r.get("cure_error")]
    if errs:
        tables.append({"title": f"Failures ({len(errs)})", "columns": ["bend_deg", "direction", "status", "error"],
                       "rows": [{**r, "error": r.get("error") or r.get("cure_error")} for r in errs]})
    return tables


def _plot(fn, *args, caption: str, **kwargs) -> dict:
    """A generic section's plot entry ({"file", "caption", "left_out"}): ``file`` None, and one line in
    ``left_out`` saying why, when the figure has nothing to show (``plots.drawn``)."""
    path, left = P.drawn(fn, *args, **kwargs)
    what = Path(args[-1]).stem.replace("_", " ")  # the PNG's name: "detection vs bend"
    lines = list(left.panels) if path is not None else [f"plot '{what}' left out: {left.figure}"]
    return {"file": path.name if path is not None else None, "caption": caption, "left_out": lines}


def _study_plots(doc: dict, rows: list[dict], out_dir: Path) -> list[dict]:
    out_dir = Path(out_dir)
    plots = []
    sh, lf = study_extras(doc)
    if rows:
        plots.append(_plot(P.plot_hidden_fraction_vs_bend, rows, out_dir / "hidden_fraction_vs_bend.png",
                           series=_series(rows), smallest_hiding=sh or None,
            caption="Top: fraction (0..1) of the true boundary hidden from the worse camera at the default pose "
                       "against the bend angle (degrees), per bend direction; small hollow triangles: left (<) and "
                       "right (>) camera; dotted verticals: smallest hiding bend. Bottom: per case, the ground truth "
                       "(circles) and the pipeline's verdict (squares): filled = yes, hollow = no, grey x = no "
                       "verdict (reconstruction failed)."))
        plots.append(_plot(P.plot_detection_vs_bend, rows, out_dir / "detection_vs_bend.png",
                      caption="Precision and recall (0..1) of the false-boundary verdict and of each of its two "
                                 "symptoms (fewer squares than expected; the arrays of the two images disagree) "
                                 "against ground truth, per bend-angle bin (degrees, n = cases); grey bars: fraction "
                                 "of cases with a ground-truth false boundary. Gaps: undefined."))
        if any(r.get("cure1_removed") is not None or r.get("cure2_removed") is not None for r in rows):
            plots.append(_plot(P.plot_cure_success_vs_bend, rows, out_dir / "cure_success_vs_bend.png",
                          caption="Cases with a ground-truth false boundary. Left: fraction of cases (0..1) in "
                                     "which each cure leaves the whole true boundary visible, by bend angle "
                                     "(degrees). Right: hidden fraction of the true boundary (0..1) before (black "
                                     "bars) and after each cure."))
        if any(finite(r.get(k)) is not None for r in rows for k in ("centres_depth_rms_mm", "boundary_mean_mm")):
            plots.append(_plot(P.plot_error_vs_bend, rows, out_dir / "error_vs_bend.png", series=_series(rows),
                                title="Study: error against bend angle",
                          caption="Depth RMS error of the square centres (mm) and mean boundary distance (mm) "
                                     "against the bend angle (degrees), solid/dashed per bend direction; red crosses "
                                     "mark cases whose reconstruction failed."))
    if lf:
        plots.append(_plot(P.plot_l_formula, lf, out_dir / "l_formula.png",
                      caption="Left: the L formula's predicted rig distance (m) and the ground-truth distance of "
                                 "complete visibility (m) against the bend angle (degrees), for a baseline along the "
                                 "bend axis and along the bend. Right: ground truth against prediction (m); points "
                                 "above the grey line mean the formula is too close."))
    return plots


def study_section(study_dir: Path, out_dir: Path) -> dict:
    """The false-boundary study of ``study_dir`` as a generic section dict; plots into ``out_dir``."""
    doc = load_study(study_dir)
    rows = doc["rows"]
    cures = doc.get("cures")
    summary = ""
    if isinstance(cures, dict) and cures:
        summary = "Cures over the cases with a ground-truth false boundary: " + ", ".join(
            f"{k.replace('_removed_frac', '')} removes it in "
            + (f"{v:.3g} of them" if finite(v) is not None else "none (no such case)")
            for k, v in cures.items()) + " (fraction 0..1)."
    const = _constant_columns(rows)
    if const:
        summary += " All cases: " + ", ".join(f"{column_label(k)} {fmt(rows[0].get(k))}" for k in const) + "."
    summary += f" Read from {doc['source']}."
    shown = [{k: v for k, v in r.items() if k not in const} for r in rows]
    return {"title": "False-boundary study", "summary": summary.strip(), "figures": _study_figures(rows),
            "tables": _study_tables(doc, shown), "plots": _study_plots(doc, rows, out_dir),
            "links": [{"label": n, "path": n} for n in ("study.json", "study.csv")],
            "notes": [] if rows else ["the study holds no case rows"]}


def _constant_columns(rows: list[dict]) -> list[str]:
    """Case parameters every row shares (said once above the table instead of in every row)."""
    if len(rows) < 2:
        return []
    keys = ("axis_deg", "aspect", "length_m", "width_m", "distance_m", "squares_expected")
    return [k for k in keys if rows[0].get(k) is not None
            and len({json.dumps(r.get(k), default=str) for r in rows}) == 1]


# ----------------------------------------------------------------------------- sensing run
def _step_row(step: dict) -> dict:
    st = SensingStep.from_dict(step)
    fb, vis = st.false_boundary, st.gt_visibility
    what = f"stage {st.stage}" if "stage" in step else str(step.get("decision", ""))
    if st.method is not None:
        what += f" (cure {st.method})"
    return {"step": what, "distance (m)": st.distance_m,
            "squares detected": fb.detected_text() if fb else None,
            "squares expected": fb.expected if fb else None, "matched": st.matched,
            "false boundary detected": fb.false_boundary_detected if fb else None,
            "GT visible L": vis["left"].visible_fraction if "left" in vis else None,
            "GT visible R": vis["right"].visible_fraction if "right" in vis else None,
            "reason": st.reason or st.pose_reason}


def sensing_section(sensing_dir: Path, out_dir: Path) -> dict:
    """The sensing run of ``sensing_dir`` (its sensing.json) as a generic section dict."""
    doc = load_sensing(sensing_dir)
    run = SensingRun.from_dict(doc)
    final = run.final
    detected = final.false_boundary.false_boundary_detected if final.false_boundary else None
    vis = final.gt_visibility
    outcome = run.outcome
    figures = [{"label": "cures", "value": run.cures},
               {"label": "points matched", "value": final.matched},
               {"label": "false boundary detected", "value": detected, "status": "bad" if detected else "good"}]
    figures += [{"label": f"GT: {cam} camera sees", "value": v.visible_fraction,
                 "unit": "fraction of the boundary"} for cam, v in vis.items()]
    figures += [{"label": column_label(k), "value": v} for k, v in final.accuracy.items()]
    if finite(run.time_s) is not None:
        figures.append({"label": "time", "value": round(run.time_s, 1), "unit": "s"})
    hidden = boundary_hidden(vis)
    summary = ((f"Outcome: {outcome}. " if outcome else "")
               + ("Ground truth: part of the true boundary is still hidden at the final pose. " if hidden else
                  "Ground truth: the final pose sees the whole true boundary. ")
               + ("The loop reports a false boundary." if detected else
                  "The loop reports no false boundary."))
    steps = [s for s in doc.get("steps") or [] if isinstance(s, dict)]  # the table's rows, as the file holds them
    stages = sorted(p.name for p in Path(sensing_dir).glob("stage*") if p.is_dir())
    links = [{"label": "sensing.json", "path": "sensing.json"}] + [{"label": f"{n} folder", "path": n} for n in stages]
    return {"title": "Sensing run", "summary": summary, "outcome": outcome, "figures": figures,
            "tables": [{"title": "Steps", "rows": [_step_row(s) for s in steps],
                        "caption": "Every stage and decision of the loop in order; distances in m; GT visible: "
                                   "fraction (0..1) of the true boundary each camera sees (ground truth, for "
                                   "scoring only)."}],
            "plots": [], "links": links, "notes": []}
