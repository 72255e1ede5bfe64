"""A compared method's error map is scored where its output is scored (``evaluation.error_maps``),
written beside the output (``bench.io.error_map_files``) and drawn by the report from that file alone:
a folder without it gives the "error map unavailable" figure, never a recomputation."""
from __future__ import annotations

import numpy as np
import pytest

from platebench.bench.report import plots as P

PNG_SIG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def tiny_sample_dir(tmp_path_factory):
    """The reference experiment at 160x120, spp 1, written."""
    from platebench.bench.config import SampleConfig, SceneParams
    from platebench.bench.io.sample_files import write_sample
    from platebench.bench.run.render import render_sample
    from platebench.scenes.scene_spec import RenderSettings
    rendered, _ = render_sample(SampleConfig(scene=SceneParams(width=160, height=120),
                                             render=RenderSettings(spp=1, seed=3)))
    return write_sample(tmp_path_factory.mktemp("samples") / "tiny", rendered)


def _drawn_notes(monkeypatch) -> list[str]:
    notes: list[str] = []
    real = P._empty

    def record(ax, text):
        notes.append(text)
        real(ax, text)
    monkeypatch.setattr(P, "_empty", record)
    return notes


def test_the_file_reads_back_what_was_written(tmp_path):
    from platebench.bench.io.error_map_files import StoredErrorMap, read_error_map, write_error_map
    from platebench.bench.io.images import DatasetError
    from platebench.evaluation.error_maps import depth_error_map

    truth = np.full((6, 8), 0.5)
    mask = np.zeros((6, 8), bool)
    mask[1:5, 2:7] = True
    z = np.where(mask, truth + 0.002, np.inf)
    z[2, 3] = np.nan  # a plate pixel without an estimate
    scored = depth_error_map(z, truth, mask)
    back = read_error_map(write_error_map(tmp_path / "error_map.npz", StoredErrorMap.of("depth", scored)))
    assert back.kind == "depth" and back.is_map and back.count == mask.sum() - 1 and back.plate_px == mask.sum()
    assert np.array_equal(back.plate, mask)
    assert np.array_equal(back.error_m, scored.error_m.astype(np.float32), equal_nan=True)
    assert back.median_m == scored.errors.median_m and back.rms_m == scored.errors.rms_m
    assert back.coverage_frac == scored.coverage_frac
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(DatasetError, match="bad.npz"):
        read_error_map(tmp_path / "bad.npz")
    with pytest.raises(DatasetError, match="missing"):
        read_error_map(tmp_path / "none.npz")


def test_a_depth_output_one_millimetre_off_is_one_millimetre_everywhere(tiny_sample_dir, tmp_path, monkeypatch):
    """A depth output equal to the truth + 1 mm: its folder's error map is what evaluation.error_maps
    gives for the written files, 1 mm on every plate pixel; the report draws it, and without the file
    says it is unavailable."""
    from platebench.bench.io.error_map_files import ERROR_MAP_FILE, read_error_map
    from platebench.bench.io.field_truth import load_field_truth
    from platebench.bench.io.method_outputs import read_depth
    from platebench.bench.run.outputs import write_error_map, write_output
    from platebench.evaluation.error_maps import depth_error_map
    from platebench.reconstruction.methods import Depth

    truth = load_field_truth(tiny_sample_dir)
    d = tmp_path / "recon" / "mine"
    d.mkdir(parents=True)
    write_output(d, Depth(np.where(truth.mask, truth.depth + 1e-3, np.inf)))
    assert write_error_map(d, "depth", truth) == d / ERROR_MAP_FILE
    m = read_error_map(d / ERROR_MAP_FILE)
    again = depth_error_map(read_depth(d / "depth.exr"), truth.depth, truth.mask)
    assert np.array_equal(m.error_m, again.error_m.astype(np.float32), equal_nan=True)
    assert np.array_equal(m.plate, truth.mask) and m.count == truth.mask.sum() and m.coverage_frac == 1.0
    on = m.error_m[truth.mask]
    assert np.allclose(on, 1e-3, atol=1e-6) and np.isnan(m.error_m[~truth.mask]).all()
    assert m.median_m == pytest.approx(1e-3, abs=1e-6) and m.rms_m == pytest.approx(1e-3, abs=1e-6)

    notes = _drawn_notes(monkeypatch)
    assert P.plot_output_error_map(tiny_sample_dir, d, tmp_path / "a.png").read_bytes()[:8] == PNG_SIG
    assert notes == []
    (d / ERROR_MAP_FILE).unlink()
    assert P.plot_output_error_map(tiny_sample_dir, d, tmp_path / "b.png").read_bytes()[:8] == PNG_SIG
    assert notes == [f"error map unavailable: {ERROR_MAP_FILE} missing"]


