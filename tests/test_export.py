"""``platebench export`` and ``PlateBenchDataset``: the Middlebury and KITTI layouts, read back by code
that isn't ours (a PFM and calib.txt reader written here, OpenCV's PFM reader, the OpenEXR package
for the truth), and the depth they imply against the sample's exact ground truth."""
from __future__ import annotations

import json
import math
import re

import cv2
import numpy as np
import OpenEXR
import pytest

from platebench.bench.cli.main import main

pytestmark = pytest.mark.render


# ----------------------------------------------------------------------------- readers written here
def read_pfm(path):
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = (int(x) for x in f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), "<f4" if scale < 0 else ">f4")
    assert kind == b"Pf"
    return np.flipud(data.reshape(h, w)).astype(np.float64)


def read_calib(path):
    out = {}
    for line in path.read_text().splitlines():
        k, v = line.split("=", 1)
        if v.startswith("["):
            out[k] = np.array([[float(x) for x in row.split()] for row in v.strip("[]").split(";")])
        else:
            out[k] = float(v)
    return out


def gt_depth(sample):
    ch = OpenEXR.File(str(sample / "gt" / "left_depth.exr")).channels()
    return np.asarray(ch["Y"].pixels, np.float64)


def export(capsys, *args):
    code = main(["export", *map(str, args)])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


# ----------------------------------------------------------------------------- tests
def test_sample_calib_txt_has_tight_range_and_rectification_figures(small_sample_dir):
    c = read_calib(small_sample_dir / "calib.txt")
    d = read_pfm(small_sample_dir / "gt" / "disp0GT.pfm")
    known = d[np.isfinite(d)]
    assert c["vmin"] == math.floor(known.min()) and c["vmax"] == math.ceil(known.max())
    assert c["vmax"] - c["vmin"] <= 3  # a 10-degree plate at 0.4 m: about 187 to 188 px here
    assert c["ndisp"] > c["vmax"] and c["ndisp"] % 16 == 0
    assert c["dyavg"] == 0 and c["dymax"] == 0


