"""Synthetic camera images with known sub-pixel geometry (the first rung of the test ladder).

``polygon_image`` draws convex polygons by their exact area coverage of every pixel (pixel
(u, v) covers [u-0.5, u+0.5] x [v-0.5, v+0.5]: OpenCV's convention, centres at integers), so
an edge's sub-pixel position, a corner and an area-weighted centroid are known exactly.
"""
from __future__ import annotations

import numpy as np


def _clip(poly: list, a: float, b: float, c: float) -> list:
    """Sutherland-Hodgman: the part of polygon ``poly`` with a x + b y <= c."""
    out = []
    n = len(poly)
    for i in range(n):
        p, q = poly[i], poly[(i + 1) % n]
        fp, fq = a * p[0] + b * p[1] - c, a * q[0] + b * q[1] - c
        if fp <= 0:
            out.append(p)
        if fp * fq < 0:
            t = fp / (fp - fq)
            out.append((p[0] + t * (q[0] - p[0]), p[1] + t * (q[1] - p[1])))
    return out


def _area(poly: list) -> float:
    if len(poly) < 3:
        return 0.0
    x = np.array([p[0] for p in poly])
    y = np.array([p[1] for p in poly])
    return 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def coverage(polygon: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """(H, W) fraction of each pixel covered by a convex ``polygon`` ((N, 2) u, v, any winding)."""
    P = np.asarray(polygon, float)
    d1, d2 = P[1] - P[0], P[2] - P[1]
    if d1[0] * d2[1] - d1[1] * d2[0] < 0:
        P = P[::-1]
    H, W = shape
    out = np.zeros(shape)
    u0, v0 = np.floor(P.min(axis=0) + 0.5).astype(int)
    u1, v1 = np.ceil(P.max(axis=0) - 0.5).astype(int)
    edges = [(P[i], P[(i + 1) % len(P)]) for i in range(len(P))]
    # half-planes a u + b v >= c of a counter-clockwise polygon (image axes: u right, v down)
    planes = np.array([(-(q[1] - p[1]), (q[0] - p[0]), -(q[1] - p[1]) * p[0] + (q[0] - p[0]) * p[1])
                       for p, q in edges])
    us = np.arange(max(u0, 0), min(u1, W - 1) + 1)
    vs = np.arange(max(v0, 0), min(v1, H - 1) + 1)
    if not us.size or not vs.size:
        return out
    uu, vv = np.meshgrid(us, vs)
    offsets = np.array([[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]])
    cu = uu[..., None] + offsets[:, 0]  # (h, w, 4) pixel corners
    cv = vv[..., None] + offsets[:, 1]
    side = planes[:, 0, None, None, None] * cu + planes[:, 1, None, None, None] * cv - planes[:, 2, None, None, None]
    inside = (side >= 0).all(axis=(0, 3))
    outside = (side <= 0).all(axis=3).any(axis=0)
    out[vv[inside], uu[inside]] = 1.0
    for v, u in zip(vv[~inside & ~outside], uu[~inside & ~outside]):
        cell = [(u + dx, v + dy) for dx, dy in offsets]
        for a, b, c in planes:
            cell = _clip(cell, -a, -b, -c)
            if not cell:
                break
        out[v, u] = _area(cell)
    return out


def polygon_image(polygons, shape=(240, 320), background=10.0, level=200.0, dtype=np.uint8) -> np.ndarray:
    """An image of bright convex ``polygons`` on a dark background, exact area anti-aliasing,
    quantised to ``dtype`` (uint8: 0..255)."""
    cov = np.zeros(shape)
    for poly in polygons:
        cov += coverage(poly, shape)
    img = background + (level - background) * np.clip(cov, 0.0, 1.0)
    if np.issubdtype(dtype, np.integer):
        return np.clip(np.rint(img), 0, np.iinfo(dtype).max).astype(dtype)
    return img.astype(dtype)


def square(center, side: float, angle_rad: float = 0.0) -> np.ndarray:
    """(4, 2) corners of a square (u, v pixels) centred at ``center``."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    R = np.array([[c, -s], [s, c]])
    h = side / 2.0
    return np.asarray(center, float) + np.array([[-h, -h], [h, -h], [h, h], [-h, h]]) @ R.T


def weighted_centroid(img: np.ndarray) -> np.ndarray:
    """(u, v) centroid of an (H, W) weight image, pixel centres at integers (OpenCV's convention)."""
    vv, uu = np.mgrid[0:img.shape[0], 0:img.shape[1]]
    w = img.sum()
    return np.array([(uu * img).sum() / w, (vv * img).sum() / w])
