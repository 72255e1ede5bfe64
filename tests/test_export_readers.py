"""``platebench export`` read back by readers written here from the published formats alone (none
of the project's readers), on a real two-sample sweep dataset: the depth each export implies
equals the sample's true depth (``gt/left_depth.exr``, read with the OpenEXR package).

Formats as published:

* Middlebury 2014 SDK (MiddEval3): ``trainingF/<scene>/`` with ``im0.png``, ``im1.png``,
  ``calib.txt`` (``key=value`` lines; ``cam0=[f 0 cx; 0 f cy; 0 0 1]``, ``doffs`` px,
  ``baseline`` mm; Z = baseline f / (d + doffs)), ``disp0GT.pfm`` (PFM: ``Pf`` for one channel,
  ``W H``, a scale whose sign gives the byte order (< 0: little-endian), float32 rows bottom-up;
  +inf unknown) and ``mask0nocc.png`` (255 non-occluded, 128 occluded, 0 unknown).
* KITTI 2015: ``training/disp_occ_0/NNNNNN_10.png`` uint16, d = value / 256, 0 = unknown;
  ``calib_cam_to_cam/NNNNNN.txt`` (``key: numbers`` lines), P_rect_02 / P_rect_03 (3 x 4, row-major),
  f = P_rect_02[0, 0], B = (P_rect_02[0, 3] - P_rect_03[0, 3]) / f, Z = f B / d.

The KITTI check is exact where the format is: the export reduces a sample by a whole factor k
where its disparities exceed 256 px and gives each k x k block the mean of its pixels' true
disparities divided by k (the module doc of ``bench.io.export``). Here that reference is computed
from the true depth (d = f B / Z per pixel, blocks whose pixels all have a truth), and the PNG
must hold it to within its quantisation (half of 1/256 px) and the truth files' float32 rounding
(``TRUTH_REL``): a block misplaced, a wrong factor, principal point, focal length or baseline, or a
disparity truncated instead of rounded, fails. Middlebury holds float32 disparities: its depth
must match the truth to 1e-5 relative at every pixel with a truth.
"""
from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import numpy as np
import OpenEXR
import pytest

from tests.conftest import run_cli

pytestmark = pytest.mark.render

REL = 1e-5  # relative depth agreement of a float32 disparity file with the true depth
TRUTH_REL = 1e-6  # relative: the float32 truth files (disp0GT.pfm, left_depth.exr) agree this well in disparity
KITTI_HALF_STEP = 0.5 / 256  # KITTI's PNG holds round(256 d)

SPEC = """\
[sweep]
name = "export-readers"
methods = ["sgbm"]

[base.scene]
width = 640
height = 480

[base.render]
spp = 1
seed = 1

[grid]
distance_m = [0.6, 0.3]
"""
# 640 x 480, f 1000 px, B 0.1 m: about 167 px at 0.6 m (KITTI as rendered) and 333 px at 0.3 m
# (beyond KITTI's 256 px: the KITTI export reduces that sample 2x)


# ----------------------------------------------------------------------------- readers from the formats
def read_pfm(path: Path) -> np.ndarray:
    """A one-channel PFM as (H, W) float64, top row first."""
    with open(path, "rb") as f:
        kind = f.readline().strip()
        w, h = (int(x) for x in f.readline().split())
        scale = float(f.readline())
        raw = f.read()
    assert kind == b"Pf" and len(raw) == 4 * w * h, (kind, len(raw), w, h)
    data = np.frombuffer(raw, "<f4" if scale < 0 else ">f4").reshape(h, w)
    return np.flipud(data).astype(np.float64)  # the file's first row is the image's bottom row


def read_middlebury_calib(path: Path) -> dict:
    out = {}
    for line in path.read_text().splitlines():
        if "=" not in line:
            continue
        key, value = (t.strip() for t in line.split("=", 1))
        if value.startswith("["):
            out[key] = np.array([[float(x) for x in row.split()] for row in value.strip("[]").split(";")])
        else:
            out[key] = float(value)
    assert out["cam0"].shape == out["cam1"].shape == (3, 3)
    return out


