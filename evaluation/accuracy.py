"""Scoring of the paper's accuracy test (section V-D) as a Monte Carlo study: which true point each
measured one is, one trial's errors, and the statistics over a budget row's trials.

The paper's "within" is one trial's worst point: depth (z) within ``PAPER_DEPTH_MM``, x and y within
``PAPER_XY_MM`` (``evaluation.score``). Per trial (``score_trial``): the worst point in depth and in
x/y (the larger of |x| and |y|), the RMS of each and the mean signed depth error. Over the trials
(``summarise_trials``): the median of the trials' worst values and its quantiles (``WORST_QUANTILES``),
the share of trials within the paper's bound, and over every point of every trial the RMS, the 95th
percentile and the maximum (``evaluation.stats.ErrorStats``).

Errors are measured minus true, (N, 3): x, y, z in the frame the caller measures in (the target
block's or the world's). ``score_trial`` takes metres; ``summarise_trials`` works in the unit of its
input (the study's records hold millimetres, the unit of the paper's bound).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from platebench.evaluation.score import PAPER_DEPTH_MM, PAPER_XY_MM
from platebench.evaluation.stats import ErrorStats

__all__ = ["MATCH_SPACING_FRACTION", "WORST_QUANTILES", "ImageMatch", "identify_in_image", "nearest_order",
           "TrialScore", "score_trial", "WorstCaseStats", "worst_case_stats", "TrialsSummary", "summarise_trials",
           "PAPER_DEPTH_MM", "PAPER_XY_MM"]

WORST_QUANTILES = (0.05, 0.25, 0.5, 0.75, 0.95)  # quantiles of the trials' worst values, keys "q05" .. "q95"
# a measured point is the true one whose image lies nearest its pixel, within this fraction of the true
# points' smallest spacing in that image: identified in the image, where an error of the camera's pose does
# not move it, not in space, where it can move a point past its neighbour
MATCH_SPACING_FRACTION = 0.3


# -- which true point each measured one is ---------------------------------------------
@dataclass(frozen=True, eq=False)
class ImageMatch:
    """The identities of M measured points read in one image: ``index`` (M,) the true point nearest
    each measured one's pixel, ``ok`` (M,) whether it stands for that true point (within
    ``fraction`` of ``spacing_px``, and the nearest of the measured points on it), ``spacing_px``
    the true points' smallest spacing in the image (pixels)."""

    index: np.ndarray
    ok: np.ndarray
    spacing_px: float
    fraction: float


def identify_in_image(measured_uv, true_uv, fraction: float = MATCH_SPACING_FRACTION) -> ImageMatch:
    """Which true point each measured point is, read in one image: ``measured_uv`` (M, 2) the
    measured points' pixels, ``true_uv`` (T, 2) the true points seen by the camera really posed, in
    the same pixels (T >= 2). Each measured point is the true point nearest its pixel when within
    ``fraction`` of the true points' smallest spacing; two on one true point: the nearer stands for it."""
    true_uv = np.asarray(true_uv, float)
    gaps = np.linalg.norm(true_uv[:, None] - true_uv[None], axis=2)
    spacing = float(np.min(gaps[~np.eye(len(true_uv), dtype=bool)]))
    d = np.linalg.norm(np.asarray(measured_uv, float)[:, None] - true_uv[None], axis=2)
    near = d.argmin(axis=1)
    dist = d[np.arange(len(near)), near]
    ok = dist <= fraction * spacing
    for j in np.unique(near[ok]):  # two measured points on one true one: the nearer stands for it
        dup = np.flatnonzero(ok & (near == j))
        ok[dup[np.argsort(dist[dup])[1:]]] = False
    return ImageMatch(near, ok, spacing, fraction)


