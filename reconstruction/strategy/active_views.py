"""Active stereo at every measuring pose, and the poses' measurements merged into one reconstruction.

The paper measures the surface once, at stage 3, with the projector on the boundary plane's normal.
Its section VI leaves the large bends to the future: "the three sensing stages should be applied
in different directions and distances, and repeated whenever needed". So every later measuring
pose (verification views, cures) also projects the square grid and measures the squares inside
its own outline by the paper's matching criteria (``square_stereo``). The projector rides with the
rig, ``PROJECTOR_OFFSET_M`` beside its centre line across the baseline (``projector_pose``), aimed
at the pose's target, its image x along the baseline: nearly the paper's condition for square
matching (the structured light's centre ray parallel to the optical axes, 4 degrees off at 0.4 m;
its plane parallel to the image planes), so pattern rows stay image rows.

A turned pose sees the plate obliquely, where the paper's matching can pair the wrong squares
(its Fig. 2: an array whose ends are cut differently in the two images, by an occluding contour,
can still hold equal counts and be matched k positions off). Each triangulated centre is therefore
checked against the projector's calibration, a third view: it must lie within ``ACTIVE_RAY_TOL_M``
of the calibrated ray of some projected feature, no other centre of the pose may claim that
feature, and each matched array must pass whole, on one pattern row with its columns in order
(``on_feature_rays``). A centre triangulated at a disparity k squares wrong lies on the left
camera's ray, off its true place; seen from the projector, it has moved along the left camera's
epipolar line by k times the projector's share of the parallax. From the mid-baseline point that
share is one half, so every even k would land exactly on a feature of the row.
``PROJECTOR_OFFSET_M`` (30 mm) across the 100 mm baseline slants that line across the grid's rows,
so that a centre matched k positions off lies off every feature ray (``tests/test_active_views.py``;
figures in docs/findings/design-record.md). ``ActivePoints.rejected`` counts what the check drops.

``merge`` puts every pose's measurements in one world-frame reconstruction: the merged boundary
of the verdict (``multiview.verify``), the checked square centres of all poses, and the surface as
the union of the poses' visible surfaces (``surface_model.view_membrane``: a pose's outline and
its square centres triangulated in its left image and lifted to 3D). World frame, metres.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.reconstruction.paper.false_boundary import FeatureRays
from platebench.reconstruction.paper.pipeline import square_stereo
from platebench.reconstruction.strategy.poses import SensorPose
from platebench.scenes.pattern import Pattern
from platebench.scenes.rig import StereoRig
from platebench.scenes.scene_spec import up_for_baseline

# A square centre lies within this of its feature's calibrated ray: the accepted centres of the 13
# later poses of the convex 240-degree plate (640 x 480, 0.4 m) lie up to 1.1 mm from it (per pose
# 0.2-1.1 mm, all within 0.53 mm of the true surface); with the projector beside the rig, centres
# matched 1-8 squares off lie 2.5 mm or more from every ray (module doc).
ACTIVE_RAY_TOL_M = 1.5e-3
# The projector sits this far from the rig's mid-baseline point, across the baseline. Between the
# cameras on the baseline (the mid-point), it would see each centre with exactly half the stereo
# parallax: squares matched two positions off would land on the neighbouring feature's ray and pass
# the check. Across the baseline, a wrong disparity moves the centre in the projector's image along
# a slanted line that passes the grid's features by 2.5 mm or more (module doc).
PROJECTOR_OFFSET_M = 0.03


@dataclass(frozen=True)
class ActivePoints:
    """One pose's square centres that passed the projector check (world frame, metres).

    ``points`` (M,3); ``uv_left`` (M,2) left-image pixels; ``feature_id`` (M,) the projected feature
    each one lies on; ``ray_distance_m`` (M,) its distance to that feature's ray; ``matched``: squares
    the paper's criteria matched at this pose; ``rejected``: of them, those the projector check
    dropped (off every feature ray, claiming a feature another centre claims, or in an array that
    failed as a whole: ``on_feature_rays``)."""

    view: str
    points: np.ndarray
    uv_left: np.ndarray
    feature_id: np.ndarray
    ray_distance_m: np.ndarray
    matched: int
    rejected: int
    row_spacing_m: float = float("nan")  # the grid's row spacing at the points' range (``row_spacing``)

    @classmethod
    def empty(cls, view: str) -> "ActivePoints":
        return cls(view, np.zeros((0, 3)), np.zeros((0, 2)), np.zeros(0, int), np.zeros(0), 0, 0)


def nearest_feature_ray(points: np.ndarray, rays: FeatureRays) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``points`` (M,3): the id of the nearest feature ray and the distance to it (m).
    A ray is a half-line from its origin; a point behind the origin is measured to the origin."""
    P = np.asarray(points, float).reshape(-1, 3)
    if len(P) == 0 or len(rays.ids) == 0:
        return np.zeros(0, int), np.zeros(0)
    d = rays.directions / np.linalg.norm(rays.directions, axis=1, keepdims=True)
    rel = P[:, None, :] - rays.origins[None, :, :]  # (M,R,3)
    t = np.maximum(np.einsum("mrj,rj->mr", rel, d), 0.0)
    dist = np.linalg.norm(rel - t[..., None] * d[None], axis=2)
    k = np.argmin(dist, axis=1)
    return np.asarray(rays.ids)[k], dist[np.arange(len(P)), k]


