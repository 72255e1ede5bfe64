"""Detection scores of a yes/no flag against ground truth: counts, precision and recall.

One definition for every place that scores a detector (the false-boundary study, the report's
tables and plots): a case counts only when both the flag and the truth are known (``None`` is
left out). Precision = TP / (TP + FP), recall = TP / (TP + FN), ``None`` where undefined.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

__all__ = ["DetectionScore", "detection_score"]


@dataclass(frozen=True)
class DetectionScore:
    """Confusion counts of a flag against ground truth, with precision and recall (0..1 or None)."""

    true_positive: int
    false_positive: int
    false_negative: int
    true_negative: int

    @property
    def precision(self) -> float | None:
        n = self.true_positive + self.false_positive
        return self.true_positive / n if n else None

    @property
    def recall(self) -> float | None:
        n = self.true_positive + self.false_negative
        return self.true_positive / n if n else None

    @property
    def cases(self) -> int:
        return self.true_positive + self.false_positive + self.false_negative + self.true_negative


def detection_score(truth: Iterable, flagged: Iterable) -> DetectionScore:
    """Score ``flagged`` (bool or None per case) against ``truth`` (bool or None per case)."""
    tp = fp = fn = tn = 0
    for g, d in zip(truth, flagged, strict=True):
        if g is None or d is None:
            continue
        g, d = bool(g), bool(d)
        tp += g and d
        fp += (not g) and d
        fn += g and not d
        tn += (not g) and not d
    return DetectionScore(int(tp), int(fp), int(fn), int(tn))
