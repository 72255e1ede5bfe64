"""Dense disparity metrics in the conventions of the Middlebury v3 and ETH3D two-view benchmarks.

Inputs are disparity maps in pixels (H, W), d = u_left - u_right. Everything
here is image-space: figures are reported in px (and % or fractions).

Common conventions
------------------
* Ground truth unknown: any non-finite GT value (Middlebury and ETH3D store
  unknown GT as +inf). Such pixels are skipped entirely.
* error = |d_est - d_gt| (absolute: errors of both signs never cancel).
* Regions: "all" = every pixel with known GT (inside ``roi`` if given);
  "nonocc" = those pixels where ``mask`` (non-occluded, True = visible in both
  views) is True. "nonocc" is computed only when ``mask`` is given.
* Quantiles use the nearest rank: A_q = the smallest error e with at least q % of
  the pixels having error <= e (``stats.nearest_rank_quantile``).

Middlebury v3 (``middlebury_metrics``), over the n pixels of the region, with the
rules of the Middlebury SDK's ``evaldisp`` (MiddEval3 ``code/evaldisp/evaldisp.cpp``):
  invalid = an estimate of +inf, and only that (a hole of a sparse map); every other
            value is an estimate, clipped to [0, maxdisp] (``max_disparity_px``: the
            ``ndisp`` of the pair's calib.txt), so 0, negative values and -inf count as
            estimates of 0 px. One difference, on purpose: NaN counts as invalid here
            (the SDK's comparisons let a NaN estimate through as valid and never bad,
            and its avgerr becomes NaN).
  bad_T   = 100 * (#valid with error > T  +  #invalid) / n     [%]
            (error > T strictly; invalid pixels count as bad: the SDK's "totbad")
  invalid = 100 * #invalid / n                                  [%]
  avgerr  = mean error over the valid estimates                 [px]  (the SDK's avgErr)
  rms     = sqrt(mean error^2) over the valid estimates         [px]
  A50/A90/A95/A99 = error quantiles over all n pixels, an invalid pixel
            counting as an infinite error (so A99 = inf when > 1 % are invalid).
  The region "nonocc" is the SDK's mask0nocc == 255. Differences that remain: the SDK
  sums errors in float32 (here float64), can score a half- or quarter-size estimate
  against full-size truth (here the sizes must match), and can round estimates first
  (``rounddisp``; here never: the bench's truth is not integer).

ETH3D two-view (``eth3d_metrics``), over the n pixels of the region, n_est of
which have a valid estimate (finite and > 0; no clipping):
  coverage = n_est / n                                          [fraction]
  bad_T    = 100 * #(error > T) / n_est                         [% of ESTIMATED pixels]
  avgerr, rms, A50/A90/A95/A99 over the n_est estimated pixels  [px]
  (missing estimates lower coverage only; they are not counted as bad.)

Undefined figures (no pixel in the region, no valid estimate) are NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .stats import check_array, nearest_rank_quantile

__all__ = [
    "BAD_THRESHOLDS_PX",
    "QUANTILES_PCT",
    "MiddleburyRegion",
    "MiddleburyScore",
    "Eth3dRegion",
    "Eth3dScore",
    "middlebury_metrics",
    "eth3d_metrics",
]

BAD_THRESHOLDS_PX: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0)
QUANTILES_PCT: tuple[int, ...] = (50, 90, 95, 99)


@dataclass(frozen=True)
class MiddleburyRegion:
    """Middlebury v3 figures for one region ("all" or "nonocc")."""

    region: str
    gt_count: int  # n: pixels with known GT in the region
    valid_count: int  # of which have a valid estimate
    bad_pct: tuple[tuple[float, float], ...]  # ((threshold px, % bad incl. invalid), ...)
    invalid_pct: float
    avgerr: float
    rms: float
    quantiles: tuple[tuple[int, float], ...]  # ((q %, error px; inf possible), ...)


@dataclass(frozen=True)
class MiddleburyScore:
    all: MiddleburyRegion
    nonocc: MiddleburyRegion | None


@dataclass(frozen=True)
class Eth3dRegion:
    """ETH3D two-view figures for one region ("all" or "nonocc")."""

    region: str
    gt_count: int
    est_count: int
    coverage: float
    bad_pct: tuple[tuple[float, float], ...]  # % of estimated pixels
    avgerr: float
    rms: float
    quantiles: tuple[tuple[int, float], ...]


@dataclass(frozen=True)
class Eth3dScore:
    all: Eth3dRegion
    nonocc: Eth3dRegion | None


# ----------------------------------------------------------------------- helpers


def _prepare(disp_est, disp_gt, mask, roi, middlebury_max=None):
    """(valid estimates, |error| (inf where invalid), regions); ``middlebury_max`` not None: the SDK's
    rules (module doc) with that maxdisp, else valid = finite and > 0, no clipping."""
    est = check_array(disp_est, "disp_est", shape=(None, None), finite=False)
    gt = check_array(disp_gt, "disp_gt", shape=(None, None), finite=False)
    if est.shape != gt.shape:
        raise ValueError(f"disp_est/disp_gt: shape mismatch {est.shape} vs {gt.shape}")
    known = np.isfinite(gt)
    if roi is not None:
        roi = _bool_mask(roi, "roi", gt.shape)
        known &= roi
    if not known.any():
        raise ValueError("disp_gt: no pixel with known (finite) ground truth" + (" inside roi" if roi is not None else ""))
    if middlebury_max is None:
        valid = np.isfinite(est) & (est > 0)
        d = np.where(valid, est, 0.0)
    else:
        valid = ~np.isnan(est) & (est != np.inf)
        d = np.clip(np.where(valid, est, 0.0), 0.0, middlebury_max)
    err = np.where(valid & known, np.abs(d - np.where(known, gt, 0.0)), np.inf)
    regions = [("all", known)]
    if mask is not None:
        regions.append(("nonocc", known & _bool_mask(mask, "mask", gt.shape)))
    return valid, err, regions


def _bool_mask(m, name: str, shape) -> np.ndarray:
    a = np.asarray(m)
    if a.dtype != np.bool_:
        raise ValueError(
            f"{name}: expected a bool array (True = evaluate / non-occluded), got dtype {a.dtype}; "
            "for Middlebury's mask0nocc.png use (png == 255)"
        )
    if a.shape != tuple(shape):
        raise ValueError(f"{name}: shape mismatch {a.shape} vs disparity {tuple(shape)}")
    return a


def _mean_rms(e: np.ndarray) -> tuple[float, float]:
    if e.size == 0:
        return math.nan, math.nan
    return float(e.mean()), float(np.sqrt(np.mean(e * e)))


# ------------------------------------------------------------------------ public


def middlebury_metrics(
    disp_est,
    disp_gt,
    mask=None,
    *,
    roi=None,
    thresholds=BAD_THRESHOLDS_PX,
    quantiles=QUANTILES_PCT,
    max_disparity_px: float = math.inf,
) -> MiddleburyScore:
    """Middlebury v3 metrics with the SDK's rules (see module doc) on "all" and, given ``mask``, "nonocc".

    Args:
        disp_est: (H, W) estimated disparity, px; +inf (and NaN) = invalid, any other value an
            estimate clipped to [0, max_disparity_px].
        disp_gt: (H, W) true disparity, px; non-finite = unknown (skipped).
        mask: optional (H, W) bool, True = non-occluded.
        roi: optional (H, W) bool, pixels outside it are ignored everywhere.
        max_disparity_px: the SDK's maxdisp (the calib.txt's ndisp); default no upper clip.
    """
    valid, err, regions = _prepare(disp_est, disp_gt, mask, roi, middlebury_max=max_disparity_px)
    out = {}
    for name, reg in regions:
        n = int(np.count_nonzero(reg))
        e_all = err[reg]  # inf where the estimate is invalid
        v = valid[reg]
        n_valid = int(np.count_nonzero(v))
        n_inv = n - n_valid
        ev = e_all[v]
        avg, rms = _mean_rms(ev)
        if n == 0:
            bad = tuple((float(t), math.nan) for t in thresholds)
            inv = math.nan
        else:
            bad = tuple(
                (float(t), 100.0 * (int(np.count_nonzero(ev > t)) + n_inv) / n) for t in thresholds
            )
            inv = 100.0 * n_inv / n
        qs = tuple((int(q), nearest_rank_quantile(e_all, q)) for q in quantiles)
        out[name] = MiddleburyRegion(name, n, n_valid, bad, inv, avg, rms, qs)
    return MiddleburyScore(all=out["all"], nonocc=out.get("nonocc"))


def eth3d_metrics(
    disp_est,
    disp_gt,
    mask=None,
    *,
    roi=None,
    thresholds=BAD_THRESHOLDS_PX,
    quantiles=QUANTILES_PCT,
) -> Eth3dScore:
    """ETH3D two-view metrics (see module doc) on "all" and, given ``mask``, "nonocc".

    Same arguments as :func:`middlebury_metrics`.
    """
    valid, err, regions = _prepare(disp_est, disp_gt, mask, roi)
    out = {}
    for name, reg in regions:
        n = int(np.count_nonzero(reg))
        ev = err[reg & valid]
        n_est = int(ev.size)
        avg, rms = _mean_rms(ev)
        cov = n_est / n if n else math.nan
        if n_est == 0:
            bad = tuple((float(t), math.nan) for t in thresholds)
        else:
            bad = tuple((float(t), 100.0 * int(np.count_nonzero(ev > t)) / n_est) for t in thresholds)
        qs = tuple((int(q), nearest_rank_quantile(ev, q)) for q in quantiles)
        out[name] = Eth3dRegion(name, n, n_est, cov, bad, avg, rms, qs)
    return Eth3dScore(all=out["all"], nonocc=out.get("nonocc"))
