"""Tests of evaluation.disparity_metrics on a 4 x 4 map worked out by hand."""

import math

import numpy as np
import pytest

from platebench.bench.io.codecs import encode
from platebench.evaluation.disparity_metrics import eth3d_metrics, middlebury_metrics

INF = np.inf

# Ground truth: inf = unknown (skipped). 14 known pixels.
GT = np.array(
    [
        [10.0, 10.0, 10.0, INF],
        [10.0, 10.0, 10.0, INF],
        [20.0, 20.0, 20.0, 20.0],
        [20.0, 20.0, 20.0, 20.0],
    ]
)
# Estimate. |error| per known pixel in the comment; (1,2) = inf is invalid (the only invalid value, as in
# Middlebury's SDK); (3,0) = 0 is an estimate of 0 px (error 20) for Middlebury, invalid for ETH3D (<= 0).
EST = np.array(
    [
        [10.2, 9.8, 10.7, 5.0],  # 0.2  0.2  0.7  (GT unknown)
        [8.5, 13.0, INF, 0.0],  # 1.5  3.0  inv  (GT unknown)
        [20.0, 20.5, 17.5, 25.0],  # 0.0  0.5  2.5  5.0
        [0.0, 21.0, 19.6, 20.1],  # inv  1.0  0.4  0.1
    ]
)
# Non-occluded: rows 0-2 except (2,3) -> known pixels (0,0..2), (1,0..2), (2,0..2) = 9.
NONOCC = np.array(
    [
        [True, True, True, True],
        [True, True, True, True],
        [True, True, True, False],
        [False, False, False, False],
    ]
)


def test_middlebury_all_by_hand():
    # n = 14 known pixels, 1 invalid (inf), 13 valid errors sorted:
    #   0, 0.1, 0.2, 0.2, 0.4, 0.5, 0.7, 1.0, 1.5, 2.5, 3.0, 5.0, 20.0  (sum 35.1, sum of squares 444.49)
    d = encode(middlebury_metrics(EST, GT))
    assert d["mb_all_gt_count"] == 14 and d["mb_all_valid_count"] == 13
    assert d["mb_all_bad_0_5_pct"] == pytest.approx(100 * 8 / 14)  # 7 (> 0.5; 0.5 itself is not) + 1 invalid
    assert d["mb_all_bad_1_0_pct"] == pytest.approx(100 * 6 / 14)  # 1.5 2.5 3.0 5.0 20 + 1 invalid
    assert d["mb_all_bad_2_0_pct"] == pytest.approx(100 * 5 / 14)  # 2.5 3.0 5.0 20 + 1
    assert d["mb_all_bad_4_0_pct"] == pytest.approx(100 * 3 / 14)  # 5.0 20 + 1
    assert d["mb_all_invalid_pct"] == pytest.approx(100 * 1 / 14)  # 7.142857 %
    assert d["mb_all_avgerr_px"] == pytest.approx(35.1 / 13)  # 2.7
    assert d["mb_all_rms_px"] == pytest.approx(math.sqrt(444.49 / 13))  # 5.847
    # quantiles over all 14 with invalid = inf: ranks ceil(0.5*14)=7 -> 0.7; ceil(0.9*14)=13 -> 20;
    # ceil(0.95*14)=14, ceil(0.99*14)=14 -> inf (the invalid pixel)
    assert d["mb_all_a50_px"] == pytest.approx(0.7)
    assert d["mb_all_a90_px"] == pytest.approx(20.0) and d["mb_all_a95_px"] == INF and d["mb_all_a99_px"] == INF
    assert not any(k.startswith("mb_nonocc") for k in d)


