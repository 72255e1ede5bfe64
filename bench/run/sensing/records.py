"""The sensing loop's options, its typed records (frozen; ``to_dict`` makes ``sensing.json``) and
the outcome classes it is scored by.

Ground truth appears here only as the scores recorded beside the loop's own verdict
(``gt_visibility``: camera -> {"visible_fraction", "false_boundary"}).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from platebench.bench.config import SampleConfig
from platebench.bench.config.sensing import VERIFY_GRID
from platebench.bench.io.records import MergedFigures, Stage3Accuracy, file_form
from platebench.reconstruction.paper.boundary_plane import BoundaryPlane
from platebench.reconstruction.paper.false_boundary import FalseBoundaryTest
from platebench.reconstruction.strategy.detectors import DetectorResult
from platebench.reconstruction.strategy.multiview import OUTLINE_BRIDGE_M, BoundaryVerdict, ViewOutline
from platebench.reconstruction.strategy.planner import MAX_CURE_VIEWS, MAX_VIEWS, PlannedView
from platebench.reconstruction.strategy.poses import Reach, SensorPose

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
VERIFY_ROWS, VERIFY_COLS, VERIFY_SQUARE_PX, VERIFY_WIDTH_PX = 6, 12, 12, 640
# a grid of 6 rows with rows 4 squares apart (``parse_grid``) fits the 768-px projector up to this square size
VERIFY_MAX_SQUARE_PX = 29


def auto_verify_grid(width_px: int) -> str:
    """The verification grid for images ``width_px`` wide: 6x12@12 from 640 px up; on narrower
    images its squares grow as the pixels do (12 x 640 / width, at most ``VERIFY_MAX_SQUARE_PX``), so
    that a square keeps the 7 or so camera pixels it has at 640 x 480 and 0.4 m (at 320 x 240 12-px
    squares are 3-4 camera pixels: the stage-2 pose kept 8 centres of the 72)."""
    sq = min(VERIFY_MAX_SQUARE_PX, max(VERIFY_SQUARE_PX, int(np.ceil(VERIFY_SQUARE_PX * VERIFY_WIDTH_PX / width_px))))
    return f"{VERIFY_ROWS}x{VERIFY_COLS}@{sq}"


def outcome_class(hidden_first: bool, hidden_final: bool, verified: bool, cured_or_raised: bool) -> str:
    """The outcome class of a sensing run (``OUTCOME_TEXT``) from ground truth's "hidden" at the stage-2
    pose and at the end, the loop's verdict, and whether it applied a cure or raised a flag."""
    if hidden_final:
        return "silent" if verified else "honest"
    if hidden_first:
        return "cured" if verified else "unconfirmed"
    return "false_alarm" if cured_or_raised else "clean"


def gt_visibility_dict(vis: dict) -> dict:
    """camera -> ``BoundaryVisibility`` as sensing.json records it (camera -> {"visible_fraction",
    "false_boundary"})."""
    return {c: {"visible_fraction": float(v.visible_fraction), "false_boundary": bool(v.false_boundary)}
            for c, v in vis.items()}


def hidden(gt_visibility: dict) -> bool:
    """Ground truth hides part of the boundary from a camera (fraction below ``HIDDEN_BELOW``)."""
    return min(v["visible_fraction"] for v in gt_visibility.values()) < HIDDEN_BELOW


@dataclass(frozen=True)
class SensingOptions:
    workspace_radius_m: float = 0.15  # stage 1 covers a disc of this radius around the workspace centre
    working_distance_m: float = 0.40  # cameras focused here: stage 2 comes no closer
    # Stage 3 places the projector on its centre line at this distance from the boundary centre;
    # None: at the cameras' distance (a fixed far projector shrinks its squares when cameras move).
    projector_distance_m: float | None = None
    max_cures: int = MAX_CURE_VIEWS  # cure poses at most
    # Measuring poses at most (stage 2, verification, cures); None: derived from ``max_cures`` (stage 2,
    # every verification view and ``max_cures`` cures: ``MAX_VIEWS`` at the default budget).
    max_views: int | None = None
    verification: bool = True  # False: the paper's loop alone (stages 1-3, no verification views)
    # Every later measuring pose also projects the square grid (projector beside the rig,
    # ``active_views.projector_pose``) and measures its centres: the merged reconstruction's points
    # and surface (``active_views``).
    active_views: bool = True
    # The square grid the verification views and cures project ('ROWSxCOLS@SQUARE_PX', "auto":
    # ``auto_verify_grid`` of the image width); None: the sample's own pattern, as stage 3.
    verify_grid: str | None = VERIFY_GRID
    write_stages: bool = True
    reach: Reach = field(default_factory=Reach)
    # For scoring only: cast ground truth's boundary visibility from every pose the loop could reach
    # (its verification views and cure candidates) to say whether a reachable set sees the boundary.
    ground_truth_reach: bool = False
    # A real rig (``cfg.realism`` not ideal): the corner-localisation noise of its calibration views
    # (px; ``bench.run.realism.RealismSetup``); None: measured on renders at the start of the run.
    corner_noise_px: float | None = None

    def __post_init__(self):
        if self.max_views is None:
            object.__setattr__(self, "max_views", MAX_VIEWS - MAX_CURE_VIEWS + int(self.max_cures))


