"""Figures travel as typed records (``bench.io.records``, ``evaluation.score.Score``,
``evaluation.metrics_row.MetricsRow``) from the sensing loop, the study and ``compare`` to the
command line and the report; a dict of them is written and read only in ``bench/io`` (and by a
record's own ``to_dict``/``from_dict``).

The scan (``figure_key_reads``) reads every module of the package outside ``bench/io`` with
Python's ``ast`` and reports each string-constant key read of a figure: ``x["KEY"]`` (a load, not
a store), ``x.get("KEY", ...)`` and ``x.pop("KEY", ...)``, where KEY is a figure of the typed
records, that is:

* a field of ``Stage3Accuracy``, ``MergedFigures``, ``StudyRow``, ``StudyTargets``,
  ``MethodFigures``, ``SparseDepthScore`` or ``MetricsRow``, or a key of score.json
  (``Score.to_dict``, every part), whose name ends in a unit (``_mm``, ``_mm2``, ``_frac``,
  ``_pct``, ``_px``, ``_m``, ``_m2``, ``_deg``, ``_rad``);
* or an older spelling the records read back (their ``RENAMED`` keys, ``coverage_pct``).

Left out of the key set: a plate's and a rig's parameters (``bend_deg``, ``axis_deg``,
``distance_m``: inputs, read by key where specification files are parsed) and timings (``_s``).
Reads inside a function named ``to_dict`` or ``from_dict`` are a record's own file form.
"""
from __future__ import annotations

import ast
import dataclasses
import re
from pathlib import Path

import pytest

from platebench.bench.io import records as R
from platebench.evaluation.dense import SparseDepthScore
from platebench.evaluation.metrics_row import METRIC_FIELDS
from platebench.evaluation.score import score_reconstruction
from tests.test_score import _recon, _truth

REPO = Path(__file__).resolve().parents[1]
PACKAGE_DIRS = ("plates", "scenes", "reconstruction", "evaluation", "bench")
UNIT = re.compile(r".+_(mm|mm2|frac|pct|px|m|m2|deg|rad)")
PARAMETERS = {"bend_deg", "axis_deg", "distance_m"}
RECORDS = (R.Stage3Accuracy, R.MergedFigures, R.StudyRow, R.StudyTargets, R.MethodFigures, SparseDepthScore)


def _keys(d: dict) -> set[str]:
    out = set()
    for k, v in d.items():
        out.add(k)
        if isinstance(v, dict):
            out |= _keys(v)
    return out


def figure_keys() -> set[str]:
    """The keys the scan looks for (module doc)."""
    names = {f.name for c in RECORDS for f in dataclasses.fields(c)} | set(METRIC_FIELDS)
    t, p = _truth()
    names |= _keys(score_reconstruction(t, _recon(t, p, depth_mm=0.1, boundary_up_mm=0.1)).to_dict())
    old = {k for c in RECORDS for k in getattr(c, "RENAMED", {})} | {"coverage_pct"}
    return {k for k in names if UNIT.fullmatch(k)} - PARAMETERS | old


def _key_read(node: ast.AST) -> str | None:
    if isinstance(node, ast.Subscript) and isinstance(node.ctx, ast.Load):
        s = node.slice
        return s.value if isinstance(s, ast.Constant) and isinstance(s.value, str) else None
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in ("get", "pop") \
            and node.args and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
        return node.args[0].value
    return None


def figure_key_reads(source: str, keys: set[str]) -> list[tuple[int, str]]:
    """(line, key) of every read of one of ``keys`` by a string constant in ``source`` (module doc)."""
    tree = ast.parse(source)
    own = {id(n) for f in ast.walk(tree) if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
           and f.name in ("to_dict", "from_dict") for n in ast.walk(f)}
    return sorted((n.lineno, k) for n in ast.walk(tree) if id(n) not in own and (k := _key_read(n)) in keys)


def _package_files():
    for d in PACKAGE_DIRS:
        for p in sorted((REPO / d).rglob("*.py")):
            rel = p.relative_to(REPO).as_posix()
            if not rel.startswith("bench/io/"):
                yield rel, p


@pytest.fixture(scope="module")
def keys():
    return figure_keys()


