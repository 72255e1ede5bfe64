"""The typed records that carry figures from the sensing loop, the study and ``compare`` to the
command line and the report, and their file form.

Each record is a frozen dataclass whose field names are its JSON keys and CSV columns, units in
the names (``_mm`` millimetres, ``_frac`` a fraction 0..1, ``_pct`` percent, ``_s`` seconds,
``_m`` metres, ``_deg`` degrees; counts bare). ``to_dict`` writes a record, ``from_dict`` reads
one back; both are called only where a file is written or read. Inside the package the figures
travel as these records and are read as attributes: a misspelt attribute is an error, where a
misspelt key of a dict is a silent None.

Figures the run did not produce are None (never NaN in a file).
"""
from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field, fields
from typing import Any, Mapping

__all__ = ["Record", "file_form", "records_from", "Stage3Accuracy", "MergedFigures", "StudyRow", "StudyTargets", "loop_verdict_text", "record_from_dict", "final_figures",
           "study_rows", "LFormulaRow", "study_extras", "MethodFigures", "compare_methods", "score_record"]


def _value(v):
    """None for a missing, NaN or infinite number; else the value."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def file_form(v):
    """``v`` as a file holds it: a record (anything with ``to_dict``, or a type with a codec in
    ``bench.io.codecs``) as its dict, a mapping as a dict and a tuple or list as a list of their items'
    file forms, a NaN or infinite number as None."""
    from platebench.bench.io.codecs import encode, has_codec  # noqa: PLC0415  (the codecs import the records)

    if has_codec(type(v)):
        return encode(v)
    if hasattr(v, "to_dict"):
        return v.to_dict()
    if isinstance(v, Mapping):
        return {k: file_form(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [file_form(x) for x in v]
    return _value(v)


def records_from(cls, d: Mapping[str, Any] | None) -> dict:
    """A mapping of ``cls`` records (name -> ``cls.from_dict``) from its dict form."""
    return {str(k): cls.from_dict(v) for k, v in (d or {}).items()}


def record_from_dict(cls, d: Mapping[str, Any] | None, renamed: Mapping[str, str] | None = None):
    """A ``cls`` record from its dict form: every field from the key of its name (missing keys: the
    field's default; ValueError for a field without one; a list as a tuple); ``renamed``: old key ->
    field name, for files written before a figure was renamed. Unknown keys are ignored (a newer
    writer's figures)."""
    d = dict(d or {})
    for old, new in (renamed or {}).items():
        if old in d and new not in d:
            d[new] = d.pop(old)
    names = {f.name for f in fields(cls) if f.init}
    missing = [f.name for f in fields(cls) if f.init and f.default is MISSING and f.default_factory is MISSING
               and f.name not in d]
    if missing:
        raise ValueError(f"a {cls.__name__} record without {missing[0]!r}")
    return cls(**{k: tuple(v) if isinstance(v, list) else _value(v) for k, v in d.items() if k in names})


class Record:
    """``to_dict`` (field name -> the value's ``file_form``) and ``from_dict`` (``record_from_dict``,
    with the class's ``RENAMED``: old key -> field name) for a frozen dataclass of figures. A record
    with records among its fields reads them back in its own ``from_dict``."""

    RENAMED: Mapping[str, str] = {}

    def to_dict(self) -> dict:
        return {f.name: file_form(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None):
        return record_from_dict(cls, d, cls.RENAMED)


@dataclass(frozen=True)
class Stage3Accuracy(Record):
    """The stage-3 reconstruction (the paper's method) scored against ground truth: depth RMS at its
    square centres, the centres scored, boundary mean distance, surface RMS and coverage, the
    paper's bound and the bench's goals (``evaluation.score``)."""

    centres_depth_rms_mm: float | None = None
    points_scored: int = 0
    boundary_mean_mm: float | None = None
    surface_rms_mm: float | None = None
    coverage_frac: float | None = None  # share of the left view's plate pixels its surface covers
    paper_bound_met: bool | None = None
    goals_met: bool | None = None


@dataclass(frozen=True)
class MergedFigures(Record):
    """The merged multi-view reconstruction (``active_views.MergedReconstruction``) scored against
    ground truth (``bench.run.sensing.scoring.merged_accuracy``): its boundary (points, mean
    symmetric and one-way distance to the true boundary, the share of the true boundary's length
    within 2 mm), its square centres (count, RMS and maximum distance to the true surface) and its
    surface (samples, RMS distance to the true surface, ``surface_coverage_frac``: the share of the true
    surface's area within 2 mm of it: the merged surface has no single left view, so no
    ``coverage_frac``). None where the merged result has no such part."""

    poses: int = 0
    boundary_points: int = 0
    points: int = 0
    boundary_mean_mm: float | None = None
    boundary_est_to_gt_mean_mm: float | None = None
    boundary_covered_frac: float | None = None
    points_rms_mm: float | None = None
    points_max_mm: float | None = None
    surface_rms_mm: float | None = None
    surface_coverage_frac: float | None = None
    surface_points: int = 0

    # sensing.json files of older spellings: both keys held the surface-area coverage
    RENAMED = {"surface_coverage": "surface_coverage_frac", "coverage_frac": "surface_coverage_frac"}


def final_figures(final: Mapping[str, Any]) -> tuple[Stage3Accuracy | None, MergedFigures]:
    """The figures of sensing.json's ``final`` section: (stage 3's accuracy, None when stage 3
    reconstructed nothing; the merged reconstruction's figures)."""
    acc = final.get("accuracy")
    return (Stage3Accuracy.from_dict(acc) if isinstance(acc, Mapping) else None,
            MergedFigures.from_dict(final.get("merged") if isinstance(final.get("merged"), Mapping) else {}))


def loop_verdict_text(outcome: str | None, verified: bool | None, cures: int | None = None,
                      reason: str | None = None) -> str:
    """The sensing loop's own verdict as one line that cannot read as a contradiction of its outcome
    class. The verdict (``boundary_verified``) is the loop's claim, made without ground truth, that
    its poses confirmed the whole boundary; the outcome class (``bench.run.sensing.OUTCOMES``) holds
    the loop's cures and claim against ground truth. A "false_alarm" whose boundary the poses
    confirmed is a plate where nothing was hidden and the loop applied cures before confirming it;
    the line says so. ``reason``: the verdict's reason, appended."""
    n = cures or 0
    if verified is None:
        text = "loop's verdict: none (the run gave no verdict)"
    elif verified:
        text = "loop's verdict (no ground truth): its poses confirmed the whole boundary"
        if outcome == "false_alarm":
            text += (f", after {n} cure{'s' if n != 1 else ''} that nothing hidden called for (the false alarm: "
                     "ground truth hid nothing at the stage-2 pose)")
        elif outcome == "silent":
            text += " (ground truth: part of it is still hidden: the silent defect)"
    else:
        text = "loop's verdict (no ground truth): its poses did not confirm the whole boundary"
        if outcome == "false_alarm":
            text += " (the false alarm: ground truth hid nothing)"
    return f"{text}: {reason}" if reason else text


@dataclass(frozen=True)
class StudyRow(Record):
    """One plate of the false-boundary study (``bench.run.sensing.study.study_row``): the plate (its case's
    parameters), the loop's outcome and verdict, ground truth's visibility (``gt_*``, for scoring
    only), each detector's verdict at the stage-2 pose (``detectors``: name -> fired, None where it
    could not be evaluated; ``det_<name>`` columns in the files), the merged reconstruction's
    figures (``merged_*``) and stage 3's depth RMS at the square centres. A plate whose run raised
    has outcome "error", its one-line ``error`` and its ``traceback`` (not written to the files)."""

    case: str
    family: str
    bend_deg: float | None = None
    direction: str | None = None
    axis_deg: float | None = None
    aspect: float | None = None
    distance_m: float | None = None
    realism: str | None = None  # the error model (bench.config.realism) when not ideal, and this plate's draw
    realism_seed: int | None = None
    outcome: str = "error"
    error: str | None = None
    boundary_verified: bool | None = None
    cures: int | None = None
    verification_views: int | None = None
    views: int | None = None
    gt_visible_first_frac: float | None = None  # the least share of the true boundary a camera sees at stage 2
    gt_visible_final_frac: float | None = None  # ... from the final poses together
    gt_hidden_first: bool | None = None
    gt_hidden_final: bool | None = None
    gt_reachable: bool | None = None
    gt_verifiable: bool | None = None
    gt_verifiable_frac: float | None = None
    gt_unconfirmable_max_mm: float | None = None
    false_boundary_gt: bool | None = None
    front_oriented_frac: float | None = None
    detectors: Mapping[str, bool | None] = field(default_factory=dict)
    merged_boundary_mean_mm: float | None = None
    merged_boundary_covered_frac: float | None = None
    merged_surface_rms_mm: float | None = None
    merged_surface_coverage_frac: float | None = None
    merged_points: int | None = None
    merged_points_rms_mm: float | None = None
    merged_points_max_mm: float | None = None
    centres_depth_rms_mm: float | None = None
    unverified_parts: int | None = None
    verdict: str | None = None
    time_s: float | None = None
    traceback: str | None = field(default=None, compare=False)

    # study.json and the journal before one spelling per figure
    RENAMED = {"gt_visible_first": "gt_visible_first_frac", "gt_visible_final": "gt_visible_final_frac",
               "gt_verifiable_fraction": "gt_verifiable_frac", "front_oriented": "front_oriented_frac",
               "merged_boundary_covered": "merged_boundary_covered_frac",
               "merged_surface_coverage": "merged_surface_coverage_frac",
               "merged_coverage_frac": "merged_surface_coverage_frac"}

    def fired(self, detector: str) -> bool | None:
        """Whether ``detector`` fired at the stage-2 pose (None: not evaluated, or no run)."""
        return self.detectors.get(detector)

    def verdict_text(self, with_reason: bool = False) -> str:
        """The loop's verdict on this plate in words consistent with its outcome (``loop_verdict_text``);
        ``with_reason``: the verdict's reason appended."""
        verified = None if self.outcome == "error" else self.boundary_verified
        return loop_verdict_text(self.outcome, verified, self.cures, self.verdict if with_reason else None)

    def to_dict(self) -> dict:
        """The row's columns: the fields (detectors as ``det_<name>``; the traceback left out)."""
        out = {}
        for f in fields(self):
            if f.name == "detectors":
                out.update({f"det_{k}": v for k, v in self.detectors.items()})
            elif f.name != "traceback":
                out[f.name] = _value(getattr(self, f.name))
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "StudyRow":
        dets = {k[len("det_"):]: v for k, v in d.items() if k.startswith("det_")}
        return record_from_dict(cls, {**{k: v for k, v in d.items() if not k.startswith("det_")},
                                      "detectors": dets}, cls.RENAMED)


@dataclass(frozen=True)
class StudyTargets(Record):
    """The study's targets (``bench.run.sensing.study.targets``): silent = 0, errors = 0, the final poses
    see the whole boundary on >= 90 % of the curable plates, verified >= 90 % of the verifiable
    ones, false alarms <= 2 % of the plates with nothing hidden; the counts they are computed from,
    and ``met``: target -> met (None where no plate is of its kind)."""

    silent: int = 0
    errors: int = 0
    curable: int = 0
    cured_of_curable: int = 0
    cured_frac: float | None = None
    seen_all_of_curable: int = 0
    seen_all_frac: float | None = None
    verifiable: int = 0
    cured_of_verifiable: int = 0
    cured_of_verifiable_frac: float | None = None
    nothing_hidden: int = 0
    false_alarms: int = 0
    false_alarm_frac: float | None = None
    met: Mapping[str, bool | None] = field(default_factory=dict)


def study_rows(doc: Mapping[str, Any]) -> list[StudyRow]:
    """study.json's rows as ``StudyRow``s."""
    return [StudyRow.from_dict(r) for r in doc.get("rows") or [] if isinstance(r, Mapping)]


@dataclass(frozen=True)
class LFormulaRow(Record):
    """The paper's L formula at one convex cylindrical bend (``bench.run.sensing.study.l_formula_table``):
    the bend (deg), the sensing distance L (m) and the rig distance it predicts (L plus the height
    of AB, m), and for a baseline along the bend's axis and along the bend the ground-truth smallest
    rig distance at which both cameras see the whole true boundary (m; infinite: never) and its
    ratio to the prediction (None where undefined). None: not computed."""

    bend_deg: float
    L_m: float | None = None
    predicted_distance_m: float | None = None
    gt_distance_baseline_along_axis_m: float | None = None
    ratio_gt_over_predicted_baseline_along_axis: float | None = None
    gt_distance_baseline_along_bend_m: float | None = None
    ratio_gt_over_predicted_baseline_along_bend: float | None = None

    def to_dict(self) -> dict:
        """The row's keys; an infinite ground-truth distance stays infinite (never fully visible)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "LFormulaRow":
        def number(v):
            return None if v is None or isinstance(v, bool) or not isinstance(v, (int, float)) else float(v)
        if number(d.get("bend_deg")) is None:
            raise ValueError("an LFormulaRow record without 'bend_deg'")
        return cls(**{f.name: number(d.get(f.name)) for f in fields(cls)})


def study_extras(doc: Mapping[str, Any]) -> tuple[dict[str, float | None], list[LFormulaRow]]:
    """study.json's (or an older study's) L-formula part: the smallest bend (deg) that hides part
    of the boundary from the straight-down rig, per bend direction (None: none up to 350 deg), and
    the L-formula rows; both empty where the study did not compute them."""
    sh = doc.get("smallest_hiding_bend_deg")
    lf = []
    for r in doc.get("l_formula") or []:
        try:
            lf.append(LFormulaRow.from_dict(r))
        except (ValueError, TypeError, AttributeError):  # not a row of a bend: nothing to show
            continue
    return (dict(sh) if isinstance(sh, Mapping) else {}), lf


@dataclass(frozen=True)
class MethodFigures(Record):
    """One method's key figures in ``compare`` (its table, compare.json, the report's comparison):
    how it is measured (``measure``: "centres" for the paper's sparse square centres, "disparity"
    or "depth" for a map over the plate's pixels, "cloud", "mesh"), its images per camera and times,
    and the figures of its kind (None where they do not apply): |depth error| at the square centres
    (sparse) or over the plate's pixels with an estimate (dense: never compared with the sparse
    ones), distance of a cloud to the true surface, accuracy of a mesh, coverage of the plate
    (``coverage_frac``: the share of the left view's plate pixels with an estimate, for every kind:
    ``evaluation.pixel_coverage``),
    Middlebury's bad 1.0 px on all pixels (disparities) and the centres on the plate (paper)."""

    measure: str | None = None
    n_images: int | None = None
    time_s: float | None = None
    render_s: float | None = None
    centres_depth_median_mm: float | None = None
    centres_depth_rms_mm: float | None = None
    centres_depth_max_mm: float | None = None
    points_on_plate: int | None = None
    depth_median_mm: float | None = None
    depth_rms_mm: float | None = None
    depth_max_mm: float | None = None
    dist_median_mm: float | None = None
    dist_rms_mm: float | None = None
    accuracy_median_mm: float | None = None
    accuracy_rms_mm: float | None = None
    surface_rms_mm: float | None = None
    coverage_frac: float | None = None
    mb_all_bad_1_0_pct: float | None = None

    @property
    def error_median_mm(self) -> float | None:
        """The median error of the method's measure (centres, map, cloud or mesh)."""
        return {"centres": self.centres_depth_median_mm, "cloud": self.dist_median_mm,
                "mesh": self.accuracy_median_mm}.get(self.measure, self.depth_median_mm)

    @property
    def error_rms_mm(self) -> float | None:
        """The RMS error of the method's measure (centres, map, cloud or mesh)."""
        return {"centres": self.centres_depth_rms_mm, "cloud": self.dist_rms_mm,
                "mesh": self.accuracy_rms_mm}.get(self.measure, self.depth_rms_mm)


def score_record(d: Mapping[str, Any]):
    """The paper pipeline's score.json as an ``evaluation.score.Score`` (``decode(Score, d)``);
    ValueError naming what is missing or malformed."""
    from platebench.bench.io.codecs import decode  # noqa: PLC0415  (its geometry imports only for a score)
    from platebench.evaluation.score import Score  # noqa: PLC0415

    try:
        return decode(Score, dict(d))
    except (KeyError, TypeError, ValueError) as e:
        raise ValueError(f"not a score record: {type(e).__name__} {e}") from None


def compare_methods(doc: Mapping[str, Any]) -> dict[str, MethodFigures]:
    """compare.json's methods (name -> ``MethodFigures``); a method's figures sit in its own
    section (``figures``); a file written before that section had them at the top (and coverage
    in percent, ``coverage_pct``)."""
    out = {}
    for name, m in (doc.get("methods") or {}).items():
        if not isinstance(m, Mapping):
            continue
        fig = m.get("figures")
        if not isinstance(fig, Mapping):  # compare.json before its figures section: the figures at the top
            fig = {k: v for part in [m, *(v for v in m.values() if isinstance(v, Mapping))] for k, v in part.items()
                   if not isinstance(v, Mapping)}
            pct = fig.pop("coverage_pct", None)
            if isinstance(pct, (int, float)) and "coverage_frac" not in fig:
                fig["coverage_frac"] = pct / 100.0
            fig.setdefault("measure", m.get("kind"))
        out[str(name)] = MethodFigures.from_dict(fig)
    return out
