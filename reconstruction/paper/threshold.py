"""Global grey-level thresholds: Tsai's moment-preserving bilevel threshold and Otsu.

The paper (Chen & Zheng 1995, section V-C) thresholds its images with the bilevel
moment-preserving method of Tsai (1985): replace the grey-level distribution by two
levels z0 < z1, with a fraction p0 of the pixels at z0, such that the first three
moments m1, m2, m3 (and m0 = 1) are preserved. With

    cd = m0*m2 - m1**2,  c0 = (m1*m3 - m2**2) / cd,  c1 = (m1*m2 - m0*m3) / cd,

z0 and z1 are the roots of z**2 + c1*z + c0 = 0, p0 = (z1 - m1) / (z1 - z0), and the
threshold is the p0-tile of the grey levels.

Conventions (both functions): thresholds are in the image's own units (DN for
integer images, the float values otherwise) and the foreground (bright class) is
``image > threshold``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["TsaiThreshold", "tsai_moment_threshold", "otsu_threshold"]


@dataclass(frozen=True)
class TsaiThreshold:
    """Result of :func:`tsai_moment_threshold` (grey levels in image units).

    threshold: split level; dark class = ``image <= threshold``, bright class =
        ``image > threshold``. It lies halfway between the brightest level of the
        dark class and the next occupied level, so ``>`` and ``>=`` agree.
    z0, z1: the two representative levels (z0 < z1) whose two-level image has the
        same first three moments as the input.
    p0: fraction of pixels the moment-preserving model puts at z0 (0 < p0 < 1).
    """

    threshold: float
    z0: float
    z1: float
    p0: float


def _checked_values(image, mask) -> np.ndarray:
    """Return the 1D array of pixel values selected by ``mask`` (validated)."""
    image = np.asarray(image)
    if image.ndim != 2:
        raise ValueError(f"image must be a 2D grey image, got shape {image.shape}")
    if image.dtype.kind not in "uif":
        raise ValueError(f"image dtype {image.dtype} not allowed; use an integer or float image")
    if mask is None:
        values = image.ravel()
    else:
        mask = np.asarray(mask)
        if mask.shape != image.shape or mask.dtype != bool:
            raise ValueError(
                f"mask must be a bool array of the image's shape {image.shape}, "
                f"got {mask.dtype} {mask.shape}"
            )
        values = image[mask]
    if values.size == 0:
        raise ValueError("no pixels to threshold: image is empty or mask selects none")
    if values.dtype.kind == "f" and not np.all(np.isfinite(values)):
        raise ValueError("image has NaN or infinite values among the pixels used; mask them out")
    return values


def _grey_levels(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Occupied grey levels (ascending, float64) and their pixel counts."""
    if values.dtype.kind in "ui":
        lo = int(values.min())
        span = int(values.max()) - lo
        if span < 1 << 24:  # histogram (fast path for 8/16-bit images)
            flat = values.ravel()
            counts = (np.bincount(flat)[lo:] if values.dtype.kind == "u" and values.itemsize <= 2
                      else np.bincount((flat.astype(np.int64) - lo), minlength=span + 1))
            occupied = np.flatnonzero(counts)
            return (occupied + lo).astype(np.float64), counts[occupied].astype(np.float64)
    if values.dtype.kind == "f" and values.size:  # a float copy of an 8/16-bit image: its histogram, no sort
        lo, hi = float(values.min()), float(values.max())
        if 0.0 <= lo and hi < 1 << 16 and np.array_equal(values, np.floor(values)):
            return _grey_levels(values.astype(np.uint16))
    levels, counts = np.unique(values.astype(np.float64), return_counts=True)
    return levels, counts.astype(np.float64)


def tsai_moment_threshold(image, mask=None) -> TsaiThreshold:
    """Tsai's (1985) bilevel moment-preserving threshold of a grey image.

    Args:
        image: 2D uint8, uint16 (any integer) or float array. Integer images use
            their histogram; float images use the values themselves.
        mask: optional bool array of the image's shape; only pixels where it is
            True are used.

    The moments are computed on the grey levels standardised to zero mean and unit
    variance (an affine change that the moment equations commute with) for numerical
    conditioning; z0 and z1 are mapped back to image units. The threshold is the
    p0-tile: the dark class is the smallest set of whole grey levels whose pixel
    fraction is closest to p0 (both classes non-empty), and the threshold is placed
    halfway to the next occupied level.

    Raises:
        ValueError: bad image/mask, or fewer than two distinct grey levels.
    """
    levels, counts = _grey_levels(_checked_values(image, mask))
    if levels.size < 2:
        raise ValueError(
            f"image is constant (single grey level {levels[0]:g}) over the pixels used; "
            "a bilevel threshold needs at least two grey levels"
        )
    prob = counts / counts.sum()
    mean = float(prob @ levels)
    std = float(np.sqrt(prob @ (levels - mean) ** 2))
    if not std > 0.0:
        raise ValueError("image grey levels have zero variance; a bilevel threshold needs two levels")
    w = (levels - mean) / std
    m0, m1, m2, m3 = 1.0, float(prob @ w), float(prob @ w**2), float(prob @ w**3)
    cd = m0 * m2 - m1 * m1
    c0 = (m1 * m3 - m2 * m2) / cd
    c1 = (m1 * m2 - m0 * m3) / cd
    root = np.sqrt(c1 * c1 - 4.0 * c0)  # c0 ~ -1 < 0, so the roots are real and distinct
    w0, w1 = (-c1 - root) / 2.0, (-c1 + root) / 2.0
    p0 = (w1 - m1) / (w1 - w0)

    cdf = np.cumsum(prob)[:-1]  # fraction <= each level; the top level would empty class 1
    k = int(np.argmin(np.abs(cdf - p0)))
    threshold = 0.5 * (levels[k] + levels[k + 1])
    return TsaiThreshold(
        threshold=float(threshold),
        z0=float(mean + std * w0),
        z1=float(mean + std * w1),
        p0=float(p0),
    )


def otsu_threshold(image) -> float:
    """Otsu's threshold via ``cv2.threshold(..., THRESH_OTSU)``, in image units.

    uint8 and uint16 images go to OpenCV unchanged and the returned value is
    OpenCV's integer level T (foreground = ``image > T``). Any other image (float,
    other integer types) is first mapped linearly to uint8 by
    ``round(255 * (image - min) / (max - min))`` (min-max scaling, so negative values
    are fine) and the level is mapped back to image units as the value halfway
    between the 8-bit bins T and T + 1, i.e. ``min + (T + 0.5) * (max - min) / 255``;
    that quantises the result to 1/255 of the image's range.

    Raises:
        ValueError: not a finite 2D numeric image, or a constant image.
    """
    values = _checked_values(image, None)
    image = np.asarray(image)
    lo, hi = values.min(), values.max()
    if lo == hi:
        raise ValueError(f"image is constant ({float(lo):g}); Otsu needs at least two grey levels")
    if image.dtype in (np.uint8, np.uint16):
        maxval = float(np.iinfo(image.dtype).max)
        level, _ = cv2.threshold(np.ascontiguousarray(image), 0, maxval, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
        return float(level)
    lo, hi = float(lo), float(hi)
    scaled = np.rint((image.astype(np.float64) - lo) * (255.0 / (hi - lo))).astype(np.uint8)
    level, _ = cv2.threshold(scaled, 0, 255, cv2.THRESH_BINARY | cv2.THRESH_OTSU)
    return lo + (float(level) + 0.5) * (hi - lo) / 255.0
