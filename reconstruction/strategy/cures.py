"""The paper's two cures of a false boundary (section II), as pure functions of measured geometry.

* Cure 1: orient the centre line to bisect, and be perpendicular to, the chord AB of the most
  bending curve (baseline perpendicular to its plane: both cameras share the cross-section).
* Cure 2: move the cameras back beyond C (``bending.tangent_intersection_distance``), at least by
  the paper's empirical rule (the more squares are missing, the further).

World frame, metres, radians. Nothing here renders or reads ground truth.
"""
from __future__ import annotations

import numpy as np

from platebench.reconstruction.strategy.bending import BendingCurve, tangent_intersection_distance
from platebench.reconstruction.strategy.poses import SensorPose
from platebench.reconstruction.strategy.poses import perpendicular as _perp
from platebench.reconstruction.strategy.poses import unit as _unit


def cure_orient(curve: BendingCurve, current: SensorPose) -> SensorPose:
    """Cure 1: centre line perpendicular to AB through its midpoint, in the bending plane, on the
    sensor's side; the baseline perpendicular to the bending plane (both cameras then share the
    cross-section, as stage 2 asks); distance kept."""
    mid = 0.5 * (curve.A + curve.B)
    ab = _unit(curve.B - curve.A)
    up = _unit(curve.normal - ab * (curve.normal @ ab))
    d = current.distance_m
    view = -up
    return SensorPose(mid + up * d, mid, _perp(np.cross(ab, up), view),
                      "cure 1: centre line bisects and is perpendicular to the chord AB of the most bending "
                      "curve; baseline perpendicular to its plane")


def cure_move_back(curve: BendingCurve, current: SensorPose, missing: int, expected: int,
                   safety: float = 1.1, step: float = 0.5) -> SensorPose:
    """Cure 2: move back along the centre line beyond C (distance from AB > L, times ``safety``);
    at least by the empirical rule: distance x (1 + step x missing/expected)."""
    L = tangent_intersection_distance(curve)
    mid = 0.5 * (curve.A + curve.B)
    view = current.view_dir
    height_above_ab = float((current.center - mid) @ -view)
    empirical = current.distance_m * (1.0 + step * max(missing, 1) / max(expected, 1))
    want = current.distance_m
    reason = []
    if np.isfinite(L) and L > 0 and height_above_ab < safety * L:
        want = current.distance_m + (safety * L - height_above_ab)
        reason.append(f"beyond C: L = {L * 1e3:.0f} mm from AB")
    if want < empirical:
        want = empirical
        reason.append(f"empirical rule: {missing} of {expected} squares missing")
    return SensorPose(current.target - view * want, current.target.copy(), current.baseline_dir,
                      "cure 2: move back (" + "; ".join(reason) + f"), distance {want * 1e3:.0f} mm")
