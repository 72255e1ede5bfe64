"""The report's one reading of a cell: a flag, a finite number, or text for a page.

Inputs are typed (``results.parquet`` stores bools as bools; ``study.json`` and
``sensing.json`` are JSON), so there is one truthiness rule: a flag is a ``bool`` (numpy's
included), anything else is unknown. Strings such as "true" are never flags.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["flag", "finite", "fmt", "DASH"]

DASH = "\u2013"  # en dash: no value


def flag(v) -> bool | None:
    """True / False for a bool (Python or numpy), None for anything else (missing, NaN, text, numbers)."""
    return bool(v) if isinstance(v, (bool, np.bool_)) else None


def finite(v) -> float | None:
    """A finite float from an int or float (not a bool), else None (None, NaN, inf, text, flags)."""
    if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, float, np.integer, np.floating)):
        return None
    x = float(v)
    return x if math.isfinite(x) else None


def fmt(v, digits: int = 4) -> str:
    """Plain text for a table cell (the template escapes it): "–" for no value, yes/no for flags,
    integers as they are, floats to ``digits`` significant figures (the whole number where that
    would take an exponent, scientific outside 1e-3..1e5),
    infinities as ∞."""
    if v is None:
        return DASH
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        v = float(v)
        if math.isnan(v):
            return DASH
        if math.isinf(v):
            return "\u221e" if v > 0 else "\u2212\u221e"
        if v == 0:
            return "0"
        if abs(v) >= 1e5 or abs(v) < 1e-3:
            return f"{v:.{digits - 1}e}"
        text = f"{v:.{digits}g}"
        return f"{v:.0f}" if "e" in text else text  # more whole digits than significant ones: never 1.113e+04
    return str(v)
