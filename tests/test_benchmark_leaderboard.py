"""The leaderboard from results folders: planted figures read back exactly, the ranking rule, tampered
and half-scored tables refused naming the file, merging, one colour per method, the HTML page."""
from __future__ import annotations

import csv
import hashlib
import json
from dataclasses import replace

import pytest

from platebench.bench.benchmark.leaderboard import (
    RESULTS_JSON,
    MethodRank,
    ResultsTableError,
    _csv_bytes,
    _parquet_bytes,
    _record_cells,
    _sorted_rows,
    breakdowns,
    coverage_accuracy_figure,
    error_by_bend_figure,
    merge,
    method_colours,
    ranking,
    read_results,
    write_leaderboard,
    write_results,
)
from platebench.bench.benchmark.records import BenchmarkRow, SparseRow, bend_bin
from platebench.bench.io.outputs import OutputRefusedError
from platebench.errors import PlateBenchError
from platebench.tolerances import tol

SPLIT, SHA = "v1", "ab" * 32
# (sample, realism, family, bend_deg, false boundary)
SAMPLES = (("s0", "ideal", "cylinder", 20.0, False), ("s1", "ideal", "fold", 120.0, True),
           ("s2", "modern", "cylinder", 60.0, False), ("s3", "modern", "flat", None, False),
           ("s4", "1995", "fold", 200.0, True), ("s5", "1995", "cylinder", 20.0, False))


def row(sample, method, bad2=4.55, bad05=20.0, cov=0.98, status="ok", rms=0.8, split=SPLIT):
    _, realism, family, bend, fb = next(s for s in SAMPLES if s[0] == sample)
    ok = status == "ok"
    return BenchmarkRow(split=split, sample_id=sample, method=method, status=status, error="" if ok else "no output",
                        family=family, bend_deg=bend, bend_bin=bend_bin(bend), direction="up" if bend else "",
                        axis_deg=0.0 if bend else None, distance_m=0.5, material="diffuse", realism=realism,
                        false_boundary_gt=fb, output_kind="disparity" if ok else "", plate_px=1000,
                        estimated_px=round(1000 * cov) if ok else 0, coverage_frac=cov if ok else 0.0,
                        bad_2mm_pct=bad2 if ok else 100.0, bad_0_5mm_pct=bad05 if ok else 100.0,
                        depth_rms_mm=rms if ok else None, depth_median_abs_mm=rms / 2 if ok else None,
                        depth_mean_signed_mm=0.1 if ok else None, time_s=1.5)


def rows_of(method, **kw):
    return [row(s[0], method, **kw) for s in SAMPLES]


def sparse_of(method):
    return [SparseRow(split=SPLIT, sample_id=s[0], method=method, points="square_centres", count=12,
                      dist_rms_mm=0.3, dist_max_mm=0.9, depth_rms_mm=None) for s in SAMPLES]


@pytest.fixture
def folder(tmp_path):
    rows = rows_of("good") + rows_of("bad", bad2=90.0, bad05=95.0, cov=0.5, rms=7.0)
    write_results(tmp_path / "res", rows, sparse_of("good"), SPLIT, SHA)
    return tmp_path / "res"


def _read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


# ----------------------------------------------------------------------------- round trip and planted figures
def test_results_folder_round_trips_and_records_the_sha256s(folder):
    doc = json.loads((folder / RESULTS_JSON).read_text())
    assert doc["format"] == "platebench-benchmark-results" and doc["split"] == SPLIT and doc["split_sha256"] == SHA
    assert doc["methods"] == ["bad", "good"] and doc["samples"] == len(SAMPLES)
    for name in ("results.parquet", "results.csv", "sparse.csv"):
        assert doc["tables"][name] == hashlib.sha256((folder / name).read_bytes()).hexdigest()
    t = read_results(folder)
    assert t.split == SPLIT and t.split_sha256 == SHA and t.methods == ("bad", "good")
    assert len(t.rows) == 2 * len(SAMPLES) and t.samples == tuple(s[0] for s in SAMPLES)
    good = t.rows[t.rows["method"] == "good"]
    assert (good["bad_2mm_pct"] == 4.55).all() and good["bend_deg"].isna().sum() == 1
    assert t.sparse is not None and len(t.sparse) == len(SAMPLES)


