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
from platebench.bench.report import plots as P
from platebench.bench.report.inputs import (
    load_compare,
    load_recon,
    load_sample_meta,
    read_json,
    recon_sample_dir,
)
from platebench.bench.report.page import Page
from platebench.bench.report.values import finite, flag, fmt

__all__ = ["recon_section", "sample_section", "compare_section", "is_reference", "score_figures"]

_TITLES = {p.name: p.title for p in PARAMETERS}
# key figures of a score: (name of the figure in score.json, at any depth; label; unit), in card order.
# The paper's score.json nests them by part (points.depth_rms_mm), a dense method's under "scores".
_SCORE_FIGURES = (
    ("depth_rms_mm", "depth RMS", "mm"), ("depth_median_mm", "depth median", "mm"),
    ("depth_max_mm", "depth max", "mm"), ("xy_radial_rms_mm", "x/y radial RMS", "mm"),
    ("xy_per_axis_max_mm", "x/y max per axis", "mm"), ("mean_sym_mm", "boundary mean", "mm"),
    ("dist_rms_mm", "surface RMS", "mm"), ("coverage_frac", "coverage of the plate", "fraction"),
    ("coverage_pct", "coverage of the plate", "%"), ("mb_all_bad_1_0_pct", "Middlebury bad 1.0 (all)", "%"),
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
    ref = SampleConfig().to_dict()
    return all(config.get(k) == ref[k] for k in ("plate", "scene", "sensor"))


def score_figures(score: dict) -> list[dict]:
    """The key figures of a score.json (cards): points matched of expected, then each of
    ``_SCORE_FIGURES`` found at any depth (its first occurrence)."""
    flat = _flatten(score)
    out = []
    m = score.get("matching") or {}
    if m.get("matched_count") is not None:
        out.append({"label": "points matched / expected", "value": f"{m['matched_count']} / "
                    f"{fmt(m.get('expected_count_gt'))}", "unit": "",
                    "status": "good" if m.get("matched_count") == m.get("expected_count_gt") else "bad"})
    labels = set()
    for name, label, unit in _SCORE_FIGURES:
        v = next((v for k, v in flat.items() if k.rsplit(".", 1)[-1] == name and finite(v) is not None), None)
        if v is not None and label not in labels:
            labels.add(label)
            out.append({"label": label, "value": v, "unit": unit, "status": ""})
    return out


def _verdicts(score: dict) -> list[dict]:
    """The paper's bound, the goals and the false-boundary verdict: {"label", "met", "text"}."""
    out = []
    pb = score.get("paper_bound")
    if isinstance(pb, dict):
        out.append({"label": "paper's bound (V-D)", "met": flag(pb.get("met")),
                    "text": f"every expected point found: {fmt(pb.get('all_points'))}; depth max "
                            f"{fmt(pb.get('depth_max_mm'), 3)} mm (bound 2 mm); x/y max per axis "
                            f"{fmt(pb.get('xy_per_axis_max_mm'), 3)} mm (bound 1 mm)"})
    g = score.get("goals")
    if isinstance(g, dict):
        out.append({"label": "bench goals", "met": flag(g.get("met")),
                    "text": f"depth RMS {fmt(g.get('depth_rms_mm'), 3)} mm (goal {fmt(g.get('depth_rms_goal_mm'))}); "
                            f"x/y RMS per axis {fmt(g.get('xy_per_axis_rms_mm'), 3)} mm (goal "
                            f"{fmt(g.get('xy_per_axis_rms_goal_mm'))}); boundary mean "
                            f"{fmt(g.get('boundary_mean_mm'), 3)} mm (goal {fmt(g.get('boundary_mean_goal_mm'))})"})
    fb = score.get("false_boundary")
    if isinstance(fb, dict):
        out.append({"label": "false-boundary verdict", "met": flag(fb.get("agrees")),
                    "text": "ground truth: " + ("part of the boundary hidden" if fb.get("ground_truth_any") else
                                                "whole boundary visible")
                            + "; the method: "
                            + ("false boundary detected" if fb.get("detected") else "none detected")})
    return out


def _score_tables(score: dict) -> list[dict]:
    """Every figure of score.json, one key/value table per part (units in the keys)."""
    tables = []
    loose = {k: v for k, v in score.items() if not isinstance(v, dict)}
    for part, body in [("score", loose)] + [(k, v) for k, v in score.items() if isinstance(v, dict)]:
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
    vis = read_json(path, "visibility record")
    if not isinstance(vis, dict):
        return None
    parts = [f"{cam} sees {fmt(100 * v['visible_fraction'], 3)} %" for cam, v in vis.items()
             if isinstance(v, dict) and finite(v.get("visible_fraction")) is not None]
    hidden = any(isinstance(v, dict) and v.get("false_boundary") for v in vis.values())
    return ("part of the true boundary is hidden (a false boundary): " if hidden else
            "the whole true boundary is visible: ") + ", ".join(parts)


def _sample_part(page: Page, sample: Path, prefix: str, thumbs: bool = True) -> dict:
    meta = load_sample_meta(sample)
    config = meta.get("config") if isinstance(meta.get("config"), dict) else {}
    timings = meta.get("timings_s") if isinstance(meta.get("timings_s"), dict) else {}
    return {"href": page.link(sample), "rel": page.rel(sample), "facts": _config_facts(config),
            "variant": meta.get("variant"), "render_s": timings.get("total_s"),
            "visibility": _visibility(sample), "reference": is_reference(config),
            "thumbs": page.thumbnails(sample, prefix) if thumbs else [],
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
    fb = meta.get("false_boundary") if isinstance(meta.get("false_boundary"), dict) else {}
    timings = meta.get("timings_s") if isinstance(meta.get("timings_s"), dict) else {}
    if not meta:
        return []
    return [("points triangulated", meta.get("n_points")), ("boundary points", meta.get("n_boundary_points")),
            ("squares detected per image", ", ".join(f"{k} {v}" for k, v in (fb.get("detected") or {}).items())),
            ("squares expected (method)", fb.get("expected")), ("counting test", fb.get("counting_test")),
            ("arrays disagree (Fig. 2)", fb.get("arrays_disagree")),
            ("false boundary detected", fb.get("false_boundary_detected")),
            ("unmatched", ", ".join(map(str, meta.get("unmatched") or [])) or None),
            ("reconstruction time (s)", timings.get("total_s"))]


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
                                      caption="Top view of the plate in world X/Y (mm). Left: the reconstructed "
                                              "surface coloured by its exact distance to the ground-truth mesh (mm), "
                                              "black = true boundary, red dashed = reconstructed boundary. Right: "
                                              "the triangulated square centres coloured by their 3D error against "
                                              "the true centres (mm)."))
    headline = {"label": title, "figures": rec["figures"], "verdicts": rec["verdicts"],
                "text": "" if score else "not scored yet (no score.json)", "met": None,
                "paper": "The paper (V): 16 points, depth error within 2 mm, x/y error within 1 mm." if ref else ""}
    return {"kind": "experiment", "title": title, "sample": part if show_sample else None,
            "sample_link": None if show_sample or part is None else {"href": part["href"], "rel": part["rel"]},
            "recon": rec, "notes": notes, "headline": headline}