def read_kitti_calib(path: Path) -> dict:
    out = {}
    for line in path.read_text().splitlines():
        key, _, value = line.partition(":")
        try:
            out[key.strip()] = np.array([float(x) for x in value.split()])
        except ValueError:
            pass  # a line that is not numbers (calib_time in KITTI's own files)
    return out


def read_kitti_disparity(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(d px, known): uint16 / 256, 0 unknown."""
    v = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert v is not None and v.dtype == np.uint16 and v.ndim == 2
    return v.astype(np.float64) / 256.0, v > 0


def true_depth(sample: Path) -> np.ndarray:
    """The sample's left z-depth (m), +inf (not finite) where the plate is not seen."""
    ch = OpenEXR.File(str(sample / "gt" / "left_depth.exr")).channels()
    return np.asarray(ch["Y"].pixels, np.float64)


def grey(path: Path) -> np.ndarray:
    return cv2.imread(str(path), cv2.IMREAD_UNCHANGED)


# ----------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def sweep_dataset(tmp_path_factory) -> Path:
    """A real sweep dataset (``platebench sweep``) of two samples: 0000 at 0.6 m, 0001 at 0.3 m."""
    root = tmp_path_factory.mktemp("export_readers")
    (root / "spec.toml").write_text(SPEC)
    r = run_cli("sweep", root / "spec.toml", "--out", root / "ds", "--workers", "0", "--no-progress")
    assert r.returncode == 0, r.stderr
    return root / "ds"


def samples_of(ds: Path) -> dict:
    return {p.parent.name: p for p in sorted((ds / "samples").glob("*/sample"))}


# ----------------------------------------------------------------------------- tests
@pytest.mark.parametrize("shift", ["0", "auto"])
def test_middlebury_tree_read_from_its_format_gives_the_true_depth(sweep_dataset, tmp_path, shift):
    out = tmp_path / "mb"
    r = run_cli("export", sweep_dataset, "--format", "middlebury", "--out", out, "--shift", shift)
    assert r.returncode == 0, r.stderr
    samples = samples_of(sweep_dataset)
    assert sorted(p.name for p in (out / "trainingF").iterdir()) == sorted(samples) == ["0000", "0001"]
    doc = json.loads((out / "export.json").read_text())
    assert [(row["id"], row["files"]) for row in doc["samples"]] == [(k, f"trainingF/{k}") for k in sorted(samples)]
    assert doc["images"] == "active"
    for scene, sample in samples.items():
        d = out / "trainingF" / scene
        c = read_middlebury_calib(d / "calib.txt")
        own = read_middlebury_calib(sample / "calib.txt")  # the sample's own record of its rig
        s = own["cam0"][0, 2] - c["cam0"][0, 2]  # the crop moves the left principal point
        assert s == round(s) and (s == 0) == (shift == "0") and c["doffs"] == c["cam1"][0, 2] - c["cam0"][0, 2]
        s = int(s)
        disp = read_pfm(d / "disp0GT.pfm")
        im0, im1 = grey(d / "im0.png"), grey(d / "im1.png")
        H, W = disp.shape
        assert im0.shape == im1.shape == (H, W) and (c["width"], c["height"]) == (W, H)
        assert np.array_equal(im0, grey(sample / "images" / "left_active.png")[:, s:])  # active images by default
        assert np.array_equal(im1, grey(sample / "images" / "right_active.png")[:, :W])
        z_true = true_depth(sample)[:, s:]
        known = np.isfinite(disp)
        assert np.array_equal(known, np.isfinite(z_true)) and known.sum() > 1000
        z = c["baseline"] * c["cam0"][0, 0] / (disp[known] + c["doffs"]) / 1000.0  # baseline in mm
        rel = np.abs(z / z_true[known] - 1)
        assert rel.max() < REL, rel.max()
        assert c["vmin"] == np.floor(disp[known].min()) >= 1 and c["vmax"] == np.ceil(disp[known].max())
        assert c["ndisp"] > c["vmax"]
        mask = grey(d / "mask0nocc.png")
        assert mask.dtype == np.uint8 and set(np.unique(mask)) <= {0, 128, 255}
        assert np.array_equal(mask > 0, known) and (mask == 255).sum() > 0.9 * known.sum()


def test_kitti_export_read_from_its_format_gives_the_true_block_disparity_and_depth(sweep_dataset, tmp_path):
    out = tmp_path / "kitti"
    r = run_cli("export", sweep_dataset, "--format", "kitti", "--out", out)
    assert r.returncode == 0, r.stderr
    factors = []
    for index, (sid, sample) in enumerate(samples_of(sweep_dataset).items()):
        t = out / "training"
        cal = read_kitti_calib(t / "calib_cam_to_cam" / f"{index:06d}.txt")
        P2, P3 = cal["P_rect_02"].reshape(3, 4), cal["P_rect_03"].reshape(3, 4)
        assert np.array_equal(P2[:, :3], P3[:, :3]) and P2[0, 3] == 0  # one K: equal principal points
        f = P2[0, 0]
        B = (P2[0, 3] - P3[0, 3]) / f
        own = read_middlebury_calib(sample / "calib.txt")
        assert own["doffs"] == 0  # parallel cameras: the truth is d = f B / Z
        z = true_depth(sample)
        Hs, Ws = z.shape
        d, known = read_kitti_disparity(t / "disp_occ_0" / f"{index:06d}_10.png")
        H, W = d.shape
        k = Ws // W
        factors.append(k)
        assert (H, W) == (Hs // k, Ws // k)
        assert abs(B / (own["baseline"] / 1000.0) - 1) < 1e-9 and abs(f * k / own["cam0"][0, 0] - 1) < 1e-12
        for row, col in ((0, 2), (1, 2)):  # a pixel centre (c + 0.5) / k - 0.5
            assert abs(P2[row, col] - ((own["cam0"][row, col] + 0.5) / k - 0.5)) < 1e-9
        # the reference: each k x k block's mean true disparity (f B / Z at full size) divided by k
        d_true = np.where(np.isfinite(z), own["cam0"][0, 0] * B / z, np.nan)
        blocks = d_true[:H * k, :W * k].reshape(H, k, W, k).transpose(0, 2, 1, 3).reshape(H, W, k * k)
        whole = np.all(np.isfinite(blocks), axis=2)
        d_ref = np.where(whole, np.nanmean(np.where(whole[..., None], blocks, 0.0), axis=2), np.nan) / k
        assert np.array_equal(known, whole) and known.sum() > 1000  # a disparity exactly where a block has a truth
        err = np.abs(d[known] - d_ref[known])
        assert np.all(err <= KITTI_HALF_STEP + TRUTH_REL * d_ref[known]), err.max()
        assert 0 < d[known].max() < 256
        # the depth the standard rule gives against the reference's (for k = 1 the true depth itself): the
        # PNG's step is all that differs
        z_kitti, z_ref = f * B / d[known], f * B / d_ref[known]
        rel = np.abs(z_kitti / z_ref - 1)
        assert np.all(rel <= (KITTI_HALF_STEP + TRUTH_REL * d_ref[known]) / d[known]), rel.max()
        noc, noc_known = read_kitti_disparity(t / "disp_noc_0" / f"{index:06d}_10.png")
        assert np.all(known[noc_known]) and np.array_equal(noc[noc_known], d[noc_known])
        assert noc_known.sum() > 0.9 * known.sum()
        # the images: the sample's active ones, each k x k block averaged
        for cam, name in (("left", "image_2"), ("right", "image_3")):
            src = grey(sample / "images" / f"{cam}_active.png").astype(np.float64)
            mean = src[:H * k, :W * k].reshape(H, k, W, k).mean(axis=(1, 3))
            got = grey(t / name / f"{index:06d}_10.png").astype(np.float64)
            assert got.shape == (H, W) and np.max(np.abs(got - mean)) <= (0 if k == 1 else 1)
    assert factors == [1, 2]  # 0000 as rendered, 0001 reduced: both paths are checked


def incomplete_copy(ds: Path, where: Path) -> Path:
    """``ds`` as an interrupted sweep leaves it: sample 0001 not rendered, pending in the manifest."""
    shutil.copytree(ds, where)
    shutil.rmtree(where / "samples" / "0001")
    m = json.loads((where / "manifest.json").read_text())
    m["state"] = "interrupted"
    m["samples"][1] = {k: m["samples"][1][k] for k in ("id", "index", "params", "config_sha256", "pose")}
    m["samples"][1]["status"] = "pending"
    (where / "manifest.json").write_text(json.dumps(m))
    return where


@pytest.mark.parametrize("fmt", ["middlebury", "kitti"])
def test_an_incomplete_sweep_is_refused_or_exported_with_a_note(sweep_dataset, tmp_path, fmt):
    ds = incomplete_copy(sweep_dataset, tmp_path / "ds")
    r = run_cli("export", ds, "--format", fmt, "--out", tmp_path / "x")
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1, r.stderr
    assert "interrupted" in lines[0] and "1 of its 2 samples" in lines[0] and "--allow-incomplete" in lines[0]
    assert not (tmp_path / "x").exists()
    r = run_cli("export", ds, "--format", fmt, "--out", tmp_path / "x", "--allow-incomplete")
    assert r.returncode == 0, r.stderr
    assert "note:" in r.stdout and "1 of its 2 samples" in r.stdout
    doc = json.loads((tmp_path / "x" / "export.json").read_text())
    assert [s["id"] for s in doc["samples"]] == ["0000"]
    assert doc["sweep"] == {"state": "interrupted", "samples_total": 2, "samples_exported": 1}
    r = run_cli("export", sweep_dataset, "--format", fmt, "--out", tmp_path / "whole")  # complete: no note
    assert r.returncode == 0 and "note:" not in r.stdout, r.stderr


@pytest.mark.parametrize("fmt", ["middlebury", "kitti"])
def test_a_pair_a_robot_took_is_left_out_or_exported_marked(tmp_path, fmt):
    """A 1995-rig sample (robot-posed, distorting lens) is no rectified pair: left out with a note (the
    rectified sample beside it exported, KITTI numbering without a gap), or exported and marked."""
    root = tmp_path / "root"
    for name, extra in (("a95", ["--realism", "1995"]), ("b", ["--width", "640", "--height", "480",
                                                                "--distance-m", "0.6"])):
        r = run_cli("render", "--out", root / name, "--spp", "1", *extra)
        assert r.returncode == 0, r.stderr
    r = run_cli("export", root, "--format", fmt, "--out", tmp_path / "x")
    assert r.returncode == 0 and "1 of the 2 samples are left out" in r.stdout, r.stdout + r.stderr
    doc = json.loads((tmp_path / "x" / "export.json").read_text())
    assert [s["id"] for s in doc["samples"]] == ["b"] and doc["left_out_unrectified"] == ["a95"]
    if fmt == "kitti":
        assert (tmp_path / "x" / "training" / "disp_occ_0" / "000000_10.png").is_file()
    r = run_cli("export", root, "--format", fmt, "--out", tmp_path / "y", "--include-unrectified")
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "y" / "export.json").read_text())
    marks = {s["id"]: s.get("unrectified") for s in doc["samples"]}
    assert marks["b"] is None and "robot" in marks["a95"]
