"""The family recipe's toy (docs/extending.md): a ripple along the plate's length, the height field
z = amplitude_m sin(2 pi u / wavelength_m) over the flat plate, registered as "toy_ripple".

One module: the frozen dataclass with its keys, its validation, its curvature bound, its defaults
and its exact surface, registered by ``register_family``; ``tests/test_recipes.py`` tests it."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

from platebench.plates.spec import DeformationFamily, PlateSpecError, register_family
from platebench.plates.surfaces import height_field


@register_family
@dataclass(frozen=True)
class Ripple(DeformationFamily):
    """A sine ripple along u: z = amplitude_m sin(2 pi u / wavelength_m), (x, y) = (u, v); metres."""

    amplitude_m: float
    wavelength_m: float
    family: ClassVar[str] = "toy_ripple"
    label: ClassVar[str] = "toy ripple"
    layout: ClassVar[str] = "grid"  # meshed on a tensor grid sized from the sampled second derivatives
    in_default_study: ClassVar[bool] = False

    def __post_init__(self) -> None:
        if not (isinstance(self.wavelength_m, (int, float)) and self.wavelength_m > 0):
            raise PlateSpecError(f"Ripple.wavelength_m = {self.wavelength_m!r} is out of range: allowed > 0 m")
        object.__setattr__(self, "amplitude_m", float(self.amplitude_m))
        object.__setattr__(self, "wavelength_m", float(self.wavelength_m))

    def max_curvature_per_m(self, length_m: float, width_m: float) -> float:
        return abs(self.amplitude_m) * (2.0 * math.pi / self.wavelength_m) ** 2

    @classmethod
    def defaults(cls, length_m: float, width_m: float) -> "Ripple":
        return cls(0.01 * length_m, 0.5 * length_m)

    def surface(self, length_m: float, width_m: float, u, v, xp):
        k = xp.const(2.0 * math.pi / self.wavelength_m)
        a = xp.const(self.amplitude_m)
        return height_field(u, v, a * xp.sin(k * u), a * k * xp.cos(k * u), xp.zeros_like(u), xp)
