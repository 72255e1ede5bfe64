"""Scoring any method's output (``platebench evaluate --disparity/--depth/--points/--mesh``) against
known answers built from a real rendered sample's exact ground truth.

* GT disparity + 0.5 px: avgerr 0.5 px exactly; with N(0, 0.2 px) noise on top, every Middlebury
  figure near its analytic value (bad-0.5 = 1/2 + Phi(-5), bad-1 = Phi(-2.5) + Phi(-7.5), ...).
* GT depth + N(0, sigma): depth RMS = sigma within 2 %, median |error| = 0.6745 sigma.
* GT points moved 1 mm along the true normal: 1 mm from the surface.
* The plate mesh offset 1 mm along its analytic normals: accuracy and completeness 1 mm.
* The non-occlusion mask agrees with ray casting against the plate mesh (trimesh/embree).

Files are written with code that isn't ours (numpy, OpenEXR, trimesh) and scored through the CLI.
"""
from __future__ import annotations

import json
import math

import numpy as np
import OpenEXR
import pytest
import trimesh
from scipy.special import ndtr  # standard normal CDF

from platebench.bench.cli.main import main
from platebench.bench.io.codecs import decode

pytestmark = pytest.mark.render


# ----------------------------------------------------------------------------- helpers (not ours)
def write_pfm(path, a):
    a = np.asarray(a, "<f4")
    path.write_bytes(f"Pf\n{a.shape[1]} {a.shape[0]}\n-1\n".encode() + np.flipud(a).tobytes())


def read_exr(path):
    ch = OpenEXR.File(str(path)).channels()
    return np.asarray(next(iter(ch.values())).pixels, np.float64)


def calib_fb(sample):
    """f * B in px * metres from the sample's calib.txt (Middlebury: baseline in mm)."""
    kv = dict(line.split("=", 1) for line in (sample / "calib.txt").read_text().splitlines() if "=" in line)
    f = float(kv["cam0"].strip("[]").split()[0])
    return f * float(kv["baseline"]) / 1e3, float(kv["doffs"])


def evaluate(capsys, sample, *args):
    code = main(["evaluate", str(sample), *map(str, args)])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


UNITS = ("_mm", "_px", "_pct", "_frac", "_count", "_mm2")


def assert_units(score: dict) -> None:
    """Every figure of a score JSON names its unit."""
    for k, v in score.items():
        if isinstance(v, dict):
            assert_units(v)
        else:
            assert k.endswith(UNITS), k


def truth(sample):
    z = read_exr(sample / "gt" / "left_depth.exr")
    mask = np.isfinite(z)
    return z, mask


# ----------------------------------------------------------------------------- disparity
def test_disparity_shifted_half_pixel_gives_avgerr_half_exactly(small_sample_dir):
    from platebench.bench.io.field_truth import load_field_truth
    from platebench.evaluation.field_scores import score_disparity
    t = load_field_truth(small_sample_dir)
    # the truth scored against is the file the user is given, bit for bit
    from platebench.bench.io.images import read_pfm
    assert np.array_equal(t.disparity, read_pfm(small_sample_dir / "gt" / "disp0GT.pfm").astype(np.float64))
    s = score_disparity(t.disparity + 0.5, t)  # the file's float32 truth + 0.5: every error is exactly 0.5 px
    for reg in (s.middlebury.all, s.middlebury.nonocc):
        assert reg.avgerr == 0.5 and reg.rms == 0.5 and reg.invalid_pct == 0.0
        assert dict(reg.bad_pct) == {0.5: 0.0, 1.0: 0.0, 2.0: 0.0, 4.0: 0.0}  # bad = error > T, strictly
        assert dict(reg.quantiles) == {50: 0.5, 90: 0.5, 95: 0.5, 99: 0.5}
    assert s.middlebury.all.gt_count == int(t.mask.sum()) > 10000
    # Implied depth: Z = f B / (d + 0.5) is nearer than the truth by Z^2 / (f B + 0.5 Z) * 0.5.
    z = t.depth[t.mask]
    expect = t.pair.fb / (t.disparity[t.mask] + 0.5 + t.pair.doffs_px) - z
    assert s.depth.errors.signed_mean_m == pytest.approx(expect.mean(), rel=1e-9)
    assert s.depth.coverage_frac == 1.0


