"""Reports: HTML of sweep datasets, false-boundary studies and compare.json files.

Most tests build small inputs by hand (no rendering); one renders a tiny real sample for the
error map, one renders the HTML with headless Chromium (skipped without it). Damaged inputs,
single samples, reconstructions and sensing runs: tests/test_report_inputs.py.
"""
from __future__ import annotations

import csv
import json
import math
import os
import re
import shutil
import statistics
import subprocess
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import record_tables

from platebench.bench.io.outputs import STAMP, OutputRefusedError
from platebench.bench.report import plots as P
from platebench.bench.report import summary as S
from platebench.bench.report.html import GENERATOR, ReportInputError, write_report
from platebench.bench.report.inputs import detect_inputs, load_results
from platebench.bench.report.summary import method_summary

PNG_SIG = b"\x89PNG\r\n\x1a\n"
FAIL_MSG = "ReconstructionError: <left_active.png> found 0 squares & see http://example.invalid/x"


# ----------------------------------------------------------------------------- synthetic inputs
def _write_csv(path: Path, rows: list[dict], columns: list[str]) -> None:
    with open(path, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(columns)
        for r in rows:
            w.writerow(["" if r.get(c) is None else (str(r[c]).lower() if isinstance(r[c], bool) else r[c])
                        for c in columns])
    if path.name == "results.csv":
        record_tables(path.parent)


def make_dataset(root: Path, columns: list[str] | None = None) -> Path:
    """A fake sweep: 4 bends x (paper, sgbm); sample 0003 failed (both methods)."""
    root.mkdir(parents=True, exist_ok=True)
    rows = []
    for i, bend in enumerate((0.0, 20.0, 40.0, 60.0)):
        sid = f"{i:04d}"
        failed = i == 3
        gt = bend >= 40
        rows.append({"sample_id": sid, "index": i, "method": "paper", "status": "failed" if failed else "ok",
                     "error": FAIL_MSG if failed else None, "family": "cylinder", "bend_deg": bend,
                     "direction": "up" if i % 2 == 0 else "down", "axis_deg": 0.0, "material": "diffuse",
                     "distance_m": 0.4, "noise": "none", "width_px": 320,
                     "centres_depth_rms_mm": None if failed else 0.02 + 0.01 * i,
                     "centres_depth_max_mm": None if failed else 0.05 * (i + 1),
                     "xy_radial_rms_mm": None if failed else 0.03,
                     "boundary_mean_mm": None if failed else 0.2 + 0.1 * i,
                     "boundary_hausdorff_mm": None if failed else 0.8, "surface_rms_mm": None if failed else 0.1,
                     "coverage_frac": None if failed else 0.99, "matched_count": None if failed else 16,
                     "correct_match_count": None if failed else 16, "expected_count_gt": None if failed else 16,
                     "false_boundary_gt": gt, "false_boundary_detected": None if failed else gt,
                     "paper_bound_met": None if failed else bend < 40, "time_recon_s": None if failed else 0.3})
        rows.append({"sample_id": sid, "index": i, "method": "sgbm", "status": "failed" if failed else "ok",
                     "error": FAIL_MSG if failed else None, "family": "cylinder", "bend_deg": bend,
                     "direction": "up" if i % 2 == 0 else "down", "axis_deg": 0.0, "material": "diffuse",
                     "distance_m": 0.4, "noise": "none", "width_px": 320,
                     "depth_rms_mm": None if failed else 3.0 + i, "depth_max_mm": None if failed else 9.0,
                     "depth_median_mm": None if failed else 2.5, "coverage_frac": None if failed else 0.7,
                     "false_boundary_gt": gt, "time_recon_s": None if failed else 0.02})
    columns = columns or list(dict.fromkeys(k for r in rows for k in r))
    _write_csv(root / "results.csv", rows, columns)
    manifest = {"format": "platebench-sweep", "version": 1, "state": "complete",
                "created_utc": "2025-01-01T00:00:00+00:00",
                "updated_utc": "2025-01-01T00:01:00+00:00",
                "spec": {"name": "fake_sweep", "description": "hand-made test sweep", "mode": "grid",
                         "methods": ["paper", "sgbm"], "axes": {"bend_deg": [0, 20, 40, 60]}},
                "spec_text": "[sweep]\nname = \"fake_sweep\"\n",
                "packages": {"python": "3.11.7", "mitsuba": "3.9.1", "drjit": "1.5.0", "numpy": "2.0.0",
                             "dask": None},
                "executor": {"kind": "local", "workers": 2},
                "counts": {"total": 4, "ok": 3, "failed": 1, "pending": 0},
                "samples": [{"id": f"{i:04d}", "index": i, "status": "failed" if i == 3 else "ok"} for i in range(4)]}
    (root / "manifest.json").write_text(json.dumps(manifest))
    return root


def make_study(root: Path, with_extras: bool = True) -> Path:
    """A fake study.json (+ study.csv): bends 0..120 up and down, one failed case."""
    root.mkdir(parents=True, exist_ok=True)
    rows = []
    for direction in ("up", "down"):
        for bend in (0, 30, 60, 90, 120):
            hidden = max(0.0, (bend - (60 if direction == "down" else 80)) / 200.0)
            gt = hidden > 0
            failed = direction == "up" and bend == 120
            r = {"bend_deg": float(bend), "direction": direction, "axis_deg": 0.0, "length_m": 0.1165,
                 "width_m": 0.0735, "distance_m": 0.4, "hidden_frac_left": hidden, "hidden_frac_right": hidden * 0.8,
                 "false_boundary_gt": gt, "status": "failed" if failed else "ok", "time_s": 1.5}
            if failed:
                r.update(error="ReconstructionError: no plate region", detected=None, counting_test=None,
                         arrays_disagree=None)
            else:
                r.update(error="", detected=gt and bend > 90 or (not gt and bend == 60), counting_test=gt and bend > 90,
                         arrays_disagree=gt, squares_expected=16, squares_left=16 - int(gt) * 2,
                         squares_right=16 - int(gt), centres_depth_rms_mm=0.02 + bend / 1000, xy_radial_rms_mm=0.03,
                         boundary_mean_mm=0.2 + bend / 100, matched=16)
                if gt:
                    r.update(cure1_removed=bend < 120, cure1_hidden_frac=0.0 if bend < 120 else 0.05,
                             cure2_removed=True, cure2_hidden_frac=0.0, cure2_steps=2, cure2_distance_m=0.6,
                             L_measured_m=0.3)
            rows.append(r)
    doc = {"rows": rows}
    if with_extras:
        doc["l_formula"] = [
            {"bend_deg": b, "L_m": 0.05 + b / 1000, "predicted_distance_m": 0.06 + b / 1000,
             "gt_distance_baseline_along_axis_m": 0.07 + b / 900,
             "ratio_gt_over_predicted_baseline_along_axis": (0.07 + b / 900) / (0.06 + b / 1000),
             "gt_distance_baseline_along_bend_m": math.inf if b == 180 else 0.08 + b / 800,
             "ratio_gt_over_predicted_baseline_along_bend": None if b == 180 else (0.08 + b / 800) / (0.06 + b / 1000)}
            for b in (90.0, 120.0, 150.0, 180.0)]
        doc["smallest_hiding_bend_deg"] = {"down": 61.25, "up": None}
        doc["precision_recall"] = {
            "detected": {"true_positive": 2, "false_positive": 1, "false_negative": 3, "precision": 0.6667,
                         "recall": 0.4},
            "counting_test": {"true_positive": 1, "false_positive": 0, "false_negative": 4, "precision": 1.0,
                              "recall": 0.2},
            "arrays_disagree": {"true_positive": 5, "false_positive": 0, "false_negative": 0, "precision": 1.0,
                                "recall": 1.0}}
    (root / "study.json").write_text(json.dumps(doc))  # json writes inf as Infinity, as json.dump does
    cols = list(dict.fromkeys(k for r in rows for k in r))
    _write_csv(root / "study.csv", rows, cols)
    return root


def make_compare(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    doc = {"sample": "s1", "scene_reproduced": True, "notes": ["a note"], "units": "depth errors in mm",
           "methods": {"paper": {"description": "paper's squares", "kind": "paper", "n_images": 2, "time_s": 0.2,
                                 "render_s": 0.0, "points": 16, "points_on_plate": 16,
                                 "centres_depth_median_mm": 0.01, "centres_depth_rms_mm": 0.013,
                                 "centres_depth_max_mm": 0.03, "surface_rms_mm": 0.02, "notes": [],
                                 "figures": {"measure": "centres", "n_images": 2, "time_s": 0.2, "render_s": 0.0,
                                             "points_on_plate": 16, "centres_depth_median_mm": 0.01,
                                             "centres_depth_rms_mm": 0.013, "centres_depth_max_mm": 0.03,
                                             "surface_rms_mm": 0.02}},
                       "graycode": {"description": "Gray code", "kind": "disparity", "n_images": 42, "time_s": 1.1,
                                    "render_s": 20.0, "coverage_frac": 0.44, "depth_median_mm": 0.17,
                                    "depth_rms_mm": 0.22, "depth_max_mm": 2.0,
                                    "middlebury": {"mb_all_bad_1_0_pct": 3.2}, "notes": [],
                                    "figures": {"measure": "disparity", "n_images": 42, "time_s": 1.1,
                                                "render_s": 20.0, "coverage_frac": 0.44, "depth_median_mm": 0.17,
                                                "depth_rms_mm": 0.22, "depth_max_mm": 2.0,
                                                "mb_all_bad_1_0_pct": 3.2}}}}
    path.write_text(json.dumps(doc))
    return path


# ----------------------------------------------------------------------------- checks
def _check_png(path: Path) -> tuple[int, int]:
    data = Path(path).read_bytes()
    assert data[:8] == PNG_SIG, path
    import cv2
    img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
    assert img is not None and img.shape[0] > 100 and img.shape[1] > 100, path
    assert img.std() > 5, f"{path} looks blank"
    return img.shape[1], img.shape[0]


def embedded_thumbnails(text: str) -> list[tuple[str, str, np.ndarray]]:
    """(alt, href, decoded image) of every thumbnail a page embeds (an image linked to its full file)."""
    import base64

    import cv2
    out = []
    for href, alt, data in re.findall(r'<a href="([^"]+)"><img alt="([^"]+)" src="data:image/png;base64,([^"]+)">',
                                      text):
        img = cv2.imdecode(np.frombuffer(base64.b64decode(data), np.uint8), cv2.IMREAD_UNCHANGED)
        assert img is not None, alt
        out.append((alt, href, img))
    return out


def _check_self_contained(index: Path) -> list[str]:
    """The page is the report on its own: no scripts, no external assets or links; every image
    embedded as a PNG data URI (plots and thumbnails: the page shows them when copied alone), every
    link a relative path that exists. Returns the embedded images' URIs."""
    text = index.read_text()
    assert text.startswith("<!DOCTYPE html>")
    assert f'content="{GENERATOR}"' in text
    low = text.lower()
    for bad in ("<script", "<link", "<iframe", 'src="http', 'href="http', "url(", "@import", 'src="file', 'href="file'):
        assert bad not in low, bad
    srcs = re.findall(r'<img[^>]*\ssrc="([^"]*)"', text)
    embedded = [s for s in srcs if s.startswith("data:")]
    assert embedded and all(s.startswith("data:image/png;base64,") for s in srcs)
    assert not (index.parent / "thumbs").exists()
    for ref in [s for s in srcs if not s.startswith("data:")] + re.findall(r'href="([^"]*)"', text):
        if ref.startswith("#"):
            assert f'id="{ref[1:]}"' in text, ref
            continue
        assert not ref.startswith("/") and "://" not in ref, ref
        assert (index.parent / ref).exists(), ref
    return embedded


def _plot_names(report: Path) -> set[str]:
    return {p.relative_to(report / "plots").with_suffix("").as_posix() for p in (report / "plots").rglob("*.png")}


# ----------------------------------------------------------------------------- tests
def test_dataset_report(tmp_path):
    ds = make_dataset(tmp_path / "ds")
    import matplotlib.pyplot as plt
    before = list(plt.get_fignums())
    index = write_report(ds)
    assert plt.get_fignums() == before  # plots use their own Figure objects
    assert index == ds / "report" / "index.html"
    srcs = _check_self_contained(index)
    text = index.read_text()
    for s in srcs:  # every embedded image decodes as a PNG
        import base64
        assert base64.b64decode(s.split(",", 1)[1])[:8] == PNG_SIG
    assert "fake_sweep" in text and "hand-made test sweep" in text
    assert "Method comparison" in text and "Package versions" in text and "3.9.1" in text
    assert "not installed" in text  # dask: None in the manifest
    assert "Failures (2)" in text
    assert "ReconstructionError: &lt;left_active.png&gt; found 0 squares &amp; see" in text  # escaped, verbatim
    assert "<left_active.png>" not in text
    assert "By bend angle" in text
    assert "x/y radial RMS at the square centres (mm)" in text  # labels from evaluation.metrics_row
    names = _plot_names(ds / "report")
    assert {"dataset_method_comparison", "dataset_error_vs_bend", "dataset_detection_vs_bend"} <= names
    assert len(srcs) == len(names)
    for p in (ds / "report" / "plots").rglob("*.png"):
        _check_png(p)
    # a second run replaces the report (it is ours) only with overwrite, leaving no temporary files behind
    with pytest.raises(OutputRefusedError, match="already exists"):
        write_report(ds)
    write_report(ds, overwrite=True)
    assert not [p for p in (ds / "report").rglob("*") if p.name.startswith(".") and p.name != STAMP]
    assert not [p for p in ds.iterdir() if p.name.startswith(".")]


def test_method_summary_values(tmp_path):
    ds = make_dataset(tmp_path / "ds")
    frame, source = load_results(ds)
    assert source == "results.csv" and len(frame) == 8
    assert frame["sample_id"].iloc[0] == "0000"
    assert [bool(v) for v in frame["false_boundary_gt"]] == [False] * 4 + [True] * 4  # typed flags
    assert frame["false_boundary_detected"].map(lambda v: v is None or isinstance(v, (bool, np.bool_))).all()
    s = method_summary(frame)
    assert list(s) == ["paper", "sgbm"]
    assert s["paper"]["ok"] == 3 and s["paper"]["failed"] == 1
    d = s["paper"]["metrics"]["centres_depth_rms_mm"]
    assert "depth_rms_mm" not in s["paper"]["metrics"] and s["sgbm"]["metrics"]["depth_rms_mm"]["n"] == 3
    assert d["n"] == 3 and d["mean"] == pytest.approx(0.03) and d["median"] == pytest.approx(0.03)
    fb = s["paper"]["metrics"]["false_boundary_detected"]
    assert fb["kind"] == "rate" and fb["mean"] == pytest.approx(1 / 3) and fb["true"] == 1
    assert "boundary_mean_mm" not in s["sgbm"]["metrics"]


def test_failures_are_counted_by_kind(tmp_path):
    """Crashes, bound violations and mismatches are counted separately (a row can be several)."""
    ds = make_dataset(tmp_path / "ds")
    frame, _ = load_results(ds)
    frame.loc[(frame["method"] == "paper") & (frame["sample_id"] == "0001"), "correct_match_count"] = 14.0
    t = S.failure_table(frame, "method")
    # by hand: paper rows 0..3; 0003 crashed; bound (bend < 40) met at 0 and 20, violated at 40; 0001 mismatched
    assert t.loc["paper"].to_dict() == {"crashed": 1, "bound_known": 3, "bound_violated": 1, "match_known": 3,
                                        "mismatched": 1, "rows": 4}
    assert t.loc["sgbm"].to_dict() == {"crashed": 1, "bound_known": 0, "bound_violated": 0, "match_known": 0,
                                       "mismatched": 0, "rows": 4}
    text = write_report(ds).read_text()
    part = text[text.index("Failures by kind"):]
    assert "<td>paper</td><td>4</td><td>1 / 4</td><td>1 / 3</td><td>0 / 3</td>" in part
    assert "<td>sgbm</td><td>4</td><td>1 / 4</td><td>–</td><td>–</td>" in part
    head = text[text.index('id="headline"'):text.index("<nav>")]
    assert "paper&#39;s bound met in 2 of 3 rows" in head and "2 crashed" in head


def test_study_report(tmp_path):
    st = make_study(tmp_path / "study")
    index = write_report(st, tmp_path / "out")
    assert index == tmp_path / "out" / "index.html"
    _check_self_contained(index)
    text = index.read_text()
    assert "False-boundary study" in text
    assert "Smallest hiding bend" in text and "61.25" in text
    assert "Detection precision / recall" in text and "0.6667" in text
    assert "L formula" in text and "\u221e" in text  # the never-visible GT distance
    assert "Cases (10)" in text and "no plate region" in text
    assert "x/y radial RMS at the square centres (mm)" in text and "bend angle (deg)" in text  # labels from the registries
    head = text[text.index('id="headline"'):text.index("<nav>")]
    assert "False-boundary study" in head and "GT false boundary" in head
    names = _plot_names(tmp_path / "out")
    assert {"study/hidden_fraction_vs_bend", "study/detection_vs_bend", "study/cure_success_vs_bend",
            "study/l_formula", "study/error_vs_bend"} <= names
    for p in (tmp_path / "out" / "plots").rglob("*.png"):
        _check_png(p)


def test_study_csv_only_and_missing_columns(tmp_path):
    """A study with only study.csv, and a dataset with only a few columns: a report, no crash."""
    st = make_study(tmp_path / "study", with_extras=False)
    (st / "study.json").unlink()
    index = write_report(st)
    _check_self_contained(index)
    text = index.read_text()
    assert "study.csv" in text and "Detection precision / recall" in text  # computed from the rows
    ds = make_dataset(tmp_path / "ds", columns=["sample_id", "method", "status", "error"])
    text = write_report(ds).read_text()
    assert "Method comparison" in text and "Failures (2)" in text
    # a manifest without a results table yet (sweep just started)
    ds2 = tmp_path / "ds2"
    ds2.mkdir()
    (ds2 / "manifest.json").write_text(json.dumps({"format": "platebench-sweep", "counts": {"total": 3, "pending": 3}}))
    text = write_report(ds2).read_text()
    assert "nothing to tabulate" in text


def test_parent_dir_with_dataset_study_and_compare(tmp_path):
    make_dataset(tmp_path / "sweep")
    make_study(tmp_path / "study")
    make_compare(tmp_path / "s1" / "compare" / "compare.json")
    inp = detect_inputs(tmp_path)
    assert [p.name for p in inp.datasets] == ["sweep"] and [p.name for p in inp.studies] == ["study"]
    assert len(inp.compares) == 1
    index = write_report(tmp_path)
    _check_self_contained(index)
    text = index.read_text()
    assert "Sweep dataset: fake_sweep" in text and "False-boundary study" in text
    assert "Method comparison: s1/compare/compare.json" in text and "Gray code" in text
    assert 'href="#dataset"' in text and 'href="#study"' in text and 'href="#compare1"' in text
    names = _plot_names(tmp_path / "report")
    assert "compare1_compare" in names and "dataset_error_vs_bend" in names and "study/l_formula" in names
    assert detect_inputs(tmp_path).datasets == inp.datasets  # the report folder is not an input


def test_nothing_to_report_and_foreign_out_dir(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ReportInputError, match="neither a sweep dataset .* nor a false-boundary study") as e:
        write_report(tmp_path / "empty")
    assert "\n" not in str(e.value)
    from platebench.bench.cli.main import main
    assert main(["report", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("platebench: error: ") and err.count("\n") == 1
    assert not (tmp_path / "empty" / "report").exists()
    # never write into a non-empty directory that is not a report
    ds = make_dataset(tmp_path / "ds")
    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    with pytest.raises(OutputRefusedError, match="already exists"):
        write_report(ds, other)
    with pytest.raises(OutputRefusedError, match="keep.txt, not a PlateBench report: refusing"):
        write_report(ds, other, overwrite=True)
    assert sorted(p.name for p in other.iterdir()) == ["keep.txt"]


def test_cli_report_prints_index(tmp_path, capsys):
    ds = make_dataset(tmp_path / "ds")
    from platebench.bench.cli.main import main
    assert main(["report", str(ds), "--out", str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out.strip()
    assert out == str(tmp_path / "r" / "index.html") and Path(out).is_file()


def test_plots_on_empty_inputs(tmp_path):
    """Every plot function draws something sensible (a note) on empty input, and returns its path."""
    import pandas as pd
    calls = [(P.plot_error_vs_bend, ([],)), (P.plot_detection_vs_bend, ([],)),
             (P.plot_hidden_fraction_vs_bend, ([],)), (P.plot_cure_success_vs_bend, ([],)),
             (P.plot_l_formula, ([],)), (P.plot_method_comparison, ({},)),
             (P.plot_metric_vs_axis, (pd.DataFrame({"method": [], "noise": []}), "noise")),
             (P.plot_error_map, (tmp_path / "nosample", tmp_path / "norecon"))]
    for i, (fn, args) in enumerate(calls):
        path = tmp_path / f"p{i}.png"
        assert fn(*args, path) == path
        assert path.read_bytes()[:8] == PNG_SIG


def test_bend_bins_and_precision_recall():
    e = P.bend_bins([0, 10, 20, 20])
    assert np.allclose(e, [-5, 5, 15, 25])
    assert len(P.bend_bins(range(100), max_bins=10)) == 11
    pr = S.precision_recall([{"false_boundary_gt": True, "d": True}, {"false_boundary_gt": False, "d": True},
                             {"false_boundary_gt": True, "d": False}, {"false_boundary_gt": True, "d": None},
                             {"false_boundary_gt": False, "d": False},
                             {"false_boundary_gt": "false", "d": "false"}], "d")  # text is never a flag
    assert (pr["true_positive"], pr["false_positive"], pr["false_negative"], pr["true_negative"]) == (1, 1, 1, 1)
    assert pr["precision"] == 0.5 and pr["recall"] == 0.5


def _chromium() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


@pytest.mark.skipif(_chromium() is None, reason="chromium is not installed (apt-get install -y chromium)")
def test_report_renders_in_headless_chromium(tmp_path):
    ds = make_dataset(tmp_path / "ds")
    make_study(tmp_path / "study")
    index = write_report(tmp_path)
    shot = tmp_path / "shot.png"
    cmd = [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync",
           f"--user-data-dir={tmp_path / 'chrome-profile'}", "--hide-scrollbars", f"--screenshot={shot}",
           "--window-size=1280,2000", index.resolve().as_uri()]
    env = dict(os.environ, HOME=str(tmp_path))
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=90, env=env)
    assert shot.is_file(), f"no screenshot (rc {proc.returncode}): {proc.stderr[-2000:]}"
    w, h = _check_png(shot)
    assert (w, h) == (1280, 2000)
    import cv2
    img = cv2.imread(str(shot), cv2.IMREAD_GRAYSCALE)
    assert (img < 200).mean() > 0.02  # text, tables and plots, not a blank page
    assert len(np.unique(img)) > 50
    assert ds.is_dir()


@pytest.mark.render
def test_error_map_on_a_real_tiny_sample(tmp_path, monkeypatch):
    from platebench.bench.config import SampleConfig, SceneParams
    from platebench.bench.io.recon_files import image_checksums, write_reconstruction
    from platebench.bench.io.sample_files import load_inputs, write_sample
    from platebench.bench.run.render import render_sample
    from platebench.plates import CylindricalBend, PlateSpec
    from platebench.reconstruction.paper.pipeline import (
        projector_feature_rays,
        reconstruct,
    )
    from platebench.scenes.scene_spec import RenderSettings

    cfg = SampleConfig(plate=PlateSpec(0.1165, 0.0735, deformation=CylindricalBend(np.radians(20))),
                       scene=SceneParams(width=160, height=120), render=RenderSettings(spp=2, seed=1))
    sample, _ = render_sample(cfg)
    ds = make_dataset(tmp_path / "ds")  # sample 0000 / paper of the fake sweep gets real files (dataset layout)
    sdir = write_sample(ds / "samples" / "0000" / "sample", sample)
    inputs = load_inputs(sdir)
    rec = reconstruct(inputs.images, inputs.calibration.rig,
                      projector_feature_rays(inputs.calibration.projector_camera, inputs.pattern), inputs.pattern)
    rdir = write_reconstruction(ds / "samples" / "0000" / "recon" / "paper", rec, sdir,
                                image_checksums(inputs.images))

    # unevaluated: the report does not score, it says so
    notes = []
    monkeypatch.setattr(P, "_empty", lambda ax, text: notes.append(text))
    P.plot_error_map(sdir, rdir, tmp_path / "unscored.png")
    assert notes == [f"error map unavailable: {P.NOT_EVALUATED}"] * 2
    monkeypatch.undo()
    from platebench.bench.run.score import score_files
    data = P.error_map_data(sdir, rdir, score_files(sdir, rdir).per_point)
    assert len(data.centres) == len(rec.points) > 0
    assert np.all(np.isfinite(data.centre_err_mm)) and np.all(data.centre_err_mm >= 0)
    assert (data.centre_kind == "3d").sum() > 0  # identities from the GT feature map
    assert data.surface_dist_mm is not None and np.all(np.isfinite(data.surface_dist_mm))
    assert data.surface_dist_mm.max() < 20.0  # mm: a 20-degree bend reconstructs to within millimetres
    from platebench.evaluation.point_metrics import point_to_surface_distance
    d = point_to_surface_distance(rec.points, sample.plate.mesh) * 1e3
    assert np.all(data.centre_err_mm[data.centre_kind == "3d"] >= d[data.centre_kind == "3d"] - 1e-9)
    out = P.plot_error_map(sdir, rdir, tmp_path / "map.png", data=data)
    w, h = _check_png(out)
    assert w >= 800 and h >= 300
    # the dataset report finds the reconstruction and draws its map; the sample is linked, with thumbnails
    index = write_report(ds)
    _check_self_contained(index)
    text = index.read_text()
    assert "Per-sample error maps" in text
    _check_png(ds / "report" / "plots" / "dataset_error_map_0000_paper.png")
    assert 'href="../samples/0000/"' in text
    thumbs = embedded_thumbnails(text)
    assert [(alt, href) for alt, href, _ in thumbs] == [("0000 left_passive", "../samples/0000/sample/images/left_passive.png"),
                                                        ("0000 left_active", "../samples/0000/sample/images/left_active.png")]
    t = thumbs[1][2]
    assert t.dtype == np.uint8 and t.shape[1] == 160  # images narrower than a thumbnail are kept as they are


# ----------------------------------------------------------------------------- swept axes (realism study)
_DEPTH = {"paper": 0.2, "graycode-subpx": 0.5, "sgbm": 3.0}


def make_realism_dataset(root: Path, with_manifest: bool = True) -> Path:
    """A fake realism sweep: roughness (0.05, 0.2, 0.5) x noise (none, high), bend 10 deg throughout,
    3 methods. Failures, each of another kind:

    * paper, roughness 0.05, noise high: status ok, 12 of 16 squares matched: the paper's bound violated;
    * paper, roughness 0.2, noise none: status ok, 15 of 16 matched squares matched correctly (a mismatch),
      bound met all the same (the counts are independent);
    * sgbm, roughness 0.05, noise high: status failed (crashed);
    * graycode-subpx, roughness 0.5: noise none crashed, noise high ok but no depth RMS;
    * graycode-subpx carries a method-specific metric, mb_all_bad_1_0_pct (Middlebury bad 1.0, %).
    Depth RMS (mm): the method's base x (1 + 10 x roughness) x (2 with noise high)."""
    root.mkdir(parents=True, exist_ok=True)
    rows = []
    i = 0
    for rough in (0.05, 0.2, 0.5):
        for noise in ("none", "high"):
            sid = f"{i:04d}"
            for m in ("paper", "graycode-subpx", "sgbm"):
                depth = _DEPTH[m] * (1 + 10 * rough) * (2 if noise == "high" else 1)
                r = {"sample_id": sid, "index": i, "method": m, "status": "ok", "error": None, "family": "cylinder",
                     "bend_deg": 10.0, "direction": "up", "material": "roughconductor", "metal": "Al",
                     "roughness": rough, "distance_m": 0.4, "noise": noise, "width_px": 320, "height_px": 240,
                     "spp": 4, "seed": 0, "centres_depth_rms_mm" if m == "paper" else "depth_rms_mm": depth}
                if m == "paper":
                    incomplete = (rough, noise) == (0.05, "high")
                    r.update(matched_count=12 if incomplete else 16, expected_count_gt=16,
                             correct_match_count=15 if (rough, noise) == (0.2, "none") else 12 if incomplete else 16,
                             paper_bound_met=not incomplete, boundary_mean_mm=0.3)
                if m == "sgbm" and (rough, noise) == (0.05, "high"):
                    r.update(status="failed", error="RuntimeError: SGBM found no disparity", depth_rms_mm=None)
                if m == "graycode-subpx":
                    r["mb_all_bad_1_0_pct"] = 10.0 * rough
                    if rough == 0.5:
                        if noise == "none":
                            r.update(status="failed", error="ValueError: decode failed", depth_rms_mm=None,
                                     mb_all_bad_1_0_pct=None)
                        else:
                            r.update(depth_rms_mm=None)
                rows.append(r)
            i += 1
    columns = list(dict.fromkeys(k for r in rows for k in r))
    columns.remove("mb_all_bad_1_0_pct")
    columns.append("mb_all_bad_1_0_pct")  # after the shared metric columns, as the sweep writes it
    _write_csv(root / "results.csv", rows, columns)
    if with_manifest:
        manifest = {"format": "platebench-sweep", "version": 1, "state": "complete",
                    "spec": {"name": "fake_realism", "mode": "grid", "methods": ["paper", "graycode-subpx", "sgbm"],
                             "axes": {"roughness": [0.05, 0.2, 0.5], "noise": ["none", "high"]}},
                    "counts": {"total": 6, "ok": 4, "failed": 2, "pending": 0}}
        (root / "manifest.json").write_text(json.dumps(manifest))
    return root


def test_axis_stats_failure_kinds_by_hand(tmp_path):
    frame, _ = load_results(make_realism_dataset(tmp_path / "ds"))
    st = S.axis_stats(frame, "roughness")
    assert st["numeric"] and [lv["key"] for lv in st["levels"]] == [0.05, 0.2, 0.5]
    assert st["methods"] == ["paper", "graycode-subpx", "sgbm"]  # the paper's pipeline first
    c = st["cells"][("paper", 0.05)]
    # by hand: 2 rows (noise none, high); the high one matched 12 < 16 squares: bound violated 1 of 2 verdicts,
    # no crash, no mismatch; its depth RMS still counts in the median: median(0.3, 0.6) = 0.45 mm
    assert (c["rows"], c["crashed"], c["bound_violated"], c["bound_known"], c["mismatched"], c["match_known"]) \
        == (2, 0, 1, 2, 0, 2)
    assert c["median"] == pytest.approx(0.45)
    c = st["cells"][("paper", 0.2)]  # a mismatch with the bound met: counted as a mismatch only
    assert (c["crashed"], c["bound_violated"], c["mismatched"], c["match_known"]) == (0, 0, 1, 2)
    c = st["cells"][("graycode-subpx", 0.5)]  # one crashed, one ok without a depth RMS; no verdicts
    assert (c["crashed"], c["rows"], c["bound_known"], c["match_known"], c["median"]) == (1, 2, 0, 0, None)
    assert st["cells"][("sgbm", 0.2)]["crashed"] == 0
    sn = S.axis_stats(frame, "noise", "depth_rms_mm")  # the dense maps' figure: sgbm's, graycode's
    assert not sn["numeric"] and [lv["key"] for lv in sn["levels"]] == ["none", "high"]
    c = sn["cells"][("sgbm", "high")]  # crashed at 0.05; ok at 0.2 and 0.5 -> 1/3
    assert (c["crashed"], c["rows"]) == (1, 3)
    assert c["median"] == pytest.approx(statistics.median([3.0 * 3 * 2, 3.0 * 6 * 2]))
    assert (sn["cells"][("paper", "high")]["bound_violated"], sn["cells"][("paper", "none")]["mismatched"]) == (1, 1)
    assert sn["cells"][("paper", "high")]["median"] is None  # the paper has no figure over the pixels


def test_axis_levels_order_and_bins():
    import pandas as pd
    frame = pd.DataFrame({"noise": ["high", "none", "medium", "low", None]})
    levels, keys, numeric = S.axis_levels(frame, "noise")
    assert not numeric and [lv["label"] for lv in levels] == ["none", "low", "medium", "high"]
    assert keys.iloc[4] is None and keys.iloc[3] == "low"
    frame = pd.DataFrame({"bend_deg": [float(b) for b in range(0, 100, 4)]})  # 25 distinct values: binned
    levels, keys, numeric = S.axis_levels(frame, "bend_deg", max_levels=5)
    assert numeric and len(levels) == 5 and levels[0]["label"] == "0\u201319.2"
    assert keys.iloc[0] == 0 and keys.iloc[-1] == 4


def test_swept_axes_from_manifest_and_columns(tmp_path):
    import pandas as pd
    frame, _ = load_results(make_realism_dataset(tmp_path / "ds"))
    axes, varying = S.swept_axes({"spec": {"axes": {"noise": ["none", "high"], "roughness": [0.05, 0.2, 0.5]}}},
                                 frame)
    assert axes == ["noise", "roughness"]  # spec order; bend_deg, spp, width_px take one value: not swept
    assert varying["roughness"] == ["0.05", "0.2", "0.5"]
    assert S.swept_axes({}, frame)[0] == ["roughness", "noise"]  # no manifest: the parameter columns that vary
    more = pd.concat([frame.assign(seed=float(s), width_px=float(w), height_px=float(w * 3 // 4),
                                   read_noise_dn=frame["noise"].map({"none": 0.0, "high": 2.0}))
                      for s in (0, 1) for w in (320, 640)], ignore_index=True)
    axes, varying = S.swept_axes({"spec": {"axes": {"scene.material.alpha": [0.05], "resolution": ["320x240"],
                                                    "seed": [0, 1]}}}, more)
    assert axes == ["roughness", "width_px", "noise"]  # seed varies (pooled) but is never plotted against
    # height_px follows width_px and read noise follows the noise preset: neither is an axis of its own
    assert "seed" in varying and "height_px" not in varying and "read_noise_dn" not in varying


def test_dataset_report_swept_axes(tmp_path):
    ds = make_realism_dataset(tmp_path / "ds")
    index = write_report(ds)
    srcs = _check_self_contained(index)
    text = index.read_text()
    assert "Against the swept axes" in text
    assert "<h4>roughness (GGX alpha)</h4>" in text and "<h4>sensor noise</h4>" in text
    names = _plot_names(ds / "report")
    assert {"dataset_vs_roughness", "dataset_vs_noise"} <= names
    assert "dataset_vs_bend_deg" not in names and "dataset_error_vs_bend" not in names  # one bend: not swept
    assert "By bend angle" not in text
    assert len(srcs) == len(names)
    for n in ("dataset_vs_roughness", "dataset_vs_noise"):
        w, h = _check_png(ds / "report" / "plots" / f"{n}.png")
        assert w >= 800 and h >= 500
    # the tables: each kind of failure with its count, medians in mm
    rough = text[text.index("<h4>roughness (GGX alpha)</h4>"):text.index("<h4>sensor noise</h4>")]
    # roughness 0.05: paper median 0.45, no crash, bound violated 1 of 2, mismatched 0 of 2
    # (each depth figure in its own column: the paper's at the centres, none over the pixels)
    assert "<td>0.05</td><td>0.45</td><td>–</td><td>0 / 2</td><td>1 / 2</td><td>0 / 2</td>" in rough
    assert "<td>1 / 2</td><td>–</td><td>–</td>" in rough  # graycode at 0.5: 1 crash of 2, no verdicts
    noise = text[text.index("<h4>sensor noise</h4>"):]
    assert "<td>1 / 3</td>" in noise
    assert noise.index("<td>none</td>") < noise.index("<td>high</td>")  # natural order, not alphabetical
    # each caption says what else is pooled into a point
    assert "every point pools their samples: sensor noise (none, high)" in rough
    assert "every point pools their samples: roughness (GGX alpha) (0.05, 0.2, 0.5)" in noise
    # the method-specific metric is shown for the method that has it, and only for it
    extra = text[text.index("Method-specific metrics"):text.index("Failures by kind")]
    label = "Middlebury bad 1.0 px, all pixels with known truth (%)"  # from the column's family
    assert label in extra and ">graycode-subpx<" in extra and ">sgbm<" not in extra
    assert f"{label}</td><td>2</td><td>2</td><td>5</td>" in extra  # (.5+.5+2+2+5)/5
    # without a manifest the same axes are found from the columns
    ds2 = make_realism_dataset(tmp_path / "ds2", with_manifest=False)
    write_report(ds2)
    assert {"dataset_vs_roughness", "dataset_vs_noise"} <= _plot_names(ds2 / "report")


def test_plot_metric_vs_axis_edge_cases(tmp_path):
    frame, _ = load_results(make_realism_dataset(tmp_path / "ds"))
    # every row of one method failed: drawn (a cross, crash rate 1), no exception; two metrics: five panels
    sub = frame[(frame["method"] != "paper") | (frame["roughness"] == 0.05)]
    out = P.plot_metric_vs_axis(sub, "roughness", tmp_path / "a.png", metrics=("depth_rms_mm", "boundary_mean_mm"),
                                pooled={"noise": ["none", "high"]})
    w, h = _check_png(out)
    assert w >= 1000 and h > 900
    _check_png(P.plot_metric_vs_axis(frame, "noise", tmp_path / "b.png", title="t"))
    # an axis no row has: a note, not an exception
    assert P.plot_metric_vs_axis(frame, "distance_mm", tmp_path / "c.png").read_bytes()[:8] == PNG_SIG
    assert P.plot_metric_vs_axis(frame.iloc[:0], "noise", tmp_path / "d.png").read_bytes()[:8] == PNG_SIG


def flat_cloud(inputs):
    """A plug-in for the report test: a flat grid of points in z = 0 over the plate's size (no truth used)."""
    from platebench.bench.run.plugins import Points
    x, y = np.meshgrid(np.linspace(-0.05, 0.05, 30), np.linspace(-0.03, 0.03, 20))
    return Points(np.c_[x.ravel(), y.ravel(), np.zeros(x.size)])


@pytest.mark.render
@pytest.mark.slow
def test_a_real_sweep_report_has_an_error_map_for_every_method(tmp_path):
    """A real (tiny) sweep with the paper's pipeline, SGBM (a disparity map) and a plug-in's point
    cloud: each method gets its error maps, labelled; the headline compares each depth figure only among
    the methods that report it, and says which figure it is."""
    from platebench.bench.sweep.executors import LocalExecutor, run_sweep
    from platebench.bench.sweep.spec import load_spec
    spec = tmp_path / "spec.toml"
    spec.write_text('[sweep]\nname = "maps"\nmethods = ["paper", "sgbm", "tests.test_report:flat_cloud"]\n'
                    '[base.scene]\nwidth = 320\nheight = 240\n[base.render]\nspp = 2\n[grid]\nbend_deg = [0, 20]\n')
    ds = tmp_path / "ds"
    summary = run_sweep(load_spec(spec), ds, LocalExecutor(0), progress=False)
    assert summary.ok == 2, summary.results
    index = write_report(ds)
    _check_self_contained(index)
    text = index.read_text()
    names = _plot_names(ds / "report")
    for m in ("paper", "sgbm", "tests_test_report_flat_cloud"):
        assert {f"dataset_error_map_0000_{m}", f"dataset_error_map_0001_{m}"} <= names, (m, sorted(names))
    assert "method sgbm; a disparity or depth map: the left view" in text
    head = text[text.index('id="headline"'):text.index("<nav>")]
    assert re.search(r"median depth RMS at the square centres: paper [0-9.]+ mm", head), head
    assert re.search(r"median depth RMS over the plate&#39;s pixels: sgbm [0-9.]+ mm", head), head
    assert "paper" not in head.split("median depth RMS over the plate")[1].split(";")[0]


def test_results_read_back_with_their_types(tmp_path):
    """results.csv's sample_id "0000" is text: platebench.results() reads it as such (a plain pandas
    read_csv would make it the number 0; README says so and gives the dtype to pass)."""
    import pandas as pd

    import platebench
    from platebench.errors import PlateBenchError
    ds = make_dataset(tmp_path / "ds")
    frame = platebench.results(ds)
    assert frame["sample_id"].tolist()[:2] == ["0000", "0000"] and frame["sample_id"].map(type).eq(str).all()
    assert pd.read_csv(ds / "results.csv")["sample_id"].iloc[0] == 0  # the pitfall, as README states it
    assert pd.read_csv(ds / "results.csv", dtype={"sample_id": str})["sample_id"].iloc[0] == "0000"
    with pytest.raises(PlateBenchError, match="holds no results"):
        platebench.results(tmp_path)
