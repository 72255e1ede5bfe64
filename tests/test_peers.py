"""Peer methods: Gray code (OpenCV decode and sub-pixel), phase shifting, SGBM, and ``platebench compare``.

Pure tests check the decoders on the projector's own frames and on synthetic shifts;
render tests use real 320 x 240 renders (f scaled to keep the reference field of view)
of the reference plate and score against the exact ground truth.
"""
from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from platebench.reconstruction.peers.graycode import (
    DenseResult,
    RowProfile,
    decode_columns,
    decode_opencv,
    decode_subpixel,
    graycode_sequence,
    match_columns_along_rows,
    profile_from_column_map,
)
from platebench.reconstruction.peers.phase_shift import (
    OPENCV_FINDINGS,
    decode_phase_columns,
    decode_phase_shift,
    phase_shift_sequence,
)
from platebench.reconstruction.peers.sgbm import (
    default_depth_range,
    disparity_range,
    sgbm,
)

W, H = 320, 240


def _rig(width=W, height=H):
    from platebench.scenes.scene_spec import reference_scene
    return reference_scene(width=width, height=height, f_px=2000.0 * width / 1280).rig


# ----------------------------------------------------------------------------- pure
def test_graycode_sequence_decodes_its_own_columns():
    seq = graycode_sequence(1024, 768)
    assert seq.n_images == 42 and seq.images.dtype == np.uint8 and seq.images.shape[1:] == (768, 1024)
    assert seq.n_col_planes == 10 and (seq.black, seq.white) == (40, 41)
    assert seq.images[seq.black].max() == 0 and seq.images[seq.white].min() == 255
    cols = np.arange(1024)[None, :]
    assert np.array_equal(decode_columns(seq.images, seq).code, np.broadcast_to(cols, (768, 1024)))
    sub = seq.columns_only()
    assert sub.n_images == 22
    dec = decode_columns(sub.images, sub, dropped=3)
    assert np.array_equal(dec.code, np.broadcast_to(cols // 8, (768, 1024)))


def _shifted_captures(seq, offset, cam_w):
    """Camera pixel x sees projector column x - offset (rows identical): a fronto-parallel plane."""
    out = np.zeros((seq.n_images, seq.proj_height, cam_w), np.uint8)
    out[:, :, offset:offset + seq.proj_width] = seq.images
    return out


def test_opencv_decode_sign_and_scale_on_synthetic_shift():
    seq = graycode_sequence(64, 32)
    rig = _rig(96, 32)
    left, right = _shifted_captures(seq, 9, 96), _shifted_captures(seq, 2, 96)
    res = decode_opencv(left, right, seq, rig)
    assert isinstance(res, DenseResult)
    d = res.disparity[:, 9:9 + 64]
    assert np.all(d == 7.0)  # u_left - u_right for the same projector column
    assert np.isnan(res.disparity[:, :9]).all()
    assert res.points.shape == (int(res.valid.sum()), 3)
    with pytest.raises(TypeError, match="8-bit"):
        decode_opencv(left.astype(np.float32), right, seq, rig)


def test_subpixel_decode_on_synthetic_shift():
    seq = graycode_sequence(64, 32).columns_only()
    rig = _rig(96, 32)
    left, right = _shifted_captures(seq, 9, 96), _shifted_captures(seq, 2, 96)
    res = decode_subpixel(left, right, seq, rig)
    assert res.n_images == 2 * 6 + 2
    assert res.valid.sum() > 0.9 * 32 * 62
    np.testing.assert_allclose(res.disparity[res.valid], 7.0, atol=1e-6)


def test_match_columns_along_rows_interpolates_and_rejects_spikes():
    u = np.arange(50, dtype=float)
    col_l = np.tile(2.0 * u + 0.3, (3, 1))
    col_r = np.tile(2.0 * (u + 10) + 0.3, (3, 1))  # the same column sits 10 px further left on the right
    col_r[1, 20] += 16.0  # a phase-order error in the right image
    col_r[2, :] = np.nan
    ur = match_columns_along_rows(col_l, profile_from_column_map(col_r), max_step=8.0)
    d = u[None, :] - ur
    ok = np.isfinite(d)
    np.testing.assert_allclose(d[ok], 10.0, atol=1e-9)
    assert ok[0].sum() >= 39 and ok[1].sum() >= 36 and not ok[2].any()
    empty = RowProfile(np.zeros(0, int), np.zeros(0), np.zeros(0), np.zeros(0, int))
    assert np.isnan(match_columns_along_rows(col_l, empty)).all()


@pytest.mark.parametrize("backend", ["numpy", "opencv"])
def test_phase_sequence_decodes_its_own_columns(backend):
    seq = phase_shift_sequence(1024, 768, period_px=16, backend=backend)
    assert seq.n_images == (4 if backend == "numpy" else 3) + 7
    col, B = decode_phase_columns(seq.images[:, 300:364, :], seq, min_modulation=8.0)
    j = np.arange(1024)[None, :]
    inner = (slice(8, -8), slice(32, -32))  # OpenCV's Fourier filtering rings at the image border
    err = np.abs(col - j)[inner]
    tol = 0.05 if backend == "numpy" else 0.2
    assert np.nanmax(err) < tol and np.isfinite(err).all()


def test_sgbm_range_and_input_checks():
    rig = _rig()
    zmin, zmax = default_depth_range(rig)
    assert zmin == pytest.approx(0.34) and zmax == pytest.approx(0.46)
    dmin, n = disparity_range(rig, (zmin, zmax))
    fb = rig.left.f_px * rig.baseline_m
    assert n % 16 == 0 and dmin <= fb / zmax and dmin + n >= fb / zmin
    with pytest.raises(TypeError):
        sgbm(np.zeros((H, W), np.float32), np.zeros((H, W), np.float32), rig)
    with pytest.raises(ValueError):
        disparity_range(rig, (0.5, 0.4))


_SINUS_PROBE = r"""
import cv2, numpy as np, json
sl = cv2.structured_light
p = sl.SinusoidalPattern.Params(); p.width, p.height, p.nbrOfPeriods, p.methodId = 256, 64, 16, sl.PSP
sp = sl.SinusoidalPattern.create(p)
ok, pats = sp.generate()
imgs = [np.ascontiguousarray(x) for x in pats]
wrapped, mask = sp.computePhaseMap(imgs)
ok2, disp = sp.decode([imgs, imgs])
matches = sp.findProCamMatches(wrapped, wrapped)
print(json.dumps({"frames": len(pats), "phase": wrapped is not None and wrapped.shape == (64, 256),
                  "decode_map": disp is not None, "matches": len(matches)}))
"""


def test_opencv_sinusoidal_findings_still_hold():
    """What OPENCV_FINDINGS records, checked in a subprocess (a crash must not take pytest down)."""
    r = subprocess.run([sys.executable, "-c", _SINUS_PROBE], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, f"OpenCV SinusoidalPattern probe crashed (rc {r.returncode}): {r.stderr[-400:]}"
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert got == {"frames": 3, "phase": True, "decode_map": False, "matches": 0}, (
        f"OpenCV's SinusoidalPattern changed: {got}; update OPENCV_FINDINGS: {OPENCV_FINDINGS[0]}")


# ----------------------------------------------------------------------------- renders
def _score(res, gt):
    est = res.valid & gt.mask
    err = np.abs(res.depth[est].astype(np.float64) - gt.depth64[est]) * 1e3
    return float(np.median(err)), float(np.sqrt(np.mean(err ** 2))), est.sum() / gt.mask.sum()


def _cfg(bend_deg, spp=8):
    from platebench.bench.config import SampleConfig, SceneParams, with_overrides
    from platebench.scenes.scene_spec import RenderSettings
    cfg = SampleConfig(scene=SceneParams(width=W, height=H), render=RenderSettings(spp=spp))
    return with_overrides(cfg, bend_deg=bend_deg)


@pytest.fixture(scope="module")
def bent():
    """10-degree reference plate at 320 x 240, spp 8: sample, renderer and the 42 Gray-code frames."""
    from platebench.bench.run.pattern_sequences import render_pattern_sequence
    from platebench.bench.run.render import render_sample
    cfg = _cfg(10.0)
    sample, renderer = render_sample(cfg)
    seq = graycode_sequence()
    builds = renderer.scene_builds
    cap = render_pattern_sequence(renderer, seq.images, cfg.render, cfg.sensor, name="graycode")
    assert renderer.scene_builds == builds  # pattern swaps are parameter updates
    return dict(cfg=cfg, sample=sample, renderer=renderer, seq=seq, cap=cap)


@pytest.mark.render
def test_pattern_sequence_stacks_and_determinism(bent):
    from platebench.bench.run.pattern_sequences import render_pattern_sequence
    cap, seq = bent["cap"], bent["seq"]
    for cam in ("left", "right"):
        assert cap[cam].shape == (42, H, W) and cap[cam].dtype == np.uint8
    g = bent["sample"].gt["left"]
    white, black = cap["left"][seq.white], cap["left"][seq.black]
    assert np.median(white[g.mask]) > 100 and np.median(black[g.mask]) < 10
    # Frame 0 of a new sequence gets frame 0's seeds: the same bytes again.
    first = render_pattern_sequence(bent["renderer"], seq.images[[0]], bent["cfg"].render, bent["cfg"].sensor)
    assert np.array_equal(first["left"][0], cap["left"][0])
    assert not np.array_equal(cap["left"][0], cap["left"][1])
    assert bent["renderer"].spec is bent["sample"].scene  # the sample's square pattern is back


@pytest.mark.render
def test_graycode_subpixel_depth_on_bent_plate(bent):
    seq, cap, s = bent["seq"], bent["cap"], bent["sample"]
    cols = seq.columns_only()
    idx = [i for p in seq.col_pairs for i in p] + [seq.black, seq.white]
    res = decode_subpixel(cap["left"][idx], cap["right"][idx], cols, s.scene.rig)
    med, rms, cov = _score(res, s.gt["left"])
    assert res.n_images == 22
    assert med < 0.5 and rms < 0.8, (med, rms)  # 1 px of disparity is 3.2 mm here
    assert cov > 0.8, cov
    assert res.points.shape == (int(res.valid.sum()), 3)


@pytest.mark.render
def test_numpy_column_decode_matches_opencv_getprojpixel(bent):
    import cv2
    seq, cap = bent["seq"], bent["cap"]
    left = cap["left"]
    dec = decode_columns(left, seq, white_threshold=5)
    gp = cv2.structured_light.GrayCodePattern.create(1024, 768)
    frames = [np.ascontiguousarray(left[i]) for i in range(40)]
    vs, us = np.nonzero(bent["sample"].gt["left"].mask)
    pick = np.random.default_rng(0).choice(len(vs), 150, replace=False)
    checked = 0
    for v, u in zip(vs[pick], us[pick]):
        err, (x, _y) = gp.getProjPixel(frames, int(u), int(v))
        if not err:
            assert dec.valid[v, u] and dec.code[v, u] == x
            checked += 1
    assert checked >= 10


@pytest.mark.render
def test_opencv_decode_agrees_roughly_and_sgbm_is_worse(bent):
    from platebench.bench.io.codecs import encode
    from platebench.evaluation.disparity_metrics import (
        eth3d_metrics,
        middlebury_metrics,
    )
    seq, cap, s = bent["seq"], bent["cap"], bent["sample"]
    rig, gt = s.scene.rig, s.gt["left"]
    cv_res = decode_opencv(cap["left"], cap["right"], seq, rig)
    idx = [i for p in seq.col_pairs for i in p] + [seq.black, seq.white]
    sub = decode_subpixel(cap["left"][idx], cap["right"][idx], seq.columns_only(), rig)
    med, rms, cov = _score(cv_res, gt)
    assert cov > 0.01 and med < 1.0, (med, cov)
    both = cv_res.valid & sub.valid
    assert both.sum() > 50
    assert np.median(np.abs(cv_res.disparity[both] - sub.disparity[both])) < 0.5
    sg = sgbm(s.digital["left_passive"], s.digital["right_passive"], rig)
    gt_disp = np.where(gt.mask, rig.disparity(gt.depth64), np.inf)
    scores = {}
    for name, r in (("sgbm", sg), ("sub", sub)):
        d = np.where(r.valid, r.disparity, np.inf)
        scores[name] = {**encode(middlebury_metrics(d, gt_disp)), **encode(eth3d_metrics(d, gt_disp))}
    for key in ("mb_all_bad_0_5_pct", "mb_all_bad_1_0_pct", "mb_all_bad_2_0_pct", "mb_all_invalid_pct",
                "mb_all_avgerr_px", "eth_all_coverage_frac", "eth_all_bad_1_0_pct", "eth_all_rms_px"):
        assert key in scores["sgbm"] and np.isfinite(scores["sgbm"][key]), key
    for key in ("mb_all_bad_0_5_pct", "mb_all_bad_1_0_pct", "eth_all_bad_1_0_pct"):
        assert scores["sgbm"][key] > scores["sub"][key], (key, scores["sgbm"][key], scores["sub"][key])


@pytest.mark.render
def test_phase_shift_sub_mm_on_flat_plate(bent):
    from platebench.bench.run.pattern_sequences import render_pattern_sequence
    from platebench.bench.run.render import render_sample
    cfg = _cfg(0.0)
    s, renderer = render_sample(cfg, renderer=bent["renderer"])
    try:
        seq = phase_shift_sequence()
        cap = render_pattern_sequence(renderer, seq.images, cfg.render, cfg.sensor, name="phase")
        res = decode_phase_shift(cap["left"], cap["right"], seq, s.scene.rig)
        med, rms, cov = _score(res, s.gt["left"])
        assert res.n_images == 11
        assert med < 0.5 and rms < 1.0, (med, rms)
        assert cov > 0.8, cov
    finally:  # give the shared renderer its bent plate back
        renderer.set_scene(bent["sample"].scene)
        renderer.set_plate(bent["sample"].plate)


@pytest.mark.render
def test_compare_command_end_to_end(bent, tmp_path, capsys):
    from platebench.bench.cli import compare as cmd_compare
    from platebench.bench.cli.main import main
    from platebench.bench.io.sample_files import write_sample
    from platebench.bench.run.outputs import score_row
    s = bent["sample"]
    sample_dir = write_sample(tmp_path / "s", s)
    # Dense peers through the Python entry point, reusing the compiled renderer.
    cmp = cmd_compare.compare_sample(sample_dir, ("graycode-subpx", "sgbm", "paper"), spp=4,
                                     renderer=bent["renderer"])
    names = [r.name for r in cmp.rows]
    assert names == ["graycode-subpx", "sgbm"]
    assert any("paper row left out" in n for n in cmp.notes)
    assert cmp.scene_reproduced is True
    sub, sg = cmp.rows
    assert sub.figures.depth_median_mm < 1.0 and sub.figures.coverage_frac > 0.8
    assert sg.figures.mb_all_bad_1_0_pct > sub.figures.mb_all_bad_1_0_pct
    # typed scores, non-occluded region included (the 10-degree plate is seen whole by both cameras)
    assert sub.score.middlebury.nonocc.gt_count == sub.score.middlebury.all.gt_count > 1000
    row = score_row(sub.score).columns()  # what a sweep's results table gets
    assert row["mb_nonocc_bad_1_0_pct"] == dict(sub.score.middlebury.nonocc.bad_pct)[1.0]
    assert row["coverage_frac"] == sub.figures.coverage_frac and row["mb_all_bad_1_0_pct"] == sub.figures.mb_all_bad_1_0_pct
    # The paper row: points.csv from a reconstruction (here: true plate points), CLI without renders.
    recon = tmp_path / "recon"
    recon.mkdir()
    g = s.gt["left"]
    pts = g.points[g.mask][::500].astype(np.float64)
    np.savetxt(recon / "points.csv", pts, delimiter=",", header="x_m,y_m,z_m", comments="")
    (recon / "recon.json").write_text(json.dumps({"n_images": 2, "timings_s": {"total_s": 0.1}}))
    out = tmp_path / "cmp"
    assert main(["compare", str(sample_dir), "--methods", "paper,sgbm", "--recon", str(recon),
                 "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "paper" in text and "sgbm" in text
    doc = json.loads((out / "compare.json").read_text())
    assert set(doc["methods"]) == {"paper", "sgbm"}
    assert doc["methods"]["paper"]["centres_depth_median_mm"] < 0.01  # the square centres: sparse
    assert "depth_median_mm" not in doc["methods"]["paper"]  # no figure over the plate's pixels for the paper
    assert doc["methods"]["sgbm"]["n_images"] == 1
    from platebench.bench.report.experiment import _COMPARE_COLUMNS, compare_section
    from platebench.bench.report.page import Page
    from tests.test_records import table_cells_not_shown
    (tmp_path / "report").mkdir()
    page = Page(tmp_path / "report", tmp_path / "report", tmp_path)
    sec = compare_section(page, out / "compare.json", "c_")  # the report shows what it holds
    cols = dict((label, key) for key, label in _COMPARE_COLUMNS)
    figs = [m["figures"] for m in doc["methods"].values()]
    assert {"centres_depth_median_mm", "depth_rms_mm", "coverage_frac", "mb_all_bad_1_0_pct"} <= \
        {cols[c] for c in sec["table"]["columns"][1:]}
    assert not table_cells_not_shown(sec["table"]["columns"][1:], [r[1:] for r in sec["table"]["rows"]], figs,
                                     [cols[c] for c in sec["table"]["columns"][1:]])
    assert (out / "compare.png").stat().st_size > 1000
    capsys.readouterr()
    assert main(["compare", str(sample_dir), "--methods", "nonsense"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown method 'nonsense': choose from paper, graycode" in err[0]
    assert "or module:function" in err[0]


@pytest.mark.render
def test_peers_that_render_their_own_patterns_run_on_a_pair_a_robot_took(tmp_path):
    """A 1995-rig sample (robot-posed cameras, estimated calibration): the re-created scene is the one
    the sample was taken with (its left passive image byte for byte), and the phase-shift peer decodes
    it through the told calibration, with depth errors of the rig's order (millimetres), not a failure."""
    from platebench.bench.run.compare import compare_sample
    from tests.conftest import run_cli
    r = run_cli("render", "--out", tmp_path / "s", "--realism", "1995", "--realism-seed", "3", "--spp", "1",
                "--bend-deg", "30")
    assert r.returncode == 0, r.stderr
    cmp = compare_sample(tmp_path / "s", ("phase",))
    assert not any("differs" in n for n in cmp.notes), cmp.notes
    row = next(x for x in cmp.rows if x.name == "phase")
    f = row.figures
    assert row.output is not None and f.coverage_frac > 0.8, (row.notes, f)
    assert 0.05 < f.error_rms_mm < 30.0, f


@pytest.mark.render
@pytest.mark.parametrize("method", ["sgbm", "sgbm-passive"])
def test_sgbm_search_beyond_the_images_is_refused_for_either_pair(bent, tmp_path, capsys, method):
    """Both registered SGBM methods get the search-range check before any work: one line, exit status 2."""
    from platebench.bench.cli.main import main
    from platebench.bench.io.sample_files import write_sample
    sample_dir = write_sample(tmp_path / "s", bent["sample"])
    out = tmp_path / "cmp"
    assert main(["compare", str(sample_dir), "--methods", method, "--min-depth-mm", "20", "--max-depth-mm", "2000",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{method}: --min-depth-mm 20 to --max-depth-mm 2000 asks for disparities" in err[0], err
    assert not out.exists()


@pytest.mark.render
def test_the_paper_row_refuses_a_reconstruction_of_another_sample(bent, tmp_path):
    """``compare_sample`` (the Python API) scores the paper row only from a reconstruction made from the
    sample (``bench.run.score.check_made_from``), as the CLI does."""
    from platebench.bench.io.images import DatasetError
    from platebench.bench.io.sample_files import write_sample
    from platebench.bench.run.compare import compare_sample
    sample_dir = write_sample(tmp_path / "s", bent["sample"])
    recon = tmp_path / "recon"
    recon.mkdir()
    np.savetxt(recon / "points.csv", np.zeros((1, 3)), delimiter=",", header="x_m,y_m,z_m", comments="")
    (recon / "recon.json").write_text(json.dumps({"n_images": 2, "input_checksums": {"left_active": "0" * 64}}))
    with pytest.raises(DatasetError, match=r"was not made from .*: image left_active differs"):
        compare_sample(sample_dir, ("paper",), recon_dir=recon)
    (recon / "recon.json").write_text(json.dumps({"n_images": 2}))  # nothing recorded: nothing to refuse
    assert [r.name for r in compare_sample(sample_dir, ("paper",), recon_dir=recon).rows] == ["paper"]
