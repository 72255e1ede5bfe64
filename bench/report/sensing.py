"""The report's sensing-run and false-boundary-study sections, from ``sensing.json`` (+
``multiview.npz``) and ``study.json``.

``sensing_section(sensing_dir, out_dir)`` and ``study_section(study_dir, out_dir)`` return the
generic section dict of ``bench.report.page`` (title, summary, outcome, figures, tables, plots,
links, notes) and write their PNG plots into ``out_dir``. A study written before the sensing study
(rows of the old cure study, no ``outcomes``) is shown by ``bench.report.interim``.

Plots: each pose's measured outline against the true boundary, and the merged boundary (top view,
millimetres); the outcome classes per bend and per family; each detector's precision and recall
per family, a detector in one colour (``bench.report.colours``). A plot or panel with nothing to
show is left out and said in one line (``plots.LeftOut``). Units: millimetres, degrees, fractions
0..1, seconds.

The loop's verdict is shown in the words of ``bench.io.records.loop_verdict_text`` (the sensing
run's summary, the plates table's "loop verdict" column), the one source the command line uses
too, so that a plate's verdict and its outcome class never read as a contradiction.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from platebench.bench.io.records import StudyRow, StudyTargets, final_figures, loop_verdict_text, study_rows
from platebench.bench.report import interim
from platebench.bench.report import plots as P
from platebench.bench.report.colours import colour_of, method_colours
from platebench.bench.report.inputs import ReportInputError, load_sensing, load_study
from platebench.bench.report.values import finite
from platebench.evaluation.detection import DetectionScore
from platebench.bench.io.report_records import SensingStep

__all__ = ["sensing_section", "study_section", "plot_multiview", "plot_outcomes", "plot_detectors",
           "detection_scores"]

OUTCOME_COLORS = {"cured": "#2ca02c", "clean": "#98df8a", "honest": "#ff7f0e", "unconfirmed": "#ffbb78",
                  "false_alarm": "#9467bd", "silent": "#d62728", "error": "#7f7f7f"}
MAX_POSE_PANELS = 15


# ----------------------------------------------------------------------------- plots
def plot_multiview(npz_path: Path, path: Path) -> Path:
    """One panel per pose: its measured outline (confirmed points green, others red) and its checked
    square centres (black dots) over the true boundary (grey), top view (x, y in mm); a last panel:
    the merged boundary and every pose's square centres over the true one."""
    d = np.load(npz_path)
    names = [str(n) for n in d["view_names"]][:MAX_POSE_PANELS]
    T = d["true_boundary"] * 1e3
    n = len(names) + 1
    cols = min(4, n)
    rows = (n + cols - 1) // cols
    fig = P._figure(3.0 * cols, 2.6 * rows)
    pts, view, conf = d["outline_points"] * 1e3, d["outline_view"], d["outline_confirmed"].astype(bool)
    act = d["active_points"] * 1e3 if "active_points" in d else np.zeros((0, 3))
    act_view = d["active_view"] if "active_view" in d else np.zeros(0, int)
    for k in range(n):
        ax = fig.add_subplot(rows, cols, k + 1)
        ax.plot(np.r_[T[:, 0], T[:, 0][:1]], np.r_[T[:, 1], T[:, 1][:1]], color="0.6", lw=1.0)
        if k < len(names):
            m = view == k
            ax.scatter(pts[m & ~conf, 0], pts[m & ~conf, 1], s=2, color="#d62728", label="not confirmed")
            ax.scatter(pts[m & conf, 0], pts[m & conf, 1], s=2, color="#2ca02c", label="confirmed")
            a = act[act_view == k]
            ax.scatter(a[:, 0], a[:, 1], s=1.5, color="k", label="square centres")
            ax.set_title(f"{names[k]} ({len(a)} squares)", fontsize=8)
        else:
            M = d["merged"] * 1e3
            if len(M):
                ax.scatter(M[:, 0], M[:, 1], s=2, color="#1f77b4")
            G = d["gaps"] * 1e3
            if len(G):
                ax.scatter(G[:, 0], G[:, 1], s=30, marker="x", color="#d62728")
            if len(act):
                ax.scatter(act[:, 0], act[:, 1], s=1, color="k")
            ax.set_title(f"merged: boundary (x: gaps), {len(act)} square centres", fontsize=8)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=6)
    fig.suptitle("Measured outline per pose vs the true boundary (grey), top view, mm", fontsize=9)
    fig.tight_layout()
    return P._save(fig, path)


