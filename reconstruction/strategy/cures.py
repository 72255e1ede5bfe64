"""The cure rules: poses proposed from measured geometry when a false boundary is suspected, the
paper's two (section II) registered first, as pure functions of measured geometry.

* Cure 1 (``OrientCure``): orient the centre line to bisect, and be perpendicular to, the chord AB
  of the most bending curve (baseline perpendicular to its plane: both cameras share the
  cross-section).
* Cure 2 (``MoveBackCure``): move the cameras back beyond C (``bending.tangent_intersection_distance``),
  at least by the paper's empirical rule (the more squares are missing, the further).

A rule is a ``CureRule``: it reads a ``CureContext`` and the thresholds of ``CureParameters`` and
proposes one pose (``CureProposal``), or says why it proposes none. ``register_cure_rule`` adds a
rule to ``CURE_RULES``; the planner (``planner.cure_views``) iterates them in registration order,
and the sensing loop plans its cures from them. World frame, metres, radians. Nothing here renders
or reads ground truth.
"""
from __future__ import annotations

import abc
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from platebench.errors import RegistrationError
from platebench.reconstruction.strategy.bending import BendingCurve, tangent_intersection_distance
from platebench.reconstruction.strategy.poses import SensorPose
from platebench.reconstruction.strategy.poses import perpendicular as _perp
from platebench.reconstruction.strategy.poses import unit as _unit

__all__ = ["CureParameters", "CURE_PARAMETERS", "CureContext", "CureProposal", "CureRule", "CURE_RULES",
           "register_cure_rule", "cure_rules", "OrientCure", "MoveBackCure", "cure_orient", "cure_move_back"]


@dataclass(frozen=True)
class CureParameters:
    """The thresholds of the built-in cure rules, in one place.

    ``min_view_turn_deg`` (2.0 deg) and ``min_baseline_turn_deg`` (10.0 deg): cure 1 is proposed when
    it turns the centre line by more than the first or the baseline by more than the second from
    the stage-2 pose; a smaller move repeats the stage-2 view (the bench's choice: the paper gives no
    number). ``move_back_safety`` (1.1): cure 2 puts the sensor this many times L above the chord AB
    (the paper asks for beyond C; the margin is the bench's). ``move_back_step`` (0.5): the paper's
    empirical rule, "the more squares are missing, the further", as distance x (1 + step x missing /
    expected) (the step is the bench's)."""

    min_view_turn_deg: float = 2.0
    min_baseline_turn_deg: float = 10.0
    move_back_safety: float = 1.1
    move_back_step: float = 0.5


CURE_PARAMETERS = CureParameters()


@dataclass(frozen=True)
class CureContext:
    """What a cure rule reads: ``curve`` the stage-3 reconstruction's most bending curve (the one with
    the largest L, ``bending.tangent_intersection_distance``), ``first`` the stage-2 pose the cure
    starts from, ``missing`` and ``expected`` the paper's counting test's squares (missing = expected
    minus the fewest detected, 0 when none were counted)."""

    curve: BendingCurve
    first: SensorPose
    missing: int
    expected: int


@dataclass(frozen=True)
class CureProposal:
    """A rule's answer: the ``pose`` it moves the sensor to, or None and a ``note`` saying why not."""

    pose: SensorPose | None
    note: str = ""


class CureRule(abc.ABC):
    """A cure rule: ``name`` (class attribute) names its view and its method in the sensing records
    ("cure 1", ...); ``propose`` is a pure function of the context and the parameters."""

    name: ClassVar[str]

    @abc.abstractmethod
    def propose(self, ctx: CureContext, params: CureParameters) -> CureProposal:
        """The pose this rule proposes for ``ctx`` under ``params``, or a note saying why none."""


# every registered cure rule by name, in the order the planner tries them (``register_cure_rule``)
CURE_RULES: dict[str, CureRule] = {}


def register_cure_rule(rule: CureRule) -> CureRule:
    """Add ``rule`` to ``CURE_RULES`` (after those registered before it); returns it. TypeError when it
    is not a ``CureRule`` with a non-empty ``name``; ``RegistrationError`` (a ValueError) when its name is
    registered already."""
    if not isinstance(rule, CureRule) or not isinstance(getattr(rule, "name", None), str) or not rule.name:
        raise TypeError(f"{rule!r} is not a CureRule with a name")
    if rule.name in CURE_RULES:
        raise RegistrationError(f"cure rule {rule.name!r} is registered already")
    CURE_RULES[rule.name] = rule
    return rule


def cure_rules() -> tuple[CureRule, ...]:
    """The registered cure rules, in registration order."""
    return tuple(CURE_RULES.values())


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
                   safety: float = CURE_PARAMETERS.move_back_safety,
                   step: float = CURE_PARAMETERS.move_back_step) -> SensorPose:
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


class OrientCure(CureRule):
    """Cure 1 (``cure_orient``), proposed when it moves the sensor: it turns the centre line by more
    than ``CureParameters.min_view_turn_deg`` or the baseline by more than ``min_baseline_turn_deg``."""

    name = "cure 1"

    def propose(self, ctx: CureContext, params: CureParameters) -> CureProposal:
        pose = cure_orient(ctx.curve, ctx.first)
        off = np.degrees(np.arccos(np.clip(pose.view_dir @ ctx.first.view_dir, -1, 1)))
        turn = np.degrees(np.arccos(np.clip(abs(pose.baseline_dir @ ctx.first.baseline_dir), -1, 1)))
        if off > params.min_view_turn_deg or turn > params.min_baseline_turn_deg:
            return CureProposal(pose)
        return CureProposal(None, f"{self.name} would not move the sensor ({off:.1f} deg, baseline {turn:.0f} deg)")


class MoveBackCure(CureRule):
    """Cure 2 (``cure_move_back`` with ``CureParameters.move_back_safety`` and ``move_back_step``),
    proposed when the most bending curve's L is finite and positive (a convex bend: there is a C to
    move beyond)."""

    name = "cure 2"

    def propose(self, ctx: CureContext, params: CureParameters) -> CureProposal:
        L = tangent_intersection_distance(ctx.curve)
        if np.isfinite(L) and L > 0:
            return CureProposal(cure_move_back(ctx.curve, ctx.first, ctx.missing, max(ctx.expected, 1),
                                               params.move_back_safety, params.move_back_step))
        return CureProposal(None, f"{self.name} has no distance to reach: L = {L * 1e3:.0f} mm "
                                  f"(a = {np.degrees(ctx.curve.a_rad):.0f}, b = {np.degrees(ctx.curve.b_rad):.0f} deg)")


register_cure_rule(OrientCure())
register_cure_rule(MoveBackCure())