def test_planted_figures_read_back_exactly_in_csv_and_markdown(folder, tmp_path):
    out = tmp_path / "lb"
    ranks = write_leaderboard(read_results(folder), out)
    board = _read_csv(out / "leaderboard.csv")
    assert [r["method"] for r in board] == ["good", "bad"] and [r["rank"] for r in board] == ["1", "2"]
    assert float(board[0]["primary"]) == 4.55 and float(board[0]["coverage_frac"]) == 0.98
    assert float(board[1]["primary"]) == 90.0 and float(board[1]["median_depth_rms_mm"]) == 7.0
    assert board[0]["n_ok"] == str(len(SAMPLES)) and board[0]["n_failed"] == "0"  # counts as integers
    md = (out / "leaderboard.md").read_text()
    assert "| 1 | good | 4.55 | 0.980 | 20.00 | 0.800 | 6 | 0 | 0 |" in md
    assert "| 2 | bad | 90.00 | 0.500 |" in md
    assert "| good | 4.55 (0.980) | 4.55 (0.980) | 4.55 (0.980) |" in md  # per preset: ideal, modern, 1995
    assert "## By realism preset" in md and "## By family" in md
    br = _read_csv(out / "breakdown.csv")
    ideal = next(r for r in br if r["method"] == "good" and r["by"] == "realism" and r["group"] == "ideal")
    assert float(ideal["primary"]) == 4.55 and ideal["n"] == "2"
    import pyarrow.parquet as pq
    assert pq.read_table(out / "leaderboard.parquet").column("primary").to_pylist() == [4.55, 90.0]


# ----------------------------------------------------------------------------- the ranking rule
def test_a_worse_method_ranks_below_and_failures_count_100(folder):
    ranks = ranking(read_results(folder))
    assert [r.method for r in ranks] == ["good", "bad"] and ranks[1].primary == 90.0
    # the primary figure decides, whatever the tie-breaker says
    rows = rows_of("good", bad05=50.0) + rows_of("aaa", bad2=90.0, bad05=1.0)
    assert [r.method for r in ranking(write_results(folder.parent / "p", rows, None, SPLIT, SHA))] \
        == ["good", "aaa"]
    rows = rows_of("steady", bad2=10.0) + [row(s[0], "flaky", bad2=0.0, status="failed" if i < 2 else "ok")
                                           for i, s in enumerate(SAMPLES)]
    t = write_results(folder.parent / "f", rows, None, SPLIT, SHA)
    flaky = next(r for r in ranking(t) if r.method == "flaky")
    assert flaky.primary == pytest.approx(200.0 / 6) and (flaky.n_failed, flaky.n_ok, flaky.n_missing) == (2, 4, 0)
    assert flaky.coverage_frac == pytest.approx(0.98 * 4 / 6) and flaky.rank == 2
    # a missing row counts 100 and coverage 0 whatever figures it carries
    rows = rows_of("steady", bad2=10.0) + [replace(row(s[0], "absent", status="missing"), bad_2mm_pct=0.0,
                                                   bad_0_5mm_pct=0.0, coverage_frac=1.0) for s in SAMPLES]
    absent = ranking(write_results(folder.parent / "g", rows, None, SPLIT, SHA))[-1]
    assert (absent.method, absent.primary, absent.coverage_frac, absent.n_missing) == ("absent", 100.0, 0.0, 6)


def test_ties_are_broken_by_bad_0_5mm_then_name(tmp_path):
    rows = rows_of("zeta", bad05=10.0) + rows_of("alpha", bad05=30.0) + rows_of("beta", bad05=30.0)
    t = write_results(tmp_path / "r", rows, None, SPLIT, SHA)
    assert [r.method for r in ranking(t)] == ["zeta", "alpha", "beta"]
    assert all(isinstance(r, MethodRank) for r in ranking(t))
    # primaries within tol.rank_tie_pct are tied; farther apart, the primary decides
    for gap, order in ((tol.rank_tie_pct / 10, ["zeta", "alpha"]), (tol.rank_tie_pct * 10, ["alpha", "zeta"])):
        rows = rows_of("zeta", bad2=4.55 + gap, bad05=10.0) + rows_of("alpha", bad2=4.55, bad05=30.0)
        t = write_results(tmp_path / f"r{gap}", rows, None, SPLIT, SHA)
        assert [r.method for r in ranking(t)] == order


def test_breakdowns_per_group(folder):
    rows = breakdowns(read_results(folder))
    fam = {(r.method, r.group): r for r in rows if r.by == "family"}
    assert fam[("good", "cylinder")].n == 3 and fam[("bad", "fold")].primary == 90.0
    assert [r.group for r in rows if r.by == "bend_bin" and r.method == "good"] == \
        ["0-30", "30-90", "90-170", "170-300", "none"]
    assert {r.group for r in rows if r.by == "false_boundary_gt"} == {"true", "false"}
    assert [r.group for r in rows if r.by == "realism" and r.method == "good"] == ["ideal", "modern", "1995"]


# ----------------------------------------------------------------------------- refusals
def _one_line(e: pytest.ExceptionInfo) -> str:
    msg = str(e.value)
    assert "\n" not in msg and isinstance(e.value, PlateBenchError)
    return msg


