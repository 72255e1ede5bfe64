"""The cure rule recipe's toy (docs/extending.md): step back along the stage-2 pose's centre line
by ``STEP_BACK``, registered as the cure rule "toy step back".

One module: a ``CureRule`` given to ``register_cure_rule``; ``tests/test_recipes.py`` tests it."""
from __future__ import annotations

from platebench.reconstruction.strategy.cures import CureContext, CureParameters, CureProposal, CureRule, \
    register_cure_rule

STEP_BACK = 1.5  # the new distance, times the stage-2 pose's distance to its target


class StepBackCure(CureRule):
    """The stage-2 pose moved back along its centre line to ``STEP_BACK`` times its distance."""

    name = "toy step back"

    def propose(self, ctx: CureContext, params: CureParameters) -> CureProposal:
        want = ctx.first.distance_m * STEP_BACK
        return CureProposal(ctx.first.at_distance(want, f"{self.name}: distance {want * 1e3:.0f} mm"))


TOY_CURE = register_cure_rule(StepBackCure())