def test_middlebury_nonocc_by_hand():
    # n = 9: valid errors 0.2 0.2 0.7 1.5 3.0 0.0 0.5 2.5 (8, sum 8.6, squares 18.32), 1 invalid
    d = encode(middlebury_metrics(EST, GT, NONOCC))
    assert d["mb_nonocc_gt_count"] == 9 and d["mb_nonocc_valid_count"] == 8
    assert d["mb_nonocc_bad_0_5_pct"] == pytest.approx(100 * 5 / 9)  # 0.7 1.5 2.5 3.0 + 1 invalid
    assert d["mb_nonocc_bad_1_0_pct"] == pytest.approx(100 * 4 / 9)  # 1.5 2.5 3.0 + 1
    assert d["mb_nonocc_bad_2_0_pct"] == pytest.approx(100 * 3 / 9)  # 2.5 3.0 + 1
    assert d["mb_nonocc_bad_4_0_pct"] == pytest.approx(100 * 1 / 9)  # only the invalid pixel
    assert d["mb_nonocc_invalid_pct"] == pytest.approx(100 / 9)
    assert d["mb_nonocc_avgerr_px"] == pytest.approx(8.6 / 8)  # 1.075
    assert d["mb_nonocc_rms_px"] == pytest.approx(math.sqrt(18.32 / 8))  # 1.513275
    # sorted 0 0.2 0.2 0.5 0.7 1.5 2.5 3.0 inf: rank ceil(4.5)=5 -> 0.7; ceil(8.1)=9 -> inf
    assert d["mb_nonocc_a50_px"] == pytest.approx(0.7)
    assert d["mb_nonocc_a90_px"] == INF
    assert d["mb_all_bad_1_0_pct"] == pytest.approx(100 * 6 / 14)  # "all" still there


def test_eth3d_by_hand():
    d = encode(eth3d_metrics(EST, GT, NONOCC))
    # all: 12 estimated of 14 known
    assert d["eth_all_coverage_frac"] == pytest.approx(12 / 14)  # 0.857143
    assert d["eth_all_bad_0_5_pct"] == pytest.approx(100 * 6 / 12)  # 0.7 1.0 1.5 2.5 3.0 5.0
    assert d["eth_all_bad_1_0_pct"] == pytest.approx(100 * 4 / 12)  # 1.5 2.5 3.0 5.0
    assert d["eth_all_bad_2_0_pct"] == pytest.approx(100 * 3 / 12)
    assert d["eth_all_bad_4_0_pct"] == pytest.approx(100 * 1 / 12)
    assert d["eth_all_avgerr_px"] == pytest.approx(15.1 / 12)
    assert d["eth_all_rms_px"] == pytest.approx(math.sqrt(44.49 / 12))
    # over the 12 sorted errors: ranks ceil(6)=6 -> 0.5, ceil(10.8)=11 -> 3.0,
    # ceil(11.4)=12 -> 5.0, ceil(11.88)=12 -> 5.0
    assert d["eth_all_a50_px"] == pytest.approx(0.5)
    assert d["eth_all_a90_px"] == pytest.approx(3.0)
    assert d["eth_all_a95_px"] == pytest.approx(5.0)
    assert d["eth_all_a99_px"] == pytest.approx(5.0)
    assert d["eth_all_gt_count"] == 14 and d["eth_all_est_count"] == 12
    # nonocc: 8 estimated of 9; sorted 0 0.2 0.2 0.5 0.7 1.5 2.5 3.0
    assert d["eth_nonocc_coverage_frac"] == pytest.approx(8 / 9)
    assert d["eth_nonocc_bad_0_5_pct"] == pytest.approx(100 * 4 / 8)
    assert d["eth_nonocc_bad_1_0_pct"] == pytest.approx(100 * 3 / 8)
    assert d["eth_nonocc_bad_2_0_pct"] == pytest.approx(100 * 2 / 8)
    assert d["eth_nonocc_bad_4_0_pct"] == pytest.approx(0.0)
    assert d["eth_nonocc_avgerr_px"] == pytest.approx(1.075)
    assert d["eth_nonocc_rms_px"] == pytest.approx(math.sqrt(18.32 / 8))
    assert d["eth_nonocc_a50_px"] == pytest.approx(0.5)  # rank ceil(4) = 4
    assert d["eth_nonocc_a90_px"] == pytest.approx(3.0)  # rank ceil(7.2) = 8


def test_signed_errors_do_not_cancel():
    gt = np.full((2, 2), 10.0)
    est = np.array([[11.0, 9.0], [11.0, 9.0]])  # +1, -1, +1, -1
    assert middlebury_metrics(est, gt).all.avgerr == pytest.approx(1.0)
    assert eth3d_metrics(est, gt).all.avgerr == pytest.approx(1.0)


def test_roi_and_empty_nonocc():
    roi = np.zeros((4, 4), bool)
    roi[2, :] = True  # row 2: errors 0, 0.5, 2.5, 5.0
    d = encode(eth3d_metrics(EST, GT, roi=roi))
    assert d["eth_all_gt_count"] == 4 and d["eth_all_avgerr_px"] == pytest.approx(2.0)
    m = middlebury_metrics(EST, GT, np.zeros((4, 4), bool))
    assert m.nonocc.gt_count == 0 and math.isnan(m.nonocc.avgerr) and math.isnan(m.nonocc.invalid_pct)


