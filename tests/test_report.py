"""Reports: self-contained HTML of sweep datasets, false-boundary studies and compare.json files.

Most tests build small inputs by hand (no rendering); one renders a tiny real sample for the
error map, one renders the HTML with headless Chromium (skipped without it).
"""
from __future__ import annotations

import csv
import json
import math
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from bench import plots as P
from bench.report import GENERATOR, ReportInputError, detect_inputs, load_results, method_summary, write_report

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
                     "depth_rms_mm": None if failed else 0.02 + 0.01 * i,
                     "depth_max_mm": None if failed else 0.05 * (i + 1),
                     "xy_rms_mm": None if failed else 0.03, "boundary_mean_mm": None if failed else 0.2 + 0.1 * i,
                     "boundary_hausdorff_mm": None if failed else 0.8, "surface_rms_mm": None if failed else 0.1,
                     "coverage_frac": None if failed else 0.99, "matched_count": None if failed else 16,
                     "correct_match_count": None if failed else 16, "expected_count_gt": None if failed else 16,
                     "false_boundary_gt": gt, "false_boundary_detected": None if failed else gt,
                     "time_recon_s": None if failed else 0.3})
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
                         squares_right=16 - int(gt), depth_rms_mm=0.02 + bend / 1000, xy_rms_mm=0.03,
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
           "methods": {"paper": {"description": "paper's squares", "n_images": 2, "time_s": 0.2, "render_s": 0.0,
                                 "points": 16, "points_on_plate": 16, "depth_median_mm": 0.01, "depth_rms_mm": 0.013,
                                 "depth_max_mm": 0.03, "surface_rms_mm": 0.02, "notes": []},
                       "graycode": {"description": "Gray code", "n_images": 42, "time_s": 1.1, "render_s": 20.0,
                                    "coverage_pct": 44.0, "depth_median_mm": 0.17, "depth_rms_mm": 0.22,
                                    "depth_max_mm": 2.0, "middlebury": {"mb_all_bad_1_0_pct": 3.2}, "notes": []}}}
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


def _check_self_contained(text: str) -> list[str]:
    assert text.startswith("<!DOCTYPE html>")
    assert f'content="{GENERATOR}"' in text
    low = text.lower()
    for bad in ("<script", "<link", "<iframe", "src=\"http", "href=\"http", "url(http", "@import", "src='http"):
        assert bad not in low, bad
    srcs = re.findall(r'<img[^>]*\ssrc="([^"]*)"', text)
    assert srcs and all(s.startswith("data:image/png;base64,") for s in srcs)
    hrefs = re.findall(r'href="([^"]*)"', text)
    assert all(h.startswith("#") for h in hrefs), hrefs
    return srcs


# ----------------------------------------------------------------------------- tests
def test_dataset_report(tmp_path):
    ds = make_dataset(tmp_path / "ds")
    import matplotlib.pyplot as plt
    before = list(plt.get_fignums())
    index = write_report(ds)
    assert plt.get_fignums() == before  # plots use their own Figure objects
    assert index == ds / "report" / "index.html"
    text = index.read_text()
    srcs = _check_self_contained(text)
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
    pngs = sorted((ds / "report" / "plots").glob("*.png"))
    names = {p.stem for p in pngs}
    assert {"dataset_method_comparison", "dataset_error_vs_bend", "dataset_detection_vs_bend"} <= names
    assert len(srcs) == len(pngs)
    for p in pngs:
        _check_png(p)
    # a second run replaces the report (it is ours), leaving no temporary files behind
    write_report(ds)
    assert not [p for p in (ds / "report").rglob("*") if p.name.startswith(".")]


def test_method_summary_values(tmp_path):
    ds = make_dataset(tmp_path / "ds")
    rows, source = load_results(ds)
    assert source == "results.csv" and len(rows) == 8
    assert rows[0]["sample_id"] == "0000" and rows[0]["false_boundary_gt"] is False
    s = method_summary(rows)
    assert s["paper"]["ok"] == 3 and s["paper"]["failed"] == 1
    d = s["paper"]["metrics"]["depth_rms_mm"]
    assert d["n"] == 3 and d["mean"] == pytest.approx(0.03) and d["median"] == pytest.approx(0.03)
    fb = s["paper"]["metrics"]["false_boundary_detected"]
    assert fb["kind"] == "rate" and fb["mean"] == pytest.approx(1 / 3)
    assert "boundary_mean_mm" not in s["sgbm"]["metrics"]


def test_study_report(tmp_path):
    st = make_study(tmp_path / "study")
    index = write_report(st, tmp_path / "out")
    assert index == tmp_path / "out" / "index.html"
    text = index.read_text()
    _check_self_contained(text)
    assert "False-boundary study" in text
    assert "Smallest hiding bend" in text and "61.25" in text
    assert "Detection precision / recall" in text and "0.667" in text
    assert "L formula" in text and "&infin;" in text  # the never-visible GT distance
    assert "Cases (10)" in text and "no plate region" in text
    names = {p.stem for p in (tmp_path / "out" / "plots").glob("*.png")}
    assert {"study_hidden_fraction_vs_bend", "study_detection_vs_bend", "study_cure_success_vs_bend",
            "study_l_formula", "study_error_vs_bend"} <= names
    for p in (tmp_path / "out" / "plots").glob("*.png"):
        _check_png(p)


