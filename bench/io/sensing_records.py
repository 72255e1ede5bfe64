"""The sensing loop's typed records (frozen) as sensing.json holds them, the outcome classes a run
is scored by, and the real rig of a study (its part of study.json's settings). The records' forms
are registered here with ``bench.io.codecs.base`` (``encode(result)`` is sensing.json); the loop itself
is ``bench.run.sensing``, the study ``bench.run.sensing.study``.

Ground truth appears here only as the scores recorded beside the loop's own verdict
(``gt_visibility``: camera -> {"visible_fraction", "false_boundary"}).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

from platebench.bench.config import SampleConfig
from platebench.bench.io.codecs import base as codec_base
from platebench.bench.io.codecs import encode
from platebench.bench.io.records import MergedFigures, Stage3Accuracy, file_form
from platebench.reconstruction.paper.boundary_plane import BoundaryPlane
from platebench.reconstruction.paper.false_boundary import FalseBoundaryTest
from platebench.reconstruction.strategy.detectors import DetectorResult
from platebench.reconstruction.strategy.multiview import OUTLINE_BRIDGE_M, BoundaryVerdict, ViewOutline
from platebench.reconstruction.strategy.planner import PlannedView
from platebench.reconstruction.strategy.poses import SensorPose

__all__ = ["OUTCOMES", "OUTCOME_TEXT", "HIDDEN_BELOW", "hidden", "StageRecord", "ActiveRecord", "ViewRecord",
           "FinalRecord", "SensingResult", "StudyRealism"]

OUTCOMES = ("cured", "honest", "silent", "clean", "false_alarm", "unconfirmed")
OUTCOME_TEXT = {
    "cured": "the stage-2 pose hid part of the boundary; the final poses see all of it and the loop verified it",
    "honest": "part of the boundary is still hidden and the loop says so",
    "silent": "part of the boundary is still hidden and the loop says it is verified (the defect)",
    "clean": "nothing was hidden and nothing was raised",
    "false_alarm": "nothing was hidden, but the loop applied a cure or did not verify the boundary",
    "unconfirmed": "the stage-2 pose hid part of the boundary; the final poses see all of it (the study's "
                   "\"seen all\" target counts it as cured), but the loop could not confirm it and says so",
}
HIDDEN_BELOW = 0.995  # ground truth "hides part of the boundary": a camera sees less than this fraction


def hidden(gt_visibility: dict) -> bool:
    """Ground truth hides part of the boundary from a camera (fraction below ``HIDDEN_BELOW``)."""
    return min(v["visible_fraction"] for v in gt_visibility.values()) < HIDDEN_BELOW


@dataclass(frozen=True)
class StageRecord:
    """Stage 1 or 2: a pose and its passive boundary."""

    stage: int
    pose: SensorPose
    boundary_points: int
    boundary_method: str
    gt_visibility: dict
    boundary_plane: BoundaryPlane | None = None


@dataclass(frozen=True)
class ActiveRecord:
    """Stage 3: the projector's pose, the paper's false-boundary test, the matching."""

    pose: SensorPose
    projector_pose: SensorPose
    false_boundary: FalseBoundaryTest | None
    matched: int
    unmatched: tuple
    gt_visibility: dict
    error: str | None = None
    cut: int = 0  # matched centres of squares cut in either image, set apart from ``matched`` (pipeline ``cut``)

    @property
    def stage(self) -> int:
        return 3


@dataclass(frozen=True)
class ViewRecord:
    """A verification view or a cure: the planned pose and what its passive stereo measured."""

    view: PlannedView
    outline_points: int
    outline_method: str
    gt_visibility: dict
    error: str | None = None
    active: dict | None = None  # an ``ActivePoints``' form (None: no active pair at this pose)


@dataclass(frozen=True)
class FinalRecord:
    """The end of the run: the loop's verdict (no ground truth), and its scores against ground truth."""

    pose: SensorPose
    stage_dir: str
    false_boundary: FalseBoundaryTest | None
    matched: int
    boundary_verified: bool
    verdict_reason: str
    unverified_parts: tuple
    poses: tuple
    gt_visibility: dict
    gt_visibility_first: dict
    accuracy: Stage3Accuracy | None  # None: stage 3 reconstructed nothing
    merged: MergedFigures
    outcome: str
    gt_reachable_visibility: dict | None = None  # union over every reachable candidate pose (scoring only)
    # the boundary points some pair of those poses could confirm (``scoring.verifiable_visibility``),
    # and the longest stretch of boundary no pair could (metres)
    gt_verifiable_visibility: dict | None = None
    gt_unconfirmable_max_m: float | None = None
    front_oriented: float | None = None  # share of the merged boundary where the square centres orient the front

    @property
    def hidden_first(self) -> bool:
        """Ground truth: the stage-2 pose hides part of the boundary."""
        return hidden(self.gt_visibility_first)

    @property
    def hidden_final(self) -> bool:
        """Ground truth: the final poses (together) still miss part of the boundary."""
        return hidden(self.gt_visibility)

    @property
    def gt_reachable(self) -> bool | None:
        """Ground truth: the reachable candidate poses together see the whole boundary (None: not cast)."""
        return None if self.gt_reachable_visibility is None else not hidden(self.gt_reachable_visibility)

    @property
    def gt_verifiable(self) -> bool | None:
        """Ground truth: pairs of reachable candidate poses could confirm the boundary by the
        verdict's rule, but for stretches no longer than the verdict links over along a measured
        outline (``multiview.OUTLINE_BRIDGE_M``) (None: not cast)."""
        if self.gt_unconfirmable_max_m is None:
            return None
        return self.gt_unconfirmable_max_m <= OUTLINE_BRIDGE_M


