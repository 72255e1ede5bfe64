"""The cut-squares study (``platebench study cut-squares``, ``bench.run.cut_study``) as typed
records, and its file form (cut_study.json).

Field names are the JSON keys, units in the names (``_deg`` degrees, ``_m`` metres, ``_mm``
millimetres, ``_s`` seconds; counts bare); ``to_dict`` writes a record and ``from_dict`` reads it
back (``bench.io.records.Record``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from platebench.bench.io.records import Record

__all__ = ["CutRow", "CutTotals", "CutStudy"]

_COUNTS = ("centres", "kept", "cut", "cut_by_outline", "cut_by_threshold", "outside_before", "outside_kept",
           "outside_cut")


@dataclass(frozen=True)
class CutRow(Record):
    """One plate: its bend (deg), direction and axis (deg), the rig's distance (m); a plate the
    pipeline could not reconstruct has its one-line ``error`` and no counts. Else: the centres the
    pipeline matched with the cut squares kept, those it keeps and those it sets apart as cut (by the
    outline, by the threshold alone), the centres outside the paper's bound (or on no square) with
    the cut ones kept, of the kept and of those set apart, and the kept centres' worst depth and x/y
    error (mm; None: none kept)."""

    bend_deg: float
    direction: str
    axis_deg: float
    distance_m: float
    error: str | None = None
    centres: int = 0
    kept: int = 0
    cut: int = 0
    cut_by_outline: int = 0
    cut_by_threshold: int = 0
    outside_before: int = 0
    outside_kept: int = 0
    outside_cut: int = 0
    kept_depth_max_mm: float | None = None
    kept_xy_max_mm: float | None = None

    @property
    def ok(self) -> bool:
        return self.error is None

    def to_dict(self) -> dict:
        """The row's keys: an error row has its error and no counts, a measured row no error key."""
        d = super().to_dict()
        if self.ok:
            del d["error"]
            return d
        return {k: v for k, v in d.items() if k not in (*_COUNTS, "kept_depth_max_mm", "kept_xy_max_mm")}


@dataclass(frozen=True)
class CutTotals(Record):
    """The study's totals: plates, failed plates, the rows' counts summed over the measured plates,
    and the plates with a centre outside the bound with the cut squares kept, and of the kept."""

    plates: int
    errors: int
    centres: int
    kept: int
    cut: int
    cut_by_outline: int
    cut_by_threshold: int
    outside_before: int
    outside_kept: int
    outside_cut: int
    plates_outside_before: int
    plates_outside_kept: int

    @classmethod
    def of(cls, rows) -> "CutTotals":
        """The totals of ``rows`` (``CutRow``s)."""
        ok = [r for r in rows if r.ok]
        return cls(plates=len(rows), errors=len(rows) - len(ok),
                   **{k: int(sum(getattr(r, k) for r in ok)) for k in _COUNTS},
                   plates_outside_before=sum(r.outside_before > 0 for r in ok),
                   plates_outside_kept=sum(r.outside_kept > 0 for r in ok))


@dataclass(frozen=True)
class CutStudy(Record):
    """The study: its rows (``CutRow``), totals, seconds and the settings it ran with (the command's
    flags, as given)."""

    rows: tuple[CutRow, ...]
    totals: CutTotals
    time_s: float
    settings: Mapping[str, Any] = field(default_factory=dict)
    kind: str = "cut-squares study"

    def to_dict(self) -> dict:
        d = super().to_dict()
        return {"kind": d.pop("kind"), "rows": d.pop("rows"), "totals": d.pop("totals"), "time_s": d.pop("time_s"),
                **d}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "CutStudy":
        d = dict(d)
        return super().from_dict({**d, "rows": tuple(CutRow.from_dict(r) for r in d.get("rows") or ()),
                                  "totals": CutTotals.from_dict(d["totals"])})
