"""Sections of single experiments: a rendered sample, a reconstruction (with its score), and the
compare.json of ``platebench compare``.

A reconstruction's section shows the score's key figures (depth and x/y errors in mm, points
matched of expected, boundary and surface distances in mm), the paper's bound (V-D: all
points, depth within 2 mm, x/y within 1 mm) and the bench's goals met or not, the false-boundary
verdict against ground truth, the error map, every figure of score.json, links to the
reconstruction and sample folders and thumbnails of the sample's images. The paper's reference
experiment (the default configuration: 116.5 x 73.5 mm plate bent 10 degrees, 1280 x 960,
0.40 m) is named as such.
"""
from __future__ import annotations

from pathlib import Path

from platebench.bench.config import SampleConfig
from platebench.bench.config.axes import PARAMETERS, parameter_columns
from platebench.bench.io.codecs import encode
from platebench.bench.io.records import compare_methods, score_record
from platebench.bench.io.report_records import FalseBoundaryRecord, RunTimings, boundary_hidden, visibility_records
from platebench.bench.report import plots as P
from platebench.bench.report.inputs import (
    load_compare,
    load_recon,
    load_sample_meta,
    load_score_document,
    read_json,
    recon_sample_dir,
    score_document_paths,
)
from platebench.bench.report.page import Page
from platebench.bench.report.values import finite, fmt
from platebench.evaluation.metrics_row import MetricsRow, metric_label, metric_unit

__all__ = ["recon_section", "sample_section", "compare_section", "score_section", "is_reference", "score_figures",
           "warned_figures", "scored_errors"]

_TITLES = {p.name: p.title for p in PARAMETERS}
# key figures of the paper's score.json (read back as a ``Score``): its results columns
# (``MetricsRow.from_score``), labelled by ``evaluation.metrics_row.metric_label``, in card order
_PAPER_FIGURES = ("centres_depth_rms_mm", "centres_depth_max_mm", "xy_radial_rms_mm", "err3d_rms_mm",
                  "boundary_mean_mm", "surface_rms_mm", "coverage_frac")
# key figures of another method's score document: (key in it, dotted from the top, under "score"; the
# results column whose label and unit it takes), in card order
_SCORE_FIGURES = (
    ("score.depth_rms_mm", "depth_rms_mm"), ("score.depth_median_mm", "depth_median_mm"),
    ("score.depth_max_mm", "depth_max_mm"), ("score.coverage_frac", "coverage_frac"),
    ("score.middlebury.mb_all_bad_1_0_pct", "mb_all_bad_1_0_pct"),
    ("score.middlebury.mb_nonocc_bad_1_0_pct", "mb_nonocc_bad_1_0_pct"),
    ("score.dist_rms_mm", "dist_rms_mm"), ("score.outlier_frac", "outlier_frac"),
    ("score.accuracy_rms_mm", "accuracy_rms_mm"), ("score.completeness_rms_mm", "completeness_rms_mm"),
    ("score.fscore_1_0_mm_pct", "fscore_1_0_mm_pct"),
)