def test_an_edited_results_csv_is_refused_naming_it(folder):
    p = folder / "results.csv"
    p.write_text(p.read_text().replace("4.55", "4.56", 1))
    with pytest.raises(ResultsTableError) as e:
        read_results(folder)
    assert _one_line(e).startswith(f"{folder / 'results.csv'}: its sha256 differs")


def test_an_edited_results_parquet_is_refused_naming_it(folder):
    rows = rows_of("good", bad2=1.0) + rows_of("bad", bad2=90.0, bad05=95.0, cov=0.5, rms=7.0)
    cells = _sorted_rows(_record_cells(BenchmarkRow, rows, "row"), BenchmarkRow)
    (folder / "results.parquet").write_bytes(_parquet_bytes(BenchmarkRow, cells))
    with pytest.raises(ResultsTableError) as e:
        read_results(folder)
    assert _one_line(e).startswith(f"{folder / 'results.parquet'}: its sha256 differs")


def test_a_missing_or_unlisted_table_is_refused(folder, tmp_path):
    (folder / "results.csv").unlink()
    with pytest.raises(ResultsTableError) as e:
        read_results(folder)
    assert "results.csv" in _one_line(e) and "missing" in str(e.value)
    other = tmp_path / "nosparse"
    write_results(other, rows_of("good"), None, SPLIT, SHA)
    (other / "sparse.csv").write_text("split\n")
    with pytest.raises(ResultsTableError) as e:
        read_results(other)
    assert "sparse.csv" in _one_line(e)


def _rewrite(folder, rows):
    """The tables of ``folder`` rewritten from ``rows`` with sha256s to match (a writer without checks)."""
    cells = _sorted_rows(_record_cells(BenchmarkRow, rows, "row"), BenchmarkRow)
    doc = json.loads((folder / RESULTS_JSON).read_text())
    for name, data in (("results.parquet", _parquet_bytes(BenchmarkRow, cells)),
                       ("results.csv", _csv_bytes(BenchmarkRow, cells))):
        (folder / name).write_bytes(data)
        doc["tables"][name] = hashlib.sha256(data).hexdigest()
    doc.pop("rows", None)
    (folder / RESULTS_JSON).write_text(json.dumps(doc))


def test_a_half_scored_or_extra_row_table_is_refused_naming_the_count(folder):
    full = rows_of("good") + rows_of("bad", bad2=90.0)
    _rewrite(folder, full[:-1])
    with pytest.raises(ResultsTableError) as e:
        read_results(folder)
    assert "1 of the 12 (sample, method) pairs" in _one_line(e) and "results.parquet" in str(e.value)
    _rewrite(folder, full + [full[0]])
    with pytest.raises(ResultsTableError) as e:
        read_results(folder)
    assert "twice" in _one_line(e)
    with pytest.raises(PlateBenchError, match="1 of the 12"):  # the writer refuses to write one
        write_results(folder.parent / "half", full[:-1], None, SPLIT, SHA)
    assert not (folder.parent / "half").exists()


def test_a_row_of_another_split_is_refused(tmp_path):
    with pytest.raises(PlateBenchError, match="split 'v0'"):
        write_results(tmp_path / "r", rows_of("good")[:-1] + [row("s5", "good", split="v0")], None, SPLIT, SHA)


# ----------------------------------------------------------------------------- merging
def test_merge_joins_methods_and_refuses_other_splits(tmp_path):
    a = write_results(tmp_path / "gpu", rows_of("good"), sparse_of("good"), SPLIT, SHA)
    b = write_results(tmp_path / "laptop", rows_of("bad", bad2=90.0), None, SPLIT, SHA)
    m = merge([a, b])
    assert set(m.methods) == {"good", "bad"} and len(m.rows) == 12
    assert m.sources == (tmp_path / "gpu", tmp_path / "laptop")
    assert [r.method for r in ranking(m)] == ["good", "bad"] and len(m.sparse) == len(SAMPLES)
    same = write_results(tmp_path / "again", rows_of("good"), sparse_of("good"), SPLIT, SHA)
    assert len(merge([a, same]).rows) == len(SAMPLES)  # the same method, identical rows: taken once
    changed = write_results(tmp_path / "changed", rows_of("good", bad2=5.0), None, SPLIT, SHA)
    with pytest.raises(ResultsTableError) as e:
        merge([a, changed])
    assert "'good'" in _one_line(e)
    other = write_results(tmp_path / "v2", rows_of("bad", split="v2"), None, "v2", SHA)
    with pytest.raises(ResultsTableError) as e:
        merge([a, other])
    assert "different splits" in _one_line(e)
    resha = write_results(tmp_path / "resha", rows_of("bad"), None, SPLIT, "cd" * 32)
    with pytest.raises(ResultsTableError, match="different splits"):
        merge([a, resha])


