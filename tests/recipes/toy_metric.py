"""The metric recipe's toy (docs/extending.md): the share of the expected square centres that the
paper's pipeline matched, registered as the column "toy_matched_frac".

One module: a ``Metric`` given to ``register_metric``; ``tests/test_recipes.py`` tests it."""
from __future__ import annotations

from platebench.evaluation.metrics_row import Metric, register_metric


def matched_fraction(score) -> float | None:
    """matched / expected square centres of the paper pipeline's ``Score``; None for a score
    without a square matching (the other kinds of method) or with no centre expected."""
    matching = getattr(score, "matching", None)
    if matching is None or not matching.expected_count_gt:
        return None
    return matching.matched_count / matching.expected_count_gt


TOY_METRIC = register_metric(Metric("toy_matched_frac", "share of the expected square centres matched",
                                    "fraction", matched_fraction))