# ----------------------------------------------------------------------------- compare.json
_COMPARE_COLUMNS = (("n_images", "images / camera"), ("depth_median_mm", "depth median (mm)"),
                    ("depth_rms_mm", "depth RMS (mm)"), ("depth_p95_mm", "depth p95 (mm)"),
                    ("depth_max_mm", "depth max (mm)"), ("coverage_pct", "coverage (%)"),
                    ("points_on_plate", "points on plate"), ("surface_rms_mm", "surface RMS (mm)"),
                    ("middlebury.mb_all_bad_1_0_pct", "Middlebury bad 1.0 (%)"), ("time_s", "time (s)"),
                    ("render_s", "render (s)"))


def compare_section(page: Page, path: Path, prefix: str) -> dict:
    """A compare.json: one row per method, their descriptions and notes, and a bar chart."""
    doc = load_compare(path)
    methods = {n: _flatten(m) for n, m in (doc.get("methods") or {}).items() if isinstance(m, dict)}
    failed = {n: m.get("error") for n, m in methods.items() if m.get("status") == "failed"}
    cols = [(k, t) for k, t in _COMPARE_COLUMNS if any(m.get(k) is not None for m in methods.values())]
    table = {"title": "", "caption": "", "cls": "", "groups": [], "columns": ["method"] + [t for _, t in cols],
             "rows": [[n] + [m.get(k) for k, _ in cols] for n, m in methods.items()]}
    bars = {n: {**{k: m.get(k) for k in ("depth_median_mm", "depth_rms_mm", "depth_max_mm", "surface_rms_mm")},
                "coverage_frac": None if finite(m.get("coverage_pct")) is None else m["coverage_pct"] / 100.0}
            for n, m in methods.items() if n not in failed}
    rel = page.rel(path)
    plots = [page.plot(f"{prefix}compare", P.plot_method_comparison, bars, title=f"compare: {rel}",
                       caption="Depth error of each method on this sample (mm: median, RMS, max over plate pixels "
                               "with an estimate, or over the paper's square centres; log scale when they span "
                               "decades) and coverage of the plate (fraction 0..1, dense methods).")] if bars else []
    return {"kind": "compare", "title": f"Method comparison: {rel}", "sample": doc.get("sample", "?"),
            "units": doc.get("units") or "", "table": table, "plots": plots,
            "descriptions": [(n, m.get("description")) for n, m in methods.items() if m.get("description")],
            "notes": [str(n) for n in doc.get("notes") or []] + [f"{n} failed: {e}" for n, e in failed.items()]}
