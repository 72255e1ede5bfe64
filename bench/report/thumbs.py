"""Thumbnails: small 8-bit PNG copies of a sample's camera images, written next to the report.

A sample's ``images/{left,right}_{passive,active}.png`` are 8- or 16-bit camera DN (see
``bench.io.sample_files``); a thumbnail is the image scaled to ``width`` pixels (area
averaging, OpenCV), 16-bit data shifted to 8 bits, written atomically as PNG.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from platebench.bench.io.atomic import write_bytes
from platebench.scenes.naming import IMAGE_NAMES

__all__ = ["write_thumbnail", "sample_thumbnails", "THUMB_WIDTH"]

THUMB_WIDTH = 200  # pixels


def write_thumbnail(image_path: Path, out_path: Path, width: int = THUMB_WIDTH) -> Path | None:
    """Write a ``width``-pixel-wide 8-bit PNG of ``image_path``; None when the image is missing or
    unreadable (the caller says so in the page)."""
    img = cv2.imread(str(image_path), cv2.IMREAD_UNCHANGED)
    if img is None or img.ndim not in (2, 3) or img.shape[1] == 0:
        return None
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    elif img.dtype != np.uint8:
        return None
    h, w = img.shape[:2]
    size = (width, max(1, round(h * width / w)))
    small = cv2.resize(img, size, interpolation=cv2.INTER_AREA) if w > width else img
    ok, buf = cv2.imencode(".png", small)
    if not ok:
        return None
    write_bytes(Path(out_path), buf.tobytes())
    return Path(out_path)


def sample_thumbnails(sample_dir: Path, out_dir: Path, prefix: str, names=IMAGE_NAMES) -> list[dict]:
    """Thumbnails of a sample's camera images into ``out_dir``: [{"name", "file" (name in out_dir)
    or None when the image is missing/unreadable}] in ``names`` order."""
    out = []
    for name in names:
        path = write_thumbnail(Path(sample_dir) / "images" / f"{name}.png", Path(out_dir) / f"{prefix}{name}.png")
        out.append({"name": name, "file": path.name if path is not None else None})
    return out