def test_bad_inputs():
    with pytest.raises(ValueError, match="shape mismatch"):
        middlebury_metrics(EST, GT[:3])
    with pytest.raises(ValueError, match="mask"):
        middlebury_metrics(EST, GT, NONOCC.astype(np.uint8) * 255)
    with pytest.raises(ValueError, match="mask: shape mismatch"):
        eth3d_metrics(EST, GT, NONOCC[:2])
    with pytest.raises(ValueError, match="disp_gt: no pixel"):
        eth3d_metrics(EST, np.full((4, 4), np.inf))
    with pytest.raises(ValueError, match="disp_est: empty"):
        eth3d_metrics(np.zeros((0, 0)), np.zeros((0, 0)))


# ----------------------------------------------------------------------------- the Middlebury SDK's rules
def evaldisp_transcribed(disp, gt, mask, badthresh, maxdisp):
    """Middlebury SDK ``evaldisp`` (MiddEval3 code/evaldisp/evaldisp.cpp, 1/27/2015), transcribed pixel
    for pixel in float32 as the C++ runs it: gt == INFINITY skipped; valid = (d != INFINITY); a valid
    d clipped by __max(0, __min(maxd, d)) (the ternary macros: a NaN stays NaN); err = fabs(d - gt);
    with a mask only mask == 255 is evaluated; bad = err > badthresh. Returns (bad %, invalid %,
    totbad %, avgErr) as it prints them (before its 2-decimal rounding)."""
    n = bad = invalid = 0
    serr = np.float32(0.0)
    maxd = np.float32(maxdisp)
    with np.errstate(invalid="ignore"):
        for y in range(gt.shape[0]):
            for x in range(gt.shape[1]):
                g = np.float32(gt[y, x])
                if g == np.inf:
                    continue
                d = np.float32(disp[y, x])
                valid = d != np.inf
                if valid:
                    m = maxd if maxd < d else d  # __min(maxd, d)
                    d = np.float32(0.0) if np.float32(0.0) > m else m  # __max(0, m)
                err = np.float32(abs(d - g))
                if mask is not None and mask[y, x] != 255:
                    continue
                n += 1
                if valid:
                    serr = np.float32(serr + err)
                    bad += bool(err > np.float32(badthresh))
                else:
                    invalid += 1
    return 100.0 * bad / n, 100.0 * invalid / n, 100.0 * (bad + invalid) / n, float(serr / np.float32(n - invalid))


def _special_map(rng, gt, maxdisp):
    """Estimates with every kind of value the SDK handles: near the truth, +inf holes, 0, negatives, -inf,
    beyond maxdisp, and errors of exactly the thresholds."""
    d = (gt + rng.normal(0.0, 1.5, gt.shape)).astype(np.float32)
    pick = rng.random(gt.shape)
    d[pick < 0.05] = np.inf
    d[(pick >= 0.05) & (pick < 0.08)] = 0.0
    d[(pick >= 0.08) & (pick < 0.10)] = -rng.uniform(0.1, 50.0, ((pick >= 0.08) & (pick < 0.10)).sum())
    d[(pick >= 0.10) & (pick < 0.11)] = -np.inf
    d[(pick >= 0.11) & (pick < 0.14)] = maxdisp + rng.uniform(0.1, 300.0, ((pick >= 0.11) & (pick < 0.14)).sum())
    exact = (pick >= 0.14) & (pick < 0.30)
    d[exact] = (gt + rng.choice([0.5, 1.0, 2.0, 4.0, -0.5, -1.0], gt.shape)).astype(np.float32)[exact]
    return d


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_middlebury_metrics_follow_the_sdk_rules(seed):
    rng = np.random.default_rng(seed)
    gt = rng.uniform(5.0, 60.0, (40, 50)).astype(np.float32)
    gt[rng.random(gt.shape) < 0.1] = np.inf  # unknown truth
    mask = np.where(rng.random(gt.shape) < 0.8, 255, 128).astype(np.uint8)
    maxdisp = 64
    est = _special_map(rng, gt, maxdisp)
    for region, m in (("all", None), ("nonocc", mask)):
        ours = middlebury_metrics(est.astype(np.float64), gt.astype(np.float64), mask == 255,
                                  max_disparity_px=maxdisp)
        reg = ours.all if region == "all" else ours.nonocc
        for t, pct in reg.bad_pct:
            bad, invalid, totbad, avg = evaldisp_transcribed(est, gt, m, t, maxdisp)
            assert pct == pytest.approx(totbad, abs=1e-9), (region, t)
        assert reg.invalid_pct == pytest.approx(invalid, abs=1e-9)
        assert reg.avgerr == pytest.approx(avg, rel=1e-5)  # the SDK sums in float32


