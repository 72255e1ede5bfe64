"""What a camera gives: radiance -> digital numbers (response curve, bit depth, noise).

Pure numpy (and scipy's interpolation). ``radiance_full_scale`` is the linear radiance that
saturates the sensor. Noise (shot noise with ``full_well_e`` electrons at full scale, Gaussian
read noise in DN) is seeded: the same seed gives the same bytes. The default is noise-free,
linear, 8-bit: the renders' Monte Carlo noise is then the only noise.

``line_jitter_px`` > 0 models an analogue frame grabber's line jitter: its pixel clock is
re-locked to every line's sync pulse, so each image row is sampled shifted horizontally by its
own amount, drawn N(0, line_jitter_px^2) per row (seeded, from a stream of its own: switching
it on changes no noise draw). Row j of the output is the camera's row j sampled at
``u + shift_j`` (linear interpolation along the row, edge values held), after the camera's
shot noise and response curve and before the grabber's read noise and quantisation. The
geometry it disturbs is the image's, never the ground truth's.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class SensorModel:
    bit_depth: int = 8
    radiance_full_scale: float = 1.0
    gamma: float = 1.0  # DN ~ (radiance / full_scale) ** (1 / gamma)
    full_well_e: float = 0.0  # 0: no shot noise
    read_noise_dn: float = 0.0
    line_jitter_px: float = 0.0  # std of the per-row horizontal shift (px); 0: none

    def __post_init__(self):
        if self.bit_depth not in (8, 16):
            raise ValueError(f"bit_depth = {self.bit_depth} is not allowed: choose 8 or 16")
        if not self.radiance_full_scale > 0:
            raise ValueError(f"radiance_full_scale = {self.radiance_full_scale} is out of range: allowed > 0")
        if not (0.1 <= self.gamma <= 10):
            raise ValueError(f"gamma = {self.gamma} is out of range: allowed 0.1 to 10")
        if self.full_well_e < 0 or self.read_noise_dn < 0:
            raise ValueError("full_well_e and read_noise_dn must be >= 0")
        if not (np.isfinite(self.line_jitter_px) and 0.0 <= self.line_jitter_px <= 5.0):
            raise ValueError(f"line_jitter_px = {self.line_jitter_px} is out of range: allowed 0 to 5 px")

    @property
    def max_dn(self) -> int:
        return (1 << self.bit_depth) - 1

    def digitize(self, radiance: np.ndarray, seed: int = 0) -> np.ndarray:
        """Linear radiance (H,W) -> uint8/uint16 digital numbers.

        In float64, in one working copy of the image (each step in place; a step that is the
        identity for this sensor, a full scale of 1 or a gamma of 1, is skipped: it would give the
        same bits)."""
        x = np.array(radiance, dtype=np.float64)
        if self.radiance_full_scale != 1.0:
            np.divide(x, self.radiance_full_scale, out=x)
        rng = np.random.default_rng(seed)
        if self.full_well_e > 0:
            np.clip(x, 0.0, None, out=x)
            x = rng.poisson(x * self.full_well_e) / self.full_well_e
        np.clip(x, 0.0, 1.0, out=x)
        if self.gamma != 1.0:
            x **= 1.0 / self.gamma  # numpy's ``**`` (its square root for 0.5), as the definition has it
        if self.line_jitter_px > 0:
            x = jitter_rows(x, line_shifts_px(x.shape[0], self.line_jitter_px, seed))
        np.multiply(x, self.max_dn, out=x)
        if self.read_noise_dn > 0:
            np.add(x, rng.normal(0.0, self.read_noise_dn, x.shape), out=x)
        np.rint(x, out=x)
        np.clip(x, 0, self.max_dn, out=x)
        return x.astype(np.uint8 if self.bit_depth == 8 else np.uint16)


def line_shifts_px(rows: int, sigma_px: float, seed: int) -> np.ndarray:
    """(rows,) seeded horizontal shift of each image row (px), N(0, sigma_px^2); the stream is the
    image's seed's own (``[seed, 1]``), apart from the noise draws of ``digitize``."""
    return np.random.default_rng([int(seed), 1]).normal(0.0, float(sigma_px), int(rows))


def jitter_rows(image: np.ndarray, shifts_px: np.ndarray) -> np.ndarray:
    """(H, W) image with row j resampled at ``u + shifts_px[j]`` (linear along the row, edges held)."""
    from scipy.ndimage import map_coordinates  # noqa: PLC0415  (only the jittered path needs it)
    img = np.asarray(image, np.float64)
    h, w = img.shape
    vv, uu = np.mgrid[0:h, 0:w].astype(np.float64)
    return map_coordinates(img, [vv, uu + np.asarray(shifts_px, float)[:, None]], order=1, mode="nearest")