def test_a_plugins_and_a_peers_folders_hold_their_scored_error_maps(tiny_sample_dir, tmp_path):
    """A plug-in's point cloud and SGBM's disparity, run as a sweep runs them: each folder holds its error
    map, equal to evaluation.error_maps recomputed from the folder's output file."""
    from platebench.bench.io.error_map_files import ERROR_MAP_FILE, read_error_map
    from platebench.bench.io.field_truth import load_field_truth
    from platebench.bench.io.method_outputs import read_disparity, read_points
    from platebench.bench.run.methods import MethodContext, get_method
    from platebench.evaluation.error_maps import output_error_map

    truth = load_field_truth(tiny_sample_dir)
    for name, kind, out, read in (("tests.test_report:flat_cloud", "points", "points.ply", read_points),
                                  ("sgbm", "disparity", "disparity.pfm", read_disparity)):
        d = tmp_path / name.replace(":", "_")
        get_method(name).run(MethodContext(tiny_sample_dir, d, None, None))
        m = read_error_map(d / ERROR_MAP_FILE)
        again = output_error_map(kind, read(d / out), truth)
        assert m.kind == kind, name
        if kind == "points":
            assert np.array_equal(m.points_m, again.points) and np.array_equal(m.distance_m, again.distance_m)
        else:
            assert np.array_equal(m.error_m, again.error_m.astype(np.float32), equal_nan=True)
        assert (m.median_m, m.rms_m, m.count) == (again.errors.median_m, again.errors.rms_m, again.errors.count)


@pytest.mark.render
def test_a_sweeps_error_maps_are_checksummed_and_drawn(tmp_path):
    """A tiny sweep with SGBM: each sample's result.json lists the method's error map with its other files,
    and the report draws the map from it (no "unavailable" figure)."""
    import json

    from platebench.bench.io.error_map_files import ERROR_MAP_FILE
    from platebench.bench.io.outputs import file_sha256
    from platebench.bench.report.html import write_report
    from platebench.bench.sweep.executors import LocalExecutor, run_sweep
    from platebench.bench.sweep.spec import load_spec
    spec = tmp_path / "spec.toml"
    spec.write_text('[sweep]\nname = "maps"\nmethods = ["sgbm"]\n'
                    '[base.scene]\nwidth = 160\nheight = 120\n[base.render]\nspp = 1\n[grid]\nbend_deg = [0]\n')
    ds = tmp_path / "ds"
    assert run_sweep(load_spec(spec), ds, LocalExecutor(0), progress=False).ok == 1
    sample = ds / "samples" / "0000"
    files = json.loads((sample / "result.json").read_text())["files"]
    rel = f"recon/sgbm/{ERROR_MAP_FILE}"
    assert files[rel] == file_sha256(sample / rel)
    text = write_report(ds).read_text()
    assert "dataset_error_map_0000_sgbm" in text and "error map unavailable" not in text