def on_feature_rays(view: str, points: np.ndarray, uv_left: np.ndarray, rays: FeatureRays,
                    tol_m: float = ACTIVE_RAY_TOL_M, arrays: np.ndarray | None = None,
                    rowcol: dict | None = None) -> ActivePoints:
    """The projector check (module doc) of one pose's triangulated square centres ``points`` (M,3)
    with their left-image pixels ``uv_left`` (M,2): kept where a feature's ray passes within
    ``tol_m`` and no other centre lies that close to that same feature's ray.

    With ``arrays`` ((M,) the matched array each centre belongs to, in the array's x order) and
    ``rowcol`` (feature id -> (pattern row, column)), an array is kept whole or not at all: every
    centre passes, all lie on one pattern row, and their columns run strictly one way. An array
    matched k squares off lands near the rays only where k times the projector's share of the
    baseline parallax is near a whole pitch; the rest of it does not, and takes the array with it."""
    P = np.asarray(points, float).reshape(-1, 3)
    uv = np.asarray(uv_left, float).reshape(-1, 2)
    finite = np.all(np.isfinite(P), axis=1)
    fid, rd = np.full(len(P), -1), np.full(len(P), np.inf)
    fid[finite], rd[finite] = nearest_feature_ray(P[finite], rays)
    ok = rd <= tol_m
    claimed, counts = np.unique(fid[ok], return_counts=True)
    ok &= ~np.isin(fid, claimed[counts > 1])  # two centres on one feature: neither is trusted
    if arrays is not None and rowcol is not None:
        arrays = np.asarray(arrays)
        for g in np.unique(arrays):
            idx = np.nonzero(arrays == g)[0]
            if not ok[idx].all():
                ok[idx] = False
                continue
            rc = np.array([rowcol.get(int(i), (-1, -1)) for i in fid[idx]])
            steps = np.diff(rc[:, 1])
            if len(set(rc[:, 0].tolist())) != 1 or not (np.all(steps > 0) or np.all(steps < 0)):
                ok[idx] = False
    spacing = row_spacing(rays, rowcol, P[ok]) if rowcol is not None else float("nan")
    return ActivePoints(view, P[ok], uv[ok], fid[ok], rd[ok], int(len(P)), int(len(P) - ok.sum()), spacing)


def row_spacing(rays: FeatureRays, rowcol: dict, points: np.ndarray) -> float:
    """The projected grid's row spacing (m) at the median range of ``points`` (M,3) from the rays'
    first origin (the projector's centre): the median angle between the rays of features one row apart in the same column, times
    that range (NaN with no point or no such pair)."""
    P = np.asarray(points, float).reshape(-1, 3)
    at = {rowcol[int(i)]: k for k, i in enumerate(rays.ids) if int(i) in rowcol}
    pairs = [(k, at[(r + 1, c)]) for (r, c), k in at.items() if (r + 1, c) in at]
    if not len(P) or not pairs:
        return float("nan")
    a, b = np.array(pairs).T
    d = rays.directions / np.linalg.norm(rays.directions, axis=1, keepdims=True)
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", d[a], d[b]), -1.0, 1.0))
    return float(np.median(angle) * np.median(np.linalg.norm(P - rays.origins[0], axis=1)))