@pytest.mark.parametrize("shift, images", [("0", []), ("auto", ["--images", "active"])])
def test_middlebury_export_is_read_by_other_code_and_gives_back_the_depth(small_sample_dir, tmp_path, capsys, shift,
                                                                          images):
    out = tmp_path / "mb"
    code, text, err = export(capsys, small_sample_dir, "--format", "middlebury", "--out", out, "--shift", shift,
                             *images)  # the active images unless told: the default and the explicit flag
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir() if not p.name.startswith(".")) == ["export.json", "trainingF"]
    d = out / "trainingF" / small_sample_dir.name  # the Middlebury 2014 SDK tree, the scene named by the sample id
    assert [p.name for p in (out / "trainingF").iterdir()] == [small_sample_dir.name]
    assert sorted(p.name for p in d.iterdir()) == ["calib.txt", "disp0GT.pfm", "disp1GT.pfm", "im0.png", "im1.png",
                                                    "mask0nocc.png"]
    c = read_calib(d / "calib.txt")
    from platebench.bench.io.middlebury import read_calib as read_calib_ours
    ours = read_calib_ours(d / "calib.txt")
    assert (ours.doffs, ours.vmin, ours.vmax, ours.ndisp) == (c["doffs"], c["vmin"], c["vmax"], c["ndisp"])
    disp = read_pfm(d / "disp0GT.pfm")
    assert np.array_equal(cv2.imread(str(d / "disp0GT.pfm"), cv2.IMREAD_UNCHANGED).astype(np.float64), disp,
                          equal_nan=True)  # OpenCV reads the same map
    im0 = cv2.imread(str(d / "im0.png"), cv2.IMREAD_UNCHANGED)
    H, W = im0.shape
    assert (W, H) == (c["width"], c["height"]) == disp.shape[::-1]
    s = int(round(c["cam1"][0, 2] - c["cam0"][0, 2]))  # the shift moves the left principal point
    assert c["doffs"] == s and (s == 0) == (shift == "0")
    src = cv2.imread(str(small_sample_dir / "images" / "left_active.png"), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(im0, src[:, s:])  # the left image loses its first s columns, the right its last s
    src1 = cv2.imread(str(small_sample_dir / "images" / "right_active.png"), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(cv2.imread(str(d / "im1.png"), cv2.IMREAD_UNCHANGED), src1[:, :src1.shape[1] - s])
    # every valid pixel: Z = baseline f / (d + doffs) gives the true depth (mm -> m)
    valid_src = np.isfinite(gt_depth(small_sample_dir))
    z_true = gt_depth(small_sample_dir)[:, s:]
    valid = np.isfinite(disp)
    assert valid.sum() > 10000 and np.array_equal(valid, np.isfinite(z_true))
    z = c["baseline"] * 1e-3 * c["cam0"][0, 0] / (disp[valid] + c["doffs"])
    assert np.max(np.abs(z / z_true[valid] - 1)) < 1e-6
    assert c["vmin"] == math.floor(disp[valid].min()) and c["vmax"] == math.ceil(disp[valid].max())
    if shift == "auto":
        assert 16 <= disp[valid].min() < 17 and c["vmax"] <= 20  # where learned stereo works
    assert c["dyavg"] == 0 and c["dymax"] == 0
    # right view: its disparity at the match of a non-occluded left pixel brackets the left one
    mask = cv2.imread(str(d / "mask0nocc.png"), cv2.IMREAD_UNCHANGED)
    assert set(np.unique(mask)) <= {0, 128, 255} and np.array_equal(mask > 0, valid)
    assert (mask == 255).sum() > 0.98 * valid.sum()  # the 10-degree plate is seen whole by both cameras
    d1 = read_pfm(d / "disp1GT.pfm")
    v, u = np.nonzero(mask == 255)
    ur = u - disp[v, u]
    a, b = d1[v, np.floor(ur).astype(int)], d1[v, np.ceil(ur).astype(int)]
    both = np.isfinite(a) & np.isfinite(b)
    lo, hi = np.minimum(a, b)[both], np.maximum(a, b)[both]
    dd = disp[v, u][both]
    assert both.mean() > 0.95 and np.all((lo - 1e-3 <= dd) & (dd <= hi + 1e-3))
    doc = json.loads((out / "export.json").read_text())
    assert doc["format"] == "middlebury" and doc["samples"][0]["shift_px"] == s and doc["images"] == "active"
    assert doc["samples"][0]["files"] == f"trainingF/{small_sample_dir.name}"
    assert doc["max_shift_px"] == math.floor(read_pfm(small_sample_dir / "gt" / "disp0GT.pfm")[valid_src].min()) - 1


def kitti_standard_loader(root, index: int):
    """A frame of a KITTI 2015 export read as KITTI tools read it (a transcription, not our code):
    calib_cam_to_cam parsed as pykitti's read_calib_file does ("key: numbers" per line, lines that
    are not numbers skipped), f = P_rect_02[0, 0], the baseline from the two projection matrices'
    [0, 3] entries (the cameras' x offsets, as pykitti derives b_rgb), disparity = uint16 PNG / 256
    with 0 invalid, depth = f B / d. Returns (depth (H, W), valid, P_rect_02, P_rect_03)."""
    calib = {}
    for line in (root / "training" / "calib_cam_to_cam" / f"{index:06d}.txt").read_text().splitlines():
        key, value = line.split(":", 1)
        try:
            calib[key] = np.array([float(x) for x in value.split()])
        except ValueError:
            pass
    P2, P3 = calib["P_rect_02"].reshape(3, 4), calib["P_rect_03"].reshape(3, 4)
    f = P2[0, 0]
    baseline = P2[0, 3] / P2[0, 0] - P3[0, 3] / P3[0, 0]
    disp = cv2.imread(str(root / "training" / "disp_occ_0" / f"{index:06d}_10.png"), cv2.IMREAD_ANYDEPTH)
    disp = disp.astype(np.float32) / 256.0
    valid = disp > 0
    depth = np.zeros(disp.shape)
    depth[valid] = f * baseline / disp[valid]
    return depth, valid, P2, P3


def true_depth_by_ray_casting(sample, K, pixels_vu):
    """z-depth (m) of the plate at the centres of ``pixels_vu`` ((N, 2) rows, columns) of a camera with
    intrinsics K at the sample's left pose (calib.json): rays cast against the sample's mesh (trimesh)."""
    import trimesh
    cam = json.loads((sample / "calib.json").read_text())["left"]
    R, t = np.array(cam["R"]), np.array(cam["t"])
    mesh = trimesh.load(sample / "plate.ply", process=False, force="mesh")
    uv1 = np.c_[pixels_vu[:, 1], pixels_vu[:, 0], np.ones(len(pixels_vu))].astype(np.float64)
    rays = (np.linalg.inv(K) @ uv1.T).T @ R  # camera-frame directions to world (R^T d, row vectors)
    origin = -R.T @ t
    hits, ray_idx, _ = mesh.ray.intersects_location(np.repeat(origin[None], len(rays), 0), rays, multiple_hits=True)
    z = np.full(len(rays), np.inf)
    zc = (hits @ R.T + t)[:, 2]
    np.minimum.at(z, ray_idx, zc)  # the first surface along each ray
    return z


@pytest.mark.parametrize("distance, bend, factor", [(None, None, 1), (0.30, 20, 2), (0.31, 12, 2)])
def test_kitti_export_read_by_a_standard_kitti_loader_gives_the_true_depth(small_sample_dir, tmp_path, capsys,
                                                                          distance, bend, factor):
    if distance is None:  # 480 x 360, f 750 px, 0.4 m: disparities about 187 px fit KITTI as rendered
        sample = small_sample_dir
    else:  # 640 x 480, f 1000 px, 0.30 m: about 330 px, beyond KITTI's 256: the export resamples
        sample = tmp_path / "near"
        assert main(["render", "--out", str(sample), "--width", "640", "--height", "480", "--spp", "1",
                     "--distance-m", str(distance), "--bend-deg", str(bend)]) == 0
        capsys.readouterr()
    out = tmp_path / "kitti"
    code, text, err = export(capsys, sample, "--format", "kitti", "--out", out)
    assert code == 0, err
    assert "doffs" not in (out / "training" / "calib_cam_to_cam" / "000000.txt").read_text()
    depth, valid, P2, P3 = kitti_standard_loader(out, 0)
    assert np.array_equal(P2[:, :3], P3[:, :3])  # one K: equal principal points
    doc = json.loads((out / "export.json").read_text())["samples"][0]
    assert doc["resample_factor"] == factor and (doc["resampled"] is None) == (factor == 1)
    if factor > 1:
        assert "reduced 2x" in doc["resampled"] and "resampled: images reduced 2x" in text
    src = cv2.imread(str(sample / "images" / "left_active.png"), cv2.IMREAD_UNCHANGED)
    im2 = cv2.imread(str(out / "training" / "image_2" / "000000_10.png"), cv2.IMREAD_UNCHANGED)
    assert im2.shape == depth.shape == (src.shape[0] // factor, src.shape[1] // factor)
    if factor == 1:  # the active images by default
        assert np.array_equal(im2, src)
    d = cv2.imread(str(out / "training" / "disp_occ_0" / "000000_10.png"), cv2.IMREAD_ANYDEPTH) / 256.0
    assert 0 < d[valid].max() < 256
    noc = cv2.imread(str(out / "training" / "disp_noc_0" / "000000_10.png"), cv2.IMREAD_ANYDEPTH)
    assert np.all(noc[noc > 0] == (d * 256)[noc > 0]) and (noc > 0).sum() > 0.9 * valid.sum()
    # the loader's depth against the plate's true depth at the same pixels of the same camera
    vu = np.argwhere(valid)
    z_true = true_depth_by_ray_casting(sample, P2[:, :3], vu)
    hit = np.isfinite(z_true)
    assert hit.mean() > 0.999 and valid.sum() > 2000
    rel = np.abs(depth[valid][hit] / z_true[hit] - 1)
    assert rel.max() < 1e-3, rel.max()  # within 0.1 % at every pixel


def test_kitti_export_refuses_a_shift_with_the_reason(small_sample_dir, tmp_path, capsys):
    for shift in ("auto", "40"):
        code, _, err = export(capsys, small_sample_dir, "--format", "kitti", "--out", tmp_path / "k", "--shift", shift)
        assert code == 2 and len(err.strip().splitlines()) == 1 and "equal principal points" in err, err
        assert not (tmp_path / "k").exists()


def test_a_shift_past_the_smallest_true_disparity_is_refused_naming_the_range(small_sample_dir, tmp_path, capsys):
    d = read_pfm(small_sample_dir / "gt" / "disp0GT.pfm")
    top = math.floor(d[np.isfinite(d)].min()) - 1  # every exported disparity stays >= 1 px
    for shift in (top + 1, top + 60):
        code, text, err = export(capsys, small_sample_dir, "--format", "middlebury", "--out", tmp_path / "x",
                                 "--shift", shift)
        assert code == 2 and len(err.strip().splitlines()) == 1, err
        assert f"--shift {shift} is out of range" in err and f"allowed 0 to {top} px" in err, err
        assert not (tmp_path / "x").exists()
    code, text, err = export(capsys, small_sample_dir, "--format", "middlebury", "--out", tmp_path / "x",
                             "--shift", top)
    assert code == 0, err
    c = read_calib(tmp_path / "x" / "trainingF" / small_sample_dir.name / "calib.txt")
    disp = read_pfm(tmp_path / "x" / "trainingF" / small_sample_dir.name / "disp0GT.pfm")
    assert disp[np.isfinite(disp)].min() >= 1 and c["vmin"] >= 1 and c["doffs"] == top


def test_export_help_states_the_crop_once_and_the_active_default(capsys):
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert text.count("first PX columns") == 1 and "right image's columns" not in text
    assert "cropping the left image's first PX columns and the right image's last PX" in text
    assert "active: the projected square grid (default" in text and "OUT/trainingF/<scene>/" in text


def test_bad_export_requests_are_one_line_errors(small_sample_dir, tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    for args, needle in [((small_sample_dir, "--format", "middlebury", "--out", tmp_path / "a", "--shift", "-3"),
                          "--shift = '-3'"),
                         ((tmp_path / "nothing", "--format", "middlebury", "--out", tmp_path / "b"),
                          "dataset directory is missing"),
                         ((tmp_path / "empty", "--format", "kitti", "--out", tmp_path / "c"), "holds no PlateBench sample"),
                         ((tmp_path, "--format", "kitti", "--out", tmp_path / "c"), "is inside the input")]:
        code, _, err = export(capsys, *args)
        assert code == 2 and len(err.strip().splitlines()) == 1 and needle in err, err
    (tmp_path / "taken").mkdir()
    code, _, err = export(capsys, small_sample_dir, "--format", "middlebury", "--out", tmp_path / "taken")
    assert code == 2 and "already exists" in err


def test_dataset_class_iterates_samples_as_numpy(small_sample_dir):
    from platebench.bench.io.dataset_reader import PlateBenchDataset
    ds = PlateBenchDataset(small_sample_dir.parent, images="passive", shift="auto")
    assert len(ds) == 1
    pair = ds[0]
    assert pair.left.shape == pair.right.shape == pair.disparity.shape == pair.nonocc.shape
    assert pair.disparity.dtype == np.float32 and pair.nonocc.dtype == np.bool_
    z = pair.calib.depth_m(pair.disparity)
    ok = np.isfinite(pair.depth)
    assert np.allclose(z[ok], pair.depth[ok], rtol=1e-6)
    d = pair.to_dict()
    assert set(d) >= {"left", "right", "disparity", "disparity_right", "nonocc", "mask", "depth", "f_px", "baseline_m",
                      "doffs_px"}
    z2 = d["f_px"] * d["baseline_m"] / (d["disparity"][ok] + d["doffs_px"])
    assert np.allclose(z2, pair.depth[ok], rtol=1e-6)
    assert [p.sample_id for p in ds] == [pair.sample_id] and ds[-1].sample_id == pair.sample_id
    with pytest.raises(IndexError):
        ds[1]
    active = PlateBenchDataset(small_sample_dir, images="active")[0]
    assert active.shift_px == 0 and not np.array_equal(active.left, PlateBenchDataset(small_sample_dir)[0].left)
    assert re.fullmatch(r"[\w.-]+", pair.sample_id)
