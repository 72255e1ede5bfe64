"""Exit statuses and messages a script can trust, each through the real ``platebench`` command line.

0 all well; 1 some work failed (recorded), or none gave a result; 2 refused before any work, one line
naming the input and what is allowed, nothing written. The samples are tiny renders (160 x 120, spp 1).
"""
from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import tomli_w

from tests.conftest import run_cli

TINY = ("--width", "160", "--height", "120", "--spp", "1")
SWEEP_BASE = {"scene": {"width": 160, "height": 120}, "render": {"spp": 1, "seed": 1}}

RAISING_PLUGIN = '''
"""A plug-in method that always fails."""


def broken(inputs):
    raise RuntimeError("this method always fails")
'''


def one_line(p, *needles: str) -> str:
    """The single 'platebench: error: ...' line of a refused command (status 2)."""
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and lines[0].startswith("platebench: error: "), (p.returncode,
                                                                                                  p.stderr)
    for n in needles:
        assert n in lines[0], (n, lines[0])
    return lines[0]


def summary(p, *needles: str) -> str:
    """The last stderr line of a run that failed in part or whole (status 1): 'platebench: ...'."""
    last = p.stderr.strip().splitlines()[-1]
    assert p.returncode == 1 and last.startswith("platebench: ") and "Traceback" not in p.stderr, (p.returncode,
                                                                                                  p.stderr)
    for n in needles:
        assert n in last, (n, last)
    return last


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """Two tiny samples (s1, s2: another seed) and the reconstruction of each (r1, r2)."""
    w = tmp_path_factory.mktemp("loud")
    for s, r, seed in (("s1", "r1", "0"), ("s2", "r2", "5")):
        p = run_cli("render", "--out", w / s, *TINY, "--seed", seed)
        assert p.returncode == 0, p.stderr
        p = run_cli("reconstruct", w / s, "--out", w / r)
        assert p.returncode == 0, p.stderr
    return w


def _copy_sample(work: Path, dst: Path) -> Path:
    shutil.copytree(work / "s1", dst, symlinks=True)
    return dst


# ----------------------------------------------------------------------------- 1. exit statuses
def test_help_states_the_exit_statuses():
    p = run_cli("--help")
    text = " ".join(p.stdout.split())
    assert p.returncode == 0
    for part in ("0 all well", "1 some work failed", "2 refused", "130 interrupted", "143 terminated"):
        assert part in text, part
    from platebench.bench.cli import main
    assert "* 1: some work failed" in main.__doc__ and (main.EXIT_OK, main.EXIT_FAILED, main.EXIT_REFUSED) == (0, 1, 2)


@pytest.mark.render
@pytest.mark.parametrize("albedo, what, counts", [
    ([0.0], "every sample failed", "0 ok, 2 failed of 2"),  # a black plate: the paper's pipeline fails
    ([0.8, 0.0], "some samples failed", "1 ok, 1 failed of 2"),
])
def test_a_sweep_with_failed_samples_exits_1_with_a_summary(tmp_path, albedo, what, counts):
    spec = tmp_path / "spec.toml"
    grid = {"albedo": albedo, "bend_deg": [0, 10]} if len(albedo) == 1 else {"albedo": albedo}
    spec.write_text(tomli_w.dumps({"sweep": {"name": "t"}, "base": SWEEP_BASE, "grid": grid}))
    p = run_cli("sweep", spec, "--out", tmp_path / "ds", "--workers", "0", "--no-progress")
    summary(p, what, counts, "results.csv")
    m = json.loads((tmp_path / "ds" / "manifest.json").read_text())
    assert m["state"] == "complete" and m["counts"]["failed"] == (2 if len(albedo) == 1 else 1)
    # --resume redoes nothing, and the dataset still holds a failed sample: still 1
    p = run_cli("sweep", spec, "--out", tmp_path / "ds", "--workers", "0", "--no-progress", "--resume")
    summary(p, what)


@pytest.mark.render
def test_compare_whose_every_method_failed_exits_1(work, tmp_path):
    (tmp_path / "loud_plugins.py").write_text(RAISING_PLUGIN)
    env = {"PYTHONPATH": os.pathsep.join([str(tmp_path), os.environ.get("PYTHONPATH", "")])}
    p = run_cli("compare", work / "s1", "--methods", "loud_plugins:broken", "--out", tmp_path / "c", env=env)
    summary(p, "every method failed", "1 of 1", "loud_plugins:broken", "compare.json")
    doc = json.loads((tmp_path / "c" / "compare.json").read_text())
    assert doc["methods"]["loud_plugins:broken"]["status"] == "failed"


