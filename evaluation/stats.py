"""Error statistics shared by the metric modules, and input checks.

Every statistic here is computed from ABSOLUTE values (distances, |errors|):
signed errors must never be averaged, or +d and -d would cancel to a perfect 0.
A module that wants to show a bias reports it separately, under a key that says
``_signed``.

Conventions
-----------
* ``mean``  = arithmetic mean of the values (weighted mean when weights are given).
* ``rms``   = sqrt(mean of the squared values) (weighted likewise).
* ``max``   = largest value.
* ``p95``   = 95th percentile. Unweighted: ``numpy.percentile(values, 95)`` with
  numpy's default linear interpolation between order statistics. Weighted: the
  smallest value whose cumulative weight reaches 95 % of the total.
* ``count`` = number of values.

Values are stored in the unit of the input (metres for geometry, pixels for
image-space metrics); their JSON form (the codec in ``bench.io.codecs.evaluation``) converts to the
reporting unit (``scale=1e3`` and ``unit_suffix="mm"`` for metres -> millimetres) and puts the unit in
every key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from platebench.tolerances import ceil_count, tol

__all__ = [
    "ErrorStats",
    "check_array",
    "nearest_rank_quantile",
    "stat_key",
]


def stat_key(prefix: str, name: str, unit_suffix: str | None = None) -> str:
    """Join ``prefix``, ``name`` and ``unit_suffix`` with underscores, skipping empty parts."""
    return "_".join(p for p in (prefix, name, unit_suffix) if p)


def check_array(
    x,
    name: str,
    *,
    shape: tuple[int | None, ...] | None = None,
    finite: bool = True,
    nonempty: bool = True,
    dtype=np.float64,
) -> np.ndarray:
    """Return ``x`` as a numpy array, raising a one-line ValueError naming ``name``.

    ``shape`` gives the expected shape, ``None`` for a free axis (``(None, 3)``:
    any number of rows of 3). ``finite=True`` rejects NaN and +-inf.
    """
    try:
        arr = np.asarray(x, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: cannot convert to a {np.dtype(dtype).name} array ({exc})") from None
    if shape is not None:
        ok = arr.ndim == len(shape) and all(s is None or s == a for s, a in zip(shape, arr.shape))
        if not ok:
            want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
            raise ValueError(f"{name}: expected shape {want}, got {arr.shape}")
    if nonempty and arr.size == 0:
        raise ValueError(f"{name}: empty array (shape {arr.shape})")
    if finite and arr.size and np.issubdtype(arr.dtype, np.floating) and not np.all(np.isfinite(arr)):
        bad = int(np.count_nonzero(~np.isfinite(arr)))
        raise ValueError(f"{name}: {bad} non-finite value(s) (NaN or inf) where none are allowed")
    return arr


def nearest_rank_quantile(values: np.ndarray, q_pct: float) -> float:
    """Nearest-rank quantile: the smallest value v with at least ``q_pct`` % of the values <= v.

    With the values sorted ascending, v_(1) <= ... <= v_(n), this is
    v_(ceil(q/100 * n)) (1-based; rank at least 1). It never interpolates, so it is
    well defined when some values are +inf (Middlebury counts invalid disparities
    as infinitely wrong) and it is easy to work out by hand. NaN for no values.
    """
    v = np.asarray(values, dtype=np.float64).ravel()
    if v.size == 0:
        return math.nan
    if not 0.0 <= q_pct <= 100.0:
        raise ValueError(f"q_pct: quantile must be in [0, 100], got {q_pct}")
    rank = max(1, ceil_count(q_pct / 100.0 * v.size))
    return float(np.partition(v, rank - 1)[rank - 1])


@dataclass(frozen=True)
class ErrorStats:
    """Summary of absolute errors, in the unit of the input (metres or pixels)."""

    mean: float
    rms: float
    max: float
    p95: float
    count: int

    @classmethod
    def from_abs(
        cls,
        values,
        *,
        name: str = "values",
        weights=None,
        allow_empty: bool = False,
    ) -> "ErrorStats":
        """Statistics of non-negative values (absolute errors or distances).

        Raises ValueError on negative values (pass ``np.abs(signed)``, never signed
        errors), on NaN/inf, and on an empty input unless ``allow_empty`` (then all
        statistics are NaN and ``count`` is 0). ``weights`` (same length, >= 0)
        weight the mean, RMS and p95, e.g. arc-length weights of boundary samples.
        """
        v = check_array(values, name, finite=True, nonempty=not allow_empty).ravel()
        if v.size == 0:
            return cls(math.nan, math.nan, math.nan, math.nan, 0)
        vmin = float(v.min())
        if vmin < 0.0:
            raise ValueError(
                f"{name}: statistics take absolute values (>= 0); got a minimum of {vmin!r} "
                "(signed errors would cancel)"
            )
        if weights is None:
            mean = float(v.mean())
            rms = float(np.sqrt(np.mean(v * v)))
            p95 = float(np.percentile(v, 95.0))
        else:
            w = check_array(weights, f"{name} weights", shape=(v.size,), finite=True)
            if np.any(w < 0) or not np.any(w > 0):
                raise ValueError(f"{name} weights: must be >= 0 with a positive sum")
            wsum = float(w.sum())
            mean = float(np.dot(w, v) / wsum)
            rms = float(np.sqrt(np.dot(w, v * v) / wsum))
            order = np.argsort(v, kind="stable")
            cw = np.cumsum(w[order])
            i = int(np.searchsorted(cw, 0.95 * cw[-1] * (1 - tol.relative), side="left"))
            p95 = float(v[order][min(i, v.size - 1)])
        return cls(mean=mean, rms=rms, max=float(v.max()), p95=p95, count=int(v.size))

    def scaled(self, factor: float) -> "ErrorStats":
        """The same statistics multiplied by ``factor`` (count unchanged)."""
        return ErrorStats(
            self.mean * factor, self.rms * factor, self.max * factor, self.p95 * factor, self.count
        )
