"""`platebench render` as a user runs it: determinism, bad input, atomic output."""
from __future__ import annotations

import hashlib
import json

import pytest

from tests.conftest import run_cli

SMALL = ("--width", "160", "--height", "120", "--spp", "4")


def _digest(d):
    h = hashlib.sha256()
    for p in sorted((d / "images").iterdir()):
        h.update(p.read_bytes())
    return h.hexdigest()


@pytest.mark.render
def test_same_seed_gives_byte_identical_images_in_two_processes(tmp_path):
    for name in ("a", "b"):
        p = run_cli("render", "--out", tmp_path / name, *SMALL, "--seed", "7")
        assert p.returncode == 0, p.stderr
    assert _digest(tmp_path / "a") == _digest(tmp_path / "b")
    p = run_cli("render", "--out", tmp_path / "c", *SMALL, "--seed", "8")
    assert _digest(tmp_path / "c") != _digest(tmp_path / "a")


@pytest.mark.parametrize("flags, message", [
    (("--bend-deg", "360"), "--bend-deg = 360.0 is out of range: allowed 0 to 350 degrees"),
    (("--bend-deg", "nan"), "--bend-deg = nan is out of range"),
    (("--spp", "0"), "spp = 0 is out of range: allowed an integer 1 to 65536"),
    (("--width", "-5"), "scene.width = -5 is out of range"),
    (("--distance-m", "0"), "scene.distance_m = 0.0 is out of range"),
])
def test_bad_flags_exit_nonzero_with_one_line_and_write_nothing(tmp_path, flags, message):
    p = run_cli("render", "--out", tmp_path / "s", *flags)
    assert p.returncode == 2
    assert p.stderr.strip().splitlines() == [f"platebench: error: {p.stderr.split('error: ')[1].strip()}"]
    assert message in p.stderr
    assert not any(tmp_path.iterdir())


def test_bad_config_file_names_the_key(tmp_path):
    cfg = tmp_path / "c.toml"
    cfg.write_text('[plate]\nlength_m = 0.1\nwidth_m = 0.05\n[plate.deformation]\nfamily = "saddle"\n')
    p = run_cli("render", "--out", tmp_path / "s", "--config", cfg)
    assert p.returncode == 2 and "saddle" in p.stderr and "cylinder" in p.stderr
    cfg.write_text("[scene]\nzoom = 2\n")
    p = run_cli("render", "--out", tmp_path / "s", "--config", cfg)
    assert p.returncode == 2 and "scene.zoom" in p.stderr
    assert not (tmp_path / "s").exists()


@pytest.mark.render
def test_existing_sample_is_not_clobbered(tmp_path):
    out = tmp_path / "s"
    assert run_cli("render", "--out", out, *SMALL).returncode == 0
    before = json.loads((out / "sample.json").read_text())
    p = run_cli("render", "--out", out, *SMALL, "--seed", "9")
    assert p.returncode == 2 and "already exists" in p.stderr
    assert json.loads((out / "sample.json").read_text()) == before
    assert [x.name for x in tmp_path.iterdir()] == ["s"]  # no staging leftovers