def plot_outcomes(counts: dict, path: Path, title: str, xlabel: str, left_out: P.LeftOut | None = None) -> Path:
    """Stacked bars of outcome counts per group (``counts``: group -> {outcome: n}); no group: the
    figure has nothing to show (``left_out.figure``, ``plots.LeftOut``)."""
    fig = P._figure(max(5.0, 0.6 * len(counts) + 2), 3.4)
    ax = fig.add_subplot(1, 1, 1)
    groups = list(counts)
    if not groups:
        P._nothing(left_out, f"no plate is grouped by {xlabel.split(' (')[0]}")
        P._empty(ax, "no plates")
        return P._save(fig, path)
    bottom = np.zeros(len(groups))
    for oc, color in OUTCOME_COLORS.items():
        v = np.array([counts[g].get(oc, 0) for g in groups], float)
        if v.any():
            ax.bar(range(len(groups)), v, bottom=bottom, color=color, label=oc.replace("_", " "))
            bottom += v
    ax.set_xticks(range(len(groups)))
    ax.set_xticklabels(groups, fontsize=8)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("plates")
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=7, ncol=4, loc="upper left")
    ax.set_ylim(0, bottom.max() * 1.35 + 1)
    fig.tight_layout()
    return P._save(fig, path)


_DETECTION_COUNTS = ("true_positive", "false_positive", "false_negative", "true_negative")
# why a detector's precision or recall is undefined (``DetectionScore``: no positive verdict; no positive truth)
_UNDEFINED = {"precision": "the detector never fired",
              "recall": "no plate hides part of the boundary at the stage-2 pose"}


def detection_scores(scores) -> dict:
    """study.json's detector scores (detector -> {the four counts, ...}) as ``DetectionScore``s; a
    detector whose counts are not all whole numbers is left out."""
    out = {}
    for det, d in (scores or {}).items() if isinstance(scores, dict) else ():
        counts = [d.get(k) for k in _DETECTION_COUNTS] if isinstance(d, dict) else []
        if len(counts) == len(_DETECTION_COUNTS) and all(isinstance(c, int) and not isinstance(c, bool)
                                                         for c in counts):
            out[str(det)] = DetectionScore(*counts)
    return out


def plot_detectors(scores: dict, path: Path, left_out: P.LeftOut | None = None) -> Path:
    """Each detector's precision and recall (0..1) per family (``scores``: family -> detector ->
    ``DetectionScore``), each detector in its colour of ``colours.method_colours`` over the detectors'
    names. A detector undefined in every family of a panel has no bars there, and a panel undefined
    for every detector is left out, each said in one line of ``left_out`` (``plots.LeftOut``); both
    panels undefined: the figure has nothing to show (``left_out.figure``)."""
    fams = list(scores)
    dets = list(dict.fromkeys(d for f in fams for d in scores[f]))
    colours = method_colours(dets)

    def value(family, det, what):
        s = scores[family].get(det)
        return None if s is None else getattr(s, what)

    shown = {what: [d for d in dets if any(value(f, d, what) is not None for f in fams)] for what in _UNDEFINED}
    panels = [what for what in _UNDEFINED if shown[what]]
    for what, why in _UNDEFINED.items():
        if left_out is None:
            break
        if what not in panels:
            left_out.panel(f"{what} panel left out: {what} is undefined for every detector in every family ({why})")
        elif gone := [d.replace("_", " ") for d in dets if d not in shown[what]]:
            left_out.panel(f"{what}: {', '.join(gone)} left out: undefined in every family ({why})")
    if not panels:
        P._nothing(left_out, "precision and recall are undefined for every detector in every family (no detector "
                             "fired and no plate hides part of the boundary at the stage-2 pose)")
    on = panels or list(_UNDEFINED)
    fig = P._figure(4.6 * len(on), 3.2)
    for j, what in enumerate(on):
        ax = fig.add_subplot(1, len(on), j + 1)
        if not shown[what]:
            P._empty(ax, f"{what} undefined for every detector ({_UNDEFINED[what]})")
            continue
        w = 0.8 / len(shown[what])
        for i, det in enumerate(shown[what]):
            v = [value(f, det, what) for f in fams]
            ax.bar(np.arange(len(fams)) + i * w, [np.nan if x is None else x for x in v], w,
                   color=colour_of(colours, det), label=det.replace("_", " "))
        ax.set_xticks(np.arange(len(fams)) + 0.4 - w / 2)
        ax.set_xticklabels(fams, fontsize=8)
        ax.set_ylim(0, 1.05)
        ax.set_ylabel(what)
        ax.set_title(f"{what} against GT 'hidden at stage 2'", fontsize=9)
        ax.legend(fontsize=6)
    fig.tight_layout()
    return P._save(fig, path)


