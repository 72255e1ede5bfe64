"""Projector patterns: the paper's square grid (section III, Fig. 5-6), or any image.

Pattern pixels follow the camera convention of ``scenes.camera``: pixel centres at
integer (u, v), u right, v down. A square occupying pixel columns c0..c0+s-1 has
its edges at c0-0.5 and c0+s-0.5 and its centre at c0+(s-1)/2.

Every feature has an integer id (``row * cols + col``); ``feature_map`` gives the
id of the feature that owns each pattern pixel (-1 for none), so ground truth can
say which feature lit which camera pixel.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from platebench.scenes.camera import centred_principal_point


@dataclass(frozen=True)
class Feature:
    """One projected feature: id, grid row/column, centre and corners in projector pixels."""

    id: int
    row: int
    col: int
    center: tuple[float, float]
    corners: tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class Pattern:
    """A projector image (H,W) float32 in [0,1], its features and per-pixel feature ids."""

    image: np.ndarray
    features: tuple[Feature, ...] = ()
    feature_map: np.ndarray | None = None
    description: dict = field(default_factory=dict)

    def __post_init__(self):
        img = np.asarray(self.image, dtype=np.float32)
        if img.ndim != 2 or min(img.shape) < 1:
            raise ValueError(f"pattern image must be 2-D (H,W), got shape {img.shape}")
        if not np.all(np.isfinite(img)) or img.min() < 0 or img.max() > 1:
            raise ValueError("pattern image values must be finite and in [0, 1]")
        object.__setattr__(self, "image", img)
        fmap = self.feature_map
        if fmap is None:
            fmap = np.full(img.shape, -1, np.int32)
        fmap = np.asarray(fmap, np.int32)
        if fmap.shape != img.shape:
            raise ValueError(f"feature_map shape {fmap.shape} differs from image {img.shape}")
        object.__setattr__(self, "feature_map", fmap)

    @property
    def width(self) -> int:
        return self.image.shape[1]

    @property
    def height(self) -> int:
        return self.image.shape[0]

    def feature_at(self, uv) -> np.ndarray:
        """Feature id lighting continuous projector coordinates (N,2); -1 for none/outside."""
        uv = np.atleast_2d(np.asarray(uv, float))
        ok = np.all(np.isfinite(uv), axis=1)
        ids = np.full(len(uv), -1, np.int32)
        col = np.floor(uv[ok, 0] + 0.5).astype(int)
        row = np.floor(uv[ok, 1] + 0.5).astype(int)
        inside = (col >= 0) & (col < self.width) & (row >= 0) & (row < self.height)
        sub = np.full(len(col), -1, np.int32)
        sub[inside] = self.feature_map[row[inside], col[inside]]
        ids[ok] = sub
        return ids


@dataclass(frozen=True)
class SquareGridLayout:
    """The layout of a square grid (``square_grid``; its pattern's ``description``): rows and
    columns of squares, a square's side, the gap between squares in x and between rows, and the
    top-left square's corner, in projector pixels. A description holds ``"kind": "square_grid"``
    and then these fields by name."""

    rows: int
    cols: int
    square_px: int
    gap_x_px: int
    gap_y_px: int
    x0: int
    y0: int


def square_grid(width: int, height: int, rows: int = 4, cols: int = 4, square_px: int = 40,
                gap_x_px: int = 24, gap_y_px: int = 80, center=None) -> Pattern:
    """The paper's array of squares: ``rows`` horizontal square arrays of ``cols`` squares.

    Section III's Fig. 6 conditions ask for a small spacing between squares adjacent
    in x (``gap_x_px``) and a large spacing between rows (``gap_y_px``).
    ``center`` is the grid centre in projector pixels (default: image centre).
    """
    for name, v, lo in (("rows", rows, 1), ("cols", cols, 1), ("square_px", square_px, 2),
                        ("gap_x_px", gap_x_px, 1), ("gap_y_px", gap_y_px, 1)):
        if int(v) != v or v < lo:
            raise ValueError(f"square_grid {name} = {v} is out of range: allowed integer >= {lo}")
    span_x = cols * square_px + (cols - 1) * gap_x_px
    span_y = rows * square_px + (rows - 1) * gap_y_px
    if center is None:
        center = centred_principal_point(width, height)
    x0 = int(round(center[0] - (span_x - 1) / 2.0))
    y0 = int(round(center[1] - (span_y - 1) / 2.0))
    if x0 < 0 or y0 < 0 or x0 + span_x > width or y0 + span_y > height:
        raise ValueError(f"square grid of {span_x}x{span_y} px does not fit a {width}x{height} pattern")
    image = np.zeros((height, width), np.float32)
    fmap = np.full((height, width), -1, np.int32)
    features = []
    for r in range(rows):
        for c in range(cols):
            c0 = x0 + c * (square_px + gap_x_px)
            r0 = y0 + r * (square_px + gap_y_px)
            fid = r * cols + c
            image[r0:r0 + square_px, c0:c0 + square_px] = 1.0
            fmap[r0:r0 + square_px, c0:c0 + square_px] = fid
            lo_u, hi_u = c0 - 0.5, c0 + square_px - 0.5
            lo_v, hi_v = r0 - 0.5, r0 + square_px - 0.5
            features.append(Feature(fid, r, c, (c0 + (square_px - 1) / 2.0, r0 + (square_px - 1) / 2.0),
                                    ((lo_u, lo_v), (hi_u, lo_v), (hi_u, hi_v), (lo_u, hi_v))))
    desc = {"kind": "square_grid", **asdict(SquareGridLayout(rows, cols, square_px, gap_x_px, gap_y_px, x0, y0))}
    return Pattern(image, tuple(features), fmap, desc)


def from_image(image, description: str = "user image") -> Pattern:
    """Wrap any user image (H,W) in [0,1] as a pattern with no numbered features."""
    return Pattern(np.asarray(image, np.float32), (), None, {"kind": "image", "note": description})


def uniform(width: int, height: int, level: float = 1.0) -> Pattern:
    """A flat field (the projector as a plain light)."""
    return Pattern(np.full((height, width), level, np.float32), (), None, {"kind": "uniform", "level": level})