def test_truth_file_plus_half_pixel_as_a_file_is_not_bad_at_half_pixel(small_sample_dir, tmp_path, capsys):
    """A user's file holding the sample's own disp0GT.pfm + 0.5 px (both float32, as the Middlebury SDK
    reads them): every error is exactly 0.5, which is not > 0.5: bad 0.5 = 0 % (the SDK gives the same)."""
    from platebench.bench.io.images import read_pfm, write_pfm
    gt = read_pfm(small_sample_dir / "gt" / "disp0GT.pfm")
    write_pfm(tmp_path / "d.pfm", np.where(np.isfinite(gt), gt + np.float32(0.5), np.inf).astype(np.float32))
    code, _, err = evaluate(capsys, small_sample_dir, "--disparity", tmp_path / "d.pfm")
    assert code == 0, err
    doc = json.loads((tmp_path / "d.score.json").read_text())["score"]["middlebury"]
    assert doc["mb_all_bad_0_5_pct"] == 0.0 and doc["mb_nonocc_bad_0_5_pct"] == 0.0
    assert doc["mb_all_avgerr_px"] == 0.5 and doc["mb_all_bad_1_0_pct"] == 0.0


def test_noisy_shifted_disparity_file_scores_near_analytic_values(small_sample_dir, tmp_path, capsys):
    z, mask = truth(small_sample_dir)
    fb, doffs = calib_fb(small_sample_dir)
    d_gt = np.where(mask, fb / z - doffs, np.inf)
    sigma, shift = 0.2, 0.5
    rng = np.random.default_rng(7)
    est = d_gt + shift + rng.normal(0.0, sigma, d_gt.shape)
    f = tmp_path / "disp0.pfm"
    write_pfm(f, np.where(mask, est, np.inf))
    code, out, err = evaluate(capsys, small_sample_dir, "--disparity", f, "--name", "noisy")
    assert code == 0, err
    doc = json.loads((tmp_path / "disp0.score.json").read_text())
    assert doc["method"] == "noisy" and doc["kind"] == "disparity"
    mb, eth = doc["score"]["middlebury"], doc["score"]["eth3d"]
    # |0.5 + n|, n ~ N(0, 0.2): analytic figures
    mu, s = shift, sigma
    avgerr = s * math.sqrt(2 / math.pi) * math.exp(-mu * mu / (2 * s * s)) + mu * (1 - 2 * ndtr(-mu / s))
    bad = {t: 100 * (ndtr((mu - t) / s) + ndtr((-mu - t) / s)) for t in (0.5, 1.0, 2.0)}
    for region in ("all", "nonocc"):
        assert mb[f"mb_{region}_avgerr_px"] == pytest.approx(avgerr, rel=0.01)
        assert mb[f"mb_{region}_rms_px"] == pytest.approx(math.sqrt(mu * mu + s * s), rel=0.01)
        assert mb[f"mb_{region}_bad_0_5_pct"] == pytest.approx(bad[0.5], abs=1.5)  # 50.0 %
        assert mb[f"mb_{region}_bad_1_0_pct"] == pytest.approx(bad[1.0], abs=0.3)  # 0.62 %
        assert mb[f"mb_{region}_bad_2_0_pct"] == 0.0 and mb[f"mb_{region}_invalid_pct"] == 0.0
        assert mb[f"mb_{region}_a50_px"] == pytest.approx(0.5, abs=0.02)
        assert eth[f"eth_{region}_coverage_frac"] == 1.0
        assert eth[f"eth_{region}_bad_1_0_pct"] == pytest.approx(mb[f"mb_{region}_bad_1_0_pct"])
    # the 10-degree plate is seen whole by both cameras
    assert doc["score"]["nonocc_px"] == int(mask.sum()) == mb["mb_nonocc_gt_count"]
    # implied depth, recomputed here from calib.txt
    zi = fb / (est[mask].astype(np.float32).astype(np.float64) + doffs)
    assert doc["score"]["depth_mean_signed_mm"] == pytest.approx(1e3 * np.mean(zi - z[mask]), rel=1e-6)
    assert doc["score"]["depth_rms_mm"] == pytest.approx(1e3 * np.sqrt(np.mean((zi - z[mask]) ** 2)), rel=1e-6)
    assert "middlebury nonocc" in out and "eth3d all" in out
    assert_units(doc["score"])


