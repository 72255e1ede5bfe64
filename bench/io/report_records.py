"""Typed records of the files the report reads: ground truth's boundary visibility
(``gt/visibility.json``, sensing.json's ``gt_visibility``), a method's false-boundary verdict
(recon.json's and sensing.json's ``false_boundary``), the timings of a sample or a reconstruction
(``timings_s`` of sample.json and recon.json), the steps of a sensing run (sensing.json) and the
flags of a study's case row.

``from_dict`` reads a file's dict; a key the file lacks reads as None (or empty), a value of the wrong
shape as absent. Units are in the field names: fractions 0..1 (``_fraction``, ``_frac``), seconds
(``_s``), metres (``_m``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from platebench.bench.io.records import Record

__all__ = ["CameraVisibility", "visibility_records", "boundary_hidden", "FalseBoundaryRecord", "RunTimings",
           "SensingStep", "SensingRun", "StudyCase"]


def _mapping(d: Any) -> Mapping[str, Any]:
    return d if isinstance(d, Mapping) else {}


@dataclass(frozen=True)
class CameraVisibility(Record):
    """Ground truth's visibility of the true boundary from one camera: the fraction (0..1, by arc
    length) it sees, whether part of it is hidden (a false boundary), the hidden runs of boundary
    points and the point counts (a ``scenes.render.ground_truth.BoundaryVisibility``'s form,
    ``bench/io/codecs/scenes.py``)."""

    visible_fraction: float | None = None
    false_boundary: bool | None = None
    hidden_segments: tuple = ()
    n_points: int | None = None
    n_visible: int | None = None


def visibility_records(d: Any) -> dict[str, CameraVisibility]:
    """camera -> ``CameraVisibility`` of a visibility dict (entries that are not mappings left out)."""
    return {str(cam): CameraVisibility.from_dict(v) for cam, v in _mapping(d).items() if isinstance(v, Mapping)}


def boundary_hidden(vis: Mapping[str, CameraVisibility]) -> bool:
    """Ground truth: part of the true boundary is hidden from some camera."""
    return any(bool(v.false_boundary) for v in vis.values())


@dataclass(frozen=True)
class FalseBoundaryRecord(Record):
    """A method's false-boundary verdict as its files hold it (a
    ``reconstruction.paper.false_boundary.FalseBoundaryTest``'s form, ``bench/io/codecs/reconstruction.py``):
    whole squares detected per image, the squares expected and their ids, the counting test (paper
    IV-B), the arrays that disagree (paper II, Fig. 2), the verdict (either of the two) and the cut
    squares per image."""

    detected: Mapping[str, int] = field(default_factory=dict)
    expected: int | None = None
    expected_ids: tuple = ()
    counting_test: bool | None = None
    arrays_disagree: bool | None = None
    false_boundary_detected: bool | None = None
    cut_squares: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def of(cls, doc: Any) -> "FalseBoundaryRecord | None":
        """The verdict of a recon.json or a sensing.json step (its ``false_boundary``); None without one."""
        fb = _mapping(doc).get("false_boundary")
        return cls.from_dict(fb) if isinstance(fb, Mapping) else None

    def detected_text(self) -> str | None:
        """'left 16, right 14': the squares detected per image (None: none recorded)."""
        return ", ".join(f"{k} {v}" for k, v in _mapping(self.detected).items()) or None


@dataclass(frozen=True)
class RunTimings:
    """The seconds a sample's rendering or a reconstruction took (its ``timings_s``): in all, for the
    ground truth, and for the images' renders together (the ``render_<image>_s`` entries summed in
    their order; None where there are none)."""

    total_s: float | None = None
    ground_truth_s: float | None = None
    renders_s: float | None = None

    @classmethod
    def from_dict(cls, d: Any) -> "RunTimings":
        """A ``timings_s`` dict read (``bench.run.render.RenderedSample.timings_s``, a pipeline's)."""
        d = _mapping(d)
        renders = [v for k, v in d.items() if k.startswith("render_") and k.endswith("_s")]
        return cls(d.get("total_s"), d.get("ground_truth_s"), sum(renders) if renders else None)

    @classmethod
    def of(cls, meta: Any) -> "RunTimings":
        """The timings of a sample.json or recon.json dict (empty when it holds none)."""
        return cls.from_dict(_mapping(meta).get("timings_s"))


@dataclass(frozen=True)
class SensingStep:
    """A step of a sensing run (sensing.json's ``steps`` or its ``final``): its stage or decision,
    the cure it applies, the pose's distance (m) and reason, the squares it matched, the loop's
    false-boundary verdict there, ground truth's visibility, and, for the final one, whether the
    boundary was verified, the stage-3 accuracy figures and the outcome."""

    stage: Any = None
    decision: str | None = None
    method: str | None = None
    distance_m: float | None = None
    pose_reason: str | None = None
    matched: int | None = None
    reason: str | None = None
    false_boundary: FalseBoundaryRecord | None = None
    gt_visibility: Mapping[str, CameraVisibility] = field(default_factory=dict)
    boundary_verified: bool | None = None
    accuracy: Mapping[str, Any] = field(default_factory=dict)
    outcome: str | None = None

    @classmethod
    def from_dict(cls, d: Any) -> "SensingStep":
        d = _mapping(d)
        pose = _mapping(d.get("pose"))
        return cls(d.get("stage"), d.get("decision"), d.get("method"), pose.get("distance_m"), pose.get("reason"),
                   d.get("matched"), d.get("reason"), FalseBoundaryRecord.of(d),
                   visibility_records(d.get("gt_visibility")),
                   d.get("boundary_verified"), dict(_mapping(d.get("accuracy"))), d.get("outcome"))


@dataclass(frozen=True)
class SensingRun:
    """A sensing run's sensing.json, as the report reads it: its outcome, cures, time (s), final step
    and steps."""

    outcome: str | None = None
    cures: int | None = None
    time_s: float | None = None
    final: SensingStep = field(default_factory=SensingStep)
    steps: tuple[SensingStep, ...] = ()

    @classmethod
    def from_dict(cls, doc: Any) -> "SensingRun":
        doc = _mapping(doc)
        final = SensingStep.from_dict(doc.get("final"))
        return cls(doc.get("outcome", final.outcome), doc.get("cures"), doc.get("time_s"), final,
                   tuple(SensingStep.from_dict(s) for s in doc.get("steps") or [] if isinstance(s, Mapping)))


@dataclass(frozen=True)
class StudyCase:
    """The flags and time of one case row of a study table: its status, ground truth's false boundary,
    the pipeline's verdict (``detected``), its outcome class and its time (s)."""

    status: str | None = None
    false_boundary_gt: Any = None
    detected: Any = None
    outcome: str | None = None
    time_s: Any = None

    @classmethod
    def from_dict(cls, row: Any) -> "StudyCase":
        row = _mapping(row)
        return cls(row.get("status"), row.get("false_boundary_gt"), row.get("detected"), row.get("outcome"),
                   row.get("time_s"))