# ----------------------------------------------------------------------------- colours and plots
def test_every_method_keeps_one_colour_across_the_plots(folder):
    colours = method_colours(["c", "a", "b"])
    assert colours == method_colours(["b", "c", "a", "a"]) and len(set(colours.values())) == 3
    many = method_colours([f"m{i}" for i in range(25)])
    assert len(set(many.values())) == 25
    t = read_results(folder)
    colours = method_colours(t.methods)
    figs = [error_by_bend_figure(t, "realism", colours), error_by_bend_figure(t, "family", colours),
            coverage_accuracy_figure(ranking(t), colours)]
    seen: dict = {}
    for fig in figs:
        for ax in fig.axes:
            for line in ax.get_lines():
                seen.setdefault(line.get_label().lstrip("_"), set()).add(line.get_color())
    assert set(seen) == {"good", "bad"} and all(c == {colours[m]} for m, c in seen.items())
    assert len(figs[0].axes) == 3 and len(figs[1].axes) == 3  # one panel per preset / family, none empty
    assert all(ax.get_lines() for fig in figs for ax in fig.axes)


def test_a_plot_with_nothing_to_show_is_skipped(tmp_path):
    t = write_results(tmp_path / "r", [row(s[0], "none", status="missing") for s in SAMPLES], None,
                                   SPLIT, SHA)
    fig = coverage_accuracy_figure(ranking(t), method_colours(t.methods))
    assert len(fig.axes) == 1  # no depth RMS anywhere: only the primary panel
    assert coverage_accuracy_figure((), {}) is None


# ----------------------------------------------------------------------------- the page
def test_the_html_page_holds_the_ranking_and_plots(folder, tmp_path):
    out = tmp_path / "lb"
    ranks = write_leaderboard(read_results(folder), out)
    html = (out / "leaderboard.html").read_text()
    assert '<meta name="generator" content="platebench leaderboard">' in html
    ranking_part = html[html.index('id="ranking"'):html.index('id="by_realism"')]
    assert ranking_part.index("<td>good</td>") < ranking_part.index("<td>bad</td>")
    assert "<td>4.55</td><td>0.980</td><td>20.00</td>" in ranking_part
    assert html.count("data:image/png;base64,") == 3 and "src=\"plots/" not in html
    assert str(tmp_path) not in html and "../res/" in html  # paths relative to the page
    assert "By family" in html and "By realism preset" in html
    assert [r.method for r in ranks] == ["good", "bad"]
    doc = json.loads((out / "leaderboard.json").read_text())
    assert doc["format"] == "platebench-leaderboard" and doc["sources"] == ["../res"]
    assert [r["method"] for r in doc["ranking"]] == ["good", "bad"]
    merged = read_results(out / "results")  # the merged results: a results folder of their own
    assert merged.rows.equals(read_results(folder).rows) and merged.sparse.equals(read_results(folder).sparse)
    with pytest.raises(OutputRefusedError):
        write_leaderboard(read_results(folder), out)
    write_leaderboard(read_results(folder), out, overwrite=True)
    with pytest.raises(OutputRefusedError):  # never into an input
        write_leaderboard(read_results(folder), folder / "lb")


def test_a_tampered_table_is_never_scored_into_a_leaderboard(folder, tmp_path):
    p = folder / "results.csv"
    p.write_text(p.read_text() + p.read_text().splitlines()[1] + "\n")
    with pytest.raises(ResultsTableError, match="results.csv"):
        write_leaderboard(read_results(folder), tmp_path / "lb")
    assert not (tmp_path / "lb").exists()



def test_results_follow_the_output_rule_and_can_carry_their_leaderboard(folder):
    with pytest.raises(OutputRefusedError, match="already exists"):
        write_results(folder, rows_of("good"), None, SPLIT, SHA)
    t = write_results(folder, rows_of("good"), None, SPLIT, SHA, overwrite=True, leaderboard=True,
                      sources={"good": "run by the bench"})
    assert t.methods == ("good",) and t.sparse is None and not (folder / "sparse.csv").exists()
    assert json.loads((folder / RESULTS_JSON).read_text())["sources"] == {"good": "run by the bench"}
    assert "| 1 | good | 4.55 |" in (folder / "leaderboard.md").read_text()
    assert (folder / "leaderboard.html").is_file() and not (folder / "leaderboard.json").exists()
    assert read_results(folder).rows.equals(t.rows)
    (folder / "notes.txt").write_text("mine")
    with pytest.raises(OutputRefusedError, match="notes.txt"):  # never replaces what PlateBench did not write
        write_results(folder, rows_of("good"), None, SPLIT, SHA, overwrite=True)