def test_kitti_style_png_disparity_with_scale(small_sample_dir, tmp_path, capsys):
    import cv2
    z, mask = truth(small_sample_dir)
    fb, doffs = calib_fb(small_sample_dir)
    d = np.where(mask, fb / np.where(mask, z, 1.0) - doffs, 0.0)
    png = tmp_path / "d.png"
    cv2.imwrite(str(png), np.rint(d * 256).astype(np.uint16))
    code, _, err = evaluate(capsys, small_sample_dir, "--disparity", png, "--disparity-scale", 256)
    assert code == 0, err
    mb = json.loads((tmp_path / "d.score.json").read_text())["score"]["middlebury"]
    assert mb["mb_all_avgerr_px"] <= 1 / 512 + 1e-9 and mb["mb_all_bad_0_5_pct"] == 0.0


# ----------------------------------------------------------------------------- depth
@pytest.mark.parametrize("fmt", ["npy", "exr", "pfm"])
def test_depth_with_gaussian_noise_gives_its_rms(small_sample_dir, tmp_path, capsys, fmt):
    z, mask = truth(small_sample_dir)
    sigma = 0.5e-3
    noisy = z + np.random.default_rng(3).normal(0.0, sigma, z.shape)
    f = tmp_path / f"depth.{fmt}"
    if fmt == "npy":
        np.save(f, noisy)
    elif fmt == "exr":
        OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                     {"Z": noisy.astype(np.float32)}).write(str(f))
    else:
        write_pfm(f, noisy)
    code, out, err = evaluate(capsys, small_sample_dir, "--depth", f)
    assert code == 0, err
    sc = json.loads((tmp_path / "depth.score.json").read_text())["score"]
    assert_units(sc)
    assert sc["depth_rms_mm"] == pytest.approx(sigma * 1e3, rel=0.02)
    assert sc["depth_median_mm"] == pytest.approx(0.6745 * sigma * 1e3, rel=0.03)  # median |N(0, s)|
    assert sc["depth_a95_mm"] == pytest.approx(1.96 * sigma * 1e3, rel=0.03)
    assert abs(sc["depth_mean_signed_mm"]) < 0.05 * sigma * 1e3
    assert sc["coverage_frac"] == 1.0 and sc["estimated_px"] == sc["plate_px"] == int(mask.sum())
    assert sc["off_plate_px"] == int((np.isfinite(noisy) & ~mask).sum()) == 0  # inf stays inf off the plate
    assert sc["depth_bad_1_0_mm_pct"] == pytest.approx(200 * ndtr(-2.0), abs=0.5)  # |e| > 2 sigma: 4.55 %