def nearest_order(true_uv, ordered_uv) -> list[int]:
    """For each of ``ordered_uv`` (K, 2) the index of the nearest of ``true_uv`` (N, 2): the true
    points in the order the measurement gives them (a square's corners TL, TR, BR, BL)."""
    true_uv = np.asarray(true_uv, float)
    return [int(np.argmin(np.linalg.norm(true_uv - c, axis=1))) for c in np.asarray(ordered_uv, float)]


# -- one trial -------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class TrialScore:
    """One trial's figures (metres): the worst point in depth (|z|) and in x/y (the larger of |x| and
    |y|), the RMS of z and of x and y together, the mean signed depth error; ``errors_m`` (N, 3) every
    point's error (x, y, z) and ``points`` the points compared."""

    worst_depth_m: float
    worst_xy_m: float
    rms_depth_m: float
    rms_xy_m: float
    mean_depth_m: float
    points: int
    errors_m: np.ndarray = field(repr=False)


def score_trial(errors_m, points: int | None = None) -> TrialScore:
    """The figures of one trial from its errors ``errors_m`` (N, 3; measured minus true, metres);
    ``points``: the points compared (N when None)."""
    e = np.asarray(errors_m, float)
    depth = ErrorStats.from_abs(np.abs(e[:, 2]), name="depth error")
    xy = ErrorStats.from_abs(np.abs(e[:, :2]), name="x/y error")
    return TrialScore(worst_depth_m=depth.max, worst_xy_m=xy.max, rms_depth_m=depth.rms, rms_xy_m=xy.rms,
                      mean_depth_m=float(np.mean(e[:, 2])), points=len(e) if points is None else int(points),
                      errors_m=e)


# -- over a budget row's trials --------------------------------------------------------
@dataclass(frozen=True)
class WorstCaseStats:
    """One measure over trials, in the unit of the input: the median of the trials' worst values and
    its quantiles (``"q05"`` .. ``"q95"``, ``WORST_QUANTILES``), over every point the RMS, 95th
    percentile and maximum of the absolute error, the share of trials whose worst value is within
    ``bound``, and (depth only) the mean signed error."""

    worst_median: float
    worst_quantiles: Mapping[str, float]
    rms: float
    p95: float
    max: float
    within_bound_frac: float
    mean_signed: float | None = None


def worst_case_stats(worst, pooled_abs, bound: float, signed=None) -> WorstCaseStats:
    """``WorstCaseStats`` of the trials' worst values ``worst`` (T,), every point's absolute error
    ``pooled_abs`` (any shape) and the bound; ``signed``: every point's signed error (its mean is
    reported; None: not reported)."""
    w = np.asarray(worst, float)
    pooled = ErrorStats.from_abs(pooled_abs, name="pooled error")
    return WorstCaseStats(
        worst_median=float(np.median(w)),
        worst_quantiles={f"q{int(q * 100):02d}": float(np.quantile(w, q)) for q in WORST_QUANTILES},
        rms=pooled.rms, p95=pooled.p95, max=pooled.max, within_bound_frac=float(np.mean(w <= bound)),
        mean_signed=None if signed is None else float(np.mean(signed)))


@dataclass(frozen=True)
class TrialsSummary:
    """A budget row's trials that measured: depth and x/y statistics (``WorstCaseStats``)."""

    depth: WorstCaseStats
    xy: WorstCaseStats


def summarise_trials(worst_depth: Sequence[float], worst_xy: Sequence[float], errors: Sequence,
                     depth_bound: float = PAPER_DEPTH_MM, xy_bound: float = PAPER_XY_MM) -> TrialsSummary:
    """Statistics of the trials that measured (one entry per trial, at least one): each trial's worst
    depth and x/y error, and its errors (N_i, 3; x, y, z), all in the unit of the bounds (millimetres
    for the paper's)."""
    e = np.concatenate([np.asarray(x, float) for x in errors])
    return TrialsSummary(
        depth=worst_case_stats(worst_depth, np.abs(e[:, 2]), depth_bound, signed=e[:, 2]),
        xy=worst_case_stats(worst_xy, np.abs(e[:, :2]).ravel(), xy_bound))