# ----------------------------------------------------------------------------- sensing run
def _pct(gv) -> str:
    try:
        return f"{gv['left']['visible_fraction'] * 100:.0f}/{gv['right']['visible_fraction'] * 100:.0f} %"
    except (KeyError, TypeError):
        return "-"


def _step_row(st: dict) -> dict:
    step = SensingStep.from_dict(st)
    if "decision" in st:
        return {"step": f"decision: {st['decision']}", "distance (m)": SensingStep.from_dict(st.get("view")).distance_m,
                "GT visible L/R": None, "what": st.get("reason")}
    if st.get("stage") == "view":
        what, name = (st.get("error") or f"{st.get('outline_points')} outline points"), \
            f"{st.get('purpose')} view {st.get('name')} ({st.get('method')})"
    elif st.get("stage") == 3:
        fb = step.false_boundary
        what = (f"{st.get('matched')} points; squares {fb.detected_text()} of {fb.expected}; paper's test "
                + ("fires" if fb.false_boundary_detected else "quiet")) if fb else st.get("error")
        name = "stage 3"
    else:
        what, name = f"{st.get('boundary_points')} boundary points ({st.get('boundary_method')})", \
            f"stage {st.get('stage')}"
    return {"step": name, "distance (m)": step.distance_m, "GT visible L/R": _pct(st.get("gt_visibility")),
            "what": what}


# the figure cards of a sensing run: (field of ``MergedFigures`` / ``Stage3Accuracy``, label, unit)
MERGED_CARDS = (("boundary_mean_mm", "merged boundary mean distance", "mm"),
                ("points", "merged square centres (all poses)", ""),
                ("points_rms_mm", "merged square centres' RMS distance to the plate", "mm"),
                ("surface_coverage_frac", "merged surface coverage (share of the true surface within 2 mm)",
                 "fraction"),
                ("surface_rms_mm", "merged surface RMS", "mm"))
STAGE3_CARDS = (("centres_depth_rms_mm", "stage-3 depth RMS at the square centres", "mm"),)