def test_the_compare_figure_draws_the_maps_scored_with_the_outputs(tiny_sample_dir):
    """``compare``'s rows carry each dense output's error map, scored with it: the same statistics as the
    row's score (median, RMS, coverage over the plate's pixels), error NaN off the plate; the figure draws them."""
    from platebench.bench.run.compare import compare_sample

    cmp = compare_sample(tiny_sample_dir, ("sgbm", "graycode"))
    for row in cmp.rows:
        m, f = row.error_map, row.figures
        assert m is not None and m.error_m.shape == cmp.gt_mask.shape, row.name
        assert np.all(np.isnan(m.error_m[~cmp.gt_mask])), row.name
        assert m.errors.median_m * 1e3 == pytest.approx(f.depth_median_mm, rel=1e-9), row.name
        assert m.errors.rms_m * 1e3 == pytest.approx(f.depth_rms_mm, rel=1e-9), row.name
        assert m.coverage_frac == pytest.approx(f.coverage_frac, rel=1e-9), row.name
    assert P.compare_error_figure(cmp).startswith(PNG_SIG)


def test_a_disparity_map_and_its_score_count_the_same_estimates_whatever_doffs(tiny_sample_dir):
    """The error map of a disparity takes its estimates by the score's rule (``field_scores.implied_depth``:
    finite d > 0 with d + doffs > 0): with doffs != 0, a plate pixel of d <= 0 < d + doffs counts in
    neither, and the map's statistics are the score's."""
    import dataclasses

    from platebench.bench.io.field_truth import load_field_truth
    from platebench.evaluation.error_maps import output_error_map
    from platebench.evaluation.field_scores import score_disparity

    base = load_field_truth(tiny_sample_dir)
    for doffs in (-3.0, 3.0):
        truth = dataclasses.replace(base, pair=dataclasses.replace(base.pair, doffs_px=doffs))
        with np.errstate(divide="ignore"):
            d = np.where(truth.mask, truth.pair.fb / truth.depth - doffs, np.inf) * 1.001
        vs, us = np.nonzero(truth.mask)
        d[vs[::7], us[::7]] = -doffs / 2  # d < 0 < d + doffs, or d + doffs < 0 < d
        m, s = output_error_map("disparity", d, truth), score_disparity(d, truth)
        assert m.errors.count == s.depth.errors.count < truth.mask.sum(), doffs
        assert m.errors.median_m == pytest.approx(s.depth.errors.median_m, rel=1e-12), doffs
        assert m.errors.rms_m == pytest.approx(s.depth.errors.rms_m, rel=1e-12), doffs
        assert m.coverage_frac == pytest.approx(s.depth.coverage_frac, rel=1e-12), doffs


def test_the_report_imports_no_error_map_scoring():
    """The report draws the scored error maps and per-point errors: no module of bench/report imports
    evaluation.error_maps, the ground truth's loader or bench.run.score to score an output, in any
    import form (``import X``, ``from X import Y``, ``from X.Y import Z``)."""
    import ast
    from pathlib import Path

    banned = ("platebench.evaluation.error_maps", "platebench.bench.io.field_truth", "platebench.bench.run.score")

    def names(node) -> list[str]:
        if isinstance(node, ast.Import):
            return [a.name for a in node.names]
        if isinstance(node, ast.ImportFrom) and node.module:
            return [node.module] + [f"{node.module}.{a.name}" for a in node.names]
        return []

    report = Path(P.__file__).parent
    for path in sorted(report.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            for name in names(node):
                assert not any(name == b or name.startswith(b + ".") for b in banned), (path.name, name)
                assert "score_files" not in name.split("."), (path.name, name)


def test_where_the_report_looks_for_an_error_map(tmp_path):
    from platebench.bench.io.error_map_files import ERROR_MAP_FILE
    d = tmp_path / "recon"
    d.mkdir()
    assert P.output_error_map_file(d) == d / ERROR_MAP_FILE
    assert P.output_error_map_file(d / "disparity.pfm") == d / ERROR_MAP_FILE
    assert P.output_error_map_file(tmp_path / "disp0.score.json") == tmp_path / "disp0.error_map.npz"
    assert P.output_error_map_file(tmp_path / "x.error_map.npz") == tmp_path / "x.error_map.npz"
