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
import statistics
import subprocess
from pathlib import Path

import numpy as np
import pytest

from platebench.bench.report import plots as P
from platebench.bench.report.html import (
    GENERATOR,
    ReportInputError,
    detect_inputs,
    load_results,
    method_summary,
    write_report,
)

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
    with pytest.raises(ReportInputError, match="refusing"):
        write_report(ds, other)
    assert sorted(p.name for p in other.iterdir()) == ["keep.txt"]


def test_cli_report_prints_index(tmp_path, capsys):
    ds = make_dataset(tmp_path / "ds")
    from platebench.bench.cli.main import main
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

    data = P.error_map_data(sdir, rdir)
    assert len(data["centres"]) == len(rec.points) > 0
    assert np.all(np.isfinite(data["centre_err_mm"])) and np.all(data["centre_err_mm"] >= 0)
    assert (data["centre_kind"] == "3d").sum() > 0  # identities from the GT feature map
    assert data["surface_dist_mm"] is not None and np.all(np.isfinite(data["surface_dist_mm"]))
    assert data["surface_dist_mm"].max() < 20.0  # mm: a 20-degree bend reconstructs to within millimetres
    from platebench.evaluation.point_metrics import point_to_surface_distance
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


# ----------------------------------------------------------------------------- swept axes (realism study)
_DEPTH = {"paper": 0.2, "graycode-subpx": 0.5, "sgbm": 3.0}