def sensing_section(sensing_dir: Path, out_dir: Path) -> dict:
    """The sensing run of ``sensing_dir`` as a generic section dict."""
    doc = load_sensing(sensing_dir)
    final = doc.get("final") or {}
    if "boundary_verified" not in final:  # a record from before the verdict: the interim section
        return interim.sensing_section(sensing_dir, out_dir)
    outcome = final.get("outcome")
    acc, merged = final_figures(final)
    verified = final.get("boundary_verified")
    verdict = loop_verdict_text(outcome, None if verified is None else bool(verified), doc.get("cures"),
                                final.get("verdict") or None)
    figures = [{"label": "outcome", "value": outcome,
                "status": "bad" if outcome in ("silent", "false_alarm") else "good" if outcome in ("clean", "cured")
                else ""},
               {"label": "cures", "value": doc.get("cures")},
               {"label": "verification views", "value": len(doc.get("verification_views") or [])},
               {"label": "poses", "value": len(final.get("poses") or [])}]
    for name, label, unit in MERGED_CARDS:
        if finite(v := getattr(merged, name)) is not None:
            figures.append({"label": label, "value": round(v, 3), "unit": unit})
    for name, label, unit in STAGE3_CARDS:
        if acc is not None and finite(v := getattr(acc, name)) is not None:
            figures.append({"label": label, "value": round(v, 4), "unit": unit})
    if (time_s := finite(doc.get("time_s"))) is not None:
        figures.append({"label": "time", "value": round(time_s, 1), "unit": "s"})
    summary = (f"Outcome: {outcome} ({final.get('outcome_text', '')}). {verdict[:1].upper() + verdict[1:]}. "
               f"Ground truth: the stage-2 pose sees L/R "
               f"{_pct(final.get('gt_visibility_first'))} of the boundary, the final poses together "
               f"{_pct(final.get('gt_visibility'))}.")
    tables = [{"title": "Steps", "rows": [_step_row(s) for s in doc.get("steps") or [] if isinstance(s, dict)],
               "caption": "Every stage, view and decision of the loop in order; distances in m; GT visible L/R: "
                          "percent of the true boundary each camera sees (ground truth, for scoring only)."}]
    dets = doc.get("detectors") or {}
    if dets:
        tables.append({"title": "Detectors at the stage-2 pose",
                       "rows": [{"detector": k, "fired": v.get("fired"), "measure": v.get("measure"),
                                 "unit": v.get("unit"), "detail": v.get("detail")} for k, v in dets.items()],
                       "caption": "Each detector's verdict on whether the stage-2 pose misses part of the boundary "
                                  "(no ground truth); a dash: it could not be evaluated."})
    parts = final.get("unverified_parts") or []
    if parts:
        tables.append({"title": "Unverified parts", "rows": [{"what": p.get("what")} for p in parts]})
    plots, notes = [], []
    npz = Path(sensing_dir) / "multiview.npz"
    if npz.is_file():
        try:
            plots.append({"file": plot_multiview(npz, Path(out_dir) / "multiview.png").name,
                          "caption": "Each pose's measured outline (green: confirmed by another pose as a true edge; "
                                     "red: not confirmed, e.g. an occluding contour) over the true boundary (grey), "
                                     "top view in mm; last panel: the merged boundary and its gaps."})
        except (OSError, KeyError, ValueError) as e:
            notes.append(f"multiview.npz not drawn: {e}")
    links = [{"label": "sensing.json", "path": "sensing.json"}, {"label": "multiview.npz", "path": "multiview.npz"},
             {"label": "stage 3 folder", "path": "stage3"}]
    return {"title": "Sensing run", "summary": summary, "outcome": outcome, "figures": figures, "tables": tables,
            "plots": plots, "links": links, "notes": notes + [str(n) for n in doc.get("notes") or []]}


# ----------------------------------------------------------------------------- study
_ROW_COLUMNS = ("case", "family", "bend_deg", "direction", "axis_deg", "aspect", "distance_m", "outcome",
                "loop_verdict", "cures", "views", "det_counting_test", "det_arrays_disagree",
                "det_viewpoint_consistency", "det_occluding_contour", "det_end_tangents", "gt_visible_first_frac",
                "gt_visible_final_frac", "gt_reachable", "gt_verifiable", "merged_boundary_mean_mm",
                "merged_surface_coverage_frac", "time_s", "error")


def _cell(row: StudyRow, column: str):
    """A study row's value in one of ``_ROW_COLUMNS`` (``det_<name>``: that detector's verdict;
    ``loop_verdict``: the loop's verdict in the words of ``StudyRow.verdict_text``)."""
    if column == "loop_verdict":
        return row.verdict_text()
    return row.fired(column[len("det_"):]) if column.startswith("det_") else getattr(row, column)


def _has(row: StudyRow, column: str) -> bool:
    return column[len("det_"):] in row.detectors if column.startswith("det_") else _cell(row, column) is not None


def _plot(fn, *args, caption: str) -> dict:
    """A plot entry of a generic section ({"file", "caption", "left_out"}, ``bench.report.page``):
    ``file`` None, and one line saying why, when the figure has nothing to show (``plots.drawn``)."""
    path, left = P.drawn(fn, *args)
    if path is None:
        return {"file": None, "caption": caption, "left_out": [f"plot '{Path(args[1]).stem.replace('_', ' ')}' "
                                                              f"left out: {left.figure}"]}
    return {"file": path.name, "caption": caption, "left_out": list(left.panels)}


