"""The benchmark end to end on a small split of real renders: build, verify, score a plug-in and folders
of outputs with one command each, and read the planted errors back from the leaderboard.

Expected figures are computed here from the ground-truth files with numpy, by the protocol's
definitions (docs/benchmark.md), not by the bench's code.
"""
from __future__ import annotations

import csv
import json
import math
import shutil
import textwrap
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import run_cli

pytestmark = pytest.mark.render

N_SAMPLES = 10
SPLIT = textwrap.dedent("""\
    [benchmark]
    name = "tiny"
    description = "ten small samples"

    [base.plate]
    length_m = 0.1165
    width_m = 0.0735
    [base.scene]
    width = 160
    height = 120
    [base.render]
    spp = 1
    seed = 0

    [[part]]
    name = "cyl"
    [part.base.plate.deformation]
    family = "cylinder"
    angle_rad = 0.0
    direction = "up"
    [part.grid]
    bend_deg = [10, 60, 120, 200]
    direction = ["up", "down"]

    [[part]]
    name = "fam"
    [part.grid]
    family = ["dome", "fold"]
    bend_deg = 40
    distance_m = 0.45
    """)
PLUGIN = textwrap.dedent("""\
    import numpy as np
    from platebench.bench.run.plugins import Depth

    def flat(inputs):
        \"\"\"A flat plate 0.40 m away: a constant depth over the whole left image.\"\"\"
        h, w = inputs.images["left_active"].shape[:2]
        return Depth(np.full((h, w), 0.40))
    """)


def _exr(path: Path) -> np.ndarray:
    from platebench.bench.io.images import read_exr
    return np.asarray(read_exr(path), np.float64)


def _truth(bench: Path, sid: str):
    d = bench / "B" / "samples" / sid / "sample"
    from platebench.bench.io.images import read_pfm, read_png
    return (_exr(d / "gt" / "left_depth.exr"), read_png(d / "gt" / "left_mask.png") > 0,
            np.asarray(read_pfm(d / "gt" / "disp0GT.pfm"), np.float64), json.loads((d / "calib.json").read_text()))


def _expected(z: np.ndarray, zt: np.ndarray, mask: np.ndarray) -> dict:
    """The protocol's figures, written out here: over the plate's pixels, no estimate counts as bad."""
    est = mask & np.isfinite(z) & (z > 0)
    e = (z - zt)[est] * 1e3
    n = int(mask.sum())
    return {"coverage_frac": est.sum() / n,
            "bad_2mm_pct": 100.0 * (np.count_nonzero(np.abs(e) > 2.0) + n - est.sum()) / n,
            "depth_rms_mm": math.sqrt(float(np.mean(e * e))) if e.size else None}


@pytest.fixture(scope="module")
def bench(tmp_path_factory):
    root = tmp_path_factory.mktemp("benchmark")
    split = root / "tiny.toml"
    split.write_text(SPLIT)
    r = run_cli("benchmark", "build", split, "--out", root / "B", "--workers", "2",
                "--record-checksums", root / "tiny.sha256.json")
    assert r.returncode == 0, r.stderr
    return root


def _ids(bench: Path) -> list[str]:
    return sorted(p.name for p in (bench / "B" / "samples").iterdir())