def test_half_covered_depth_map_and_off_plate_estimates(small_sample_dir, tmp_path, capsys):
    z, mask = truth(small_sample_dir)
    part = np.where(mask, z, 0.5)  # the ground gets a (wrong) estimate too
    part[:, : z.shape[1] // 2] = np.nan
    f = tmp_path / "z.npy"
    np.save(f, part)
    code, _, err = evaluate(capsys, small_sample_dir, "--depth", f)
    assert code == 0, err
    sc = json.loads((tmp_path / "z.score.json").read_text())["score"]
    assert sc["estimated_px"] == int(mask[:, z.shape[1] // 2:].sum())
    assert sc["coverage_frac"] == pytest.approx(sc["estimated_px"] / mask.sum())
    assert sc["off_plate_px"] == int((~mask[:, z.shape[1] // 2:]).sum())
    assert sc["depth_max_mm"] < 1e-3  # float32 EXR truth vs float64 here


# ----------------------------------------------------------------------------- points
def test_points_moved_one_mm_along_the_normal_are_one_mm_away(small_sample_dir, tmp_path, capsys):
    z, mask = truth(small_sample_dir)
    P = np.asarray(OpenEXR.File(str(small_sample_dir / "gt" / "left_points.exr")).channels()["RGB"].pixels,
                   np.float64)[mask]
    N = np.asarray(OpenEXR.File(str(small_sample_dir / "gt" / "left_normal.exr")).channels()["RGB"].pixels,
                   np.float64)[mask]
    moved = P + 1e-3 * N / np.linalg.norm(N, axis=1, keepdims=True)
    far = np.zeros(len(moved), bool)
    far[::20] = True  # 5 % pushed 10 mm out: outliers
    moved[far] = P[far] + 10e-3 * N[far]
    f = tmp_path / "cloud.ply"
    trimesh.PointCloud(moved).export(f)
    code, out, err = evaluate(capsys, small_sample_dir, "--points", f)
    assert code == 0, err
    sc = json.loads((tmp_path / "cloud.score.json").read_text())["score"]
    assert_units(sc)
    assert sc["dist_median_mm"] == pytest.approx(1.0, abs=2e-3)
    assert sc["outlier_count"] == int(far.sum()) and sc["outlier_frac"] == pytest.approx(far.mean())
    assert sc["dist_max_mm"] == pytest.approx(10.0, abs=2e-3)
    assert sc["coverage_frac"] > 0.95 and sc["surface_coverage_frac"] > 0.95 and sc["points_count"] == len(moved)
    # without the outliers, through CSV: every point 1 mm away
    csv = tmp_path / "pts.csv"
    np.savetxt(csv, P[~far] + 1e-3 * N[~far], delimiter=",", header="x,y,z", comments="")
    code, _, err = evaluate(capsys, small_sample_dir, "--points", csv, "--outlier-mm", 0.5)
    assert code == 0, err
    sc = json.loads((tmp_path / "pts.score.json").read_text())["score"]
    for k in ("dist_mean_mm", "dist_median_mm", "dist_rms_mm", "dist_max_mm", "dist_a99_mm"):
        assert sc[k] == pytest.approx(1.0, abs=2e-3), k
    # every point is an outlier at 0.5 mm: none covers the plate's surface, yet they land on its pixels
    assert sc["outlier_frac"] == 1.0 and sc["surface_coverage_frac"] == 0.0 and sc["coverage_frac"] > 0.5


# ----------------------------------------------------------------------------- mesh
def test_mesh_offset_one_mm_has_accuracy_and_completeness_one_mm(small_sample_dir, tmp_path, capsys):
    from platebench.plates import PlateSpec, build_plate
    meta = json.loads((small_sample_dir / "sample.json").read_text())
    plate = build_plate(decode(PlateSpec, meta["config"]["plate"]))
    top = plate.top_vertices
    verts = plate.mesh.vertices[top] + 1e-3 * plate.surface_normal(plate.mesh_uv[top])  # exact offset surface
    faces = plate.mesh.faces[plate.top_faces]
    f = tmp_path / "offset.ply"
    trimesh.Trimesh(verts, faces, process=False).export(f)
    code, out, err = evaluate(capsys, small_sample_dir, "--mesh", f)
    assert code == 0, err
    sc = json.loads((tmp_path / "offset.score.json").read_text())["score"]
    assert_units(sc)
    for side in ("accuracy", "completeness"):
        for stat in ("mean", "median", "rms", "max"):
            assert sc[f"{side}_{stat}_mm"] == pytest.approx(1.0, abs=2e-3), (side, stat)
    assert sc["overall_mm"] == pytest.approx(1.0, abs=2e-3)
    assert sc["fscore_2_0_mm_pct"] == 100.0 and sc["fscore_0_5_mm_pct"] == 0.0
    # half the plate: precision stays, recall (completeness) halves
    keep = plate.mesh.vertices[faces].mean(axis=1)[:, 0] > 0  # faces with x > 0
    half = tmp_path / "half.ply"
    trimesh.Trimesh(verts, faces[keep], process=False).export(half)
    code, _, err = evaluate(capsys, small_sample_dir, "--mesh", half)
    assert code == 0, err
    sc = json.loads((tmp_path / "half.score.json").read_text())["score"]
    assert sc["precision_2_0_mm_pct"] == 100.0 and sc["recall_2_0_mm_pct"] == pytest.approx(50.0, abs=3.0)
    assert sc["completeness_max_mm"] > 50.0  # the far end of the plate


# ----------------------------------------------------------------------------- errors
def test_bad_outputs_are_one_line_errors_and_write_nothing(small_sample_dir, tmp_path, capsys):
    import cv2
    z, mask = truth(small_sample_dir)
    H, W = z.shape
    small = tmp_path / "small.pfm"
    write_pfm(small, np.ones((H // 2, W // 2)))
    nan = tmp_path / "nan.pfm"
    write_pfm(nan, np.full((H, W), np.nan))
    tif = tmp_path / "d.tif"
    tif.write_bytes(b"II*\0")
    png8 = tmp_path / "d8.png"
    cv2.imwrite(str(png8), np.ones((H, W), np.uint8))
    nanpts = tmp_path / "p.npy"
    np.save(nanpts, np.full((5, 3), np.nan))
    cases = [
        (("--disparity", small), f"does not match the sample's left image {W}x{H}"),
        (("--disparity", nan), "no finite value > 0"),
        (("--depth", nan), "no finite value > 0"),
        (("--disparity", tif), "unknown format '.tif'"),
        (("--mesh", tif), "unknown format '.tif' for a mesh file: allowed .ply"),
        (("--disparity", png8, "--disparity-scale", 256), "must be single-channel 16-bit"),
        (("--disparity", png8), "needs --disparity-scale"),
        (("--points", nanpts), "no finite point"),
        (("--depth", small, "--points", nanpts), "give exactly one of"),
        ((), "give exactly one of"),
        (("--depth", small, "--outlier-mm", 1), "--outlier-mm goes with --points"),
        (("--points", nanpts, "--radius-mm", 0), "--radius-mm = 0.0 is out of range"),
        (("--depth", tmp_path / "missing.npy"), "missing.npy: file is missing"),
    ]
    for args, needle in cases:
        code, out, err = evaluate(capsys, small_sample_dir, *args)
        lines = err.strip().splitlines()
        assert code == 2 and len(lines) == 1 and lines[0].startswith("platebench: error:"), (args, err)
        assert needle in lines[0], (needle, lines[0])
    assert not list(tmp_path.glob("*.score.json"))


# ----------------------------------------------------------------------------- non-occlusion
def test_nonocclusion_mask_agrees_with_ray_casting(tmp_path):
    """A plate bent 200 degrees across the baseline (a U whose rims lean inward): the right camera
    cannot see part of what the left one sees. The mask from the left/right check of the ground-truth
    maps matches rays cast from the right camera at the true points, up to one pixel along the
    visibility edges."""
    import scipy.ndimage as ndi

    from platebench.bench.config import SampleConfig, SceneParams
    from platebench.bench.config.sample_config import with_overrides
    from platebench.bench.run.render import render_sample
    from platebench.evaluation.field_scores import FieldTruth
    from platebench.scenes.scene_spec import RenderSettings
    cfg = with_overrides(SampleConfig(scene=SceneParams(width=240, height=180), render=RenderSettings(spp=1, seed=1)),
                         bend_deg=200, bend_direction="up", bend_axis_deg=90)
    s, _ = render_sample(cfg)
    gl, gr, rig = s.gt["left"], s.gt["right"], s.scene.rig
    t = FieldTruth.from_maps(rig, gl.depth, gl.mask, gl.points, gr.depth, gr.mask, s.plate.mesh)
    vv, uu = np.nonzero(gl.mask)
    P = gl.points[vv, uu].astype(np.float64)
    C = rig.right.center
    d = P - C
    dist = np.linalg.norm(d, axis=1)
    d /= dist[:, None]
    locs, ray, _ = s.plate.mesh.ray.intersects_location(np.repeat(C[None], len(d), 0), d, multiple_hits=True)
    hit = np.einsum("ij,ij->i", locs - C, d[ray])
    blocked = np.zeros(len(d), bool)
    blocked[ray[hit < dist[ray] - 2e-4]] = True
    seen = np.zeros(gl.mask.shape, bool)
    seen[vv, uu] = rig.right.in_image(rig.right.project(P)) & ~blocked
    assert (~seen & gl.mask).sum() > 100  # a real occlusion
    assert not (t.nonocc & ~gl.mask).any()
    edges = gl.mask & ((seen != ndi.binary_erosion(seen, border_value=1)) | (seen != ndi.binary_dilation(seen)))
    band = ndi.binary_dilation(edges, iterations=1)
    disagree = (t.nonocc != seen) & gl.mask
    assert not (disagree & ~band).any()
    assert disagree.sum() <= 0.1 * gl.mask.sum()  # a column or two along each edge (rows repeat here)
    # The true right disparity at a seen point's match brackets its left one (the right view's pixels
    # on either side of the match lie on the same surface; at the right silhouette, where a rim is
    # seen edge-on, one side is off the plate; near a contour the surface folds within a pixel, hence
    # the occlusion test's half-pixel slack).
    ok = t.nonocc[vv, uu]
    d0 = t.disparity[vv, uu][ok]
    ur = uu[ok] - d0
    W = gl.mask.shape[1]
    a = t.disparity_right[vv[ok], np.clip(np.floor(ur).astype(int), 0, W - 1)]
    b = t.disparity_right[vv[ok], np.clip(np.ceil(ur).astype(int), 0, W - 1)]
    both = np.isfinite(a) & np.isfinite(b)
    inside = (np.minimum(a, b) - 0.5 <= d0) & (d0 <= np.maximum(a, b) + 0.5)
    assert both.mean() > 0.8 and inside[both].mean() > 0.99


def test_every_column_of_every_kind_has_a_label_of_its_own(small_sample_dir):
    """Every results column the four kinds produce is a shared field or of a known family, and its label
    is words, not a mangled name ("depth bad 0 1 mm", "mb all bad 1 0")."""
    import re

    from platebench.bench.io.field_truth import load_field_truth
    from platebench.bench.run.outputs import score_row
    from platebench.evaluation.field_scores import score_depth, score_disparity, score_mesh, score_point_cloud
    from platebench.evaluation.metrics_row import METRIC_FIELDS, is_metric, metric_label
    t = load_field_truth(small_sample_dir)
    mesh = trimesh.load(small_sample_dir / "plate.ply", process=False, force="mesh")
    scores = [score_disparity(t.disparity + 0.2, t), score_depth(t.depth + 1e-4, t),
              score_point_cloud(trimesh.sample.sample_surface(mesh, 500, seed=0)[0], t), score_mesh(mesh, t)]
    names = {k for s in scores for k in score_row(s).columns()} | {"method_lit_px"}
    assert len(names) > 80
    unknown = sorted(n for n in names if not is_metric(n))
    assert not unknown, unknown
    for n in names:
        label = metric_label(n)
        assert not re.search(r"\d \d|\b(mb|eth|pct|frac)\b", label), (n, label)
        assert n in METRIC_FIELDS or "_" not in label.split("'")[0], (n, label)
