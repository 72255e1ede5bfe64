"""Names of a sample's cameras, lightings and images: written once, used by every layer.

A sample has two cameras (the conventional stereo pair) and two lightings (passive: the
overhead light that shows the plate's boundary; active: the projected square grid), so
four images named ``{camera}_{lighting}``: ``left_passive``, ``right_passive``,
``left_active``, ``right_active``.
"""
from __future__ import annotations

__all__ = ["CAMERAS", "LIGHTINGS", "IMAGE_NAMES", "image_name", "image_seed"]

CAMERAS = ("left", "right")
LIGHTINGS = ("passive", "active")
IMAGE_NAMES = tuple(f"{c}_{lt}" for lt in LIGHTINGS for c in CAMERAS)


def image_name(camera: str, lighting: str) -> str:
    """``'left', 'active'`` -> ``'left_active'`` (ValueError for an unknown camera or lighting)."""
    if camera not in CAMERAS or lighting not in LIGHTINGS:
        raise ValueError(f"image ({camera!r}, {lighting!r}) is unknown: cameras {CAMERAS}, lightings {LIGHTINGS}")
    return f"{camera}_{lighting}"


def image_seed(base_seed: int, camera: str, lighting: str) -> int:
    """Distinct, reproducible seed for each of a sample's four images."""
    return base_seed * 4 + CAMERAS.index(camera) * 2 + LIGHTINGS.index(lighting)
