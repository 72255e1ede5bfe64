"""Ground-truth derivations for scoring (pure functions; may read the plate, never the renderer).

* True square centres: the projector ray through each pattern feature's centre,
  intersected with the plate mesh (trimesh ray casting, world frame, metres).
* Squares each camera sees: feature ids present in the camera's ground-truth
  feature map (lit, unoccluded, in view) over at least half of their typical area.
* Expected squares inside the true boundary: features whose ray hits the plate.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from platebench.scenes.camera import Camera

if TYPE_CHECKING:
    import trimesh  # annotations only: importing trimesh takes a second


def true_feature_points(mesh: trimesh.Trimesh, projector: Camera, feature_centers: np.ndarray) -> np.ndarray:
    """(N,3) first hit of each feature's centre ray with the mesh; NaN where it misses."""
    o, d = projector.rays(np.asarray(feature_centers, float).reshape(-1, 2))
    origins = np.repeat(o[None], len(d), 0)
    locs, idx, _ = mesh.ray.intersects_location(origins, d, multiple_hits=False)
    out = np.full((len(d), 3), np.nan)
    out[idx] = locs
    return out


@dataclass(frozen=True)
class FeatureVisibility:
    """Which feature ids each camera sees, and how many features land on the plate."""

    seen: dict  # camera -> sorted list of ids
    on_plate: tuple[int, ...]

    def visible_in_both(self) -> set:
        return set(self.seen["left"]) & set(self.seen["right"])


def feature_visibility(feature_maps: dict, true_points: np.ndarray, ids: np.ndarray,
                       min_fraction: float = 0.5) -> FeatureVisibility:
    """Ids seen by each camera (>= ``min_fraction`` of the median lit area) and ids on the plate."""
    seen = {}
    for cam, fmap in feature_maps.items():
        vals, counts = np.unique(fmap[fmap >= 0], return_counts=True)
        if counts.size:
            keep = counts >= min_fraction * np.median(counts)
            seen[cam] = sorted(int(v) for v in vals[keep])
        else:
            seen[cam] = []
    on_plate = tuple(int(i) for i, p in zip(ids, true_points) if np.all(np.isfinite(p)))
    return FeatureVisibility(seen, on_plate)


def feature_at_pixels(feature_map: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Ground-truth feature id at (N,2) pixel positions (nearest pixel; -1 outside)."""
    uv = np.asarray(uv, float).reshape(-1, 2)
    H, W = feature_map.shape
    u = np.rint(uv[:, 0]).astype(int)
    v = np.rint(uv[:, 1]).astype(int)
    ok = (u >= 0) & (u < W) & (v >= 0) & (v < H)
    out = np.full(len(uv), -1)
    out[ok] = feature_map[v[ok], u[ok]]
    return out