@pytest.mark.render
def test_compare_that_gives_no_row_exits_1(work, tmp_path):
    s = _copy_sample(work, tmp_path / "alone" / "s1")  # no reconstruction beside it
    p = run_cli("compare", s, "--methods", "paper", "--out", tmp_path / "c")
    summary(p, "no method gave a result")


def test_compare_with_a_recon_that_does_not_exist_is_refused(work, tmp_path):
    p = run_cli("compare", work / "s1", "--methods", "paper", "--recon", tmp_path / "nonexist", "--out",
                tmp_path / "c")
    one_line(p, "nonexist", "does not exist")
    assert not (tmp_path / "c").exists()
    (tmp_path / "empty").mkdir()
    p = run_cli("compare", work / "s1", "--methods", "paper", "--recon", tmp_path / "empty", "--out", tmp_path / "c")
    one_line(p, "points.csv", "file is missing")
    assert not (tmp_path / "c").exists()


# ----------------------------------------------------------------------------- 2. pairs that belong together
def test_compare_and_evaluate_refuse_a_reconstruction_of_another_sample(work, tmp_path):
    p = run_cli("compare", work / "s1", "--methods", "paper", "--recon", work / "r2", "--out", tmp_path / "c")
    line = one_line(p, "r2 was not made from", "s1", "differs")
    assert not (tmp_path / "c").exists()
    q = run_cli("evaluate", work / "s1", work / "r2", "--out", tmp_path / "score.json")
    assert one_line(q) == line  # one check for both
    p = run_cli("compare", work / "s1", "--methods", "paper", "--recon", work / "r1", "--out", tmp_path / "ok")
    assert p.returncode == 0, p.stderr  # its own reconstruction is scored


def test_check_made_from_is_the_one_check():
    import inspect

    from platebench.bench.run import compare, score
    for fn in (score.score_files, compare.paper_reconstruction):
        assert "check_made_from(" in inspect.getsource(fn) and "verify_reconstruction(" in inspect.getsource(fn)


def test_compare_refuses_an_edited_reconstruction_as_evaluate_does(work, tmp_path):
    r = tmp_path / "r1"
    shutil.copytree(work / "r1", r)
    data = bytearray((r / "points.csv").read_bytes())
    at = next(i for i in range(len(data) - 1, -1, -1) if chr(data[i]).isdigit())  # a digit of the last point
    data[at] = ord("1") if data[at] != ord("1") else ord("2")
    (r / "points.csv").write_bytes(bytes(data))
    p = run_cli("compare", work / "s1", "--methods", "paper", "--recon", r, "--out", tmp_path / "c")
    line = one_line(p, str(r / "points.csv"), "differs from the checksum")
    assert not (tmp_path / "c").exists()
    q = run_cli("evaluate", work / "s1", r, "--out", tmp_path / "score.json")
    assert one_line(q) == line  # one check for both


@pytest.mark.render
def test_reconstruct_refuses_an_image_swapped_in_or_linked(work, tmp_path):
    s = _copy_sample(work, tmp_path / "s")
    shutil.copy(work / "s2" / "images" / "left_active.png", s / "images" / "left_active.png")
    p = run_cli("reconstruct", s, "--out", tmp_path / "r")
    one_line(p, str(s / "images" / "left_active.png"), "differs from the checksum")
    assert not (tmp_path / "r").exists()
    (s / "images" / "left_active.png").unlink()
    os.symlink(work / "s1" / "images" / "left_active.png", s / "images" / "left_active.png")  # the right bytes
    p = run_cli("reconstruct", s, "--out", tmp_path / "r")
    one_line(p, str(s / "images" / "left_active.png"), "symbolic link")
    assert not (tmp_path / "r").exists()
    (s / "calib.json").write_text((s / "calib.json").read_text() + "\n")  # still valid JSON, other bytes
    (s / "images" / "left_active.png").unlink()
    shutil.copy(work / "s1" / "images" / "left_active.png", s / "images" / "left_active.png")
    p = run_cli("reconstruct", s, "--out", tmp_path / "r")
    one_line(p, "calib.json", "differs from the checksum")


# ----------------------------------------------------------------------------- 3. messages that say what is wrong
def test_an_unknown_method_is_named_before_the_output_is_looked_at(work, tmp_path):
    s = _copy_sample(work, tmp_path / "s")
    (s / "compare").mkdir()
    (s / "compare" / "note.txt").write_text("mine")
    p = run_cli("compare", s, "--methods", "nosuchmethod")
    one_line(p, "unknown method 'nosuchmethod'")
    assert (s / "compare" / "note.txt").read_text() == "mine"


