"""What a reader of the report sees first and compares: one colour per method in every figure, no
empty panels, a headline table of the key figures (the full table folded), counts as whole numbers,
the output folder's name and relative paths (never a staging folder or an absolute path), and a
plausibility warning beside the figure it concerns."""
from __future__ import annotations

import json
import re
from pathlib import Path

import matplotlib.colors as mcolors
import pandas as pd
import pytest

from platebench.bench.report import plots as P
from platebench.bench.report.colours import method_colours
from platebench.bench.report.html import write_report
from platebench.bench.report.values import fmt
from tests.test_report import make_compare, make_dataset
from tests.conftest import record_tables


def _with_method(ds: Path, copy_of: str, name: str, **values) -> Path:
    """Add a method to a fake sweep: ``copy_of``'s rows under ``name``, with ``values`` set."""
    frame = pd.read_csv(ds / "results.csv", dtype={"sample_id": str})
    extra = frame[frame["method"] == copy_of].copy()
    extra["method"] = name
    for k, v in values.items():
        extra[k] = v
    pd.concat([frame, extra], ignore_index=True).to_csv(ds / "results.csv", index=False)
    record_tables(ds)
    return ds


def _legend_colours(figures, methods) -> dict[str, set[str]]:
    """{method: the colours its legend entries have} over every axes of every captured figure; a
    legend label names one of ``methods`` as "method" or "method / direction"."""
    out: dict[str, set[str]] = {}
    for _, fig in figures:
        for ax in fig.axes:
            handles, labels = ax.get_legend_handles_labels()
            for h, label in zip(handles, labels):
                if ":" in label:
                    continue  # "paper: no value", "paper / up: failed": markers of another colour
                method = label.split(" / ")[0]
                if method not in methods:
                    continue
                patch = h.patches[0] if hasattr(h, "patches") else h
                colour = patch.get_facecolor() if hasattr(h, "patches") else h.get_color()
                out.setdefault(method, set()).add(mcolors.to_hex(colour))
    return out


@pytest.fixture()
def captured(monkeypatch):
    """Every figure the report's plots save: [(path, matplotlib Figure)]."""
    figures = []
    save = P._save

    def keep(fig, path):
        figures.append((Path(path), fig))
        return save(fig, path)
    monkeypatch.setattr(P, "_save", keep)
    return figures


def test_a_method_has_one_colour_in_every_figure_of_a_report(tmp_path, captured):
    root = tmp_path / "all"
    # "blockmatch" sorts before "paper", which the results order puts first: any order-dependent colouring shows
    _with_method(make_dataset(root / "ds"), "sgbm", "blockmatch")
    make_compare(root / "cmp" / "compare.json")  # paper and graycode, in another section of the same report
    write_report(root)
    expected = method_colours(["blockmatch", "graycode", "paper", "sgbm"])
    seen = _legend_colours(captured, expected)
    assert set(seen) == set(expected)
    for method, colours in seen.items():
        assert colours == {expected[method]}, (method, colours)
    figures = {p.stem for p, _ in captured}
    assert {"dataset_method_comparison", "dataset_error_vs_bend", "compare1_compare"} <= figures


def test_method_colours_are_stable_and_shared_with_the_leaderboard():
    from platebench.bench.benchmark import leaderboard
    a = method_colours(["sgbm", "paper", "blockmatch"])
    assert a == method_colours(["paper", "blockmatch", "sgbm", "paper"])  # order and repeats change nothing
    assert list(a) == ["blockmatch", "paper", "sgbm"] and len(set(a.values())) == 3
    assert leaderboard.method_colours is method_colours


def _headline(text: str) -> str:
    return text.split('<div class="headline" id="headline">', 1)[1].split("<nav>", 1)[0]