def _flatten(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flatten(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def is_reference(config: dict) -> bool:
    """Whether a sample's configuration is the paper's reference experiment (the default plate and scene)."""
    ref = encode(SampleConfig())
    return all(config.get(k) == ref[k] for k in ("plate", "scene", "sensor"))


def _card(column: str, value) -> dict:
    unit = metric_unit(column)
    label = metric_label(column)
    return {"label": label[: -len(f" ({unit})")] if unit and label.endswith(f" ({unit})") else label,
            "value": value, "unit": unit if unit != "count" else "", "status": ""}


def _is_paper_score(score: dict) -> bool:
    """The paper pipeline's score.json (``evaluation.score.Score.to_dict``), not another method's document."""
    return isinstance(score.get("matching"), dict)


def score_figures(score: dict) -> list[dict]:
    """The key figures of a score.json or score document (cards). The paper's score.json (read back
    as a ``Score``): points matched of expected, then each of ``_PAPER_FIGURES`` it holds; another
    method's document: each of ``_SCORE_FIGURES`` it holds; labelled as its results column."""
    if _is_paper_score(score):
        s = score_record(score)
        m = s.matching
        row = MetricsRow.from_score(s)
        return [{"label": "points matched / expected", "value": f"{m.matched_count} / {m.expected_count_gt}",
                 "unit": "", "status": "good" if m.matched_count == m.expected_count_gt else "bad"}] + \
            [_card(c, v) for c in _PAPER_FIGURES if (v := finite(getattr(row, c))) is not None]
    flat = _flatten(score)
    flat.update({"score." + k[len("scores."):]: v for k, v in flat.items() if k.startswith("scores.")})  # a peer's
    return [_card(column, v) for key, column in _SCORE_FIGURES if (v := finite(flat.get(key))) is not None]


def warned_figures(figures: list[dict], hints) -> list[dict]:
    """``figures`` with the plausibility hints (``evaluation.plausibility``) as a warning beside each
    figure they concern: a hint says the file's errors lie beyond the scene, so every length error
    (mm) read from it; the warned figures come first, so that the headline shows them."""
    text = " ".join(str(h) for h in hints if str(h).strip())
    if not text:
        return figures
    out = [{**f, "warning": text, "status": "bad"} if f.get("unit") == "mm" else f for f in figures]
    return [f for f in out if f.get("warning")] + [f for f in out if not f.get("warning")]


def _verdicts(score: dict) -> list[dict]:
    """The paper's bound, the goals and the false-boundary verdict of the paper's score.json (read
    back as a ``Score``): {"label", "met", "text"}; [] for another method's document."""
    if not _is_paper_score(score):
        return []
    s = score_record(score)
    out = []
    pb = s.paper_bound
    if pb is not None:
        out.append({"label": "paper's bound (V-D)", "met": pb.met,
                    "text": f"every expected point found: {fmt(pb.all_points)}; depth max "
                            f"{fmt(pb.depth_max_mm, 3)} mm (bound {fmt(pb.depth_limit_mm)} mm); x/y max per axis "
                            f"{fmt(pb.xy_per_axis_max_mm, 3)} mm (bound {fmt(pb.xy_limit_mm)} mm)"})
    g = s.goals
    if g is not None:
        out.append({"label": "bench goals", "met": g.met,
                    "text": f"depth RMS {fmt(g.depth_rms_mm, 3)} mm (goal {fmt(g.depth_rms_goal_mm)}); "
                            f"x/y RMS per axis {fmt(g.xy_per_axis_rms_mm, 3)} mm (goal "
                            f"{fmt(g.xy_per_axis_rms_goal_mm)}); boundary mean "
                            f"{fmt(g.boundary_mean_mm, 3)} mm (goal {fmt(g.boundary_mean_goal_mm)})"})
    fb = s.false_boundary
    out.append({"label": "false-boundary verdict", "met": fb.agrees,
                "text": "ground truth: " + ("part of the boundary hidden" if fb.ground_truth_any else
                                            "whole boundary visible")
                        + "; the method: " + ("false boundary detected" if fb.detected else "none detected")})
    return out


def _score_tables(score: dict) -> list[dict]:
    """Every figure of score.json, one key/value table per part (units in the keys)."""
    tables = []
    loose = {k: v for k, v in score.items() if not isinstance(v, dict)}
    parts = [(k, v) for k, v in score.items() if isinstance(v, dict) and k != "per_point"]  # per point: the error map
    for part, body in [("score", loose)] + parts:
        flat = _flatten(body)
        if flat:
            tables.append({"title": part.replace("_", " "), "rows": list(flat.items())})
    return tables


def _config_facts(config: dict, pose: dict | None = None) -> list[tuple[str, object]]:
    """The sample's parameters as (label with unit, value), from the one parameter registry."""
    return [(_TITLES[k], v) for k, v in parameter_columns(config, pose).items() if v is not None]


def _visibility(sample: Path) -> str | None:
    path = sample / "gt" / "visibility.json"
    if not path.is_file():
        return None
    doc = read_json(path, "visibility record")
    if not isinstance(doc, dict):
        return None
    vis = visibility_records(doc)
    parts = [f"{cam} sees {fmt(100 * v.visible_fraction, 3)} %" for cam, v in vis.items()
             if finite(v.visible_fraction) is not None]
    hidden = boundary_hidden(vis)
    return ("part of the true boundary is hidden (a false boundary): " if hidden else
            "the whole true boundary is visible: ") + ", ".join(parts)


def _sample_part(page: Page, sample: Path, prefix: str, thumbs: bool = True) -> dict:
    meta = load_sample_meta(sample)
    config = meta.get("config") if isinstance(meta.get("config"), dict) else {}
    return {"href": page.link(sample), "rel": page.rel(sample), "facts": _config_facts(config),
            "variant": meta.get("variant"), "render_s": RunTimings.of(meta).total_s,
            "visibility": _visibility(sample), "reference": is_reference(config),
            "thumbs": page.thumbnails(sample) if thumbs else [],
            "packages": [(k, v if v is not None else "not installed")
                         for k, v in (meta.get("packages") or {}).items()]}


def sample_section(page: Page, sample: Path, prefix: str) -> dict:
    """A rendered sample on its own: parameters, ground-truth visibility, thumbnails, its folder."""
    part = _sample_part(page, sample, prefix)
    title = "The paper's reference experiment: sample" if part["reference"] else f"Sample {part['rel']}"
    return {"kind": "experiment", "title": title, "sample": part, "recon": None, "sample_link": None,
            "headline": {"label": title, "text": part["visibility"] or "no ground-truth visibility record",
                         "met": None}}


def _recon_facts(meta: dict) -> list[tuple[str, object]]:
    """What recon.json (the paper's pipeline) says of itself; [] for other methods' folders."""
    if not meta:
        return []
    fb = FalseBoundaryRecord.of(meta) or FalseBoundaryRecord()
    return [("points triangulated", meta.get("n_points")), ("boundary points", meta.get("n_boundary_points")),
            ("squares detected per image", fb.detected_text() or ""),
            ("squares expected (method)", fb.expected), ("counting test", fb.counting_test),
            ("arrays disagree (Fig. 2)", fb.arrays_disagree),
            ("false boundary detected", fb.false_boundary_detected),
            ("unmatched", ", ".join(map(str, meta.get("unmatched") or [])) or None),
            ("reconstruction time (s)", RunTimings.of(meta).total_s)]


def scored_errors(score: dict | None):
    """The per-point errors (``evaluation.score.PerPointErrors``) of a parsed score.json of the
    paper's pipeline; None when not evaluated, another method's document, or without them."""
    if not score or not _is_paper_score(score):
        return None
    try:
        return score_record(score).per_point
    except ValueError:  # not the paper's score.json layout
        return None


def recon_section(page: Page, recon: Path, prefix: str, show_sample: bool = True) -> dict:
    """A reconstruction with its score (when evaluated) and the sample it came from (its details
    only when ``show_sample``; a link otherwise, for a sample several reconstructions share)."""
    meta, score = load_recon(recon)
    sample = recon_sample_dir(recon, meta)
    part = _sample_part(page, sample, prefix, thumbs=show_sample) if sample is not None else None
    ref = bool(part and part["reference"])
    method = meta.get("method") or (score or {}).get("method") or recon.name
    title = (f"The paper's reference experiment (V){'' if method == 'paper' else f': {method}'}" if ref
             else f"Reconstruction {page.rel(recon)} ({method})")
    rec = {"href": page.link(recon), "rel": page.rel(recon), "method": method, "facts": _recon_facts(meta),
           "score_href": page.link(recon / "score.json") if score is not None else None,
           "figures": score_figures(score) if score else [], "verdicts": _verdicts(score) if score else [],
           "score_tables": _score_tables(score) if score else [], "plots": []}
    notes = [] if score is not None else [f"{page.rel(recon)} holds no score.json yet: run 'platebench evaluate "
                                          "SAMPLE RECON' to score it against the ground truth"]
    if sample is None:
        notes.append(f"the sample of {page.rel(recon)} was not found (recon.json names {meta.get('sample_dir')!r})")
    elif (recon / "points.csv").is_file():
        rec["plots"].append(page.plot(f"{prefix}error_map", P.plot_error_map, sample, recon,
                                      per_point=scored_errors(score),
                                      caption="Top view of the plate in world X/Y (mm). Left: the reconstructed "
                                              "surface coloured by its exact distance to the ground-truth mesh (mm), "
                                              "black = true boundary, red dashed = reconstructed boundary. Right: "
                                              "the triangulated square centres coloured by their 3D error against "
                                              "the true centres (mm)."))
    elif P.output_file(recon) is not None:
        rec["plots"].append(page.plot(f"{prefix}error_map", P.plot_output_error_map, sample, recon,
                                      caption=f"Error map of {method}'s output: {P.OUTPUT_MAP_CAPTION}"))
    headline = {"label": title, "figures": rec["figures"], "verdicts": rec["verdicts"],
                "text": "" if score else "not scored yet (no score.json)", "met": None,
                "paper": "The paper (V): 16 points, depth error within 2 mm, x/y error within 1 mm." if ref else ""}
    return {"kind": "experiment", "title": title, "sample": part if show_sample else None,
            "sample_link": None if show_sample or part is None else {"href": part["href"], "rel": part["rel"]},
            "recon": rec, "notes": notes, "headline": headline}


# ----------------------------------------------------------------------------- compare.json
_COMPARE_COLUMNS = (("n_images", "images / camera"),
                    *((k, metric_label(k)) for k in ("centres_depth_median_mm", "centres_depth_rms_mm",
                                                     "centres_depth_max_mm", "depth_median_mm", "depth_rms_mm",
                                                     "depth_max_mm", "coverage_frac")),
                    ("points_on_plate", "square centres on the plate"),
                    ("surface_rms_mm", metric_label("surface_rms_mm")),
                    ("mb_all_bad_1_0_pct", metric_label("mb_all_bad_1_0_pct")), ("time_s", "time (s)"),
                    ("render_s", "render (s)"))  # MethodFigures' fields
_COMPARE_BARS = ("centres_depth_median_mm", "centres_depth_rms_mm", "centres_depth_max_mm", "depth_median_mm",
                 "depth_rms_mm", "depth_max_mm", "surface_rms_mm")


def compare_section(page: Page, path: Path, prefix: str) -> dict:
    """A compare.json: one row per method, their descriptions and notes, and a bar chart."""
    doc = load_compare(path)
    entries = {n: m for n, m in (doc.get("methods") or {}).items() if isinstance(m, dict)}
    methods = compare_methods(doc)
    failed = {n: m.get("error") for n, m in entries.items() if m.get("status") == "failed"}
    cols = [(k, t) for k, t in _COMPARE_COLUMNS if any(getattr(f, k) is not None for f in methods.values())]
    table = {"title": "", "caption": "", "cls": "", "groups": [], "columns": ["method"] + [t for _, t in cols],
             "rows": [[n] + [getattr(f, k) for k, _ in cols] for n, f in methods.items()]}
    bars = {n: {k: getattr(f, k) for k in (*_COMPARE_BARS, "coverage_frac")}
            for n, f in methods.items() if n not in failed}
    rel = page.rel(path)
    plots = [page.plot(f"{prefix}compare", P.plot_method_comparison, bars, metrics=list(_COMPARE_BARS),
                       title=f"compare: {rel}",
                       caption="Depth error of each method on this sample (mm; log scale when the values span "
                               "decades), one group of bars per figure, each group comparing only the methods "
                               "that report that figure: at the square centres (the paper's points, sparse) and "
                               "over the plate's pixels with an estimate (dense maps) are separate groups, never "
                               "side by side. Right: coverage of the plate (fraction 0..1, dense methods).")] \
        if bars else []
    return {"kind": "compare", "title": f"Method comparison: {rel}", "sample": doc.get("sample", "?"),
            "units": doc.get("units") or "", "table": table, "plots": plots,
            "descriptions": [(n, m.get("description")) for n, m in entries.items() if m.get("description")],
            "notes": [str(n) for n in doc.get("notes") or []] + [f"{n} failed: {e}" for n, e in failed.items()]}


# ----------------------------------------------------------------------------- score documents
def score_section(path: Path, out_dir: Path) -> dict:
    """A generic section (``page.normalise_section``) of a score document that ``platebench
    evaluate`` wrote for another program's output (``--disparity``, ``--depth``, ``--points``,
    ``--mesh``): its key figures, its plausibility hints, every figure by part, and the error
    map of the output against the sample's ground truth (when both files are found)."""
    doc = load_score_document(path)
    method, kind = str(doc.get("method") or Path(path).stem), str(doc.get("kind"))
    sample, output = score_document_paths(path, doc)
    notes = [f"plausibility: {h}" for h in doc.get("hints") or []]
    plots = []
    if sample is not None and output is not None:
        name = P.plot_output_error_map(sample, path, Path(out_dir) / "error_map.png", kind=kind,
                                       title=f"{method} ({kind}) against {sample.name}'s ground truth").name
        plots.append({"file": name, "caption": f"Error map of {method}'s {kind} output: {P.OUTPUT_MAP_CAPTION}"})
    else:
        notes.append(f"no error map: the {'sample ' + str(doc.get('sample')) if sample is None else ''}"
                     f"{' and the ' if sample is None and output is None else ''}"
                     f"{'output ' + str(doc.get('input')) if output is None else ''} named in {Path(path).name} "
                     "could not be found")
    score = doc.get("score") or {}
    tables = []
    for part, body in [("score", {k: v for k, v in score.items() if not isinstance(v, dict)})] + \
            [(k, v) for k, v in score.items() if isinstance(v, dict)]:
        flat = _flatten(body)
        if flat:
            tables.append({"title": part.replace("_", " "), "columns": [{"key": "figure", "label": "figure"},
                                                                        {"key": "key", "label": "key"},
                                                                        {"key": "value", "label": "value"}],
                           "rows": [{"figure": metric_label(k.rsplit(".", 1)[-1]), "key": k, "value": v}
                                    for k, v in flat.items()]})
    links = [{"label": "score document", "path": str(Path(path).resolve())}]
    links += [{"label": what, "path": str(p.resolve())} for what, p in (("sample", sample), ("output", output)) if p]
    return {"title": f"Score of {method} ({kind} output)",
            "summary": f"{method}'s {kind} output, scored by 'platebench evaluate' against the exact ground truth of "
                       f"sample {doc.get('sample')}" + (f" ({doc['input']})" if doc.get("input") else "") + ".",
            "figures": warned_figures(score_figures(doc), doc.get("hints") or []), "tables": tables,
            "plots": plots, "links": links, "notes": notes}