def study_section(study_dir: Path, out_dir: Path) -> dict:
    """The false-boundary study of ``study_dir`` as a generic section dict."""
    doc = load_study(study_dir)
    if "outcomes" not in doc:  # a study.json without outcomes: the interim section's rows
        return interim.study_section(study_dir, out_dir)
    try:
        rows = study_rows(doc)
    except ValueError as e:
        raise ReportInputError(f"{Path(study_dir) / 'study.json'}: {e}") from None
    t = StudyTargets.from_dict(doc["targets"]) if isinstance(doc.get("targets"), dict) else None
    oc = doc.get("outcomes") or {}
    if not isinstance(oc, dict):
        raise ReportInputError(f"{Path(study_dir) / 'study.json'}: 'outcomes' must be an object")
    figures = [{"label": "plates", "value": len(rows)}] + [
        {"label": k.replace("_", " "), "value": v,
         "status": ("bad" if v else "good") if k in ("silent", "error") else ""} for k, v in oc.items()]
    if (time_s := finite(doc.get("time_s"))) is not None:
        ran = doc.get("plates_run", len(rows))  # time_s covers the plates this run measured (not a journal's)
        if isinstance(ran, int) and ran > 0:
            figures.append({"label": "time per plate", "value": round(time_s / ran, 1), "unit": "s"})
    met = t.met if t is not None else {}
    summary = ("Targets: " + ", ".join(f"{k} {'n/a' if v is None else ('met' if v else 'NOT met')}"
                                       for k, v in met.items())
               + (f". Cured {t.seen_all_of_curable} of {t.curable} plates whose stage-2 pose hides "
                  f"part of the boundary and whose reachable poses see it (the final poses see it all); the loop "
                  f"verified {t.cured_of_curable} of them, {t.cured_of_verifiable} of the "
                  f"{t.verifiable} that pairs of reachable poses could confirm; false alarms "
                  f"{t.false_alarms} of {t.nothing_hidden} plates with nothing hidden." if t is not None else ""))
    det = doc.get("detectors") if isinstance(doc.get("detectors"), dict) else {}
    keys = (*_DETECTION_COUNTS, "precision", "recall")
    tables = [{"title": "Outcomes per family", "columns": ["family", *OUTCOME_COLORS],
               "rows": [{"family": f, **c} for f, c in (doc.get("outcomes_by_family") or {}).items()]},
              {"title": "Outcomes per bend", "columns": ["bend (deg)", *OUTCOME_COLORS],
               "rows": [{"bend (deg)": b, **c} for b, c in (doc.get("outcomes_by_bend") or {}).items()],
               "caption": "Cylinders, folds and the flat plate by bend angle (degrees)."},
              {"title": "Detectors: precision and recall", "columns": ["detector", *keys],
               "rows": [{"detector": d, **{k: getattr(s, k) for k in keys}}
                        for d, s in detection_scores(det.get("all")).items()],
               "caption": "Each detector against ground truth's 'the stage-2 pose hides part of the true boundary', "
                          "over the plates without error (evaluation.detection)."},
              {"title": f"Plates ({len(rows)})", "columns": (cols := [c for c in _ROW_COLUMNS
                                                                      if any(_has(r, c) for r in rows)]),
               "rows": [{c: _cell(r, c) for c in cols} for r in rows]}]
    plots = []
    if rows:
        plots.append(_plot(plot_outcomes, doc.get("outcomes_by_bend") or {}, Path(out_dir) / "outcomes_bend.png",
                           "Outcome classes per bend (cylinders, folds, flat)", "bend (deg)",
                           caption="Number of plates in each outcome class per bend angle (degrees)."))
        plots.append(_plot(plot_outcomes, doc.get("outcomes_by_family") or {}, Path(out_dir) / "outcomes_family.png",
                           "Outcome classes per family", "family",
                           caption="Number of plates in each outcome class per deformation family."))
        by_family = det.get("by_family") if isinstance(det.get("by_family"), dict) else {}
        if by_family:
            plots.append(_plot(plot_detectors, {f: detection_scores(s) for f, s in by_family.items()},
                               Path(out_dir) / "detectors_family.png",
                               caption="Each detector's precision and recall (0..1) per family, a detector in one "
                                       "colour; a missing bar: undefined in that family (no plate of it hidden, or "
                                       "the detector never fired there)."))
    return {"title": "False-boundary study (sensing loop)", "summary": summary, "outcome": None,
            "figures": figures, "tables": tables, "plots": plots,
            "links": [{"label": n, "path": n} for n in ("study.json", "study.csv")],
            "notes": [f"{r.case}: {r.error}" for r in rows if r.outcome == "error"]}