def test_evaluate_with_swapped_arguments_says_so(work):
    p = run_cli("evaluate", work / "r1", work / "s1")
    one_line(p, "swapped", f"platebench evaluate {work / 's1'} {work / 'r1'}")
    p = run_cli("evaluate", work / "s1", work / "s2")
    one_line(p, f"RECON_DIR {work / 's2'} is a sample")
    p = run_cli("evaluate", work / "r1", work / "r2")
    one_line(p, f"SAMPLE_DIR {work / 'r1'} is a reconstruction")


# ----------------------------------------------------------------------------- 4. --overwrite keeps a user's edit
@pytest.mark.render
def test_overwrite_refuses_a_sample_whose_file_was_edited(tmp_path):
    out = tmp_path / "s"
    assert run_cli("render", "--out", out, *TINY).returncode == 0
    (out / "calib.json").write_text('{"edited":true}\n')
    p = run_cli("render", "--out", out, *TINY, "--overwrite")
    one_line(p, "calib.json", "changed after PlateBench wrote it")
    assert (out / "calib.json").read_text() == '{"edited":true}\n'
    assert sorted(x.name for x in tmp_path.iterdir()) == ["s"]


def test_the_output_rule_names_an_edited_or_replaced_file(tmp_path):
    from platebench.bench.io.outputs import OutputRefusedError, check_output, foreign_entries, output_dir
    out = tmp_path / "o"
    with output_dir(out, "comparison") as d:
        (d / "compare.json").write_text(json.dumps({"methods": {}}))
        (d / "sub").mkdir()
        (d / "sub" / "x.bin").write_bytes(b"1")
    check_output(out, "comparison", overwrite=True)
    (out / "sub" / "x.bin").write_bytes(b"2")
    with pytest.raises(OutputRefusedError, match="holds sub/x.bin, which was changed after PlateBench wrote it"):
        check_output(out, "comparison", overwrite=True)
    assert foreign_entries(out, "comparison") == ["sub/x.bin"]
    (out / "sub" / "x.bin").unlink()
    os.symlink(tmp_path / "elsewhere", out / "sub" / "x.bin")
    with pytest.raises(OutputRefusedError, match="holds sub/x.bin, which was changed"):
        check_output(out, "comparison", overwrite=True)


# ----------------------------------------------------------------------------- 5. inputs checked before any work
def test_every_allowed_size_and_spp_renders_in_passes_mitsuba_takes():
    """Sizes and spp Mitsuba refused in one call (more than 2^32 - 1 samples) are split into passes it
    takes; only an image whose one sample per pixel exceeds that is refused (no allowed size does)."""
    from platebench.bench.config.sample_config import ConfigError, check_render_size
    from platebench.scenes.render.passes import WAVEFRONT_LIMIT, pass_plan
    for w, h, spp in ((2048, 2048, 1025), (8192, 8192, 65), (8192, 8192, 65536), (160, 120, 65536)):
        check_render_size(w, h, spp)
        plan = pass_plan(w, h, spp)
        assert sum(plan) == spp and max(plan) * w * h <= WAVEFRONT_LIMIT
    with pytest.raises(ConfigError, match="70000 x 70000"):
        check_render_size(70000, 70000, 1)


def test_a_bend_too_small_to_mesh_is_refused_and_the_smallest_allowed_one_builds(tmp_path):
    p = run_cli("render", "--out", tmp_path / "s", *TINY, "--bend-deg", "1e-12")
    one_line(p, "--bend-deg = 1e-12", "allowed 0 (flat) or 1e-06 to 350 degrees")
    assert not any(tmp_path.iterdir())
    from platebench.plates import build_plate
    from platebench.plates.spec import MIN_BEND_DEG, CylindricalBend, Fold, PlateSpec, PlateSpecError, SCurve
    for make in (lambda a: CylindricalBend(a), lambda a: SCurve(a),
                 lambda a: Fold(a, 0.0, 0.01, "up")):
        with pytest.raises(PlateSpecError, match="allowed 0 \\(flat\\) or 1e-06"):
            make(math.radians(1e-12))
        for side in (0.1165, 10.0):  # the smallest bend on the smallest radius-to-size and the largest plate
            plate = build_plate(PlateSpec(side, 0.0735, 0.0, make(math.radians(MIN_BEND_DEG))))
            assert plate.mesh.vertices.shape[0] > 0