def make_realism_dataset(root: Path, with_manifest: bool = True) -> Path:
    """A fake realism sweep: roughness (0.05, 0.2, 0.5) x noise (none, high), bend 10 deg throughout,
    3 methods. Failures, each of another kind:

    * paper, roughness 0.05, noise high: status ok but 12 of 16 squares matched (incomplete);
    * sgbm, roughness 0.05, noise high: status failed;
    * graycode-subpx, roughness 0.5: noise none status failed, noise high ok but no depth RMS.
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
                     "spp": 4, "seed": 0, "depth_rms_mm": depth}
                if m == "paper":
                    r.update(matched_count=12 if (rough, noise) == (0.05, "high") else 16, expected_count_gt=16,
                             boundary_mean_mm=0.3)
                if m == "sgbm" and (rough, noise) == (0.05, "high"):
                    r.update(status="failed", error="RuntimeError: SGBM found no disparity", depth_rms_mm=None)
                if m == "graycode-subpx" and rough == 0.5:
                    if noise == "none":
                        r.update(status="failed", error="ValueError: decode failed", depth_rms_mm=None)
                    else:
                        r.update(depth_rms_mm=None)
                rows.append(r)
            i += 1
    _write_csv(root / "results.csv", rows, list(dict.fromkeys(k for r in rows for k in r)))
    if with_manifest:
        manifest = {"format": "platebench-sweep", "version": 1, "state": "complete",
                    "spec": {"name": "fake_realism", "mode": "grid", "methods": ["paper", "graycode-subpx", "sgbm"],
                             "axes": {"roughness": [0.05, 0.2, 0.5], "noise": ["none", "high"]}},
                    "counts": {"total": 6, "ok": 4, "failed": 2, "pending": 0}}
        (root / "manifest.json").write_text(json.dumps(manifest))
    return root


def test_axis_stats_failure_rates_by_hand(tmp_path):
    rows, _ = load_results(make_realism_dataset(tmp_path / "ds"))
    st = P.axis_stats(rows, "roughness")
    assert st["numeric"] and [lv["key"] for lv in st["levels"]] == [0.05, 0.2, 0.5]
    assert st["methods"] == ["paper", "graycode-subpx", "sgbm"]  # the paper's pipeline first
    c = st["cells"][("paper", 0.05)]
    # by hand: 2 rows (noise none, high); the high one matched 12 < 16 squares -> 1 failure of 2 = 0.5;
    # its depth RMS still counts in the median: median(0.2 x 1.5, 0.2 x 1.5 x 2) = (0.3 + 0.6) / 2 = 0.45 mm
    assert (c["rows"], c["failed"], c["failure_rate"]) == (2, 1, 0.5)
    assert c["median"] == pytest.approx(0.45)
    c = st["cells"][("graycode-subpx", 0.5)]  # one failed, one ok without a depth RMS: both count, no value
    assert (c["failed"], c["rows"], c["failure_rate"], c["median"]) == (2, 2, 1.0, None)
    assert st["cells"][("sgbm", 0.2)]["failure_rate"] == 0.0
    sn = P.axis_stats(rows, "noise")
    assert not sn["numeric"] and [lv["key"] for lv in sn["levels"]] == ["none", "high"]
    c = sn["cells"][("sgbm", "high")]  # failed at 0.05; ok at 0.2 and 0.5 -> 1/3
    assert (c["failed"], c["rows"]) == (1, 3) and c["failure_rate"] == pytest.approx(1 / 3)
    assert c["median"] == pytest.approx(statistics.median([3.0 * 3 * 2, 3.0 * 6 * 2]))
    assert sn["cells"][("paper", "high")]["failure_rate"] == pytest.approx(1 / 3)
    assert sn["cells"][("paper", "none")]["failure_rate"] == 0.0
    # row_failed on its own
    assert P.row_failed({"status": "ok", "depth_rms_mm": 0.1, "matched_count": 16, "expected_count_gt": 16}) is False
    assert P.row_failed({"status": "ok", "depth_rms_mm": float("nan")}) is True
    assert P.row_failed({"status": "failed", "depth_rms_mm": 0.1}) is True


def test_axis_levels_order_and_bins():
    levels, key_of, numeric = P.axis_levels([{"noise": n} for n in ("high", "none", "medium", "low", None)], "noise")
    assert not numeric and [lv["label"] for lv in levels] == ["none", "low", "medium", "high"]
    assert key_of({"noise": None}) is None and key_of({"noise": "low"}) == "low"
    rows = [{"bend_deg": float(b)} for b in range(0, 100, 4)]  # 25 distinct values (random draws): binned
    levels, key_of, numeric = P.axis_levels(rows, "bend_deg", max_levels=5)
    assert numeric and len(levels) == 5 and levels[0]["label"] == "0\u201319.2"
    assert key_of({"bend_deg": 0.0}) == 0 and key_of({"bend_deg": 96.0}) == 4


def test_swept_axes_from_manifest_and_columns(tmp_path):
    from platebench.bench.report.html import swept_axes
    rows, _ = load_results(make_realism_dataset(tmp_path / "ds"))
    axes, varying = swept_axes({"spec": {"axes": {"noise": ["none", "high"], "roughness": [0.05, 0.2, 0.5]}}}, rows)
    assert axes == ["noise", "roughness"]  # spec order; bend_deg, spp, width_px take one value: not swept
    assert varying["roughness"] == ["0.05", "0.2", "0.5"]
    assert swept_axes({}, rows)[0] == ["roughness", "noise"]  # no manifest: the candidate columns that vary
    more = [dict(r, seed=s, width_px=w, height_px=w * 3 // 4) for r in rows for s in (0, 1) for w in (320, 640)]
    axes, varying = swept_axes({"spec": {"axes": {"scene.material.alpha": [0.05], "resolution": ["320x240"],
                                                  "seed": [0, 1]}}}, more)
    assert axes == ["roughness", "width_px", "noise"]  # seed varies (pooled) but is never plotted against
    assert "seed" in varying and "height_px" not in varying  # resolution: its width stands for it


def test_dataset_report_swept_axes(tmp_path):
    ds = make_realism_dataset(tmp_path / "ds")
    text = write_report(ds).read_text()
    srcs = _check_self_contained(text)
    assert "Against the swept axes" in text
    assert "<h4>roughness (GGX alpha)</h4>" in text and "<h4>sensor noise preset</h4>" in text
    names = {p.stem for p in (ds / "report" / "plots").glob("*.png")}
    assert {"dataset_vs_roughness", "dataset_vs_noise"} <= names
    assert "dataset_vs_bend_deg" not in names and "dataset_error_vs_bend" not in names  # one bend: not swept
    assert "By bend angle" not in text
    assert len(srcs) == len(names)
    for n in ("dataset_vs_roughness", "dataset_vs_noise"):
        w, h = _check_png(ds / "report" / "plots" / f"{n}.png")
        assert w >= 800 and h >= 350
    # the tables: failure rates with their counts, medians in mm
    rough = text[text.index("<h4>roughness (GGX alpha)</h4>"):text.index("<h4>sensor noise preset</h4>")]
    assert "0.50 (1/2)" in rough and "1.00 (2/2)" in rough and "<td>0.45</td>" in rough
    noise = text[text.index("<h4>sensor noise preset</h4>"):]
    assert "0.33 (1/3)" in noise
    assert noise.index("<td>none</td>") < noise.index("<td>high</td>")  # natural order, not alphabetical
    # each caption says what else is pooled into a point
    assert "every point pools their samples: sensor noise preset (none, high)" in rough
    assert "every point pools their samples: roughness (GGX alpha) (0.05, 0.2, 0.5)" in noise
    # without a manifest the same axes are found from the columns
    ds2 = make_realism_dataset(tmp_path / "ds2", with_manifest=False)
    write_report(ds2)
    assert {"dataset_vs_roughness", "dataset_vs_noise"} <= {p.stem for p in (ds2 / "report" / "plots").glob("*.png")}


def test_plot_metric_vs_axis_edge_cases(tmp_path):
    rows, _ = load_results(make_realism_dataset(tmp_path / "ds"))
    # every row of one method failed: drawn (a cross, failure rate 1), no exception; two metrics: three panels
    out = P.plot_metric_vs_axis([r for r in rows if r["method"] != "paper" or r["roughness"] == 0.05], "roughness",
                                tmp_path / "a.png", metrics=("depth_rms_mm", "boundary_mean_mm"),
                                pooled={"noise": ["none", "high"]})
    w, _ = _check_png(out)
    assert w > 1200
    _check_png(P.plot_metric_vs_axis(rows, "noise", tmp_path / "b.png", title="t"))
    # an axis no row has: a note, not an exception
    assert P.plot_metric_vs_axis(rows, "distance_mm", tmp_path / "c.png").read_bytes()[:8] == PNG_SIG
    assert P.plot_metric_vs_axis([], "noise", tmp_path / "d.png").read_bytes()[:8] == PNG_SIG