def _rows(results: Path) -> list[dict]:
    with open(results / "results.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_the_shipped_split_covers_what_it_says():
    from platebench.bench.benchmark.split import load_split
    s = load_split("v1")
    fam = {x.family for x in s.samples}
    from platebench.plates.spec import FAMILIES
    assert fam == set(FAMILIES)
    bends = [x.bend_deg for x in s.samples if x.family == "cylinder" and x.realism == "ideal"]
    assert min(bends) == 0 and max(bends) == 300
    assert {x.direction for x in s.samples if x.family == "cylinder"} == {"up", "down"}
    assert len({x.axis_deg for x in s.samples if x.family == "cylinder"}) >= 3
    assert {x.distance_m for x in s.samples} == {0.40, 0.50}
    assert {x.material for x in s.samples} == {"diffuse", "roughconductor"}
    assert {x.realism for x in s.samples} == {"ideal", "modern", "1995"}
    assert len({x.sample_id for x in s.samples}) == len(s.samples)
    from platebench.bench.benchmark.split import split_checksums_path
    doc = json.loads(split_checksums_path(s).read_text())
    assert doc["split_sha256"] == s.sha256 and set(doc["samples"]) == {x.sample_id for x in s.samples}


def test_a_second_build_elsewhere_gives_the_same_checksums(bench, tmp_path):
    r = run_cli("benchmark", "build", bench / "tiny.toml", "--out", tmp_path / "B2", "--workers", "0",
                "--record-checksums", tmp_path / "again.sha256.json")
    assert r.returncode == 0, r.stderr
    a = json.loads((bench / "tiny.sha256.json").read_text())
    b = json.loads((tmp_path / "again.sha256.json").read_text())
    assert a["samples"] and a == b
    r = run_cli("benchmark", "verify", tmp_path / "B2", "--split", bench / "tiny.toml")
    assert r.returncode == 0 and "this copy is tiny" in r.stdout, r.stdout + r.stderr


def test_verify_names_a_changed_truth_file_and_refuses_a_half_built_copy(bench, tmp_path):
    shutil.copy(bench / "tiny.toml", tmp_path / "tiny.toml")
    sums = json.loads((bench / "tiny.sha256.json").read_text())
    sid = _ids(bench)[2]
    sums["samples"][sid]["truth"]["gt/left_depth.exr"] = "0" * 64  # the published truth differs from this copy's
    (tmp_path / "tiny.sha256.json").write_text(json.dumps(sums))
    r = run_cli("benchmark", "verify", bench / "B", "--split", tmp_path / "tiny.toml")
    assert r.returncode == 1 and f"{sid}/gt/left_depth.exr" in r.stdout and "NOT tiny" in r.stdout, r.stdout
    copy = tmp_path / "B"
    shutil.copytree(bench / "B", copy)
    (copy / "samples" / sid / "sample" / "gt" / "left_mask.png").write_bytes(b"\x89PNG")
    r = run_cli("benchmark", "verify", copy, "--split", bench / "tiny.toml")
    assert r.returncode == 2 and "left_mask.png" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    shutil.rmtree(copy / "samples" / sid)
    r = run_cli("benchmark", "verify", copy, "--split", bench / "tiny.toml")
    assert r.returncode == 2 and "1 of the split's 10 samples are not built" in r.stderr, r.stderr
    r = run_cli("benchmark", "score", copy, "--split", bench / "tiny.toml", "--methods", "sgbm",
                "--out", tmp_path / "R")
    assert r.returncode == 2 and not (tmp_path / "R").exists(), r.stderr


def test_a_plugin_is_scored_on_the_split_with_one_command(bench, tmp_path):
    (tmp_path / "flatplug.py").write_text(PLUGIN)
    out = tmp_path / "R"
    r = run_cli("benchmark", "score", bench / "B", "--split", bench / "tiny.toml", "--methods", "flatplug:flat",
                "--out", out, "--workers", "1", env={"PYTHONPATH": str(tmp_path)})
    assert r.returncode == 0, r.stdout + r.stderr
    rows = {x["sample_id"]: x for x in _rows(out)}
    assert set(rows) == set(_ids(bench))
    for sid, row in rows.items():
        zt, mask, _, _ = _truth(bench, sid)
        exp = _expected(np.full(zt.shape, float(np.float32(0.40))), zt, mask)  # depth.exr holds float32
        assert row["status"] == "ok" and row["output_kind"] == "depth"
        assert float(row["coverage_frac"]) == pytest.approx(exp["coverage_frac"], abs=1e-12)
        assert float(row["bad_2mm_pct"]) == pytest.approx(exp["bad_2mm_pct"], abs=1e-9)
        assert float(row["depth_rms_mm"]) == pytest.approx(exp["depth_rms_mm"], rel=1e-9)
    assert "flatplug:flat" in (out / "leaderboard.md").read_text()
    assert "flatplug:flat" in (out / "leaderboard.html").read_text()


def _write_outputs(bench: Path, folder: Path, make, skip=()) -> None:
    from platebench.bench.io.images import write_pfm
    for sid in _ids(bench):
        if sid in skip:
            continue
        zt, mask, disp, calib = _truth(bench, sid)
        d = folder / sid
        d.mkdir(parents=True)
        kind, value = make(zt, mask, disp, sid)
        if kind == "depth":
            np.save(d / "depth.npy", value)
        else:
            write_pfm(d / "disparity.pfm", value.astype(np.float32))


def test_folders_of_outputs_planted_errors_and_missing_samples_read_back_exactly(bench, tmp_path):
    ids = _ids(bench)
    missing = ids[3]  # one of the ten: 10 % missing
    _write_outputs(bench, tmp_path / "plus1mm", lambda zt, m, d, s: ("depth", np.where(m, zt + 1e-3, np.nan)),
                   skip=(missing,))
    _write_outputs(bench, tmp_path / "plushalfpx", lambda zt, m, d, s: ("disparity", np.where(m, d + 0.5, np.inf)))
    out = tmp_path / "R"
    r = run_cli("benchmark", "score", bench / "B", "--split", bench / "tiny.toml", "--out", out, "--workers", "1",
                "--outputs", f"plus1mm={tmp_path / 'plus1mm'}", "--outputs", f"plushalfpx={tmp_path / 'plushalfpx'}")
    assert r.returncode == 0, r.stdout + r.stderr
    rows = _rows(out)
    plus = {x["sample_id"]: x for x in rows if x["method"] == "plus1mm"}
    assert plus[missing]["status"] == "missing" and float(plus[missing]["bad_2mm_pct"]) == 100.0
    assert float(plus[missing]["coverage_frac"]) == 0.0
    for sid, row in plus.items():
        if sid != missing:
            assert row["status"] == "ok"
            assert float(row["depth_rms_mm"]) == pytest.approx(1.0, abs=1e-9)
            assert float(row["bad_2mm_pct"]) == 0.0 and float(row["coverage_frac"]) == 1.0
    lead = {x["method"]: x for x in csv.DictReader(open(out / "leaderboard.csv", newline=""))}
    assert float(lead["plus1mm"]["primary"]) == pytest.approx(100.0 / N_SAMPLES, abs=1e-9)
    half = [x for x in rows if x["method"] == "plushalfpx"]
    exp_primary = []
    for row in half:
        zt, mask, disp, calib = _truth(bench, row["sample_id"])
        f, b = calib["left"]["K"][0][0], calib["baseline_m"]
        doffs = calib["right"]["K"][0][2] - calib["left"]["K"][0][2]
        z = np.where(mask, f * b / (disp + 0.5 + doffs), np.nan)
        exp = _expected(z, zt, mask)
        assert float(row["depth_rms_mm"]) == pytest.approx(exp["depth_rms_mm"], rel=1e-6)
        assert float(row["bad_2mm_pct"]) == pytest.approx(exp["bad_2mm_pct"], abs=1e-9)
        exp_primary.append(exp["bad_2mm_pct"])
    assert float(lead["plushalfpx"]["primary"]) == pytest.approx(float(np.mean(exp_primary)), abs=1e-9)


def test_a_method_answering_on_its_best_tenth_ranks_below_the_same_answering_everywhere(bench, tmp_path):
    rng = np.random.default_rng(7)
    noisy = {sid: rng.normal(0.0, 1e-3, _truth(bench, sid)[0].shape) for sid in _ids(bench)}

    def everywhere(zt, m, d, sid):
        return "depth", np.where(m, zt + noisy[sid], np.nan)

    def best_tenth(zt, m, d, sid):
        e = np.abs(noisy[sid])
        cut = np.quantile(e[m], 0.10)
        return "depth", np.where(m & (e <= cut), zt + noisy[sid], np.nan)

    _write_outputs(bench, tmp_path / "all", everywhere)
    _write_outputs(bench, tmp_path / "best", best_tenth)
    out = tmp_path / "R"
    r = run_cli("benchmark", "score", bench / "B", "--split", bench / "tiny.toml", "--out", out, "--workers", "1",
                "--outputs", f"best={tmp_path / 'best'}", "--outputs", f"all={tmp_path / 'all'}")
    assert r.returncode == 0, r.stdout + r.stderr
    lead = {x["method"]: x for x in csv.DictReader(open(out / "leaderboard.csv", newline=""))}
    assert int(lead["all"]["rank"]) < int(lead["best"]["rank"])
    assert float(lead["best"]["primary"]) >= 89.9 > float(lead["all"]["primary"])
    rows = [x for x in _rows(out) if x["method"] == "best"]
    assert all(float(x["depth_rms_mm"]) < 0.2 for x in rows)  # on its tenth it is far more accurate


def test_an_edited_results_table_is_refused_by_name(bench, tmp_path):
    _write_outputs(bench, tmp_path / "o", lambda zt, m, d, s: ("depth", np.where(m, zt, np.nan)))
    out = tmp_path / "R"
    r = run_cli("benchmark", "score", bench / "B", "--split", bench / "tiny.toml", "--out", out, "--workers", "0",
                "--outputs", f"o={tmp_path / 'o'}")
    assert r.returncode == 0, r.stderr
    text = (out / "results.csv").read_text()
    (out / "results.csv").write_text(text.replace(",ok,", ",ok,", 1).replace("0.0,", "0.5,", 1))
    r = run_cli("benchmark", "leaderboard", out, "--out", tmp_path / "L")
    assert r.returncode == 2 and "results.csv" in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