@dataclass(frozen=True)
class StageRecord:
    """Stage 1 or 2: a pose and its passive boundary."""

    stage: int
    pose: SensorPose
    boundary_points: int
    boundary_method: str
    gt_visibility: dict
    boundary_plane: BoundaryPlane | None = None

    def to_dict(self) -> dict:
        d = {"stage": self.stage, "pose": self.pose.to_dict(), "boundary_points": self.boundary_points,
             "boundary_method": self.boundary_method, "gt_visibility": self.gt_visibility}
        if self.boundary_plane is not None:
            d["boundary_plane"] = {"normal": self.boundary_plane.normal.tolist(),
                                   "point_m": self.boundary_plane.point.tolist()}
        return d


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

    def to_dict(self) -> dict:
        return {"stage": 3, "pose": self.pose.to_dict(), "projector_pose": self.projector_pose.to_dict(),
                "false_boundary": None if self.false_boundary is None else self.false_boundary.to_dict(),
                "matched": self.matched, "cut_squares": self.cut, "unmatched": list(self.unmatched),
                "gt_visibility": self.gt_visibility, "error": self.error}


@dataclass(frozen=True)
class ViewRecord:
    """A verification view or a cure: the planned pose and what its passive stereo measured."""

    view: PlannedView
    outline_points: int
    outline_method: str
    gt_visibility: dict
    error: str | None = None
    active: dict | None = None  # ``ActivePoints.to_dict()`` (None: no active pair at this pose)

    def to_dict(self) -> dict:
        return {"stage": "view", **self.view.to_dict(), "outline_points": self.outline_points,
                "outline_method": self.outline_method, "gt_visibility": self.gt_visibility, "error": self.error,
                "active": self.active}


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

    def to_dict(self) -> dict:
        return {"pose": self.pose.to_dict(), "stage_dir": self.stage_dir,
                "false_boundary": None if self.false_boundary is None else self.false_boundary.to_dict(),
                "matched": self.matched, "boundary_verified": self.boundary_verified,
                "verdict": self.verdict_reason, "unverified_parts": list(self.unverified_parts),
                "poses": list(self.poses), "gt_visibility": self.gt_visibility,
                "gt_visibility_first": self.gt_visibility_first,
                "accuracy": None if self.accuracy is None else self.accuracy.to_dict(), "merged": self.merged.to_dict(),
                "outcome": self.outcome, "outcome_text": OUTCOME_TEXT[self.outcome],
                "gt_hidden_first": self.hidden_first, "gt_hidden_final": self.hidden_final,
                "gt_reachable_visibility": self.gt_reachable_visibility, "gt_reachable": self.gt_reachable,
                "gt_verifiable_visibility": self.gt_verifiable_visibility, "gt_verifiable": self.gt_verifiable,
                "gt_unconfirmable_max_mm": None if self.gt_unconfirmable_max_m is None
                else round(self.gt_unconfirmable_max_m * 1e3, 1),
                "front_oriented_frac": None if self.front_oriented is None else round(self.front_oriented, 3)}


@dataclass(frozen=True)
class SensingResult:
    """Everything the loop did, typed; ``to_dict`` is sensing.json."""

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

    def to_dict(self) -> dict:
        return {"config": self.config.to_dict(), "steps": [s.to_dict() for s in self.steps],
                "detectors": {d.name: d.to_dict() for d in self.detectors},
                "verification_views": [v.to_dict() for v in self.verification_views],
                "cures": self.cures, "cure_views": [v.to_dict() for v in self.cure_views],
                "verdict": self.verdict.to_dict(), "notes": list(self.notes),
                "patterns": self.patterns, "final": self.final.to_dict(), "time_s": self.time_s,
                **({} if self.acquisition is None else {"acquisition": file_form(self.acquisition)})}
