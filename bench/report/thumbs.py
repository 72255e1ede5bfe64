"""Thumbnails: small 8-bit PNG copies of a sample's camera images, embedded in the report page.

A sample's ``images/{left,right}_{passive,active}.png`` are 8- or 16-bit camera DN (see
``bench.io.sample_files``); a thumbnail is the image scaled to ``width`` pixels (area
averaging, OpenCV), 16-bit data shifted to 8 bits, encoded as PNG bytes. The page embeds them
as data URIs, so that ``index.html`` alone shows them (no thumbnail files are written).
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from platebench.scenes.naming import IMAGE_NAMES

__all__ = ["thumbnail_png", "sample_thumbnails", "THUMB_WIDTH"]

THUMB_WIDTH = 200  # pixels


def thumbnail_png(image_path: Path, width: int = THUMB_WIDTH) -> bytes | None:
    """PNG bytes of a ``width``-pixel-wide 8-bit copy of ``image_path``; None when the image is missing
    or unreadable (the caller says so in the page)."""
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
    return buf.tobytes() if ok else None


def sample_thumbnails(sample_dir: Path, names=IMAGE_NAMES) -> list[dict]:
    """Thumbnails of a sample's camera images: [{"name", "png" (bytes, or None when the image is
    missing/unreadable)}] in ``names`` order."""
    return [{"name": n, "png": thumbnail_png(Path(sample_dir) / "images" / f"{n}.png")} for n in names]
