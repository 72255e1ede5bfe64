"""Range expressions, bounded in count BEFORE they are expanded.

One parser for every range a user writes: a sweep spec's ``{start, stop, step}`` /
``{start, stop, num}`` tables (``bench.sweep.spec``) and the study command's
``START:STOP:STEP`` or ``a,b,c`` flags (``--bend 0:180:10``). The number of values is
computed from the numbers first and refused above ``max_count``, so that
``--bend 0:1e12:1e-3`` is a one-line error instead of a MemoryError; every number must
be finite, the step positive, and every value inside ``[lo, hi]``. Errors are
``RangeError`` (a ``ConfigError``) with one line naming the key, the value and what is
allowed.
"""
from __future__ import annotations

import math

import numpy as np

from platebench.bench.config.sample_config import ConfigError
from platebench.tolerances import tol

__all__ = ["RangeError", "MAX_VALUES", "range_count", "expand_range", "parse_range_text"]

MAX_VALUES = 100_000


class RangeError(ConfigError):
    """A range expression is malformed, too large, or leaves the allowed interval."""


def _finite(key: str, what: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v):
        raise RangeError(f"{key}: {what} = {v!r} is not a finite number")
    return float(v)


def range_count(key: str, start, stop, step, max_count: int = MAX_VALUES) -> int:
    """How many values START, START+STEP, ... <= STOP has (STOP included); refused above ``max_count``."""
    a, b, c = _finite(key, "start", start), _finite(key, "stop", stop), _finite(key, "step", step)
    if c <= 0:
        raise RangeError(f"{key}: step = {step!r} is out of range: allowed > 0")
    if b < a:
        raise RangeError(f"{key}: stop = {stop!r} is below start = {start!r}: allowed stop >= start")
    # a stop within tol.step_count of a step of the grid is included (0:180:20 ends at 180)
    n = math.floor((b - a) / c + tol.step_count) + 1  # a float: no huge list is ever made
    if not n <= max_count:
        raise RangeError(f"{key}: {start!r} to {stop!r} in steps of {step!r} is {n:.3g} values: allowed at most "
                         f"{max_count}")
    return int(n)


def expand_range(key: str, start, stop, step=None, num=None, max_count: int = MAX_VALUES,
                 lo: float = -math.inf, hi: float = math.inf, integers: bool = False) -> list:
    """The values of a range (exactly one of ``step`` and ``num``), counted before they are made.

    ``integers``: start, stop and step are all integers and the values are ints. Values are
    rounded to 12 decimals (so 0.1 steps give 0.3, not 0.30000000000000004) and must lie in
    [``lo``, ``hi``]."""
    if (step is None) == (num is None):
        raise RangeError(f"{key}: a range needs start, stop and exactly one of step or num")
    if num is not None:
        if isinstance(num, bool) or not isinstance(num, (int, np.integer)):
            raise RangeError(f"{key}: num = {num!r} is not an integer: allowed 1 to {max_count}")
        if not 1 <= num <= max_count:
            raise RangeError(f"{key}: num = {num} is out of range: allowed 1 to {max_count}")
        a, b = _finite(key, "start", start), _finite(key, "stop", stop)
        values = [float(x) for x in np.linspace(a, b, int(num))]
    else:
        n = range_count(key, start, stop, step, max_count)
        a, c = float(start), float(step)
        values = [a + i * c for i in range(n)]
    values = [int(round(x)) if integers else round(x, 12) for x in values]
    _check_bounds(key, values, lo, hi)
    return values


def _check_bounds(key: str, values: list, lo: float, hi: float) -> None:
    bad = next((v for v in values if not lo <= v <= hi), None)
    if bad is not None:
        raise RangeError(f"{key} value {bad:g} is out of range: allowed {lo:g} to {hi:g}")


def parse_range_text(text: str, key: str, lo: float = -math.inf, hi: float = math.inf,
                     max_count: int = MAX_VALUES) -> list[float]:
    """'START:STOP:STEP' (stop included) or 'a,b,c' -> floats in [lo, hi], at most ``max_count`` of them
    (counted before they are made). For command-line flags such as ``study --bend``."""
    if not isinstance(text, str) or not text.strip():
        raise RangeError(f"{key} = {text!r} is empty: allowed START:STOP:STEP or a comma list")
    try:
        if ":" in text:
            parts = text.split(":")
            if len(parts) != 3:
                raise ValueError
            a, b, c = (float(x) for x in parts)
            return [float(v) for v in expand_range(key, a, b, step=c, max_count=max_count, lo=lo, hi=hi)]
        values = [float(x) for x in text.split(",") if x.strip()]
    except RangeError:
        raise
    except ValueError:
        raise RangeError(f"{key} = {text!r} is not START:STOP:STEP or a comma list of numbers") from None
    if not values:
        raise RangeError(f"{key} = {text!r} is an empty range")
    if len(values) > max_count:
        raise RangeError(f"{key} has {len(values)} values: allowed at most {max_count}")
    for v in values:
        _finite(key, "value", v)
    _check_bounds(key, values, lo, hi)
    return values