def test_a_panel_with_nothing_to_show_is_left_out_and_said(tmp_path, captured):
    # the verdict never fires: precision is undefined in every bin, recall (0) is not
    ds = make_dataset(tmp_path / "ds")
    frame = pd.read_csv(ds / "results.csv", dtype={"sample_id": str})
    paper_ok = (frame["method"] == "paper") & (frame["status"] == "ok")
    frame["false_boundary_detected"] = frame["false_boundary_detected"].astype(object)
    frame.loc[paper_ok, "false_boundary_detected"] = False
    frame.to_csv(ds / "results.csv", index=False)
    record_tables(ds)
    text = write_report(ds).read_text()
    det = [f for p, f in captured if p.stem == "dataset_detection_vs_bend"]
    assert len(det) == 1
    ylabels = [ax.get_ylabel() for ax in det[0].axes]
    assert "recall" in ylabels and "precision" not in ylabels
    assert "precision panel left out: precision is undefined in every bin (no positive verdict in any bin)" in text
    assert "undefined everywhere" not in " ".join(t.get_text() for ax in det[0].axes for t in ax.texts)

    # no ground-truth false boundary and no positive verdict: the figure itself is left out, in one line
    frame["false_boundary_gt"] = False
    frame.to_csv(ds / "results.csv", index=False)
    record_tables(ds)
    captured.clear()
    index = write_report(ds, overwrite=True)
    text = index.read_text()
    assert not (ds / "report" / "plots" / "dataset_detection_vs_bend.png").exists()
    assert re.search(r"<p class=\"note left-out\">plot &#39;fake_sweep: false-boundary detection against ground "
                     r"truth&#39; left out: precision and recall are undefined in every bin", text)
    # a dense-only sweep: the axis plot keeps no panel that no row can fill
    frame = frame[frame["method"] == "sgbm"]
    frame.to_csv(ds / "results.csv", index=False)
    record_tables(ds)
    captured.clear()
    text = write_report(ds, overwrite=True).read_text()
    axis = [f for p, f in captured if p.stem.startswith("dataset_vs_")]
    assert axis
    for fig in axis:
        titles = [ax.get_title() for ax in fig.axes if ax.axison]
        assert not any("bound violated" in t or "mismatched" in t for t in titles), titles
    assert "&#39;paper&#39;s bound violated&#39; panel left out: no row of any method can say" in text


def test_headline_table_of_key_figures_and_the_full_table_folded(tmp_path):
    ds = _with_method(make_dataset(tmp_path / "ds"), "sgbm", "blockmatch")
    frame = pd.read_csv(ds / "results.csv", dtype={"sample_id": str})
    frame["depth_count"] = [11128.0 if m != "paper" and s == "ok" else None
                            for m, s in zip(frame["method"], frame["status"])]
    frame.loc[frame.index[-1], "depth_count"] = None
    frame.loc[(frame["method"] == "sgbm") & (frame["sample_id"] == "0001"), "depth_count"] = 11131.0
    frame.to_csv(ds / "results.csv", index=False)
    record_tables(ds)
    text = write_report(ds).read_text()
    head = _headline(text)
    table = head.split("<table", 1)[1].split("</table>", 1)[0]
    for column in ("method", "median depth RMS over the plate&#39;s pixels (mm)",
                   "median depth RMS at the square centres (mm)", "median coverage", "failed / rows",
                   "median boundary mean (mm)", "median time (s)"):
        assert f"<th>{column}" in table, column
    assert table.count("<tr>") == 1 + 3  # the header and one row per method
    assert "1 / 4 (25 %)" in table
    # the full table, every metric of every method, sits behind a fold
    fold = text.split('<details class="full">', 1)[1].split("</details>", 1)[0]
    assert "Method comparison" in fold and "Method-specific metrics" in fold
    assert "Method comparison" not in text.replace(fold, "")
    # counts are whole numbers, labelled as counts
    assert "depth error over the plate&#39;s pixels: values (count)" in fold
    assert "1.113e+04" not in text and "11129" in fold  # the mean of 11128, 11128, 11131 rounded


def test_fmt_never_writes_an_exponent_for_a_whole_number_it_can_write():
    assert fmt(11129.0) == "11129" and fmt(9999.6) == "10000" and fmt(1234.5, 3) == "1234"
    assert fmt(3.14159) == "3.142" and fmt(3.992e5) == "3.992e+05" and fmt(2e-4) == "2.000e-04"


def test_the_report_names_the_output_not_the_staging_folder_and_no_absolute_path(tmp_path):
    staged = tmp_path / ".tmp-demo~host~4242~0a1b2c3d"  # how bench.io.atomic stages the demo's folder
    make_dataset(staged / "sweep")
    text = write_report(staged).read_text()
    header = text.split("<header>", 1)[1].split("</header>", 1)[0]
    assert "input demo (.. from this report)" in header
    assert ".tmp-" not in text and "~host~" not in text
    assert str(tmp_path) not in text  # the missing sample folders are named from the input folder
    assert "demo/sweep/samples/0000" in text