def test_middlebury_exact_half_pixel_offset_on_float32_truth_is_not_bad():
    # what the SDK gives for the truth file + 0.5 (float32 both): error exactly 0.5, never > 0.5
    rng = np.random.default_rng(3)
    gt = rng.uniform(150.0, 250.0, (30, 30)).astype(np.float32)
    est = gt + np.float32(0.5)
    assert evaldisp_transcribed(est, gt, None, 0.5, 256)[2] == 0.0
    s = middlebury_metrics(est.astype(np.float64), gt.astype(np.float64), max_disparity_px=256)
    assert dict(s.all.bad_pct)[0.5] == 0.0 and s.all.avgerr == 0.5


def test_middlebury_nan_is_invalid_here_where_the_sdk_lets_it_through():
    # the one difference on purpose (README, "Metric semantics"): the SDK counts a NaN estimate as valid
    # and never bad, and its avgErr turns NaN; here NaN is a hole, like +inf
    gt = np.full((2, 2), 10.0, np.float32)
    est = np.array([[10.0, np.nan], [12.0, np.inf]], np.float32)
    bad, invalid, totbad, avg = evaldisp_transcribed(est, gt, None, 1.0, 64)
    assert (bad, invalid) == (25.0, 25.0) and math.isnan(avg)
    s = middlebury_metrics(est.astype(np.float64), gt.astype(np.float64), max_disparity_px=64).all
    assert s.invalid_pct == 50.0 and dict(s.bad_pct)[1.0] == 75.0 and s.avgerr == 1.0


def _evaldisp_binary():
    import shutil
    return shutil.which("evaldisp")


@pytest.mark.skipif(_evaldisp_binary() is None,
                    reason="the Middlebury SDK's evaldisp is not on PATH (build MiddEval3's code/evaldisp to compare "
                           "the scorer with it on the same files)")
def test_middlebury_metrics_match_the_sdk_evaldisp_on_the_same_files(tmp_path):
    """The SDK's own program on PFM files written here, with a mask0nocc-style mask; its output has two
    decimals. (Its imageLib reads PNG masks; a build may read PGM instead: both are written.)"""
    import subprocess

    import cv2

    from platebench.bench.io.images import write_pfm
    rng = np.random.default_rng(11)
    gt = rng.uniform(5.0, 60.0, (60, 80)).astype(np.float32)
    gt[rng.random(gt.shape) < 0.1] = np.inf
    mask = np.where(np.isfinite(gt), np.where(rng.random(gt.shape) < 0.8, 255, 128), 0).astype(np.uint8)
    est = _special_map(rng, gt, 64)
    write_pfm(tmp_path / "disp0.pfm", est)
    write_pfm(tmp_path / "disp0GT.pfm", gt)
    cv2.imwrite(str(tmp_path / "mask0nocc.png"), mask)
    (tmp_path / "mask0nocc.pgm").write_bytes(f"P5\n{mask.shape[1]} {mask.shape[0]}\n255\n".encode() + mask.tobytes())
    probe = subprocess.run([_evaldisp_binary(), "disp0.pfm", "disp0GT.pfm", "1", "64", "0", "mask0nocc.png"],
                           cwd=tmp_path, capture_output=True, text=True)
    mask_file = "mask0nocc.png" if probe.returncode == 0 else "mask0nocc.pgm"
    for t in (0.5, 1.0, 2.0, 4.0):
        for region, mfile in (("all", None), ("nonocc", mask_file)):
            args = [_evaldisp_binary(), "disp0.pfm", "disp0GT.pfm", str(t), "64", "0"] + ([mfile] if mfile else [])
            out = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, check=True).stdout.split()
            cover, bad, invalid, totbad, avg = map(float, out[:5])
            ours = middlebury_metrics(est.astype(np.float64), gt.astype(np.float64), mask == 255, max_disparity_px=64)
            reg = ours.all if region == "all" else ours.nonocc
            assert round(dict(reg.bad_pct)[t], 2) == pytest.approx(totbad, abs=0.006), (region, t)
            assert round(reg.invalid_pct, 2) == pytest.approx(invalid, abs=0.006)
            assert round(reg.avgerr, 2) == pytest.approx(avg, abs=0.006)
