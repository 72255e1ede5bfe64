"""Report inputs: damaged files and hostile sample ids are refused (one line, exit 2, nothing
written); a single sample, a reconstruction and a sensing run each get a report that starts
with a headline. Inputs are built by hand here (no rendering), except the last test, which
renders a tiny sample and goes through the real command line (render, reconstruct, evaluate,
report)."""
from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest

from platebench.bench.cli.main import main
from platebench.bench.config import SampleConfig
from platebench.bench.io.codecs import encode
from platebench.bench.report.html import ReportInputError, write_report
from platebench.bench.report.inputs import detect_inputs, load_results, sample_folder
from platebench.errors import UserValueError
from tests.test_report import embedded_thumbnails, make_dataset, make_study
from tests.conftest import record_tables


def _refused(capsys, path: Path, match: str) -> None:
    """write_report raises a one-line ReportInputError matching ``match``, the CLI exits 2 with one
    line, and no report (nor a staging folder) is left behind."""
    with pytest.raises(ReportInputError, match=match) as e:
        write_report(path)
    assert isinstance(e.value, UserValueError) and "\n" not in str(e.value)
    capsys.readouterr()
    assert main(["report", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("platebench: error: ") and err.count("\n") == 1 and re.search(match, err)
    assert not (path / "report").exists()
    assert not [p for p in path.iterdir() if p.name.startswith((".tmp-report", ".old-report"))]


# ----------------------------------------------------------------------------- sample ids
def _outside_recon(root: Path) -> Path:
    """A folder outside the dataset that looks like a sample with a paper reconstruction."""
    elsewhere = root / "elsewhere"
    (elsewhere / "recon" / "paper").mkdir(parents=True)
    (elsewhere / "recon" / "paper" / "points.csv").write_text("x\n")
    (elsewhere / "sample").mkdir()
    (elsewhere / "sample" / "plate.ply").write_text("secret")
    return elsewhere


@pytest.mark.parametrize("bad", ["../../elsewhere", "ABS", "0001/../../..", "..", "a\\b"])
def test_sample_id_outside_the_dataset_is_refused(tmp_path, capsys, bad):
    elsewhere = _outside_recon(tmp_path)
    ds = make_dataset(tmp_path / "ds")
    (ds / "samples").mkdir()
    bad = str(elsewhere) if bad == "ABS" else bad
    text = (ds / "results.csv").read_text().replace("\n0000,", f"\n{bad},", 1)
    (ds / "results.csv").write_text(text)
    record_tables(ds)
    _refused(capsys, ds, r"results\.csv: line 2: sample_id .* is not the name of a folder inside")
    assert (elsewhere / "sample" / "plate.ply").read_text() == "secret"


def test_sample_id_through_a_link_leading_out_is_refused(tmp_path, capsys):
    elsewhere = _outside_recon(tmp_path)
    ds = make_dataset(tmp_path / "ds")
    (ds / "samples").mkdir()
    (ds / "samples" / "0002").symlink_to(elsewhere, target_is_directory=True)
    _refused(capsys, ds, r"sample_id '0002' is not the name of a folder inside")


def test_sample_folder_accepts_plain_names(tmp_path):
    ds = make_dataset(tmp_path / "ds")
    (ds / "samples" / "0001").mkdir(parents=True)
    assert sample_folder(ds, "0001") == ds / "samples" / "0001"
    assert sample_folder(ds, "0009") == ds / "samples" / "0009"  # not there (yet): still inside
    for bad in (None, "", ".", "../x", "/tmp", "a/b"):
        with pytest.raises(ReportInputError):
            sample_folder(ds, bad)


# ----------------------------------------------------------------------------- damaged files
def test_truncated_study_json_is_refused(tmp_path, capsys):
    st = make_study(tmp_path / "study")
    text = (st / "study.json").read_text()
    (st / "study.json").write_text(text[: len(text) // 2])
    _refused(capsys, st, r"study\.json: not valid JSON .*: a truncated or damaged study")


def test_study_json_of_the_wrong_shape_is_refused(tmp_path, capsys):
    st = make_study(tmp_path / "study")
    (st / "study.json").write_text(json.dumps({"rows": [1, 2]}))
    _refused(capsys, st, r"study\.json: 'rows' must be a list of objects")


@pytest.mark.parametrize("content, match", [
    (b"\x89\xff\x00garbage\xfe" * 50, r"results\.csv: not a readable CSV table"),
    (b"hello,world\n1,2\n", r"results\.csv: not a PlateBench results table: no column 'sample_id'"),
    (b"", r"results\.csv: not a readable CSV table"),
])
def test_garbage_results_csv_is_refused(tmp_path, capsys, content, match):
    ds = make_dataset(tmp_path / "ds")
    (ds / "results.csv").write_bytes(content)
    record_tables(ds)
    _refused(capsys, ds, match)


def test_results_csv_with_bad_cells_is_refused(tmp_path, capsys):
    ds = make_dataset(tmp_path / "ds")
    good = (ds / "results.csv").read_text()
    lines = good.splitlines()
    header = lines[0].split(",")
    cells = lines[2].split(",")
    cells[header.index("depth_rms_mm")] = "abc"
    (ds / "results.csv").write_text("\n".join([lines[0], lines[1], ",".join(cells), *lines[3:]]) + "\n")
    record_tables(ds)
    _refused(capsys, ds, r"results\.csv: line 3, column 'depth_rms_mm': 'abc' is not a number")
    cells = lines[1].split(",")
    cells[header.index("paper_bound_met")] = "maybe"
    (ds / "results.csv").write_text("\n".join([lines[0], ",".join(cells), *lines[2:]]) + "\n")
    record_tables(ds)
    _refused(capsys, ds, r"line 2, column 'paper_bound_met': 'maybe' is not true or false")


def test_garbage_parquet_is_refused_and_a_good_one_is_typed(tmp_path, capsys):
    import pyarrow as pa
    import pyarrow.parquet as pq
    ds = make_dataset(tmp_path / "ds")
    frame, _ = load_results(ds)
    (ds / "results.parquet").write_bytes(b"PAR1 this is not parquet")
    record_tables(ds)
    _refused(capsys, ds, r"results\.parquet: not a readable Parquet table")
    # a typed table (what the sweep writes): flags stay flags, the parquet wins over the CSV
    table = pa.table({"sample_id": ["0000", "0001"], "method": ["paper", "paper"], "status": ["ok", "ok"],
                      "depth_rms_mm": [0.01, None], "paper_bound_met": pa.array([True, None], pa.bool_()),
                      "matched_count": pa.array([16, 12], pa.int64())})
    pq.write_table(table, ds / "results.parquet")
    record_tables(ds)
    frame, source = load_results(ds)
    assert source == "results.parquet" and len(frame) == 2
    assert frame["paper_bound_met"].tolist()[0] is True and frame["paper_bound_met"].tolist()[1] is None


@pytest.mark.parametrize("name, maker", [("manifest.json", "dataset"), ("sensing.json", "sensing"),
                                         ("score.json", "recon"), ("recon.json", "recon")])
def test_truncated_json_inputs_are_refused(tmp_path, capsys, name, maker):
    d = {"dataset": lambda: make_dataset(tmp_path / "ds"), "sensing": lambda: make_sensing(tmp_path / "sense"),
         "recon": lambda: make_recon(tmp_path / "x")[1]}[maker]()
    text = (d / name).read_text()
    (d / name).write_text(text[: len(text) // 3])
    _refused(capsys, d, rf"{re.escape(name)}: not valid JSON")


# ----------------------------------------------------------------------------- single experiments
def make_sample(root: Path, hidden: bool = False) -> Path:
    """A hand-made sample folder: the reference configuration, four camera images (one 16-bit),
    and the ground-truth visibility record."""
    (root / "images").mkdir(parents=True)
    (root / "gt").mkdir()
    rng = np.random.default_rng(0)
    for name in ("left_passive", "right_passive", "left_active"):
        cv2.imwrite(str(root / "images" / f"{name}.png"), rng.integers(0, 255, (480, 640), dtype=np.uint8))
    cv2.imwrite(str(root / "images" / "right_active.png"), rng.integers(0, 65535, (480, 640), dtype=np.uint16))
    (root / "sample.json").write_text(json.dumps({"layout_version": 1, "config": encode(SampleConfig()),
                                                  "variant": "llvm_ad_rgb", "timings_s": {"total_s": 1.5},
                                                  "packages": {"mitsuba": "3.9.1", "dask": None}}))
    vis = {cam: {"visible_fraction": 0.8 if hidden else 1.0, "false_boundary": hidden} for cam in ("left", "right")}
    (root / "gt" / "visibility.json").write_text(json.dumps(vis))
    return root


def make_recon(root: Path, bound_met: bool = False, scored: bool = True) -> tuple[Path, Path]:
    """A sample and a reconstruction of it with a score.json whose paper bound is (not) met."""
    sample = make_sample(root / "sample")
    recon = root / "recon"
    recon.mkdir()
    (recon / "recon.json").write_text(json.dumps({
        "method": "paper", "sample_dir": str(sample.resolve()), "n_points": 16, "n_boundary_points": 900,
        "false_boundary": {"detected": {"left_active": 16, "right_active": 14}, "expected": 16,
                           "counting_test": True, "arrays_disagree": False, "false_boundary_detected": True},
        "unmatched": [3, 7], "timings_s": {"total_s": 0.7}}))
    if scored:
        n, depth_max = (16, 0.03) if bound_met else (14, 2.5)  # the bound: every point, depth within 2 mm
        (recon / "score.json").write_text(json.dumps({
            "points": {"depth_rms_mm": 0.0102, "depth_max_mm": depth_max, "xy_radial_rms_mm": 0.0045, "count": n},
            "matching": {"matched_count": n, "correct_match_count": n, "expected_count_gt": 16},
            "false_boundary": {"ground_truth": {"left": False, "right": False}, "ground_truth_any": False,
                               "detected": True, "agrees": False},
            "paper_bound": {"depth_max_mm": depth_max, "xy_per_axis_max_mm": 0.007, "all_points": bound_met,
                            "met": bound_met},
            "goals": {"depth_rms_mm": 0.0102, "depth_rms_goal_mm": 0.03, "xy_per_axis_rms_mm": 0.004,
                      "boundary_mean_mm": 0.1, "met": True}}))
    return sample, recon


def make_sensing(root: Path, outcome: str | None = "clean") -> Path:
    root.mkdir(parents=True)
    vis = {"left": {"visible_fraction": 1.0, "false_boundary": False},
           "right": {"visible_fraction": 1.0, "false_boundary": False}}
    doc = {"config": encode(SampleConfig()),
           "steps": [{"stage": 1, "pose": {"distance_m": 0.83, "reason": "stage 1: far pose"}, "gt_visibility": vis},
                     {"stage": 3, "pose": {"distance_m": 0.4, "reason": "stage 3 <near>"}, "matched": 16,
                      "false_boundary": {"detected": {"left_active": 16, "right_active": 16}, "expected": 16,
                                         "false_boundary_detected": False}, "gt_visibility": vis}],
           "cures": 0, "final": {"matched": 16, "gt_visibility": vis,
                                 "false_boundary": {"false_boundary_detected": False},
                                 "accuracy": {"centres_depth_rms_mm": 0.016, "paper_bound_met": True}},
           "time_s": 32.0}
    if outcome:
        doc["final"]["outcome"] = outcome
    (root / "sensing.json").write_text(json.dumps(doc))
    return root


def _headline(text: str) -> str:
    return text[text.index('id="headline"'):text.index("<nav>")]


def _check_links(index: Path) -> list[str]:
    text = index.read_text()
    refs = re.findall(r'(?:href|src)="([^"#][^"]*)"', text)
    refs = [r for r in refs if not r.startswith("data:")]
    for r in refs:
        assert not r.startswith("/") and "://" not in r, r
        assert (index.parent / r).exists(), r
    return refs


def test_report_of_a_single_sample(tmp_path):
    sample = make_sample(tmp_path / "s", hidden=True)
    index = write_report(sample)
    text = index.read_text()
    head = _headline(text)
    assert "reference experiment" in head and "part of the true boundary is hidden" in head
    refs = _check_links(index)
    thumbs = embedded_thumbnails(text)  # in the page itself: no thumbnail files
    assert len(thumbs) == 4 and all(href in refs for _, href, _ in thumbs) and not (index.parent / "thumbs").exists()
    for _, _, img in thumbs:
        assert img.dtype == np.uint8 and img.shape == (150, 200)  # 640x480 scaled to 200 px wide, 8-bit
    assert "../images/left_active.png" in refs and "../" in refs  # each thumbnail opens its image; the folder
    assert "bend angle (deg)" in text and "sensor noise" in text  # the parameters, labelled by the registry


def test_report_of_a_reconstruction_with_its_score(tmp_path):
    sample, recon = make_recon(tmp_path / "x", bound_met=False)
    index = write_report(recon)
    text = index.read_text()
    head = _headline(text)
    assert "The paper&#39;s reference experiment (V)" in head
    assert '<span class="badge not">not met</span><b>paper&#39;s bound (V-D)</b>' in head
    assert "14 / 16" in head and "0.0102" in head and "x/y radial RMS at the square centres" in head
    assert "depth RMS at the square centres" in head  # the score's points part: the paper's sparse centres
    assert "false boundary detected" in text and "3, 7" in text  # recon.json's verdict and unmatched squares
    refs = _check_links(index)
    assert "../score.json" in refs and "../" in refs and "../../sample/" in refs
    assert len(embedded_thumbnails(text)) == 4
    # the sample it came from is shown with it, not twice
    inp = detect_inputs(tmp_path / "x")
    assert inp.recons == [recon] and inp.samples == []
    write_report(tmp_path / "x")
    # met: the badge says so
    _, recon2 = make_recon(tmp_path / "y", bound_met=True)
    assert '<span class="badge met">met</span><b>paper&#39;s bound' in _headline(write_report(recon2).read_text())


def test_report_of_an_unscored_reconstruction_says_so(tmp_path):
    _, recon = make_recon(tmp_path / "x", scored=False)
    text = write_report(recon).read_text()
    assert "not scored yet" in _headline(text) and "run &#39;platebench evaluate" in text


def test_report_of_a_sensing_run_gives_its_outcome(tmp_path):
    d = make_sensing(tmp_path / "sense", outcome="clean")
    index = write_report(d)
    text = index.read_text()
    assert "Outcome: clean" in _headline(text)
    assert "stage 3 &lt;near&gt;" in text  # reasons escaped, verbatim
    assert "depth RMS at the square centres" in text  # the final accuracy, labelled by the metric registry
    d2 = make_sensing(tmp_path / "sense2", outcome=None)  # today's sensing.json: no outcome class yet
    assert "The loop reports no false boundary" in _headline(write_report(d2).read_text())


def test_demo_like_folder_is_one_report(tmp_path):
    """The demo's layout: reference/{sample,recon}, sensing/, a sweep, a study: one page, headline first."""
    make_recon(tmp_path / "reference", bound_met=True)
    make_sensing(tmp_path / "sensing")
    make_dataset(tmp_path / "bend_sweep")
    make_study(tmp_path / "study")
    index = write_report(tmp_path)
    text = index.read_text()
    head = _headline(text)
    assert text.index('id="headline"') < text.index("<section")
    assert head.index("reference experiment") < head.index("Sensing run") < head.index("Sweep fake_sweep") \
        < head.index("False-boundary study")
    assert "paper&#39;s bound met in 2 of 3 rows" in head and "Outcome: clean" in head
    for anchor in ("recon", "sensing", "dataset", "study"):
        assert f'<section id="{anchor}">' in text
    _check_links(index)
    shutil.rmtree(tmp_path / "report")


def test_report_of_a_dataset_sample_with_peer_outputs(tmp_path):
    """A sweep sample's folder: the paper's reconstruction and a dense peer's output (score.json only,
    Middlebury figures nested under "scores"); the paper's first, the shared sample shown once."""
    _, recon = make_recon(tmp_path / "0003", bound_met=True)  # 0003/sample, 0003/recon
    moved = recon.rename(tmp_path / "0003" / "moved")
    recon.mkdir()
    paper = moved.rename(recon / "paper")  # the dataset layout: 0003/recon/<method>
    sgbm = tmp_path / "0003" / "recon" / "sgbm"
    sgbm.mkdir()
    (sgbm / "score.json").write_text(json.dumps({
        "method": "sgbm", "scores": {"depth_rms_mm": 6.41, "depth_median_mm": 1.16, "coverage_frac": 0.155,
                                     "middlebury": {"mb_all_bad_1_0_pct": 91.0}}}))
    inp = detect_inputs(tmp_path / "0003")
    assert inp.recons == [paper, sgbm] and inp.samples == []
    index = write_report(tmp_path / "0003")
    text = index.read_text()
    head = _headline(text)
    assert head.index("reference experiment (V)</h2>") < head.index("reference experiment (V): sgbm</h2>")
    sg = head[head.index(": sgbm"):]
    assert "6.41" in sg and "1.16" in sg and "Middlebury bad 1.0 px, all pixels with known truth" in sg
    assert "depth RMS over the plate&#39;s pixels" in sg
    assert len(embedded_thumbnails(text)) == 4  # the sample's images once
    assert "(shown above)" in text
    _check_links(index)


def test_sensing_report_links_its_stages(tmp_path):
    d = make_sensing(tmp_path / "sense")
    for n in ("stage1", "stage3_cure1"):
        (d / n).mkdir()
    index = write_report(d)
    refs = _check_links(index)
    assert {"../stage1/", "../stage3_cure1/", "../sensing.json"} <= set(refs)


@pytest.mark.render
@pytest.mark.slow
def test_render_reconstruct_evaluate_report_from_the_command_line(tmp_path):
    """As a user would: render a small sample, reconstruct and evaluate it, then report the sample alone,
    the reconstruction alone, and the folder holding both."""
    from tests.conftest import run_cli
    s, r = tmp_path / "s", tmp_path / "r"
    for args in (("render", "--out", s, "--width", 320, "--height", 240, "--spp", 2),
                 ("reconstruct", s, "--out", r), ("evaluate", s, r)):
        proc = run_cli(*args)
        assert proc.returncode == 0, proc.stderr[-2000:]
    score = json.loads((r / "score.json").read_text())
    proc = run_cli("report", s)
    assert proc.returncode == 0 and proc.stdout.strip() == str(s / "report" / "index.html"), proc.stderr[-2000:]
    head = _headline((s / "report" / "index.html").read_text())
    assert "Sample s" in head and "the whole true boundary is visible" in head  # 320x240: not the reference
    assert len(embedded_thumbnails((s / "report" / "index.html").read_text())) == 4
    proc = run_cli("report", r)
    assert proc.returncode == 0, proc.stderr[-2000:]
    index = r / "report" / "index.html"
    head = _headline(index.read_text())
    met = score["paper_bound"]["met"]
    assert f'<span class="badge {"met" if met else "not"}">' in head and "paper&#39;s bound (V-D)" in head
    assert f"{score['matching']['matched_count']} / {score['matching']['expected_count_gt']}" in head
    assert "../../s/" in _check_links(index)  # the sample it was made from, linked
    assert (r / "report" / "plots" / "recon_error_map.png").is_file()
    shutil.rmtree(s / "report")
    shutil.rmtree(r / "report")
    assert run_cli("report", tmp_path).returncode == 0
    assert detect_inputs(tmp_path).samples == []  # shown with its reconstruction


def test_parquet_and_csv_of_one_table_read_the_same(tmp_path):
    """The sweep's typed parquet and its CSV give the same frame (one reading of flags and numbers)."""
    from platebench.bench.report.inputs import records
    from platebench.bench.report.summary import failure_table, method_summary
    from platebench.bench.sweep.dataset import csv_text, parquet_bytes
    from tests.test_report import make_realism_dataset
    frame, _ = load_results(make_realism_dataset(tmp_path / "a"))
    rows = records(frame)  # flags as bools, numbers as floats: what a sweep's rows carry
    (tmp_path / "p").mkdir()
    (tmp_path / "c").mkdir()
    (tmp_path / "p" / "results.parquet").write_bytes(parquet_bytes(rows))
    record_tables(tmp_path / "p")
    (tmp_path / "c" / "results.csv").write_text(csv_text(rows))
    record_tables(tmp_path / "c")
    p, _ = load_results(tmp_path / "p")
    c, _ = load_results(tmp_path / "c")
    assert list(p.columns) == list(c.columns)
    assert json.dumps(method_summary(p), sort_keys=True) == json.dumps(method_summary(c), sort_keys=True)
    assert failure_table(p, "method").equals(failure_table(c, "method"))
    assert records(p) == records(c)
    assert set(map(type, p["paper_bound_met"].dropna())) <= {bool, np.bool_}


def test_a_generic_section_builder_renders_in_any_documented_shape(tmp_path):
    """What bench.report.sensing's study_section / sensing_section will return (page.py's contract):
    figures as a list or a dict, tables as dicts or bare lists of rows, plots as dicts or pairs."""
    from platebench.bench.report import plots as P
    from platebench.bench.report.html import _generic, render_page
    from platebench.bench.report.page import Page

    def builder(folder: Path, out_dir: Path) -> dict:
        P.plot_l_formula([], out_dir / "l.png")
        P.plot_l_formula([], out_dir / "m.png")
        return {"title": "Study <of> plates", "outcome": "cured", "summary": "60 plates & more",
                "key_figures": {"silent": 0, "cured": 12, "verified": True},
                "tables": [{"title": "Outcomes", "rows": [{"family": "fold", "bend_deg": 170.0, "silent": 0}]},
                           [{"detector": "viewpoint", "recall": 0.95}]],
                "plots": [{"file": "l.png", "caption": "L <formula>"}, ("m.png", "second")],
                "links": [{"label": "study.json", "path": "study.json"}, {"label": "gone", "path": "nothing"}],
                "notes": ["a note"]}

    folder = make_study(tmp_path / "study")
    stage = tmp_path / "stage"
    stage.mkdir()
    page = Page(stage, tmp_path / "out", tmp_path)
    sec = _generic(page, builder, folder, "study", "study")
    assert [f["label"] for f in sec["figures"]] == ["silent", "cured", "verified"]
    assert sec["figures"][2]["status"] == "good"
    assert [t["columns"][1]["label"] for t in sec["tables"]] == ["bend angle (deg)", "recall"]
    assert [p["caption"] for p in sec["plots"]] == ["L <formula>", "second"]
    assert [lk["label"] for lk in sec["links"]] == ["study.json"]  # a link to nothing is left out
    html = render_page("report.html", generator="g", name="n", input="i", found="f", version="v", notes=[],
                       sections=[sec], headline=[sec["headline"]], generated="now")
    assert "Study &lt;of&gt; plates" in html and "L &lt;formula&gt;" in html and "60 plates &amp; more" in html
    assert "Outcome: cured" in html and "<td>viewpoint</td>" in html and html.count("data:image/png") == 2


def test_a_sample_holding_its_reconstruction(tmp_path):
    """platebench reconstruct SAMPLE --out SAMPLE/recon: reporting SAMPLE finds the reconstruction."""
    sample, recon = make_recon(tmp_path / "x")
    inner = recon.rename(sample / "recon")
    inp = detect_inputs(sample)
    assert inp.recons == [inner] and inp.samples == []
    assert "reference experiment (V)" in _headline(write_report(sample).read_text())


@pytest.mark.render
def test_report_of_scores_that_evaluate_wrote_for_other_programs_outputs(small_sample_dir, tmp_path, capsys):
    """A folder of a user's outputs, each scored with 'platebench evaluate' (F.score.json beside F): the
    report shows each score with labelled figures, its plausibility hints and an error map of the file."""
    import trimesh

    from platebench.bench.io.field_truth import load_field_truth
    from platebench.bench.io.images import write_pfm
    from tests.test_report import _check_self_contained
    t = load_field_truth(small_sample_dir)
    mine = tmp_path / "mine"
    mine.mkdir()
    write_pfm(mine / "disp0.pfm", np.where(np.isfinite(t.disparity), t.disparity + 0.3, np.inf).astype(np.float32))
    np.save(mine / "depth_mm.npy", np.where(t.mask, t.depth * 1e3, np.inf))
    mesh = trimesh.load(small_sample_dir / "plate.ply", process=False, force="mesh")
    np.save(mine / "cloud.npy", trimesh.sample.sample_surface(mesh, 2000, seed=1)[0])
    for flag, name in (("disparity", "disp0.pfm"), ("depth", "depth_mm.npy"), ("points", "cloud.npy")):
        assert main(["evaluate", str(small_sample_dir), f"--{flag}", str(mine / name)]) == 0
    capsys.readouterr()
    assert [p.name for p in detect_inputs(mine).scores] == ["cloud.score.json", "depth_mm.score.json",
                                                            "disp0.score.json"]
    index = write_report(mine)
    _check_self_contained(index)
    text = index.read_text()
    for title in ("Score of disp0 (disparity output)", "Score of depth_mm (depth output)",
                  "Score of cloud (points output)"):
        assert title in text
    assert "Middlebury bad 1.0 px, all pixels with known truth" in text  # labels from the column registry
    assert "depth RMS over the plate&#39;s pixels" in text
    assert "plausibility: the median depth error" in text and "is this file in millimetres?" in text
    assert text.count("Error map of disp0&#39;s disparity output") == 1
    assert text.count("Error map of cloud&#39;s points output") == 1
    assert "error map unavailable" not in text
    # a sensing run's merged reconstruction, scored as README shows it, is reported with the run
    sense = make_sensing(tmp_path / "sense")
    np.save(sense / "merged_points.npy", trimesh.sample.sample_surface(mesh, 500, seed=2)[0])
    assert main(["evaluate", str(small_sample_dir), "--points", str(sense / "merged_points.npy")]) == 0
    capsys.readouterr()
    text = write_report(sense).read_text()
    assert "Outcome: clean" in _headline(text) and "Score of merged_points (points output)" in text