def test_a_plausibility_warning_sits_beside_the_headline_figure(tmp_path):
    mine = tmp_path / "mine"
    mine.mkdir()
    hint = ("the median depth error is 3.992e+05 mm, beyond the plate's 117 mm: the values are about 1000 x the "
            "true depth (median ratio 1000): is this file in millimetres? --depth takes z-depth in metres")
    (mine / "depth_mm.score.json").write_text(json.dumps({
        "method": "depth_mm", "kind": "depth", "sample": "elsewhere", "input": "depth_mm.npy",
        "score": {"coverage_frac": 0.9, "depth_rms_mm": 399200.0, "depth_median_mm": 399000.0},
        "hints": [hint]}))
    head = _headline(write_report(mine).read_text())
    cards = re.findall(r'<div class="card[^"]*">.*?</div></div>', head, re.S)
    rms = next(c for c in cards if "depth RMS over the plate" in c)
    assert "warned" in rms and "3.992e+05" in rms and "is this file in millimetres?" in rms
    assert head.index("3.992e+05") < head.index("coverage")  # the warned figures come first
    cov = next(c for c in cards if "coverage" in c)
    assert "warning" not in cov


def _detector_study(root: Path, fired: dict, plates=(("cylinder", 60.0), ("dome", None))) -> Path:
    """A study folder whose study.json is a real ``StudyResult``: one plate per (family, bend) of
    ``plates``, nothing hidden at the stage-2 pose, ``fired``: family -> the detectors that fire on
    its plate."""
    from platebench.bench.io.codecs import encode
    from platebench.bench.io.records import StudyRow
    from platebench.bench.run.sensing.study import StudyResult
    from platebench.reconstruction.strategy.detectors import DETECTORS
    rows = []
    for family, bend in plates:
        on = set(fired.get(family, ()))
        rows.append(StudyRow(case=f"{family} plate", family=family, bend_deg=bend, outcome="false_alarm" if on else "clean",
                             boundary_verified=True, cures=len(on), views=14,
                             detectors={d: d in on for d in DETECTORS}, gt_visible_first_frac=1.0,
                             gt_visible_final_frac=1.0, gt_hidden_first=False, gt_hidden_final=False, time_s=2.0))
    root.mkdir(parents=True)
    (root / "study.json").write_text(json.dumps(encode(StudyResult(tuple(rows), {}, 4.0))))
    return root


def test_a_study_report_colours_each_detector_once_and_leaves_out_empty_panels(tmp_path, captured):
    import html
    from platebench.reconstruction.strategy.detectors import DETECTORS
    # nothing hidden: recall is undefined everywhere; two detectors fire (precision 0), three never do
    study = _detector_study(tmp_path / "study", {"cylinder": ["counting_test"], "dome": ["arrays_disagree"]})
    text = html.unescape(write_report(study).read_text())
    det = [f for p, f in captured if p.stem == "detectors_family"]
    assert len(det) == 1
    assert [ax.get_ylabel() for ax in det[0].axes] == ["precision"]
    expected = method_colours(DETECTORS)
    seen = _legend_colours(captured, {d.replace("_", " "): c for d, c in expected.items()})
    assert seen == {"counting test": {expected["counting_test"]}, "arrays disagree": {expected["arrays_disagree"]}}
    assert ("recall panel left out: recall is undefined for every detector in every family (no plate hides part "
            "of the boundary at the stage-2 pose)") in text
    assert ("precision: viewpoint consistency, occluding contour, end tangents left out: undefined in every "
            "family (the detector never fired)") in text
    # no detector fires either: the figure itself is left out, in one line, and no PNG is kept; no
    # family split by bend: the outcomes-per-bend figure is left out too
    captured.clear()
    study = _detector_study(tmp_path / "quiet", {}, plates=(("dome", None), ("twist", None)))
    index = write_report(study)
    text = html.unescape(index.read_text())
    assert "plot 'detectors family' left out: precision and recall are undefined for every detector" in text
    assert not list(index.parent.rglob("detectors_family.png"))
    assert "detectors_family" not in index.read_text()
    assert "plot 'outcomes bend' left out: no plate is grouped by bend" in text
    assert not list(index.parent.rglob("outcomes_bend.png")) and list(index.parent.rglob("outcomes_family.png"))
