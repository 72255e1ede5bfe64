"""Plausibility hints: is a scored file what its flag says it is?

A file given to ``platebench evaluate`` in the wrong unit or of the wrong kind (a disparity given
as ``--depth``, depth in millimetres, points in millimetres or in the camera's frame) is still
scored, but its errors then lie orders of magnitude beyond the scene. These functions say so in
words ("is this file in millimetres?"), never refuse: a method that is merely bad is scored as it
is, and gets no hint. A hint is given only when the median error is larger than the scene itself
(the plate's largest extent; for a disparity, the depth error it implies); it then names
the explanation the numbers support, when one does:

* the estimate is 1000 x the truth (median ratio within ``RATIO_SLACK`` of 1000): millimetres;
* depths that match the true disparity, or disparities that give the true depth through
  Z = f B / d: the other kind of map;
* a disparity 16 x or 256 x the truth: OpenCV's fixed point (16 d) or KITTI's PNG scale (256 d);
* points (or mesh vertices) that fit the plate (median distance under 1 % of its extent, spread
  over at least a tenth of it) once divided by 1000, or once moved from the left camera's frame
  to the world frame (x_world = R^T (x_cam - t)), or both; the best fit is named.

Inputs: the scored values (metres, px; left view for maps) and the ``FieldTruth``. Outputs: a tuple
of one-line hints (empty when the file is plausible).
"""
from __future__ import annotations

import numpy as np

from platebench.evaluation.field_scores import FieldTruth
from platebench.evaluation.point_metrics import closest_point_on_mesh

__all__ = ["plausibility_hints", "RATIO_SLACK", "FIT_SAMPLE"]

RATIO_SLACK = 0.2  # a median ratio within 20 % of a factor (1000, 16, 256, 1) is taken to be that factor
FIT_SAMPLE = 2000  # points tested for a better fit (a seeded sample of the cloud)


def _near(ratio: float, factor: float) -> bool:
    return bool(np.isfinite(ratio) and ratio > 0 and abs(ratio / factor - 1.0) <= RATIO_SLACK)


def _scene_m(truth: FieldTruth) -> float:
    """The plate's largest extent (m): the scale a length error is compared with."""
    return float(np.max(truth.mesh.extents))


def _map_hints(kind: str, values: np.ndarray, truth: FieldTruth) -> tuple[str, ...]:
    v = np.asarray(values, np.float64)
    on = truth.mask & np.isfinite(v) & (v > 0)
    if not on.any():
        return ()
    est, z_true, d_true = v[on], truth.depth[on], truth.disparity[on] + truth.pair.doffs_px
    if kind == "depth":
        err = float(np.median(np.abs(est - z_true)))
        scene = _scene_m(truth)
        if err <= scene:
            return ()
        ratio = float(np.median(est / z_true))
        lead = (f"the median depth error is {err * 1e3:.4g} mm, beyond the plate's {scene * 1e3:.0f} mm: ")
        if _near(ratio, 1000.0):
            return (lead + f"the values are about 1000 x the true depth (median ratio {ratio:.4g}): is this file in "
                           "millimetres? --depth takes z-depth in metres",)
        if _near(float(np.median(est / d_true)), 1.0):
            return (lead + f"the values match the true disparity (median {np.median(d_true):.4g} px), not the depth "
                           f"({np.median(z_true):.4g} m): is this file a disparity? score it with --disparity",)
        return (lead + "is this file in millimetres, or a disparity? --depth takes z-depth in metres",)
    # disparity: the depth it implies, Z = f B / (d + doffs), against the scene
    with np.errstate(divide="ignore", invalid="ignore"):
        implied = truth.pair.fb / (est + truth.pair.doffs_px)
        as_depth = truth.pair.fb / est
    err = float(np.median(np.abs(np.where(implied > 0, implied, np.inf) - z_true)))
    scene = _scene_m(truth)
    if err <= scene:
        return ()
    lead = (f"the median depth error it implies is {err * 1e3:.4g} mm, beyond the plate's {scene * 1e3:.0f} mm "
            f"(median disparity {np.median(est - truth.pair.doffs_px):.4g} px, true {np.median(d_true):.4g} px): ")
    ratio = float(np.median(est / d_true))
    if _near(float(np.median(as_depth / d_true)), 1.0):
        return (lead + f"the values match the true depth in metres (median {np.median(z_true):.4g} m): is this file "
                       "a depth map? score it with --depth",)
    for factor, what in ((16.0, "OpenCV's fixed-point disparity (16 d): divide by 16"),
                         (256.0, "a KITTI-style disparity (256 d): give the PNG with --disparity-scale 256, "
                                 "or divide by 256"),
                         (1000.0, "a depth in millimetres? score depth in metres with --depth")):
        if _near(ratio, factor):
            return (lead + f"the values are about {factor:g} x the true disparity: is this file {what}",)
    return (lead + "is this file a disparity in px of the LEFT view at the sample's resolution?",)


def _median_distance(points: np.ndarray, truth: FieldTruth) -> float:
    return float(np.median(closest_point_on_mesh(points, truth.mesh)[1]))


def _points_hints(kind: str, points: np.ndarray, truth: FieldTruth) -> tuple[str, ...]:
    P = np.asarray(points, np.float64).reshape(-1, 3)
    P = P[np.all(np.isfinite(P), axis=1)]
    if not len(P):
        return ()
    if len(P) > FIT_SAMPLE:
        P = P[np.random.default_rng(0).choice(len(P), FIT_SAMPLE, replace=False)]
    err = _median_distance(P, truth)
    scene = _scene_m(truth)
    if err <= scene:
        return ()
    what = "points" if kind == "points" else "mesh's vertices"
    lead = (f"the {what}' median distance to the true surface is {err * 1e3:.4g} mm, beyond the plate's "
            f"{scene * 1e3:.0f} mm: ")
    cam = truth.rig.left
    to_world = (lambda Q: (Q - cam.t) @ cam.R)  # x_world = R^T (x_cam - t), row vectors
    tries = ((P * 1e-3, "in millimetres? the bench takes metres"),
             (to_world(P), "in the left camera's frame? the bench takes the world frame"),
             (to_world(P * 1e-3), "in millimetres and in the left camera's frame? the bench takes metres, world frame"))
    fits = [(_median_distance(Q, truth), what_if) for Q, what_if in tries
            if float(np.ptp(Q, axis=0).max()) >= scene / 10.0]  # a cloud shrunk onto one spot fits nothing
    fits = [f for f in fits if f[0] <= scene / 100.0]
    if fits:
        _, what_if = min(fits)
        return (lead + f"they fit the plate once read {what_if.split('?')[0]}: is this file {what_if}",)
    return (lead + f"is this file in millimetres, or in another frame? --{kind} takes metres in the world frame",)


def plausibility_hints(kind: str, values, truth: FieldTruth) -> tuple[str, ...]:
    """Hints (module doc) for a scored output of ``kind`` ("disparity", "depth", "points", "mesh"):
    ``values`` is the map (H, W), the (N, 3) points, or the mesh (its vertices are tested)."""
    if kind in ("disparity", "depth"):
        return _map_hints(kind, values, truth)
    if kind == "mesh":
        return _points_hints(kind, np.asarray(values.vertices), truth)
    return _points_hints(kind, values, truth)
