"""The paper's bending curves and its L formula (section II, Fig. 4).

A bending curve is the plate surface cut by a normal plane (a plane holding the sensor's centre
line); the most bending curve has the largest angle between its end tangents. With A and B its
end points and a, b the angles between AB and the end tangents, the cameras must lie beyond the
point C where the tangents meet, ``L = AB tan a tan b / (tan a + tan b)`` from AB, to see both
ends. World frame, metres, radians.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.reconstruction.paper.boundary_plane import BoundaryPlane
from platebench.reconstruction.strategy.poses import unit as _unit
from platebench.tolerances import tol


@dataclass(frozen=True)
class BendingCurve:
    """The most bending curve's end points A, B and the angles a, b between AB and the end tangents."""

    A: np.ndarray
    B: np.ndarray
    tangent_A: np.ndarray  # unit, pointing from A into the plate
    tangent_B: np.ndarray
    a_rad: float
    b_rad: float
    normal: np.ndarray  # unit normal of the bending plane's "up" side (toward the sensor)

    @property
    def chord_m(self) -> float:
        return float(np.linalg.norm(self.B - self.A))


def bending_curve(profile: np.ndarray, up: np.ndarray, end_fraction: float = 0.12) -> BendingCurve:
    """End points and end-tangent angles of a bending curve given as an ordered (N,3) polyline.

    Tangents: derivative at the end of a quadratic fit (coordinates vs arc length) to the
    first/last ``end_fraction`` of the curve's arc.
    The angle at A is between AB and the tangent at A pointing into the plate, signed positive
    when it rises from the chord toward the sensor (``up``): positive for a convex bend whose ends
    fall away from the sensor, negative for a concave one.
    """
    P = np.asarray(profile, float)
    A, B = P[0], P[-1]
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(P, axis=0), axis=1))])
    k = max(3, int(np.searchsorted(s, end_fraction * s[-1])))

    def tangent(pts):
        # Quadratic fit of each coordinate against arc length; its derivative at the end point.
        sl = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))])
        t = np.array([np.polyfit(sl, pts[:, k], 2)[1] for k in range(3)])
        return _unit(t)

    tA = tangent(P[:k])  # from A into the plate
    tB = tangent(P[::-1][:k])  # from B into the plate
    ab = _unit(B - A)
    up = _unit(up - ab * (up @ ab))

    def angle(t, chord):  # signed angle of tangent t above the chord direction (toward up)
        return float(np.arctan2(t @ up, t @ chord))

    return BendingCurve(A, B, tA, tB, angle(tA, ab), angle(tB, -ab), up)


def tangent_intersection_distance(curve: BendingCurve) -> float:
    """Paper's L = AB tan a tan b / (tan a + tan b): distance from chord AB to the point C where the
    end tangent lines meet. Positive: C lies on the sensor's side and the cameras must be beyond it
    (a convex bend, whose ends fall away from the sensor). Negative or zero: C lies behind AB and
    distance is no constraint (a concave bend under 180 degrees). Infinite: an end tangent turns past
    90 degrees (the plate curls over itself), which no distance along this centre line cures.
    """
    a, b = curve.a_rad, curve.b_rad
    if abs(a) >= np.pi / 2 or abs(b) >= np.pi / 2:
        return float("inf")
    ta, tb = np.tan(a), np.tan(b)
    if abs(ta + tb) < tol.relative:
        return float("inf") if ta * tb > 0 else 0.0
    return float(curve.chord_m * ta * tb / (ta + tb))


def boundary_edges(boundary: np.ndarray, source: np.ndarray) -> list[np.ndarray]:
    """Split a matched boundary polygon at its four corners into four ordered edges (corner to corner)."""
    idx = np.nonzero(np.asarray(source) == "corner")[0]
    if len(idx) != 4:
        raise ValueError(f"boundary has {len(idx)} corners, expected 4")
    n = len(boundary)
    edges = []
    for k in range(4):
        i, j = idx[k], idx[(k + 1) % 4]
        sel = np.arange(i, j + 1) if j > i else np.concatenate([np.arange(i, n), np.arange(0, j + 1)])
        edges.append(boundary[sel])
    return edges


def most_bending_curves(boundary: np.ndarray, source: np.ndarray, plane: BoundaryPlane,
                        bent_dir: np.ndarray) -> list[BendingCurve]:
    """The two boundary edges running along the most-bent direction, as bending curves (A -> B)."""
    edges = boundary_edges(boundary, source)
    align = [abs(_unit(e[-1] - e[0]) @ bent_dir) for e in edges]
    order = np.argsort(align)[::-1][:2]
    curves = []
    for k in order:
        e = edges[k]
        if (e[-1] - e[0]) @ bent_dir < 0:
            e = e[::-1]
        curves.append(bending_curve(e, plane.normal))
    return curves


PROFILE_HALF_WIDTH_M = 3e-3  # surface points this close to the profile's plane make the profile
PROFILE_BIN_M = 1e-3  # the profile is averaged in bins of this length along the bent direction


def surface_profile(points: np.ndarray, plane: BoundaryPlane, bent_dir: np.ndarray,
                    half_width_m: float = PROFILE_HALF_WIDTH_M) -> BendingCurve:
    """The bending curve of a measured surface (e.g. the stage-3 interpolated surface, (N,3)): the
    surface cut by the normal plane through the boundary centre holding ``bent_dir``, averaged in
    ``PROFILE_BIN_M`` bins along it, as an ordered polyline. Needs no corners. Raises ValueError
    when fewer than 8 bins hold points."""
    n = _unit(plane.normal)
    e = _unit(bent_dir - n * (bent_dir @ n))
    g = np.cross(n, e)
    P = np.asarray(points, float)
    P = P[np.all(np.isfinite(P), axis=1)]
    rel = P - plane.point
    P = P[np.abs(rel @ g) <= half_width_m]
    if len(P) < 8:
        raise ValueError(f"{len(P)} surface points near the profile plane")
    s = (P - plane.point) @ e
    k = np.floor(s / PROFILE_BIN_M).astype(int)
    bins = np.unique(k)
    if len(bins) < 8:
        raise ValueError(f"the profile spans {len(bins)} mm")
    prof = np.array([P[k == b].mean(axis=0) for b in bins])
    return bending_curve(prof, n)


def measured_bending_curves(boundary: np.ndarray, source: np.ndarray, plane: BoundaryPlane, bent_dir: np.ndarray,
                            surface_points: np.ndarray | None = None) -> tuple[list[BendingCurve], str]:
    """The most bending curves: the boundary edges along the bent direction where the boundary has
    the paper's four corners ("corner edges"), else the measured surface's profile ("surface
    profile"). Raises ValueError when neither is available."""
    try:
        return most_bending_curves(boundary, source, plane, bent_dir), "corner edges"
    except ValueError as e:
        if surface_points is None or not len(surface_points):
            raise
        try:
            return [surface_profile(surface_points, plane, bent_dir)], "surface profile"
        except ValueError as e2:
            raise ValueError(f"{e}; surface profile: {e2}") from None