def active_points(view: str, images: dict, masks: dict, rig: StereoRig, rays: FeatureRays, pattern: Pattern,
                  tol_m: float = ACTIVE_RAY_TOL_M) -> ActivePoints:
    """The squares of one pose's active pair (``images``: "left_active", "right_active") inside its
    plate masks ((H,W) bool by camera), matched by the paper's criteria, triangulated, and checked
    against the projector's feature rays, array by array (``on_feature_rays``; ``pattern`` gives
    each feature's row and column)."""
    sq = square_stereo(images, masks, rig)
    arrays = np.concatenate([np.full(len(sq.groups["left"][gl]), k) for k, (gl, _) in
                             enumerate(sq.matches.group_pairs)]) if sq.matches.group_pairs else np.zeros(0, int)
    return on_feature_rays(view, sq.points, sq.uv_left, rays, tol_m, arrays, pattern_rowcol(pattern))


def pattern_rowcol(pattern: Pattern) -> dict:
    """feature id -> (row, column) of the pattern's grid."""
    return {f.id: (f.row, f.col) for f in pattern.features}


def projector_pose(pose: SensorPose, offset_m: float = PROJECTOR_OFFSET_M) -> SensorPose:
    """Where a measuring pose's projector sits: ``offset_m`` from the mid-baseline point across the
    baseline (along the images' "up"), aimed at the pose's target, its image x along the baseline."""
    up = up_for_baseline(pose.view_dir, pose.baseline_dir)  # the rig's image "up" (scene_spec's convention)
    return SensorPose(pose.center + offset_m * up, pose.target.copy(), pose.baseline_dir.copy(),
                      "projector of a measuring pose: beside the rig's centre line, across the baseline")


@dataclass(frozen=True)
class MergedReconstruction:
    """Every pose's measurements in one reconstruction (world frame, metres).

    ``boundary`` (B,3): the verdict's merged boundary (confirmed pieces, one point per
    ``multiview.MERGE_SPACING_M``); ``points`` (P,3) every pose's checked square centres, with
    ``point_view`` (P,) the index of the pose that measured each; ``surface_vertices`` (V,3) and
    ``surface_faces`` (F,3): the union of the poses' visible surfaces (module doc);
    ``views``: the poses' names, in order."""

    boundary: np.ndarray
    points: np.ndarray
    point_view: np.ndarray
    surface_vertices: np.ndarray
    surface_faces: np.ndarray
    views: tuple[str, ...]


def merge(boundary: np.ndarray, actives: list[ActivePoints], membranes: list) -> MergedReconstruction:
    """One reconstruction from the verdict's merged ``boundary`` (B,3), each pose's ``ActivePoints``
    and each pose's ``surface_model.Membrane`` (same order as ``actives``)."""
    pts = [a.points for a in actives]
    P = np.vstack(pts) if pts else np.zeros((0, 3))
    pv = np.concatenate([np.full(len(p), k) for k, p in enumerate(pts)]) if pts else np.zeros(0, int)
    V, F, off = [], [], 0
    for m in membranes:
        V.append(m.vertices)
        F.append(np.asarray(m.faces, int) + off)
        off += len(m.vertices)
    return MergedReconstruction(np.asarray(boundary, float).reshape(-1, 3), P, pv,
                                np.vstack(V) if V else np.zeros((0, 3)),
                                np.vstack(F) if F else np.zeros((0, 3), int),
                                tuple(a.view for a in actives))


__all__ = ["ACTIVE_RAY_TOL_M", "PROJECTOR_OFFSET_M", "ActivePoints", "MergedReconstruction", "active_points",
           "merge", "nearest_feature_ray", "on_feature_rays", "pattern_rowcol", "projector_pose"]
