"""What a camera gives: radiance -> digital numbers (response curve, bit depth, noise).

Pure numpy. ``radiance_full_scale`` is the linear radiance that saturates the sensor.
Noise (shot noise with ``full_well_e`` electrons at full scale, Gaussian read noise in
DN) is seeded: the same seed gives the same bytes. The default is noise-free, linear,
8-bit: the renders' Monte Carlo noise is then the only noise.
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

    def __post_init__(self):
        if self.bit_depth not in (8, 16):
            raise ValueError(f"bit_depth = {self.bit_depth} is not allowed: choose 8 or 16")
        if not self.radiance_full_scale > 0:
            raise ValueError(f"radiance_full_scale = {self.radiance_full_scale} is out of range: allowed > 0")
        if not (0.1 <= self.gamma <= 10):
            raise ValueError(f"gamma = {self.gamma} is out of range: allowed 0.1 to 10")
        if self.full_well_e < 0 or self.read_noise_dn < 0:
            raise ValueError("full_well_e and read_noise_dn must be >= 0")

    @property
    def max_dn(self) -> int:
        return (1 << self.bit_depth) - 1

    def digitize(self, radiance: np.ndarray, seed: int = 0) -> np.ndarray:
        """Linear radiance (H,W) -> uint8/uint16 digital numbers."""
        x = np.clip(np.asarray(radiance, np.float64) / self.radiance_full_scale, 0.0, None)
        rng = np.random.default_rng(seed)
        if self.full_well_e > 0:
            x = rng.poisson(x * self.full_well_e) / self.full_well_e
        x = np.clip(x, 0.0, 1.0) ** (1.0 / self.gamma)
        dn = x * self.max_dn
        if self.read_noise_dn > 0:
            dn = dn + rng.normal(0.0, self.read_noise_dn, dn.shape)
        dn = np.clip(np.rint(dn), 0, self.max_dn)
        return dn.astype(np.uint8 if self.bit_depth == 8 else np.uint16)

    def to_dict(self) -> dict:
        return {"bit_depth": self.bit_depth, "radiance_full_scale": self.radiance_full_scale, "gamma": self.gamma,
                "full_well_e": self.full_well_e, "read_noise_dn": self.read_noise_dn}
