"""``coverage_frac`` has one meaning in every table, plot and file that carries it: the share of the left
view's plate pixels (the truth's plate mask) that have an estimate, 0..1.

One small sweep (320 x 240, spp 2, the paper's method and SGBM) is read back everywhere a coverage is
written: each method's score.json, the sweep's results.csv and results.parquet, the report's coverage
panel, and compare.json (with the report's compare panel). Every figure must equal the pixel share
computed here from the sample's files alone: the paper's as the plate pixels whose true ray (left
camera centre through ``gt/left_points.exr``) hits its ``surface.ply`` (a trimesh ray cast), SGBM's as
the plate pixels holding a finite disparity (``disparity.pfm``)."""
from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from platebench.tolerances import tol

pytestmark = pytest.mark.render

SMALL = {"scene": {"width": 320, "height": 240}, "render": {"spp": 2, "seed": 3}}
METHODS = ("paper", "sgbm")


def _same(a, b) -> bool:
    return a is not None and b is not None and math.isclose(float(a), float(b), rel_tol=tol.relative)


@pytest.fixture(scope="module")
def sweep(tmp_path_factory):
    """(dataset directory, sample id) of a one-sample sweep of the paper's method and SGBM."""
    from platebench.bench.sweep.executors import LocalExecutor, run_sweep
    from platebench.bench.sweep.spec import parse_spec
    out = tmp_path_factory.mktemp("coverage") / "ds"
    spec = parse_spec({"sweep": {"name": "coverage", "methods": list(METHODS)}, "base": SMALL,
                       "grid": {"bend_deg": [10]}})
    run_sweep(spec, out, LocalExecutor(1), progress=False)
    (sid,) = [p.name for p in (out / "samples").iterdir() if not p.name.startswith(".")]
    return out, sid


@pytest.fixture(scope="module")
def expected(sweep):
    """method -> the pixel share computed from the sample's files, independently of the bench's scoring."""
    import trimesh

    from platebench.bench.io.images import read_exr, read_pfm, read_png
    ds, sid = sweep
    sample, recon = ds / "samples" / sid / "sample", ds / "samples" / sid / "recon"
    mask = read_png(sample / "gt" / "left_mask.png") > 0
    points = read_exr(sample / "gt" / "left_points.exr").astype(np.float64)
    left = json.loads((sample / "calib.json").read_text())["left"]
    R, t = np.asarray(left["R"], float), np.asarray(left["t"], float)
    eye = -R.T @ t
    mesh = trimesh.load(recon / "paper" / "surface.ply", process=False, force="mesh")
    d = points[mask] - eye
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hit = mesh.ray.intersects_any(np.tile(eye, (len(d), 1)), d)
    disp = read_pfm(recon / "sgbm" / "disparity.pfm")
    return {"paper": np.count_nonzero(hit) / mask.sum(),
            "sgbm": np.count_nonzero(np.isfinite(disp) & mask) / mask.sum()}


def test_expected_figures_are_pixel_shares(expected):
    for m in METHODS:
        assert 0 < expected[m] <= 1, (m, expected[m])


def test_score_files(sweep, expected):
    ds, sid = sweep
    recon = ds / "samples" / sid / "recon"
    paper = json.loads((recon / "paper" / "score.json").read_text())
    assert _same(paper["coverage"]["coverage_frac"], expected["paper"]), paper.get("coverage")
    assert "coverage_frac" not in paper["surface"]  # the surface's area coverage has a name of its own
    assert 0 < paper["surface"]["surface_coverage_frac"]
    sgbm = json.loads((recon / "sgbm" / "score.json").read_text())
    assert _same(sgbm["scores"]["coverage_frac"], expected["sgbm"]), sgbm["scores"]["coverage_frac"]
    assert _same(sgbm["figures"]["coverage_frac"], expected["sgbm"])


@pytest.mark.parametrize("table", ["results.csv", "results.parquet"])
def test_results_tables(sweep, expected, table):
    ds, _ = sweep
    frame = pd.read_csv(ds / table) if table.endswith(".csv") else pd.read_parquet(ds / table)
    for m in METHODS:
        (value,) = frame.loc[frame["method"] == m, "coverage_frac"].tolist()
        assert _same(value, expected[m]), (table, m, value, expected[m])


def test_report_coverage_panels(sweep, expected, tmp_path, monkeypatch):
    """The report's coverage panel, of the sweep and of a compare.json (``compare --methods paper,sgbm``)."""
    from platebench.bench.cli.main import main
    from platebench.bench.report import plots
    from platebench.bench.report.html import write_report
    ds, sid = sweep
    root = ds.parent  # the report reads the sweep and the comparison beside it
    cmp_dir = root / "cmp"
    assert main(["compare", str(ds / "samples" / sid / "sample"), "--methods", "paper,sgbm", "--recon",
                 str(ds / "samples" / sid / "recon" / "paper"), "--out", str(cmp_dir)]) == 0
    doc = json.loads((cmp_dir / "compare.json").read_text())
    for m in METHODS:
        assert _same(doc["methods"][m]["figures"]["coverage_frac"], expected[m]), (m, doc["methods"][m]["figures"])
    assert _same(doc["methods"]["paper"]["coverage_frac"], expected["paper"])

    drawn = []
    original = plots.plot_method_comparison

    def spy(table, path, *args, **kwargs):
        drawn.append(table)
        return original(table, path, *args, **kwargs)
    monkeypatch.setattr(plots, "plot_method_comparison", spy)
    write_report(root, tmp_path / "report")
    assert len(drawn) == 2, drawn  # the sweep's panel and the comparison's
    for table in drawn:
        for m in METHODS:
            assert _same(table[m]["coverage_frac"], expected[m]), (m, table[m])


def test_one_definition_for_every_kind(small_sample):
    """A map, a cloud and a mesh of the true plate each cover the plate's pixels by the one rule."""
    from platebench.bench.io.codecs import encode
    from platebench.bench.run.outputs import score_row
    from platebench.evaluation.field_scores import FieldTruth, score_depth, score_mesh, score_point_cloud
    s = small_sample[0]
    gl, gr = s.gt["left"], s.gt["right"]
    truth = FieldTruth.from_maps(s.scene.rig, gl.depth, gl.mask, gl.points, gr.depth, gr.mask, s.plate.mesh)
    plate = int(gl.mask.sum())
    depth = np.where(gl.mask, gl.depth, np.inf)
    depth[: depth.shape[0] // 2] = np.inf  # the upper half has no estimate
    want = np.count_nonzero(np.isfinite(depth) & gl.mask) / plate
    assert score_row(score_depth(depth, truth)).coverage_frac == want
    pts = gl.points[gl.mask].astype(np.float64)
    cloud = score_point_cloud(pts[::2], truth)
    uv = np.rint(s.scene.rig.left.project(pts[::2])).astype(int)
    hit = np.zeros_like(gl.mask)
    hit[uv[:, 1], uv[:, 0]] = True
    assert score_row(cloud).coverage_frac == np.count_nonzero(hit & gl.mask) / plate
    assert encode(cloud)["surface_coverage_frac"] == cloud.surface.surface_coverage_frac
    mesh = score_mesh(s.plate.mesh, truth)
    assert score_row(mesh).coverage_frac == mesh.coverage.estimated_px / plate
    assert mesh.coverage.estimated_px >= plate - mesh.coverage.plate_px // 100  # the true plate covers its pixels