@dataclass(frozen=True)
class SensingResult:
    """Everything the loop did, typed; its form (``encode``) is sensing.json."""

    config: SampleConfig
    steps: tuple
    detectors: tuple[DetectorResult, ...]
    verification_views: tuple[PlannedView, ...]
    cure_views: tuple[PlannedView, ...]
    verdict: BoundaryVerdict
    final: FinalRecord
    notes: tuple[str, ...]
    time_s: float
    views: tuple[ViewOutline, ...] = ()  # every measuring pose's outline (not in sensing.json: multiview.npz)
    # the projected patterns (``Pattern.description``): stage 3's, and the verification views' and cures'
    patterns: dict = field(default_factory=dict)
    # a real rig (``cfg.realism`` not ideal): "realism" (its file form), "estimates": what its draw's
    # estimates missed by (``bench.run.realism.RigDraw.report``, a ``DrawReport``) and "moves": every
    # move, commanded vs really posed (``RobotMove``s); None: ideal
    acquisition: dict | None = None

    @property
    def cures(self) -> int:
        return len(self.cure_views)


@dataclass(frozen=True)
class StudyRealism:
    """The real rig a study measured with (its part of the study's settings; all None: ideal): the
    realism preset's name, the error sources on, how each plate's draw is seeded, the corner noise
    of the calibration views (px per axis, measured once for every plate) and the sources scaled from
    their sourced magnitude (``--realism-scale``; written only when some are)."""

    realism: str | None = None
    realism_sources: tuple = ()
    realism_seeds: str | None = None
    corner_noise_px: float | None = None
    realism_scales: tuple = ()  # ((source, factor), ...): sources not at their sourced magnitude


# ----------------------------------------------------------------------------- the forms (sensing.json, study.json)
@codec_base.encode.register(StageRecord)
def _(x: StageRecord) -> dict:
    d = {"stage": x.stage, "pose": encode(x.pose), "boundary_points": x.boundary_points,
         "boundary_method": x.boundary_method, "gt_visibility": x.gt_visibility}
    if x.boundary_plane is not None:
        d["boundary_plane"] = {"normal": x.boundary_plane.normal.tolist(),
                               "point_m": x.boundary_plane.point.tolist()}
    return d


@codec_base.encode.register(ActiveRecord)
def _(x: ActiveRecord) -> dict:
    return {"stage": 3, "pose": encode(x.pose), "projector_pose": encode(x.projector_pose),
            "false_boundary": None if x.false_boundary is None else encode(x.false_boundary),
            "matched": x.matched, "cut_squares": x.cut, "unmatched": list(x.unmatched),
            "gt_visibility": x.gt_visibility, "error": x.error}


@codec_base.encode.register(ViewRecord)
def _(x: ViewRecord) -> dict:
    return {"stage": "view", **encode(x.view), "outline_points": x.outline_points,
            "outline_method": x.outline_method, "gt_visibility": x.gt_visibility, "error": x.error,
            "active": x.active}


@codec_base.encode.register(FinalRecord)
def _(x: FinalRecord) -> dict:
    return {"pose": encode(x.pose), "stage_dir": x.stage_dir,
            "false_boundary": None if x.false_boundary is None else encode(x.false_boundary),
            "matched": x.matched, "boundary_verified": x.boundary_verified,
            "verdict": x.verdict_reason, "unverified_parts": list(x.unverified_parts),
            "poses": list(x.poses), "gt_visibility": x.gt_visibility,
            "gt_visibility_first": x.gt_visibility_first,
            "accuracy": None if x.accuracy is None else x.accuracy.to_dict(), "merged": x.merged.to_dict(),
            "outcome": x.outcome, "outcome_text": OUTCOME_TEXT[x.outcome],
            "gt_hidden_first": x.hidden_first, "gt_hidden_final": x.hidden_final,
            "gt_reachable_visibility": x.gt_reachable_visibility, "gt_reachable": x.gt_reachable,
            "gt_verifiable_visibility": x.gt_verifiable_visibility, "gt_verifiable": x.gt_verifiable,
            "gt_unconfirmable_max_mm": None if x.gt_unconfirmable_max_m is None
            else round(x.gt_unconfirmable_max_m * 1e3, 1),
            "front_oriented_frac": None if x.front_oriented is None else round(x.front_oriented, 3)}


@codec_base.encode.register(SensingResult)
def _(x: SensingResult) -> dict:
    """sensing.json."""
    return {"config": encode(x.config), "steps": [encode(s) for s in x.steps],
            "detectors": {d.name: encode(d) for d in x.detectors},
            "verification_views": [encode(v) for v in x.verification_views],
            "cures": x.cures, "cure_views": [encode(v) for v in x.cure_views],
            "verdict": encode(x.verdict), "notes": list(x.notes),
            "patterns": x.patterns, "final": encode(x.final), "time_s": x.time_s,
            **({} if x.acquisition is None else {"acquisition": file_form(x.acquisition)})}


@codec_base.encode.register(StudyRealism)
def _(x: StudyRealism) -> dict:
    out = {"realism": x.realism, "realism_sources": list(x.realism_sources),
           "realism_seeds": x.realism_seeds, "corner_noise_px": x.corner_noise_px}
    return {**out, "realism_scales": dict(x.realism_scales)} if x.realism_scales else out


@codec_base.decoder(StudyRealism)
def _(settings: Mapping) -> StudyRealism:
    """The realism part of a study's settings (the other settings are left alone)."""
    return StudyRealism(settings.get("realism"), tuple(settings.get("realism_sources") or ()),
                        settings.get("realism_seeds"), settings.get("corner_noise_px"),
                        tuple((settings.get("realism_scales") or {}).items()))
