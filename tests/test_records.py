"""Figures travel as typed records (``bench.io.records``, ``evaluation.score.Score``,
``evaluation.metrics_row.MetricsRow`` and the records of the calibration, the realism's draw, the
accuracy and cut-squares studies) between the modules of the package, down to the command line
and the report; a dict of them is written and read only in ``bench/io`` (and by a record's own
``to_dict``/``from_dict``).

The scan (``figure_key_reads``) reads every module of the package outside ``bench/io`` with
Python's ``ast`` and reports each string-constant key read of a figure: ``x["KEY"]`` (a load, not
a store), ``x.get("KEY", ...)`` and ``x.pop("KEY", ...)``, where KEY is a figure, that is:

* any key whose name ends in a unit (``_mm``, ``_mm2``, ``_frac``, ``_pct``, ``_px``, ``_m``,
  ``_m2``, ``_deg``, ``_rad``): a figure, or a specification's value in its unit, which a
  specification's codec (``bench.io.codecs``) parses;
* a field of ``Stage3Accuracy``, ``MergedFigures``, ``StudyRow``, ``StudyTargets``,
  ``MethodFigures``, ``SparseDepthScore`` or ``MetricsRow``, or a key of score.json
  (``Score``'s codec in ``bench.io.codecs.evaluation``, every part), whose name ends in a unit;
* or an older spelling the records read back (their ``RENAMED`` keys, ``coverage_pct``).

Left out of the key set: a plate's and a rig's parameters (``bend_deg``, ``axis_deg``,
``distance_m``), which name a plate of a results table (the rows of a study or a sweep that the
report plots and tabulates by column, and the steps of sensing.json it lists) as much as a figure;
and timings (``_s``). A results table read with pandas (results.csv) is read by column name in
the report: by those parameters' names, or by a figure's name held in a variable (the metric
lists of ``bench.report.summary``), which a scan of string constants does not see; the table is
the file's own form, and no other exemption is made for it.
Reads inside a function named ``to_dict`` or ``from_dict`` are a record's own file form.
"""
from __future__ import annotations

import ast
import dataclasses
import math
import re
from pathlib import Path

import pytest

from platebench.bench.io import records as R
from platebench.bench.io.codecs import decode, encode
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


class FigureKeys(frozenset):
    """The keys the scan looks for (module doc): the records' figures and older spellings (the set),
    and any other key whose name ends in a unit (``in``)."""

    def __contains__(self, key) -> bool:
        return frozenset.__contains__(self, key) or (isinstance(key, str) and UNIT.fullmatch(key) is not None
                                                      and key not in PARAMETERS)


def figure_keys() -> FigureKeys:
    """The keys the scan looks for (module doc)."""
    names = {f.name for c in RECORDS for f in dataclasses.fields(c)} | set(METRIC_FIELDS)
    t, p = _truth()
    names |= _keys(encode(score_reconstruction(t, _recon(t, p, depth_mm=0.1, boundary_up_mm=0.1))))
    old = {k for c in RECORDS for k in getattr(c, "RENAMED", {})} | {"coverage_pct"}
    return FigureKeys({k for k in names if UNIT.fullmatch(k)} - PARAMETERS | old)


def _key_read(node: ast.AST) -> str | None:
    if isinstance(node, ast.Subscript) and isinstance(node.ctx, ast.Load):
        s = node.slice
        return s.value if isinstance(s, ast.Constant) and isinstance(s.value, str) else None
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in ("get", "pop") \
            and node.args and isinstance(node.args[0], ast.Constant) and isinstance(node.args[0].value, str):
        return node.args[0].value
    return None


def figure_key_reads(source: str, keys) -> list[tuple[int, str]]:
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
              "coverage_pct", "merged_surface_coverage",
              # any key with a unit, of a record or not
              "fx_error_px", "worst_median_mm", "position_error_m", "kept_depth_max_mm", "tilt_deg", "f_px"):
        assert k in keys, k
    for k in ("bend_deg", "axis_deg", "distance_m", "time_s", "outcome", "case", "views", "exact", "kind"):
        assert k not in keys, k


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
def calibration(report, acq, row, pose):
    c = report["config"]
    return (c["width_px"], report["cameras"]["free_distortion"]["left"]["fx_error_px"],
            acq["views"]["left"].get("position_error_m"), row.pop("kept_depth_max_mm"), pose.get("tilt_deg", 0.0))
