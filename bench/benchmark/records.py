"""The benchmark's results table, one frozen record per row, and its file form.

A results folder (``platebench benchmark score``) holds ``results.parquet`` and ``results.csv``: one
``BenchmarkRow`` per (sample, method) of the split, every sample of the split present for every
method scored (a sample without an output is a row with ``status = "missing"``, counted as a failure:
no estimate anywhere); and ``sparse.csv``: one ``SparseRow`` per (sample, method) for methods whose
output includes sparse points (the paper's square centres).

Units are in the field names (``_mm`` millimetres, ``_m`` metres, ``_deg`` degrees, ``_pct`` percent
0..100, ``_frac`` fraction 0..1, ``_px`` pixels, ``_s`` seconds). A figure that does not exist is
None in a file (NaN in a pandas frame). Definitions: ``docs/benchmark.md`` and
``platebench.evaluation.protocol``.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from types import SimpleNamespace

from platebench.bench.io.records import Record

__all__ = ["BenchmarkRow", "SparseRow", "STATUSES", "PRIMARY", "BEND_BINS", "bend_bin", "COLUMNS"]

STATUSES = ("ok", "failed", "missing")  # ok: an output was scored; failed: the method raised or its
# output could not be read; missing: no output for the sample. Failed and missing rows count every
# plate pixel as bad and have coverage 0.
PRIMARY = "bad_2mm_pct"  # the primary figure: ranks methods (lower is better)

# Bend bins of the breakdowns, degrees of |bend| (the bend angle of cylinder, fold, S-curve; the
# twist angle's magnitude; families without a bend angle: "none").
BEND_BINS = ((0.0, 30.0, "0-30"), (30.0, 90.0, "30-90"), (90.0, 170.0, "90-170"), (170.0, 361.0, "170-300"))


def bend_bin(bend_deg: float | None) -> str:
    """The breakdown bin of a bend angle in degrees (its magnitude); "none" for None."""
    if bend_deg is None:
        return "none"
    a = abs(float(bend_deg))
    for lo, hi, name in BEND_BINS:
        if lo <= a < hi:
            return name
    raise ValueError(f"bend_deg = {bend_deg} is outside the bend bins (0 to 360 degrees)")


@dataclass(frozen=True)
class BenchmarkRow(Record):
    """One (sample, method) of a benchmark run: the sample's descriptors, then its dense figures.

    Dense figures are taken over the plate's pixels in the left view (the truth's plate mask,
    ``plate_px`` of them); ``coverage_frac`` = ``estimated_px / plate_px`` is reported beside them and
    never mixed into the error statistics, except in the ``bad_*_pct`` figures, where a plate pixel
    without an estimate counts as bad (so abstaining cannot win)."""

    split: str  # the split's name and version, e.g. "v1"
    sample_id: str  # the sample's id in the split
    method: str  # the method's name (a built-in, plug-in or the name given to a folder of outputs)
    status: str  # one of STATUSES
    error: str  # why a row is failed or missing ("" when ok)
    # --- the sample (from the split's definition and its ground truth)
    family: str  # deformation family (plates.spec.FAMILIES)
    bend_deg: float | None  # bend angle, degrees (None: a family without one)
    bend_bin: str  # bend_bin(bend_deg)
    direction: str  # "up" (convex) or "down" (concave); "" where the family has none
    axis_deg: float | None  # bend axis, degrees from the plate's length (None where the family has none)
    distance_m: float  # rig height above the plate centre, metres
    material: str  # "diffuse" (white) or "roughconductor" (rough aluminium)
    realism: str  # realism preset: "ideal", "modern" or "1995"
    false_boundary_gt: bool  # the truth: part of the plate's true boundary is hidden in a view
    # --- what the method gave
    output_kind: str  # "disparity", "depth", "points", "mesh"; "" when there was none
    plate_px: int  # plate pixels in the left view (the truth's mask)
    estimated_px: int  # plate pixels with an estimate
    coverage_frac: float  # estimated_px / plate_px, 0..1 (0 for failed and missing rows)
    bad_2mm_pct: float  # PRIMARY: % of plate pixels whose depth error exceeds 2 mm or that have no estimate
    bad_0_5mm_pct: float  # the same with 0.5 mm
    depth_rms_mm: float | None  # RMS depth error over the estimated plate pixels (None: none estimated)
    depth_median_abs_mm: float | None  # median |depth error| over the estimated plate pixels
    depth_mean_signed_mm: float | None  # mean signed depth error (+ = too far) over the estimated plate pixels
    time_s: float | None  # the method's wall time on the sample (None: not run by the bench)


@dataclass(frozen=True)
class SparseRow(Record):
    """One (sample, method) of sparse points (the paper's square centres): scored apart from the
    dense figures, under their own names."""

    split: str
    sample_id: str
    method: str
    points: str  # what the points are, e.g. "square_centres"
    count: int  # points scored
    dist_rms_mm: float | None  # RMS distance of the points to the true surface
    dist_max_mm: float | None  # largest distance of a point to the true surface
    depth_rms_mm: float | None  # RMS z-depth error in the left camera at the points (None: not known)


# The results table's column names as attributes (``COLUMNS.coverage_frac``): a misspelt one is an
# AttributeError where a misspelt string would be a missing column.
COLUMNS = SimpleNamespace(**{f.name: f.name for f in fields(BenchmarkRow)})
