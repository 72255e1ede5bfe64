"""Tests of evaluation.disparity_metrics on a 4 x 4 map worked out by hand."""

import math

import numpy as np
import pytest

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
# Estimate. |error| per known pixel in the comment; (1,2) = inf and (3,0) = 0 are invalid.
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
    # n = 14 known pixels, 2 invalid, 12 valid errors sorted:
    #   0, 0.1, 0.2, 0.2, 0.4, 0.5, 0.7, 1.0, 1.5, 2.5, 3.0, 5.0  (sum 15.1, sum of squares 44.49)
    d = middlebury_metrics(EST, GT).to_dict()
    assert d["mb_all_gt_count"] == 14 and d["mb_all_valid_count"] == 12
    assert d["mb_all_bad_0_5_pct"] == pytest.approx(100 * 8 / 14)  # 6 (> 0.5; 0.5 itself is not) + 2 invalid
    assert d["mb_all_bad_1_0_pct"] == pytest.approx(100 * 6 / 14)  # 1.5 2.5 3.0 5.0 + 2 invalid
    assert d["mb_all_bad_2_0_pct"] == pytest.approx(100 * 5 / 14)  # 2.5 3.0 5.0 + 2
    assert d["mb_all_bad_4_0_pct"] == pytest.approx(100 * 3 / 14)  # 5.0 + 2
    assert d["mb_all_invalid_pct"] == pytest.approx(100 * 2 / 14)  # 14.2857 %
    assert d["mb_all_avgerr_px"] == pytest.approx(15.1 / 12)  # 1.258333
    assert d["mb_all_rms_px"] == pytest.approx(math.sqrt(44.49 / 12))  # 1.925487
    # quantiles over all 14 with invalid = inf: ranks ceil(0.5*14)=7 -> 0.7;
    # ceil(0.9*14)=13, ceil(0.95*14)=14, ceil(0.99*14)=14 -> inf (the two invalid pixels)
    assert d["mb_all_a50_px"] == pytest.approx(0.7)
    assert d["mb_all_a90_px"] == INF and d["mb_all_a95_px"] == INF and d["mb_all_a99_px"] == INF
    assert not any(k.startswith("mb_nonocc") for k in d)


def test_middlebury_nonocc_by_hand():
    # n = 9: valid errors 0.2 0.2 0.7 1.5 3.0 0.0 0.5 2.5 (8, sum 8.6, squares 18.32), 1 invalid
    d = middlebury_metrics(EST, GT, NONOCC).to_dict()
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
    d = eth3d_metrics(EST, GT, NONOCC).to_dict()
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
    d = eth3d_metrics(EST, GT, roi=roi).to_dict()
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