def test_the_scan_looks_for_the_records_figures(keys):
    for k in ("centres_depth_rms_mm", "coverage_frac", "merged_boundary_mean_mm", "seen_all_frac", "mb_all_bad_1_0_pct",
              "gt_unconfirmable_max_mm", "depth_max_mm", "xy_per_axis_max_mm", "mean_sym_mm", "surface_coverage",
              "coverage_pct", "merged_surface_coverage"):
        assert k in keys, k
    assert not keys & {"bend_deg", "distance_m", "time_s", "outcome", "case"}


def test_the_scan_finds_what_the_package_used_to_do(keys):
    """The reads the records replaced, as they were written: each is found, and the typed forms are not."""
    before = '''
def study_row(f, m, row):
    row.update(merged_boundary_mean_mm=m.get("boundary_mean_mm"), merged_surface_coverage=m.get("surface_coverage"),
               centres_depth_rms_mm=(f.accuracy or {}).get("centres_depth_rms_mm"))
def cells(s):
    return s["depth_median_mm"], f"{s['coverage_pct']:.1f} %"
def lines(t, pb):
    return f"{t['seen_all_frac']} {pb.get('depth_max_mm')}"
'''
    assert sorted(k for _, k in figure_key_reads(before, keys)) == sorted([
        "boundary_mean_mm", "surface_coverage", "centres_depth_rms_mm", "depth_median_mm", "coverage_pct",
        "seen_all_frac", "depth_max_mm"])
    after = '''
def study_row(f, m):
    return m.boundary_mean_mm, m.coverage_frac, f.accuracy.centres_depth_rms_mm
def write(d, m):
    d["coverage_frac"] = m.coverage_frac  # a store builds the file form
class Rec:
    @classmethod
    def from_dict(cls, d):
        return cls(d.get("coverage_frac"))
'''
    assert figure_key_reads(after, keys) == []


def test_no_figure_is_read_from_a_dict_outside_bench_io(keys):
    found = [f"{rel}:{line}: [{key!r}]" for rel, p in _package_files()
             for line, key in figure_key_reads(p.read_text(), keys)]
    assert not found, ("figures read from a dict by key outside bench/io (read the typed record's attribute, "
                       "or read the file in bench/io):\n" + "\n".join(found))


OLD_SPELLINGS = ("coverage_pct", "surface_coverage", "merged_surface_coverage", "merged_boundary_covered",
                 "gt_verifiable_fraction", "gt_visible_first", "gt_visible_final", "front_oriented")


def test_one_spelling_of_coverage_in_the_package_and_its_documents():
    """No key of an older spelling is written or named: in the package a quoted key (outside the
    readers of older files in bench/io/records.py), in README, docs/ and the report's templates
    any mention."""
    names = "|".join(OLD_SPELLINGS)
    quoted = re.compile(rf"[\"']({names})[\"']")
    named = re.compile(rf"\b({names})\b(?!_frac)")
    files = [(p, quoted) for _, p in _package_files()] + \
        [(p, named) for p in (REPO / "README.md", *sorted((REPO / "docs").rglob("*.md")),
                              *sorted((REPO / "bench" / "report" / "templates").rglob("*")))]
    found = []
    for p, old in files:
        if p.is_file() and p.relative_to(REPO).as_posix() != "bench/io/records.py":
            found += [f"{p.relative_to(REPO)}:{i}: {m.group(0)}" for i, line in enumerate(p.read_text().splitlines(), 1)
                      for m in old.finditer(line)]
    assert not found, "older spellings of a figure:\n" + "\n".join(found)


