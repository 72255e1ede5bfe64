"""Thumbnails: small 8-bit PNG copies of a sample's camera images, embedded in the report page.

A sample's ``images/{left,right}_{passive,active}.png`` are 8- or 16-bit camera DN (see
``bench.io.sample_files``); a thumbnail is the image scaled to ``width`` pixels (area
averaging, OpenCV), 16-bit data shifted to 8 bits, encoded as PNG bytes. The page embeds them
as data URIs, so that ``index.html`` alone shows them (no thumbnail files are written). The image
is read with ``bench.io.images.read_png`` (its size checked from the header before decoding, a
truncated or damaged file refused), and only from inside the sample: an image that is a symbolic
link, or leads out of the sample folder, is not read.
"""
from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from platebench.bench.io.images import DatasetError, read_png
from platebench.scenes.naming import IMAGE_NAMES

__all__ = ["thumbnail_png", "sample_thumbnails", "image_problem", "THUMB_WIDTH"]

THUMB_WIDTH = 200  # pixels


def image_problem(sample_dir: Path, image_path: Path) -> str | None:
    """Why ``image_path`` may not be shown from ``sample_dir`` (a link, a path leading out of the
    sample, missing), or None."""
    sample_dir, image_path = Path(sample_dir), Path(image_path)
    rel = image_path.relative_to(sample_dir)
    p = sample_dir
    for part in rel.parts:
        p = p / part
        if os.path.islink(p):
            return f"{p} is a symbolic link (to {os.readlink(p)}): not followed out of the sample"
    if not image_path.resolve().is_relative_to(sample_dir.resolve()):
        return f"{image_path} leads out of its sample folder: not shown"
    if not image_path.is_file():
        return f"{image_path} is missing"
    return None


def thumbnail_png(image_path: Path, width: int = THUMB_WIDTH) -> bytes:
    """PNG bytes of a ``width``-pixel-wide 8-bit copy of ``image_path``; ``DatasetError`` (one line
    naming the file) when the image is missing, truncated, damaged or too large."""
    img = read_png(image_path)
    if img.dtype == np.uint16:
        img = (img >> 8).astype(np.uint8)
    h, w = img.shape[:2]
    size = (width, max(1, round(h * width / w)))
    small = cv2.resize(img, size, interpolation=cv2.INTER_AREA) if w > width else img
    ok, buf = cv2.imencode(".png", small)
    if not ok:
        raise DatasetError(f"{image_path}: its thumbnail could not be encoded")
    return buf.tobytes()


def sample_thumbnails(sample_dir: Path, names=IMAGE_NAMES, check=None) -> list[dict]:
    """Thumbnails of a sample's camera images: [{"name", "png" (bytes, or None when not shown),
    "problem" (why not shown, or None)}] in ``names`` order. ``check(image_path)``: a further test
    (a checksum) raising ``DatasetError`` when the image may not be shown."""
    out = []
    for name in names:
        image = Path(sample_dir) / "images" / f"{name}.png"
        problem = image_problem(sample_dir, image)
        png = None
        if problem is None:
            try:
                if check is not None:
                    check(image)
                png = thumbnail_png(image)
            except DatasetError as e:
                problem = str(e)
        out.append({"name": name, "png": png, "problem": problem})
    return out
