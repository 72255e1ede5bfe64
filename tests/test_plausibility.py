"""Wrong units or kinds are said, never refused: a file whose errors lie orders of magnitude beyond the
scene gets a hint naming the likely mistake, in the output and in the score JSON; a method that is only
bad gets none. Each case as a user makes it: a file written, ``platebench evaluate`` on it."""
from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from platebench.bench.cli.main import main
from platebench.bench.io.images import read_pfm

pytestmark = pytest.mark.render


def _evaluate(capsys, sample, flag, path):
    code = main(["evaluate", str(sample), f"--{flag}", str(path)])
    out = capsys.readouterr()
    assert code == 0, out.err  # scored, never refused
    doc = json.loads(path.with_name(f"{path.stem}.score.json").read_text())
    hints = [ln for ln in out.out.splitlines() if ln.startswith("hint")]
    assert len(hints) == len(doc["hints"])
    return doc["hints"]


@pytest.fixture(scope="module")
def truth(small_sample_dir):
    from platebench.bench.io.field_truth import load_field_truth
    return load_field_truth(small_sample_dir)


def _surface_points(sample, n=3000, seed=0):
    mesh = trimesh.load(sample / "plate.ply", process=False, force="mesh")
    return trimesh.sample.sample_surface(mesh, n, seed=seed)[0]


@pytest.mark.parametrize("scale", [1000.0, 1001.0])  # millimetres (and a rounding of them)
def test_depth_in_millimetres_is_asked_about(small_sample_dir, truth, tmp_path, capsys, scale):
    np.save(tmp_path / "z.npy", np.where(truth.mask, truth.depth * scale, np.inf))
    hints = _evaluate(capsys, small_sample_dir, "depth", tmp_path / "z.npy")
    assert len(hints) == 1 and "is this file in millimetres?" in hints[0], hints


def test_a_disparity_given_as_depth_is_asked_about(small_sample_dir, tmp_path, capsys):
    np.save(tmp_path / "d.npy", read_pfm(small_sample_dir / "gt" / "disp0GT.pfm").astype(np.float64))
    hints = _evaluate(capsys, small_sample_dir, "depth", tmp_path / "d.npy")
    assert len(hints) == 1 and "is this file a disparity?" in hints[0], hints


def test_a_depth_given_as_disparity_is_asked_about(small_sample_dir, truth, tmp_path, capsys):
    from platebench.bench.io.images import write_pfm
    write_pfm(tmp_path / "z.pfm", np.where(truth.mask, truth.depth, np.inf).astype(np.float32))
    hints = _evaluate(capsys, small_sample_dir, "disparity", tmp_path / "z.pfm")
    assert len(hints) == 1 and "is this file a depth map?" in hints[0], hints


@pytest.mark.parametrize("how, words", [("mm", "in millimetres?"), ("camera", "in the left camera's frame?"),
                                        ("both", "in millimetres and in the left camera's frame?")])
def test_points_in_millimetres_or_camera_frame_are_asked_about(small_sample_dir, truth, tmp_path, capsys, how, words):
    P = _surface_points(small_sample_dir)
    if how in ("camera", "both"):
        P = P @ truth.rig.left.R.T + truth.rig.left.t  # x_cam = R x_world + t
    if how in ("mm", "both"):
        P = P * 1e3
    np.save(tmp_path / "p.npy", P)
    hints = _evaluate(capsys, small_sample_dir, "points", tmp_path / "p.npy")
    assert len(hints) == 1 and f"is this file {words}" in hints[0], hints


@pytest.mark.parametrize("case", ["depth noise 5 mm", "depth 40 mm too far", "flat plane", "points noise 10 mm",
                                  "disparity noise 20 px"])
def test_a_method_that_is_only_bad_gets_no_hint(small_sample_dir, truth, tmp_path, capsys, case):
    rng = np.random.default_rng(5)
    z = np.where(truth.mask, truth.depth, np.inf)
    if case == "depth noise 5 mm":
        flag, path = "depth", tmp_path / "a.npy"
        np.save(path, z + rng.normal(0, 5e-3, z.shape))
    elif case == "depth 40 mm too far":
        flag, path = "depth", tmp_path / "b.npy"
        np.save(path, z + 0.040)
    elif case == "flat plane":
        flag, path = "depth", tmp_path / "c.npy"
        np.save(path, np.where(truth.mask, 0.45, np.inf))
    elif case == "points noise 10 mm":
        flag, path = "points", tmp_path / "d.npy"
        np.save(path, _surface_points(small_sample_dir) + rng.normal(0, 0.010, (3000, 3)))
    else:
        from platebench.bench.io.images import write_pfm
        flag, path = "disparity", tmp_path / "e.pfm"
        write_pfm(path, (truth.disparity + rng.normal(0, 20.0, z.shape)).astype(np.float32))
    assert _evaluate(capsys, small_sample_dir, flag, path) == []