def test_records_read_back_what_they_write_and_older_spellings():
    row = R.StudyRow("dome", "dome", outcome="clean", detectors={"counting_test": False, "end_tangents": None},
                     merged_coverage_frac=0.93, gt_visible_first_frac=1.0, time_s=3.5, traceback="x")
    d = row.to_dict()
    assert d["det_counting_test"] is False and "traceback" not in d and "detectors" not in d
    assert R.StudyRow.from_dict(d) == row
    old = {k: v for k, v in d.items() if k not in ("merged_coverage_frac", "gt_visible_first_frac")}
    back = R.StudyRow.from_dict({**old, "merged_surface_coverage": 0.93, "gt_visible_first": 1.0})
    assert back.merged_coverage_frac == 0.93 and back.gt_visible_first_frac == 1.0
    with pytest.raises(ValueError, match="'case'"):
        R.StudyRow.from_dict({"family": "dome"})
    m = R.MergedFigures(poses=5, points=40, coverage_frac=float("nan"), surface_rms_mm=0.2)
    assert m.to_dict()["coverage_frac"] is None and R.MergedFigures.from_dict(m.to_dict()).surface_rms_mm == 0.2
    assert R.Stage3Accuracy.from_dict({"surface_coverage": 0.4}).coverage_frac == 0.4
    t = R.StudyTargets(silent=0, cured_frac=0.5, met={"silent = 0": True})
    assert R.StudyTargets.from_dict(t.to_dict()) == t
    f = R.compare_methods({"methods": {"gc": {"kind": "disparity", "coverage_pct": 44.0, "depth_rms_mm": 0.2,
                                              "middlebury": {"mb_all_bad_1_0_pct": 3.2}}}})["gc"]
    assert (f.measure, f.coverage_frac, f.error_rms_mm, f.mb_all_bad_1_0_pct) == ("disparity", 0.44, 0.2, 3.2)


# ----------------------------------------------------------------------------- the report shows what the data holds
def sensing_figures_not_shown(section: dict, doc: dict) -> list[str]:
    """The figures of sensing.json's ``final`` (read here by key, as the file holds them) that the
    report's sensing section does not show, or shows as something else."""
    final = doc["final"]
    merged, acc = final["merged"], final.get("accuracy") or {}
    want = {"merged boundary mean distance": merged.get("boundary_mean_mm"),
            "merged square centres (all poses)": merged.get("points"),
            "merged square centres' RMS distance to the plate": merged.get("points_rms_mm"),
            "merged surface coverage": merged.get("coverage_frac"), "merged surface RMS": merged.get("surface_rms_mm"),
            "stage-3 depth RMS at the square centres": acc.get("centres_depth_rms_mm")}
    cards = {f["label"]: f.get("value") for f in section["figures"]}
    return [f"{label}: data {v}, shown {cards.get(label)}" for label, v in want.items()
            if v is not None and (cards.get(label) is None or abs(cards[label] - v) > 1e-3 * max(1.0, abs(v)))]


def table_cells_not_shown(columns: list, rows: list, data: list[dict], keys: list) -> list[str]:
    """Cells of a report table (``columns`` and ``rows`` of lists, or of dicts by column) that are
    None or "-" where the data row (a dict as the file holds it) has a value under ``keys[i]``
    (the key of column i; None: not a figure)."""
    out = []
    for row, d in zip(rows, data, strict=True):
        cells = [row.get(c) for c in columns] if isinstance(row, dict) else list(row)
        for col, key, cell in zip(columns, keys, cells):
            if key is not None and d.get(key) is not None and (cell is None or cell == "-" or cell != d[key]):
                out.append(f"{col}: data {d[key]!r}, shown {cell!r}")
    return out


@pytest.mark.render
def test_the_study_report_shows_every_figure_a_row_holds(tmp_path):
    """One real plate (the flat one, 320 x 240) through the study and the report: every figure of
    study.json's row (read by key from the file) is in the plates table, as the file has it."""
    import json

    from platebench.bench.config import SampleConfig, SceneParams
    from platebench.bench.report.sensing import study_section
    from platebench.bench.run.study import study_cases, write_study
    from platebench.scenes.scene_spec import RenderSettings
    base = SampleConfig(scene=SceneParams(width=320, height=240), render=RenderSettings(spp=2, seed=0))
    write_study(tmp_path / "study", [c for c in study_cases() if c.family == "flat"][:1], base)
    doc = json.loads((tmp_path / "study" / "study.json").read_text())
    row = doc["rows"][0]
    sec = study_section(tmp_path / "study", tmp_path / "plots")
    table = next(t for t in sec["tables"] if t["title"].startswith("Plates"))
    for key in ("merged_boundary_mean_mm", "merged_coverage_frac", "gt_visible_first_frac", "gt_visible_final_frac",
                "time_s", "det_counting_test"):
        assert row[key] is not None and key in table["columns"], key
    assert not table_cells_not_shown(table["columns"], table["rows"], doc["rows"], table["columns"])
    t = doc["targets"]
    assert f"false alarms {t['false_alarms']} of {t['nothing_hidden']}" in sec["summary"]
