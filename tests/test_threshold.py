"""Tests for reconstruction.paper.threshold (Tsai moment-preserving and Otsu thresholds)."""

import numpy as np
import pytest

from platebench.reconstruction.paper.threshold import (
    TsaiThreshold,
    otsu_threshold,
    tsai_moment_threshold,
)


def _two_level(a, b, p, n=1000, dtype=np.uint8, seed=0):
    n_low = int(round(p * n))
    values = np.array([a] * n_low + [b] * (n - n_low), dtype=dtype)
    return np.random.default_rng(seed).permutation(values).reshape(25, n // 25)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.float32, np.float64])
def test_two_level_image_is_reproduced_exactly(dtype):
    a, b, p = 40, 200, 0.3
    result = tsai_moment_threshold(_two_level(a, b, p, dtype=dtype))
    assert isinstance(result, TsaiThreshold)
    assert result.z0 == pytest.approx(a, abs=1e-9)
    assert result.z1 == pytest.approx(b, abs=1e-9)
    assert result.p0 == pytest.approx(p, abs=1e-9)
    assert a < result.threshold < b


def _bimodal(n=200_000, frac=0.35, mu=(60.0, 180.0), sigma=(10.0, 10.0), seed=1):
    """Two-Gaussian grey-level sample (float) and its true labels (True = bright)."""
    rng = np.random.default_rng(seed)
    n_low = int(frac * n)
    values = np.concatenate(
        [rng.normal(mu[0], sigma[0], n_low), rng.normal(mu[1], sigma[1], n - n_low)]
    )
    labels = np.arange(n) >= n_low
    order = rng.permutation(n)
    return values[order].reshape(400, -1), labels[order].reshape(400, -1)


def test_gaussian_mixture_threshold_between_modes_and_p0_near_mixing_fraction():
    # Tsai's threshold is the p0-tile, so it sits where a fraction p0 of the pixels
    # lies below it: with well-separated modes a small p0 error moves it into the
    # tail of one mode (here ~156 DN for p0 = 0.356); what is stable is the split
    # itself: the misclassified fraction is about |p0 - frac|.
    frac = 0.35
    values, labels = _bimodal(frac=frac)
    for image in (values, np.clip(np.rint(values), 0, 255).astype(np.uint8)):
        result = tsai_moment_threshold(image)
        assert 60.0 < result.threshold < 180.0
        assert abs(result.p0 - frac) < 0.01
        assert abs(result.z0 - 60.0) < 2.0 and abs(result.z1 - 180.0) < 2.0
        assert np.mean((image > result.threshold) != labels) < 0.01
        otsu = otsu_threshold(image)
        assert 60.0 < otsu < 180.0
        assert np.mean((image > otsu) != labels) < 0.01


def test_mask_restricts_pixels():
    image = _two_level(40, 200, 0.3).astype(np.uint8)
    mask = np.ones(image.shape, bool)
    image_with_junk = image.copy()
    image_with_junk[:5] = 255
    mask[:5] = False
    full = tsai_moment_threshold(image[5:])
    masked = tsai_moment_threshold(image_with_junk, mask=mask)
    assert masked == full


def test_affine_intensity_change_scales_threshold():
    base, _ = _bimodal(n=40_000)
    ref = tsai_moment_threshold(base)
    gain, bias = 0.0125, -0.3
    moved = tsai_moment_threshold(gain * base + bias)
    assert moved.threshold == pytest.approx(gain * ref.threshold + bias, rel=1e-12, abs=1e-12)
    assert moved.z0 == pytest.approx(gain * ref.z0 + bias, rel=1e-9, abs=1e-12)
    assert moved.z1 == pytest.approx(gain * ref.z1 + bias, rel=1e-9, abs=1e-12)
    assert moved.p0 == pytest.approx(ref.p0, abs=1e-9)
    # Otsu on floats is quantised to 1/255 of the range: equal up to that
    otsu_ref, otsu_moved = otsu_threshold(base), otsu_threshold(gain * base + bias)
    step = gain * (base.max() - base.min()) / 255
    assert abs(otsu_moved - (gain * otsu_ref + bias)) <= step * (1 + 1e-9)


def test_constant_image_raises():
    with pytest.raises(ValueError, match="constant"):
        tsai_moment_threshold(np.full((8, 8), 7, np.uint8))
    with pytest.raises(ValueError, match="constant"):
        tsai_moment_threshold(np.full((8, 8), 0.5))
    with pytest.raises(ValueError, match="constant"):
        otsu_threshold(np.full((8, 8), 7, np.uint8))


def test_bad_inputs_raise():
    with pytest.raises(ValueError, match="2D"):
        tsai_moment_threshold(np.zeros((2, 3, 3)))
    with pytest.raises(ValueError, match="NaN"):
        tsai_moment_threshold(np.array([[0.0, np.nan], [1.0, 2.0]]))
    with pytest.raises(ValueError, match="mask"):
        tsai_moment_threshold(np.eye(3), mask=np.ones((2, 2), bool))
    with pytest.raises(ValueError, match="none"):
        tsai_moment_threshold(np.eye(3), mask=np.zeros((3, 3), bool))
    with pytest.raises(ValueError, match="dtype"):
        tsai_moment_threshold(np.eye(3, dtype=bool))