def test_study_csv_only_and_missing_columns(tmp_path):
    """A study with only study.csv, and a dataset with only a few columns: a report, no crash."""
    st = make_study(tmp_path / "study", with_extras=False)
    (st / "study.json").unlink()
    text = write_report(st).read_text()
    _check_self_contained(text)
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
    text = write_report(tmp_path).read_text()
    _check_self_contained(text)
    assert "Sweep dataset: fake_sweep" in text and "False-boundary study" in text
    assert "Method comparison: s1/compare/compare.json" in text and "Gray code" in text
    assert 'href="#dataset1"' in text and 'href="#study1"' in text and 'href="#compare1"' in text
    names = {p.stem for p in (tmp_path / "report" / "plots").glob("*.png")}
    assert "compare1_compare" in names and "dataset1_error_vs_bend" in names and "study1_l_formula" in names


def test_nothing_to_report_and_foreign_out_dir(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="neither a sweep dataset .* nor a false-boundary study") as e:
        write_report(tmp_path / "empty")
    assert "\n" not in str(e.value)
    from bench.cli import main
    assert main(["report", str(tmp_path / "empty")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("platebench: error: ") and err.count("\n") == 1
    assert not (tmp_path / "empty" / "report").exists()
    # never write into a non-empty directory that is not a report
    ds = make_dataset(tmp_path / "ds")
    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    with pytest.raises(ReportInputError, match="refusing"):
        write_report(ds, other)
    assert sorted(p.name for p in other.iterdir()) == ["keep.txt"]


def test_cli_report_prints_index(tmp_path, capsys):
    ds = make_dataset(tmp_path / "ds")
    from bench.cli import main
    assert main(["report", str(ds), "--out", str(tmp_path / "r")]) == 0
    out = capsys.readouterr().out.strip()
    assert out == str(tmp_path / "r" / "index.html") and Path(out).is_file()


def test_plots_on_empty_inputs(tmp_path):
    """Every plot function draws something sensible (a note) on empty input, and returns its path."""
    calls = [(P.plot_error_vs_bend, ([],)), (P.plot_detection_vs_bend, ([],)),
             (P.plot_hidden_fraction_vs_bend, ([],)), (P.plot_cure_success_vs_bend, ([],)),
             (P.plot_l_formula, ([],)), (P.plot_method_comparison, ({},)),
             (P.plot_error_map, (tmp_path / "nosample", tmp_path / "norecon"))]
    for i, (fn, args) in enumerate(calls):
        path = tmp_path / f"p{i}.png"
        assert fn(*args, path) == path
        assert path.read_bytes()[:8] == PNG_SIG


def test_bend_bins_and_precision_recall():
    e = P.bend_bins([0, 10, 20, 20])
    assert np.allclose(e, [-5, 5, 15, 25])
    assert len(P.bend_bins(range(100), max_bins=10)) == 11
    pr = P.precision_recall_counts([{"false_boundary_gt": True, "d": True}, {"false_boundary_gt": False, "d": True},
                                    {"false_boundary_gt": True, "d": False}, {"false_boundary_gt": True, "d": None},
                                    {"false_boundary_gt": "false", "d": "false"}], "d")
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
def test_error_map_on_a_real_tiny_sample(tmp_path):
    from bench.config import SampleConfig, SceneParams
    from bench.recon_io import image_checksums, write_reconstruction
    from bench.sample import load_inputs, render_sample, write_sample
    from plates import CylindricalBend, PlateSpec
    from reconstruction.pipeline import projector_feature_rays, reconstruct
    from scenes.renderer import RenderSettings

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

    data = P.error_map_data(sdir, rdir)
    assert len(data["centres"]) == len(rec.points) > 0
    assert np.all(np.isfinite(data["centre_err_mm"])) and np.all(data["centre_err_mm"] >= 0)
    assert (data["centre_kind"] == "3d").sum() > 0  # identities from the GT feature map
    assert data["surface_dist_mm"] is not None and np.all(np.isfinite(data["surface_dist_mm"]))
    assert data["surface_dist_mm"].max() < 20.0  # mm: a 20-degree bend reconstructs to within millimetres
    from evaluation.point_metrics import point_to_surface_distance
    d = point_to_surface_distance(rec.points, sample.plate.mesh) * 1e3
    assert np.all(data["centre_err_mm"][data["centre_kind"] == "3d"] >= d[data["centre_kind"] == "3d"] - 1e-9)
    out = P.plot_error_map(sdir, rdir, tmp_path / "map.png", data=data)
    w, h = _check_png(out)
    assert w >= 800 and h >= 300
    # the dataset report finds the reconstruction and draws its map
    text = write_report(ds).read_text()
    _check_self_contained(text)
    assert "Per-sample error maps" in text
    _check_png(ds / "report" / "plots" / "dataset_error_map_0000_paper.png")
