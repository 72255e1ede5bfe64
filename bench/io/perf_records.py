"""Typed records read from the figures of a ``platebench perf gpu`` run (``bench.perf.gpu.perf_gpu``,
the ``figures`` of its ``--json`` document).

``GpuTargetFigures.from_dict`` reads the figures its GPU targets are checked on; a figure the run
did not measure (its section failed or did not run) reads as None.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

__all__ = ["GpuTargetFigures"]


def _mapping(d: Any) -> Mapping[str, Any]:
    return d if isinstance(d, Mapping) else {}


@dataclass(frozen=True)
class GpuTargetFigures:
    """The figures the GPU targets are checked on: a whole sample's seconds in the GPU variant
    (section ``sample``), the two-stage sweep's samples per second (section ``sweep``, its
    ``pipeline``) and the study's wall seconds (section ``study``)."""

    whole_sample_s: float | None = None
    sweep_samples_per_s: float | None = None
    study_s: float | None = None

    @classmethod
    def from_dict(cls, figures: Mapping[str, Any], gpu_variant: str) -> "GpuTargetFigures":
        sample = _mapping(_mapping(figures.get("sample")).get(gpu_variant))
        pipeline = _mapping(_mapping(figures.get("sweep")).get("pipeline"))
        return cls(sample.get("whole_sample_s"), pipeline.get("samples_per_s"),
                   _mapping(figures.get("study")).get("wall_s"))