'''
    assert sorted(k for _, k in figure_key_reads(before, keys)) == sorted([
        "boundary_mean_mm", "surface_coverage", "centres_depth_rms_mm", "depth_median_mm", "coverage_pct",
        "seen_all_frac", "depth_max_mm", "width_px", "fx_error_px", "position_error_m", "kept_depth_max_mm",
        "tilt_deg"])
    after = '''
def study_row(f, m):
    return m.boundary_mean_mm, m.coverage_frac, f.accuracy.centres_depth_rms_mm
def write(d, m):
    d["coverage_frac"] = m.coverage_frac  # a store builds the file form
class Rec:
    @classmethod
    def from_dict(cls, d):
        return cls(d.get("coverage_frac"), d["tilt_deg"])
def calibration(report, pose):
    return report.config.width_px, report.cameras["free_distortion"]["left"].fx_error_px, pose.tilt_deg
'''
    assert figure_key_reads(after, keys) == []


def test_no_figure_is_read_from_a_dict_outside_bench_io(keys):
    found = [f"{rel}:{line}: [{key!r}]" for rel, p in _package_files()
             for line, key in figure_key_reads(p.read_text(), keys)]
    assert not found, ("figures read from a dict by key outside bench/io (read the typed record's attribute, "
                       "or read the file in bench/io):\n" + "\n".join(found))


def codec_methods(source: str) -> list[tuple[int, str]]:
    """(line, Class.method) of every ``to_dict``/``from_dict`` method defined on a class in ``source``:
    a type's file form written on the type instead of in ``bench.io.codecs``."""
    return sorted((f.lineno, f"{c.name}.{f.name}") for c in ast.walk(ast.parse(source)) if isinstance(c, ast.ClassDef)
                  for f in c.body if isinstance(f, (ast.FunctionDef, ast.AsyncFunctionDef))
                  and f.name in ("to_dict", "from_dict"))


def test_file_forms_live_at_the_file_boundary():
    """No type outside ``bench/io`` carries its own JSON form: its codec is in ``bench.io.codecs``."""
    found = [f"{rel}:{line}: {name}" for rel, p in _package_files()
             for line, name in codec_methods(p.read_text())]
    assert not found, "write the codec in bench/io/codecs (encode.register / decoder):\n" + "\n".join(found)
    planted = "class Score:\n    x: float\n    def to_dict(self):\n        return {'x_mm': self.x}\n"
    assert codec_methods(planted) == [(3, "Score.to_dict")]


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
                     merged_surface_coverage_frac=0.93, gt_visible_first_frac=1.0, time_s=3.5, traceback="x")
    d = row.to_dict()
    assert d["det_counting_test"] is False and "traceback" not in d and "detectors" not in d
    assert R.StudyRow.from_dict(d) == row
    old = {k: v for k, v in d.items() if k not in ("merged_surface_coverage_frac", "gt_visible_first_frac")}
    back = R.StudyRow.from_dict({**old, "merged_surface_coverage": 0.93, "gt_visible_first": 1.0})
    assert back.merged_surface_coverage_frac == 0.93 and back.gt_visible_first_frac == 1.0
    back = R.StudyRow.from_dict({**old, "merged_coverage_frac": 0.93})  # a study.json of that spelling
    assert back.merged_surface_coverage_frac == 0.93
    with pytest.raises(ValueError, match="'case'"):
        R.StudyRow.from_dict({"family": "dome"})
    m = R.MergedFigures(poses=5, points=40, surface_coverage_frac=float("nan"), surface_rms_mm=0.2)
    assert m.to_dict()["surface_coverage_frac"] is None and "coverage_frac" not in m.to_dict()
    assert R.MergedFigures.from_dict(m.to_dict()).surface_rms_mm == 0.2
    for old_key in ("coverage_frac", "surface_coverage"):  # both spellings held the surface-area coverage
        assert R.MergedFigures.from_dict({old_key: 0.4}).surface_coverage_frac == 0.4
    # a stage-3 surface coverage of an older file is not read as the share of plate pixels
    assert R.Stage3Accuracy.from_dict({"surface_coverage": 0.4}).coverage_frac is None
    t = R.StudyTargets(silent=0, cured_frac=0.5, met={"silent = 0": True})
    assert R.StudyTargets.from_dict(t.to_dict()) == t
    f = R.compare_methods({"methods": {"gc": {"kind": "disparity", "coverage_pct": 44.0, "depth_rms_mm": 0.2,
                                              "middlebury": {"mb_all_bad_1_0_pct": 3.2}}}})["gc"]
    assert (f.measure, f.coverage_frac, f.error_rms_mm, f.mb_all_bad_1_0_pct) == ("disparity", 0.44, 0.2, 3.2)


def _json(d: dict) -> dict:
    """``d`` as a JSON file gives it back (lists for tuples; infinities kept, as ``json`` writes them)."""
    import json
    return json.loads(json.dumps(d))


def test_a_realism_draws_report_and_moves_read_back_what_they_write():
    from platebench.bench.io.realism_records import (
        DrawReport,
        HandEyeEstimate,
        IntrinsicsEstimate,
        RobotMove,
        ViewPoseError,
    )
    assert DrawReport(exact=True).to_dict() == {"exact": True}  # an exact draw: nothing missed
    cal = IntrinsicsEstimate(1.5, -0.25, 0.1, 0.9, 0.15, 12, True, (-0.2, 0.05, 0.0, 0.0, 0.0))
    he = HandEyeEstimate(0.003, 0.0013, 0.0008, 0.0024, 0.0038, 0.0015, 12)
    views = {"left": ViewPoseError(0.0029, 0.00048), "right": ViewPoseError(0.0028, 0.00056)}
    r = DrawReport(False, cal, he, 0.12).with_views(views)
    d = _json(r.to_dict())
    assert list(d) == ["exact", "calibration", "hand_eye", "corner_noise_px", "views"]
    assert d["views"]["right"] == {"position_error_m": 0.0028, "rotation_error_rad": 0.00056}
    assert DrawReport.from_dict(d) == r and DrawReport.from_dict({"exact": False}) == DrawReport()
    m = RobotMove("stage 2", 15.0, views)
    md = _json(m.to_dict())
    assert md == {"view": "stage 2", "cell_turn_deg": 15.0, "left_position_error_m": 0.0029,
                  "left_rotation_error_rad": 0.00048, "right_position_error_m": 0.0028,
                  "right_rotation_error_rad": 0.00056}
    assert RobotMove.from_dict(md) == m and RobotMove.from_dict({"view": None, "cell_turn_deg": 0.0}).views == {}


def test_the_accuracy_studys_records_read_back_what_they_write():
    from platebench.bench.config.realism import REALISM_PRESETS
    from platebench.bench.io.accuracy_records import (
        AccuracyCamera,
        AccuracyPaper,
        AccuracyRobot,
        AccuracySettings,
        AccuracyStudy,
        AccuracyTargetBlock,
        AccuracyTrial,
        ConfigSummary,
        ErrorStats,
    )
    from platebench.bench.io.realism_records import DrawReport
    ok = AccuracyTrial("block", "all sources", "all", "1995", "noise", 3, "ok", None, 4, 1.2, 0.4, 0.8, 0.2, -0.1,
                       ((0.1, -0.4, 1.2), (0.0, 0.3, -0.9)), 2.5, DrawReport(exact=True))
    failed = AccuracyTrial("plate", "all sources", "all", "1995", "noise", 4, "failed", "no square centre measured",
                           time_s=0.0)
    assert "worst_depth_mm" not in failed.to_dict() and "error" in ok.to_dict()
    depth = ErrorStats(1.2, {"q05": 1.0, "q95": 1.4}, 0.8, 1.3, 1.5, 1.0, mean_signed_mm=-0.1)
    xy = ErrorStats(0.4, {"q05": 0.3, "q95": 0.5}, 0.2, 0.45, 0.5, 1.0)
    assert "mean_signed_mm" not in xy.to_dict() and "xy" not in ConfigSummary("none", (), 2, 2).to_dict()
    study = AccuracyStudy(
        AccuracySettings(REALISM_PRESETS["1995"], 2, ("block", "plate")), AccuracyPaper(2.0, 1.0, 0.4, "worst corner"),
        AccuracyCamera("pulnix", 512, 480, 1000.0, 1020.0, 0.1, 0.4, (-0.2, 0.0, 0.0, 0.0, 0.0), 0.0, 0.1, 2e4, 0.5, 8),
        AccuracyTargetBlock(5, 5, 0.02, 0.3), AccuracyRobot("puma560", "a PUMA", 1e-4, 2e-4, 1e-5), {"all sources": 0.1},
        {"noise": "sensor noise"}, {"block": {"all sources": ConfigSummary("all", ("noise",), 1, 0, depth, xy)},
                                    "plate": {"all sources": ConfigSummary("all", ("noise",), 1, 1)}}, (ok, failed), 9.5)
    d = _json(study.to_dict())
    assert list(d)[:2] == ["study", "settings"] and d["summary"]["block"]["all sources"]["depth"]["worst_median_mm"] == 1.2
    assert AccuracyStudy.from_dict(d) == study and AccuracyStudy.from_dict(d).summary["block"]["all sources"].stats(
        "xy") == xy
    assert AccuracyRobot("ideal arm", "none").to_dict() == {"name": "ideal arm", "description": "none"}


def test_the_cut_squares_studys_records_read_back_what_they_write():
    from platebench.bench.io.cut_records import CutRow, CutStudy, CutTotals
    rows = (CutRow(40.0, "down", 31.0, 0.495, centres=16, kept=14, cut=2, cut_by_outline=2, outside_before=2,
                   outside_cut=2, kept_depth_max_mm=0.4, kept_xy_max_mm=0.2),
            CutRow(40.0, "up", 31.0, 0.495, centres=16, kept=16, outside_before=1, outside_kept=1,
                   kept_depth_max_mm=2.4, kept_xy_max_mm=0.3),
            CutRow(60.0, "up", 31.0, 0.495, error="ReconstructionError: no plate region"))
    t = CutTotals.of(rows)
    assert (t.plates, t.errors, t.centres, t.cut, t.outside_before, t.plates_outside_before, t.plates_outside_kept) == \
        (3, 1, 32, 2, 3, 2, 1)
    study = CutStudy(rows, t, 12.0, {"bends_deg": [40.0, 60.0], "grid": "paper's 4x4"})
    d = _json(study.to_dict())
    assert list(d) == ["kind", "rows", "totals", "time_s", "settings"]
    assert "error" not in d["rows"][0] and set(d["rows"][2]) == {"bend_deg", "direction", "axis_deg", "distance_m", "error"}
    assert CutStudy.from_dict(d) == study


def test_the_l_formula_rows_read_back_what_they_write_infinity_kept():
    row = R.LFormulaRow(180.0, 0.23, 0.24, 0.26, 0.26 / 0.24, math.inf, None)
    d = _json(row.to_dict())
    assert d["gt_distance_baseline_along_bend_m"] == math.inf  # never fully visible, as study.json writes it
    assert R.LFormulaRow.from_dict(d) == row
    sh, lf = R.study_extras({"smallest_hiding_bend_deg": {"down": 61.25, "up": None},
                             "l_formula": [d, {"L_m": 0.2}, "not a row"]})
    assert sh == {"down": 61.25, "up": None} and lf == [row]
    assert R.study_extras({}) == ({}, [])


def test_specification_records_read_back_what_they_write():
    import numpy as np

    from platebench.bench.config import RigPose
    from platebench.bench.io.export import ExportedSample
    from platebench.bench.io.sensing_records import StudyRealism
    from platebench.reconstruction.calibration.stereo import StereoCalibration
    from platebench.reconstruction.paper.false_boundary import FeatureRays
    from platebench.scenes.pattern import SquareGridLayout, square_grid
    from platebench.scenes.scene_spec import reference_scene
    assert decode(RigPose, encode(RigPose(30.0, -45.0))) == RigPose(30.0, -45.0)
    assert decode(RigPose, {"tilt_deg": 20}) == RigPose(20.0, 0.0) and decode(RigPose, None) == RigPose()
    g = square_grid(1024, 768, rows=6, cols=12, square_px=12)
    layout = decode(SquareGridLayout, g.description)
    assert (layout.rows, layout.cols, layout.square_px) == (6, 12, 12) and encode(layout) == g.description
    with pytest.raises(ValueError, match="not a square grid"):
        decode(SquareGridLayout, {"kind": "image", "note": "user image"})
    rz = StudyRealism("1995", ("noise", "hand_eye"), "--seed + CRC-32", 0.12)
    assert decode(StudyRealism, {"plates": 3, **_json(encode(rz))}) == rz
    assert decode(StudyRealism, {"plates": 3}) == StudyRealism()
    mb = ExportedSample("0000", "0000", "/d/0000", 3, 12.5, 40, 90, 640, 480)
    kitti = ExportedSample("0001", "training/*/000001_10.png", "/d/0001", 0, 0.0, 20, 60, 320, 240, resample_factor=2,
                           resampled="images reduced 2x", f_px=500.0, baseline_m=0.1)
    assert list(mb.to_dict())[-4:] == ["vmin", "vmax", "width", "height"] and "f_px" not in mb.to_dict()
    assert list(kitti.to_dict())[5:9] == ["resample_factor", "resampled", "f_px", "baseline_m"]
    assert ExportedSample.from_dict(_json(mb.to_dict())) == mb and ExportedSample.from_dict(_json(kitti.to_dict())) == kitti
    st = StereoCalibration.from_rig(reference_scene().rig)
    back = decode(StereoCalibration, _json(encode(st)))
    assert encode(back) == _json(encode(st)) and np.array_equal(back.t_world, st.t_world)
    rays = FeatureRays(np.array([[0.0, 0.0, 0.4], [0.01, 0.0, 0.4]]), np.array([[0.0, 0.0, -1.0], [0.0, 0.6, -0.8]]),
                       np.array([3, 7]))
    r = decode(FeatureRays, _json(encode(rays)))
    assert np.array_equal(r.origins, rays.origins) and np.array_equal(r.directions, rays.directions) \
        and r.ids.tolist() == [3, 7]


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
    from platebench.bench.run.sensing.study import study_cases, write_study
    from platebench.scenes.scene_spec import RenderSettings
    base = SampleConfig(scene=SceneParams(width=320, height=240), render=RenderSettings(spp=2, seed=0))
    write_study(tmp_path / "study", [c for c in study_cases() if c.family == "flat"][:1], base)
    doc = json.loads((tmp_path / "study" / "study.json").read_text())
    row = doc["rows"][0]
    sec = study_section(tmp_path / "study", tmp_path / "plots")
    table = next(t for t in sec["tables"] if t["title"].startswith("Plates"))
    for key in ("merged_boundary_mean_mm", "merged_surface_coverage_frac", "gt_visible_first_frac",
                "gt_visible_final_frac",
                "time_s", "det_counting_test"):
        assert row[key] is not None and key in table["columns"], key
    assert not table_cells_not_shown(table["columns"], table["rows"], doc["rows"], table["columns"])
    t = doc["targets"]
    assert f"false alarms {t['false_alarms']} of {t['nothing_hidden']}" in sec["summary"]


# ----------------------------------------------------------------------------- a sweep sample's result
_RESULT_OK = {
    "format": "platebench-sweep-result", "version": 1, "sample_id": "0000", "index": 0, "config_sha256": "ab" * 32,
    "status": "ok", "error": None, "phase": None, "params": {"bend_deg": 30}, "config": {"plate": {}},
    "pose": None, "methods": ["paper"], "variant": "llvm_ad_rgb", "false_boundary_gt": False,
    "rows": [{"method": "paper", "status": "ok", "error": None, "metrics": {"matched_count": 16},
              "time_recon_s": 0.5, "time_eval_s": 0.1, "time_render_extra_s": 0.0}],
    "timings_s": {"render_s": 1.0, "write_s": 0.2, "total_s": 2.0}, "files": {"sample/sample.json": "cd" * 32},
    "images": {"left_passive": "ef" * 32}, "worker": {"host": "h", "pid": 7, "maxrss_mb": 300.0},
    "finished_utc": "2026-01-01T00:00:00+00:00", "render_worker": {"host": "g", "pid": 8}}


def test_a_sample_result_reads_back_what_result_json_holds_key_for_key_in_order():
    import json

    from platebench.bench.io.layout import RESULT_FORMAT, VERSION
    from platebench.bench.io.sweep_records import MethodRun, SampleResult, SampleTimings
    doc = {**_RESULT_OK, "format": RESULT_FORMAT, "version": VERSION}
    res = SampleResult.from_dict(doc)
    assert res.ok and res.timings == SampleTimings(1.0, 0.2, 2.0) and res.rows[0].time_recon_s == 0.5
    assert json.dumps(res.to_dict()) == json.dumps(doc)  # same keys, same order: result.json unchanged
    failed = {k: v for k, v in doc.items() if k != "render_worker"}
    failed.update(status="failed", error="RuntimeError: x", phase="render", variant=None, false_boundary_gt=None,
                  rows=[MethodRun.failed("paper", "RuntimeError: x").to_dict()], timings_s={"render_s": 1.0,
                                                                                          "total_s": 1.5})
    back = SampleResult.from_dict(failed)
    assert json.dumps(back.to_dict()) == json.dumps(failed) and not back.ok
    assert list(failed["rows"][0]) == ["method", "status", "error", "metrics"]  # a failed run has no times


def test_a_sample_result_gives_the_results_tables_rows():
    from platebench.bench.io.sweep_records import SampleResult, table_rows
    res = SampleResult.from_dict({**_RESULT_OK, "config": _small_config()})
    (row,) = table_rows(res)
    assert (row["method"], row["matched_count"], row["false_boundary_gt"]) == ("paper", 16, False)
    assert row["time_render_s"] == 1.0 and row["time_total_s"] == 2.0 and row["worker"] == "h:7"


def _small_config() -> dict:
    from platebench.bench.config import SampleConfig
    return encode(SampleConfig())


def test_visibility_and_false_boundary_verdicts_read_from_their_files():
    from platebench.bench.io.report_records import (
        FalseBoundaryRecord,
        RunTimings,
        SensingRun,
        boundary_hidden,
        visibility_records,
    )
    vis = visibility_records({"left": {"visible_fraction": 0.8, "false_boundary": True, "hidden_segments": [],
                                       "n_points": 10, "n_visible": 8},
                              "right": {"visible_fraction": 1.0, "false_boundary": False}, "note": "x"})
    assert set(vis) == {"left", "right"} and vis["left"].visible_fraction == 0.8 and boundary_hidden(vis)
    assert not boundary_hidden({"right": vis["right"]})
    fb = FalseBoundaryRecord.of({"false_boundary": {"detected": {"left": 16, "right": 14}, "expected": 16,
                                                    "expected_ids": [1, 2], "counting_test": True,
                                                    "arrays_disagree": False, "false_boundary_detected": True,
                                                    "cut_squares": {}}})
    assert fb.false_boundary_detected and fb.expected_ids == (1, 2) and fb.detected_text() == "left 16, right 14"
    assert FalseBoundaryRecord.of({}) is None and FalseBoundaryRecord.of({"false_boundary": None}) is None
    t = RunTimings.from_dict({"plate_s": 0.1, "render_left_passive_s": 1.0, "render_right_passive_s": 2.0,
                              "ground_truth_s": 0.5, "total_s": 4.0})
    assert (t.total_s, t.ground_truth_s, t.renders_s) == (4.0, 0.5, 3.0)
    assert RunTimings.of({"timings_s": {"total_s": 1.5}}).total_s == 1.5 and RunTimings.of({}).total_s is None
    run = SensingRun.from_dict({"cures": 1, "time_s": 9.0, "final": {"outcome": "cured", "matched": 40,
                                "false_boundary": {"false_boundary_detected": False},
                                "gt_visibility": {"left": {"visible_fraction": 1.0, "false_boundary": False}}},
                                "steps": [{"stage": 2, "pose": {"distance_m": 0.4}}, "junk"]})
    assert (run.outcome, run.cures, run.time_s, run.final.matched) == ("cured", 1, 9.0, 40)
    assert run.final.false_boundary.false_boundary_detected is False and len(run.steps) == 1
    assert run.steps[0].distance_m == 0.4 and run.steps[0].false_boundary is None