def test_a_plate_size_out_of_range_is_refused_by_the_spec(tmp_path):
    spec = tmp_path / "spec.toml"
    spec.write_text(tomli_w.dumps({"sweep": {"name": "t"}, "grid": {"bend_deg": [0, 10]},
                                   "base": {**SWEEP_BASE, "plate": {"length_m": 1e300, "width_m": 0.07}}}))
    p = run_cli("sweep", spec, "--out", tmp_path / "ds", "--workers", "0")
    one_line(p, "length_m = 1e+300", "allowed 0.001 to 10 m")
    assert not (tmp_path / "ds").exists()


@pytest.mark.parametrize("text", ["a = " + "[" * 50_000 + "]" * 50_000,
                                  "x = " + "{a = " * 50_000 + "1" + "}" * 50_000,
                                  "a = " + "[" * 70 + "]" * 70])
def test_a_toml_nested_too_deep_is_one_line(tmp_path, text):
    cfg = tmp_path / "deep.toml"
    cfg.write_text(text + "\n")
    p = run_cli("render", "--out", tmp_path / "s", "--config", cfg)
    one_line(p, "deep.toml", "nested deeper than 64 levels")
    p = run_cli("sweep", cfg, "--out", tmp_path / "ds", "--workers", "0")
    one_line(p, "deep.toml", "nested deeper than 64 levels")
    assert sorted(x.name for x in tmp_path.iterdir()) == ["deep.toml"]


def test_an_sgbm_search_wider_than_the_images_is_refused(work, tmp_path):
    p = run_cli("compare", work / "s1", "--methods", "sgbm", "--min-depth-mm", "100", "--max-depth-mm", "110",
                "--out", tmp_path / "c")
    one_line(p, "sgbm", "160 px wide", "multiple of 16")
    assert not (tmp_path / "c").exists()


@pytest.mark.render
def test_an_sgbm_search_that_fits_runs(work, tmp_path):
    p = run_cli("compare", work / "s1", "--methods", "sgbm", "--min-depth-mm", "300", "--max-depth-mm", "500",
                "--out", tmp_path / "c")
    assert p.returncode in (0, 1) and "Traceback" not in p.stderr, p.stderr
    assert (tmp_path / "c" / "compare.json").is_file()


def test_a_working_directory_that_was_removed_is_one_line(tmp_path):
    gone = tmp_path / "gone"
    gone.mkdir()
    # no PYTHONPATH: with a relative entry there Python itself stops before any of our code (main's doc)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    script = f'cd "{gone}" && rmdir "{gone}" && exec "{sys.executable}" -m platebench.bench.cli.main info'
    p = subprocess.run(["sh", "-c", script], env=env, capture_output=True, text=True, timeout=120)
    one_line(p, "working directory no longer exists")


@pytest.mark.render
@pytest.mark.parametrize("table", ["results.csv", "results.parquet"])
def test_an_edited_results_table_is_refused_by_its_readers_and_kept_by_overwrite(tmp_path, table):
    """The sweep records each table's sha256 (``results.sha256.json``): ``report`` and
    ``platebench.results()`` refuse a table changed since, naming it, and ``--overwrite`` keeps it."""
    spec = tmp_path / "spec.toml"
    spec.write_text(tomli_w.dumps({"sweep": {"name": "t"}, "base": SWEEP_BASE, "grid": {"bend_deg": [0]}}))
    ds = tmp_path / "ds"
    p = run_cli("sweep", spec, "--out", ds, "--workers", "0", "--no-progress")
    assert p.returncode == 0, p.stderr[-2000:]
    import platebench
    assert len(platebench.results(ds)) >= 1  # the untouched tables are read
    if table == "results.csv":
        (ds / "results.parquet").unlink()  # the report reads the CSV where there is no parquet
        (ds / table).write_text((ds / table).read_text().replace(",ok,", ",ok ,", 1) + "\n")
    else:
        (ds / table).write_bytes((ds / table).read_bytes() + b"\0")
    edited = (ds / table).read_bytes()
    p = run_cli("report", ds, "--out", tmp_path / "rep")
    one_line(p, table, "changed after the sweep wrote it")
    assert p.returncode == 2 and not (tmp_path / "rep").exists()
    with pytest.raises(Exception, match="changed after the sweep wrote it"):
        platebench.results(ds)
    p = run_cli("sweep", spec, "--out", ds, "--workers", "0", "--no-progress", "--overwrite")
    one_line(p, table)
    assert p.returncode == 2 and (ds / table).read_bytes() == edited
