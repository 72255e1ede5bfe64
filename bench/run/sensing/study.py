"""The false-boundary study: the sensing loop (``bench.run.sensing``) on a set of plates covering
every deformation family, its outcome classes, and each detector's precision and recall; plus the
geometry-only questions (the smallest hiding bend, the L formula against ground truth).

Ground-truth visibility (``scenes.render.ground_truth``) is the referee throughout: a plate is "hidden"
when the stage-2 pose misses part of its true boundary, "reachable" when the poses the loop could
reach (all its candidates) see all of it. Geometry-only questions need no images: they move the
rig and ask the ground-truth caster. World frame, metres; angles in degrees in tables and flags.
"""
from __future__ import annotations

import csv
import io
import math
import time
import traceback
import zlib
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from platebench.bench.config import SampleConfig
from platebench.bench.config.sensing import DEFAULT_BENDS_DEG, REFERENCE_ASPECT, STUDY_AXES_DEG  # noqa: F401 (re-exported)
from platebench.bench.io.atomic import write_json, write_text
from platebench.bench.io.outputs import output_dir
from platebench.bench.io.records import LFormulaRow, StudyRow, StudyTargets, file_form
from platebench.bench.io.codecs import base as codec_base
from platebench.bench.io.codecs import encode
from platebench.bench.io.sensing_records import OUTCOMES
from platebench.bench.run.journal import StudyJournal, case_key, code_digest
from platebench.bench.run.sensing.loop import run_sensing
from platebench.bench.run.sensing.records import SensingOptions
from platebench.evaluation.detection import detection_score
from platebench.plates import CylindricalBend, PlateSpec, build_plate
from platebench.plates.spec import FAMILIES, Fold, Twist
from platebench.reconstruction.strategy.detectors import DETECTORS
from platebench.reconstruction.strategy.exploring import bending_curve, tangent_intersection_distance
from platebench.scenes.render.ground_truth import GroundTruthCaster
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.scene_spec import scene_for_pose
from platebench.tolerances import tol
from platebench.version import __version__


class VisibilityProbe:
    """Ground-truth boundary visibility for many plates and poses through one renderer."""

    def __init__(self, cfg: SampleConfig):
        self.base = cfg.scene.build()
        self.renderer = None

    def hidden(self, plate, center, target, baseline_dir, require_in_view: bool = True) -> dict:
        scene = scene_for_pose(center, target, baseline_dir, self.base)
        if self.renderer is None:
            self.renderer = PlateRenderer(scene, plate)
        else:
            self.renderer.set_scene(scene)
            self.renderer.set_plate(plate)
        caster = GroundTruthCaster(self.renderer)
        vis = {c: caster.boundary_visibility(c, require_in_view) for c in ("left", "right")}
        return {c: 1.0 - v.visible_fraction for c, v in vis.items()}

    def any_hidden(self, plate, distance_m: float, baseline_dir, require_in_view: bool = True) -> bool:
        h = self.hidden(plate, np.array([0.0, 0.0, distance_m]), np.zeros(3), baseline_dir, require_in_view)
        return max(h.values()) > 0.0


def bent_plate(cfg: SampleConfig, bend_deg: float, direction: str, axis_rad: float = 0.0):
    spec = replace(cfg.plate, deformation=CylindricalBend(math.radians(bend_deg), direction, axis_rad))
    return build_plate(spec)


def smallest_hiding_bend(probe: VisibilityProbe, cfg: SampleConfig, direction: str, distance_m: float,
                         baseline_dir=(0.0, 1.0, 0.0), step_deg: float = 10.0, tol_deg: float = 0.25) -> float | None:
    """Smallest bend (deg) at which a straight-down rig at ``distance_m`` misses part of the true
    boundary: a coarse scan, then bisection. None if no bend up to 350 degrees hides it."""
    prev = 0.0
    for b in np.arange(step_deg, 350.0 + tol.step_count * step_deg, step_deg):
        if probe.any_hidden(bent_plate(cfg, b, direction), distance_m, baseline_dir):
            lo, hi = prev, float(b)
            while hi - lo > tol_deg:
                mid = 0.5 * (lo + hi)
                if probe.any_hidden(bent_plate(cfg, mid, direction), distance_m, baseline_dir):
                    hi = mid
                else:
                    lo = mid
            return hi
        prev = float(b)
    return None


def visibility_distance(probe: VisibilityProbe, plate, baseline_dir, lo: float = 0.06, hi: float = 5.0,
                        tol: float = 1e-3) -> float:
    """Smallest straight-down rig distance (m) at which both cameras see the whole true boundary
    (front-facing and unoccluded; image borders ignored, as in the L formula)."""
    if probe.any_hidden(plate, hi, baseline_dir, False):
        return math.inf
    if not probe.any_hidden(plate, lo, baseline_dir, False):
        return lo
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        if probe.any_hidden(plate, mid, baseline_dir, False):
            lo = mid
        else:
            hi = mid
    return hi


def analytic_L(spec: PlateSpec) -> tuple[float, float]:
    """The paper's L for a cylindrical bend from its exact geometry: (L from AB, AB's height above
    the plate centre), metres. The bending curve is the plate's centre line along its length."""
    d = spec.deformation
    R = spec.length_m / d.angle_rad
    phi = np.linspace(-d.angle_rad / 2, d.angle_rad / 2, 801)
    sign = 1.0 if d.direction == "up" else -1.0
    P = np.column_stack([R * np.sin(phi), np.zeros_like(phi), sign * R * (1 - np.cos(phi))])
    curve = bending_curve(P, np.array([0.0, 0.0, 1.0]))
    return tangent_intersection_distance(curve), float(P[0, 2])


def l_formula_table(cfg: SampleConfig, bends_deg, probe: VisibilityProbe | None = None) -> list[LFormulaRow]:
    """L-formula prediction vs the ground-truth distance of complete visibility (convex bends).

    Predicted rig distance above the plate centre = L + height of AB. Two baselines: across the
    bend's axis (the paper's stage-2 choice: cameras share the cross-section, the formula's case)
    and along the bend (cameras on either side of the centre line need more)."""
    probe = probe or VisibilityProbe(cfg)
    rows = []
    for b in bends_deg:
        plate = bent_plate(cfg, b, "down")
        L, ab_height = analytic_L(plate.spec)
        predicted = L + ab_height
        gt = [visibility_distance(probe, plate, bdir) for bdir in ((0.0, 1.0, 0.0), (1.0, 0.0, 0.0))]
        ratio = [g / predicted if predicted > 0 and math.isfinite(g) else None for g in gt]
        rows.append(LFormulaRow(float(b), L, predicted, gt_distance_baseline_along_axis_m=gt[0],
                                ratio_gt_over_predicted_baseline_along_axis=ratio[0],
                                gt_distance_baseline_along_bend_m=gt[1],
                                ratio_gt_over_predicted_baseline_along_bend=ratio[1]))
    return rows


# ------------------------------------------------------------------------------------------
# The sensing study: the loop on a set of plates of every family.

FAMILY_ORDER = tuple(FAMILIES)  # the families in the order tables show them (plates.spec)
FOLD_BENDS_DEG = (60.0, 120.0, 170.0)
OTHER_ASPECT = 3.0
OTHER_FOLD_DEG = 120.0  # the second aspect ratio's fold (one of FOLD_BENDS_DEG)
OTHER_DISTANCE_M = 0.5


@dataclass(frozen=True)
class StudyCase:
    """One plate of the study: its deformation and where it differs from the reference plate.

    ``bend_deg``: the cylinder's or fold's angle, the twist's angle, or None (dome, dent, flat);
    ``aspect``: length / width at the reference plate's area; ``distance_m``: the working
    distance of stage 2 (``SensingOptions.working_distance_m``)."""

    name: str
    family: str
    deformation: object
    bend_deg: float | None = None
    direction: str | None = None
    axis_deg: float | None = None
    aspect: float = REFERENCE_ASPECT
    distance_m: float = 0.40
    realism_seed: int | None = None  # under a real rig: this plate's draw (``with_realism_seeds``); None: ideal

    def config(self, base: SampleConfig) -> SampleConfig:
        area = base.plate.length_m * base.plate.width_m
        plate = replace(base.plate, length_m=float(np.sqrt(area * self.aspect)),
                        width_m=float(np.sqrt(area / self.aspect)), deformation=self.deformation)
        if self.realism_seed is not None:
            return replace(base, plate=plate, realism=base.realism.with_seed(self.realism_seed))
        return replace(base, plate=plate)

    def params(self) -> dict:
        return {"case": self.name, "family": self.family, "bend_deg": self.bend_deg, "direction": self.direction,
                "axis_deg": self.axis_deg, "aspect": round(self.aspect, 3), "distance_m": self.distance_m}


def with_realism_seeds(cases: list[StudyCase], seed: int) -> list[StudyCase]:
    """Each plate's draw of a real rig: ``seed`` plus the CRC-32 of the plate's name, modulo 2^31, so a
    plate keeps its draw in any set of plates (``sense --realism-seed`` repeats it)."""
    return [replace(c, realism_seed=(int(seed) + zlib.crc32(c.name.encode())) % 2 ** 31) for c in cases]


def _cyl(b: float, d: str, ax: float, **kw) -> StudyCase:
    fam = "flat" if b == 0 else "cylinder"
    name = f"{fam} {b:g} {d} axis {ax:g}" if b else "flat (cylinder 0)"
    extra = "".join(f" {k} {v:g}" for k, v in kw.items())
    return StudyCase(name + extra, fam, CylindricalBend(math.radians(b), d, math.radians(ax)), b, d, ax, **kw)


def _fold(b: float, d: str, **kw) -> StudyCase:
    extra = "".join(f" {k} {v:g}" for k, v in kw.items())
    return StudyCase(f"fold {b:g} {d}{extra}", "fold", Fold(math.radians(b), 0.015, 0.02, d), b, d, 0.0, **kw)


def family_cases(families=None, aspect: float = REFERENCE_ASPECT) -> list[StudyCase]:
    """The named example plates of the families not swept by bend (``DeformationFamily.study_examples``:
    two twists, a dome and a bowl, two dents, ...), each family's under its study label:
    those ``in_default_study`` when ``families`` is None, else those of ``families``; at ``aspect``."""
    out = []
    kw = {} if aspect == REFERENCE_ASPECT else {"aspect": aspect}
    tag = "".join(f" {k} {v:g}" for k, v in kw.items())
    for name, cls in FAMILIES.items():
        if families is None and not cls.in_default_study or families is not None and name not in families:
            continue
        out += [StudyCase(label + tag, d.study_label(), d, d.bend_deg(), **kw) for label, d in cls.study_examples()]
    return out


def study_cases(bends_deg=DEFAULT_BENDS_DEG, families=None, axes_deg=STUDY_AXES_DEG,
                aspect: float = REFERENCE_ASPECT, extra_axes_deg=None) -> list[StudyCase]:
    """The study's plates: cylinders at ``bends_deg`` convex and concave about ``axes_deg`` (default
    0/30/60/90 degrees; bend 0 once: the flat plate), folds of 60/120/170 degrees (those not above
    the largest bend) both ways, the other families' examples (``family_cases``: two twists, a dome
    and a bowl, two dents), all at ``aspect`` (length / width, default the paper's plate's), and a
    second aspect ratio (3:1) and a second working distance (0.5 m) on a few plates: at the largest
    bend up to 180 degrees a convex cylinder about the first of ``axes_deg`` and a concave one about
    the last, at the smallest bend above 180 a convex one about the first, and a fold (aspect) or a
    twist (distance); the fold only where the set's folds reach it. ``extra_axes_deg``: (first, last)
    axes of those cylinders instead of the first and last of ``axes_deg``. Default: 61 plates.
    ``families``: the family keys to keep (None: the default study's); a family outside the default
    study adds its examples. ``bends_deg``, ``axes_deg`` (unless ``extra_axes_deg``) and ``families``
    restrict every plate of the set, the second aspect's and distance's too."""
    bends = sorted({float(b) for b in bends_deg})
    kw = {} if aspect == REFERENCE_ASPECT else {"aspect": float(aspect)}
    cases: list[StudyCase] = []
    if 0.0 in bends:
        cases.append(_cyl(0.0, "down", 0.0, **kw))
    for b in (b for b in bends if b > 0):
        for d in ("down", "up"):
            cases += [_cyl(b, d, float(ax), **kw) for ax in axes_deg]
    top = max(bends) if bends else 0.0
    cases += [_fold(b, d, **kw) for b in FOLD_BENDS_DEG if b <= max(top, FOLD_BENDS_DEG[0]) for d in ("down", "up")]
    cases += family_cases(None, aspect)
    mid = [b for b in bends if 0 < b <= 180]
    far = [b for b in bends if b > 180]
    axes = sorted({float(a) for a in axes_deg}) if extra_axes_deg is None else [float(a) for a in extra_axes_deg]
    for kw in ({"aspect": OTHER_ASPECT}, {"distance_m": OTHER_DISTANCE_M}):
        if mid and axes:
            cases += [_cyl(mid[-1], "down", axes[0], **kw), _cyl(mid[-1], "up", axes[-1], **kw)]
        if far and axes:
            cases.append(_cyl(far[0], "down", axes[0], **kw))
        if "distance_m" in kw:
            cases.append(StudyCase("twist 45 distance_m 0.5", "twist", Twist(math.radians(45.0)), 45.0, **kw))
        elif OTHER_FOLD_DEG <= max(top, FOLD_BENDS_DEG[0]):  # the folds of the set above, as there
            cases.append(_fold(OTHER_FOLD_DEG, "up", **kw))
    if families is None:
        return cases
    unknown = [f for f in families if f not in FAMILIES]
    if unknown:
        raise ValueError(f"family {unknown[0]!r} is unknown: allowed " + ", ".join(FAMILIES))
    added = [f for f in families if not FAMILIES[f].in_default_study]
    return [c for c in cases if c.family in families] + family_cases(added, aspect)


def split_by_bend(row: StudyRow) -> bool:
    """A study row whose family the tables split by bend angle (``DeformationFamily.by_bend``)."""
    return FAMILIES[row.family].by_bend and row.bend_deg is not None


# Deformations whose plate is the same with the bending coordinate reversed (e -> -e): a bend centred
# on the plate. Only these may have their axis wrapped past 0 or 180 degrees (a fold, anchored on one
# side of an off-centre band, wrapped is another plate; docs/findings/design-record.md).
AXIS_WRAP_SAFE = (CylindricalBend,)


def perturbed_cases(cases: list[StudyCase], axis_deg: float = 0.0, distance_mm: float = 0.0) -> list[StudyCase]:
    """The same plates shifted a little, to check that the study's rates are not knife-edge results:
    every bend axis (cylinders, folds) turned by ``axis_deg`` and every working distance changed by
    ``distance_mm``. An axis that would leave [0, 180) degrees is wrapped (the axis is a line) where
    that gives the same plate (``AXIS_WRAP_SAFE``); elsewhere it is kept, and the name says so. Each
    name says what was shifted; unchanged when both are 0. ValueError when a distance would not stay
    positive."""
    if axis_deg == 0.0 and distance_mm == 0.0:
        return list(cases)
    dist_tag = f" distance {distance_mm:+g} mm" if distance_mm else ""
    out = []
    for c in cases:
        d, axis_tag = c.deformation, ""
        if axis_deg and hasattr(d, "axis_rad"):
            turned = d.axis_rad + math.radians(axis_deg)
            if 0.0 <= turned < math.pi or isinstance(d, AXIS_WRAP_SAFE):
                d = replace(d, axis_rad=float(turned % math.pi))
                axis_tag = f" axis {axis_deg:+g}"
            else:
                axis_tag = f" axis kept ({axis_deg:+g} would mirror this {c.family})"
        if not (axis_tag or dist_tag):
            out.append(c)
            continue
        dist = c.distance_m + distance_mm * 1e-3
        if dist <= 0:
            raise ValueError(f"{c.name}: distance {c.distance_m:g} m + {distance_mm:g} mm is not positive")
        axis = math.degrees(d.axis_rad) if d is not c.deformation and c.axis_deg is not None else c.axis_deg
        out.append(replace(c, name=c.name + " perturbed" + axis_tag + dist_tag, deformation=d, axis_deg=axis,
                           distance_m=dist))
    return out


def _min_visible(gv: dict) -> float:
    return float(min(v["visible_fraction"] for v in gv.values()))


def study_row(case: StudyCase, base: SampleConfig, options: SensingOptions = SensingOptions()) -> StudyRow:
    """Run the sensing loop on one plate and flatten what the study needs into a row (``StudyRow``;
    see ``StudyResult``). An exception becomes outcome "error" with its message (never dropped)."""
    params = case.params()
    cfg = case.config(base)
    if not cfg.realism.is_ideal:  # the error model and this plate's draw of it
        params.update(realism=cfg.realism.name, realism_seed=cfg.realism.seed)
    t0 = time.perf_counter()
    try:
        r = run_sensing(cfg, None, replace(options, working_distance_m=case.distance_m,
                                           write_stages=False, ground_truth_reach=True))
    except Exception as e:  # noqa: BLE001 (a study records every failure and goes on)
        return StudyRow(**params, outcome="error", error=f"{type(e).__name__}: {e}".splitlines()[0],
                        traceback=traceback.format_exc(limit=3), time_s=time.perf_counter() - t0)
    f, m = r.final, r.final.merged
    return StudyRow(
        **params, outcome=f.outcome, boundary_verified=f.boundary_verified, cures=r.cures,
        verification_views=len(r.verification_views), views=len(f.poses),
        gt_visible_first_frac=_min_visible(f.gt_visibility_first), gt_visible_final_frac=_min_visible(f.gt_visibility),
        gt_hidden_first=f.hidden_first, gt_hidden_final=f.hidden_final,
        gt_reachable=f.gt_reachable, gt_verifiable=f.gt_verifiable,
        gt_verifiable_frac=_min_visible(f.gt_verifiable_visibility) if f.gt_verifiable_visibility else None,
        gt_unconfirmable_max_mm=None if f.gt_unconfirmable_max_m is None else f.gt_unconfirmable_max_m * 1e3,
        false_boundary_gt=f.hidden_first, front_oriented_frac=f.front_oriented,
        detectors={d.name: d.fired for d in r.detectors},
        merged_boundary_mean_mm=m.boundary_mean_mm, merged_boundary_covered_frac=m.boundary_covered_frac,
        merged_surface_rms_mm=m.surface_rms_mm, merged_surface_coverage_frac=m.surface_coverage_frac, merged_points=m.points,
        merged_points_rms_mm=m.points_rms_mm, merged_points_max_mm=m.points_max_mm,
        centres_depth_rms_mm=None if f.accuracy is None else f.accuracy.centres_depth_rms_mm,
        unverified_parts=len(f.unverified_parts), verdict=f.verdict_reason, time_s=time.perf_counter() - t0)


def _groups(rows: list[StudyRow], key) -> dict:
    out: dict = {}
    for r in rows:
        out.setdefault(key(r), []).append(r)
    return out


def detector_scores(rows: list[StudyRow]) -> dict:
    """Each detector's precision and recall against ground truth's "hidden at the stage-2 pose":
    over all plates, per family and per bend (cylinders and folds): {"all": detector ->
    ``DetectionScore``, "by_family": family -> detector -> ``DetectionScore``, "by_bend": bend -> ...}
    (``detector_scores_dict``: study.json's form)."""
    ok = [r for r in rows if r.outcome != "error"]

    def score(rs):
        return {d: detection_score([r.gt_hidden_first for r in rs], [r.fired(d) for r in rs]) for d in DETECTORS}
    by_family = _groups(ok, lambda r: r.family)
    bent = [r for r in ok if split_by_bend(r)]
    by_bend = _groups(bent, lambda r: float(r.bend_deg))
    return {"all": score(ok), "by_family": {k: score(v) for k, v in sorted(by_family.items(),
                                                                          key=lambda kv: FAMILY_ORDER.index(kv[0]))},
            "by_bend": {f"{k:g}": score(v) for k, v in sorted(by_bend.items())}}


def detector_scores_dict(scores: dict) -> dict:
    """``detector_scores`` as study.json holds it (each score's ``encode``)."""
    return {"all": {d: encode(s) for d, s in scores["all"].items()},
            **{part: {k: {d: encode(s) for d, s in v.items()} for k, v in scores[part].items()}
               for part in ("by_family", "by_bend")}}


def outcome_counts(rows: list[StudyRow], key=None) -> dict:
    """Outcome class counts (``OUTCOMES`` and "error"), overall or per ``key(row)``."""
    classes = (*OUTCOMES, "error")
    if key is None:
        return {c: sum(r.outcome == c for r in rows) for c in classes}
    return {str(k): outcome_counts(v) for k, v in _groups(rows, key).items()}


def targets(rows: list[StudyRow]) -> StudyTargets:
    """The study's targets: silent = 0, errors = 0, cured >= 90 % of the plates whose stage-2 pose
    hides part of the boundary and whose reachable poses see all of it ("curable"), false alarms
    <= 2 % of the plates where nothing is hidden.

    "Cured" in the first target means: the final poses see the whole boundary (outcome "cured" or
    "unconfirmed", ``seen_all_of_curable``). The loop's own verdict is stricter, and is scored
    beside it: the outcome "cured" asks that the loop also *verified* the boundary
    (``cured_of_curable``, ``cured_frac``). A verification needs a pair of poses turned about
    each stretch of the boundary (``multiview.confirm``), which no reachable pair offers along the
    tips of a 300-degree curl (ground truth: ``gt_verifiable``, ``scoring.verifiable_visibility``);
    so the second target asks for verified cures on >= 90 % of the curable plates that pairs of
    reachable poses could verify (``cured_of_verifiable``)."""
    c = outcome_counts(rows)
    curable = [r for r in rows if r.gt_hidden_first and r.gt_reachable]
    verifiable = [r for r in curable if r.gt_verifiable]
    clean = [r for r in rows if r.outcome != "error" and not r.gt_hidden_first]
    cured = sum(r.outcome == "cured" for r in curable)
    seen_all = sum(r.outcome in ("cured", "unconfirmed") for r in curable)
    cured_v = sum(r.outcome == "cured" for r in verifiable)
    fa = sum(r.outcome == "false_alarm" for r in clean)

    def frac(a, b):
        return a / len(b) if b else None

    def at_least(f, bound):
        return None if f is None else f >= bound
    cured_frac, seen_frac, fa_frac = frac(cured, curable), frac(seen_all, curable), frac(fa, clean)
    cured_v_frac = frac(cured_v, verifiable)
    return StudyTargets(silent=c["silent"], errors=c["error"], curable=len(curable), cured_of_curable=cured,
                        cured_frac=cured_frac, seen_all_of_curable=seen_all, seen_all_frac=seen_frac,
                        verifiable=len(verifiable), cured_of_verifiable=cured_v, cured_of_verifiable_frac=cured_v_frac,
                        nothing_hidden=len(clean), false_alarms=fa, false_alarm_frac=fa_frac,
                        met={"silent = 0": c["silent"] == 0, "errors = 0": c["error"] == 0,
                             "cured >= 90 %": at_least(seen_frac, 0.9),
                             "verified >= 90 % of the verifiable": at_least(cured_v_frac, 0.9),
                             "false alarms <= 2 %": None if fa_frac is None else fa_frac <= 0.02})


@dataclass(frozen=True)
class StudyResult:
    """Per-plate rows (``StudyRow``), the outcome counts, the detectors' scores and the targets;
    its form (``encode``) is study.json."""

    rows: tuple[StudyRow, ...]
    settings: dict
    time_s: float
    extra: dict = field(default_factory=dict)  # smallest hiding bend, L formula (when computed)

    @property
    def plates_run(self) -> int:
        """The plates this run measured (the others came from an interrupted run's journal)."""
        return self.extra.get("plates_run", len(self.rows))

    @property
    def resumed_plates(self) -> int:
        return self.extra.get("resumed_plates", 0)

    @property
    def targets(self) -> StudyTargets:
        return targets(list(self.rows))

    def outcomes(self, key=None) -> dict:
        """Outcome counts (``outcome_counts``): overall, or per ``key`` "family" or "bend" (the
        families split by bend, ``split_by_bend``; bends in increasing order)."""
        rows = list(self.rows)
        if key is None:
            return outcome_counts(rows)
        if key == "family":
            return outcome_counts(rows, lambda r: r.family)
        return dict(sorted(outcome_counts([r for r in rows if split_by_bend(r)], lambda r: f"{r.bend_deg:g}").items(),
                           key=lambda kv: float(kv[0])))


@codec_base.encode.register(StudyResult)
def _(x: StudyResult) -> dict:
    """study.json; registered beside the type, as ``bench.io`` does not import ``bench.run`` (its
    outcome counts, detector scores and targets are computed here)."""
    return {"kind": "false-boundary sensing study", "rows": [r.to_dict() for r in x.rows],
            "outcomes": x.outcomes(), "outcomes_by_family": x.outcomes("family"),
            "outcomes_by_bend": x.outcomes("bend"),
            "detectors": detector_scores_dict(detector_scores(list(x.rows))),
            "targets": x.targets.to_dict(), "settings": x.settings, "time_s": x.time_s,
            **file_form(x.extra)}


def run_study(cases: list[StudyCase], base: SampleConfig, options: SensingOptions = SensingOptions(),
              progress=None, settings: dict | None = None, l_bends_deg=(), workers: int = 1,
              done: dict[int, StudyRow] | None = None, record=None) -> StudyResult:
    """The sensing loop on every case (``study_row``); ``progress(row)`` after each, in the order
    they finish. With ``l_bends_deg``: also the smallest hiding bend and the L formula at those
    convex bends. ``workers`` > 1: the plates run in that many spawned processes, the CPU cores
    shared between their renderers (``_study_rows``); rows come back in case order either way, and
    each row's figures are the same (every plate is its own deterministic run). ``done``: case
    index -> a row already run (an interrupted study's journal, ``bench.run.journal``), not run
    again; ``record(index, row)``: told of each row as it finishes."""
    t0 = time.perf_counter()
    if workers < 1:
        raise ValueError(f"workers = {workers} is out of range: allowed >= 1")
    done = dict(done or {})
    todo = [i for i in range(len(cases)) if i not in done]
    if progress is not None:
        for i in sorted(done):
            progress(done[i])

    def finished(k, row):
        if record is not None:
            record(todo[k], row)
        if progress is not None:
            progress(row)
    ran = list(_study_rows([cases[i] for i in todo], base, options, finished, workers))
    rows = [done[i] if i in done else None for i in range(len(cases))]
    for i, row in zip(todo, ran):
        rows[i] = row
    extra = {"plates_run": len(todo), **({"resumed_plates": len(done)} if done else {})}  # time_s covers plates_run
    if len(l_bends_deg):
        probe = VisibilityProbe(base)
        extra["smallest_hiding_bend_deg"] = {d: smallest_hiding_bend(probe, base, d, base.scene.distance_m)
                                             for d in ("down", "up")}
        extra["l_formula"] = l_formula_table(base, l_bends_deg, probe)
    return StudyResult(tuple(rows), dict(settings or {}), time.perf_counter() - t0, extra)


def _study_rows(cases: list[StudyCase], base: SampleConfig, options: SensingOptions, progress, workers: int):
    """``study_row`` of every case, in case order; ``progress(k, row)`` as case ``k`` finishes. One
    worker: in this process. More: a spawned
    process pool (each worker dies with this process, ``workers.pool_worker_init``; the renderer's threads are
    the cores divided among them). Rendering uses every core it is given, but the loop's decisions
    (confirmation, planning, ray casts against the measured surface) run on one, so two plates at a
    time keep both cores of a 2-core machine busy (docs/findings/throughput.md gives the times)."""
    if workers == 1 or len(cases) <= 1:
        for k, case in enumerate(cases):
            row = study_row(case, base, options)
            if progress is not None:
                progress(k, row)
            yield row
        return
    import multiprocessing  # noqa: PLC0415
    import os  # noqa: PLC0415
    from concurrent.futures import ProcessPoolExecutor, as_completed  # noqa: PLC0415

    from platebench.bench.run.workers import pool_worker_init, stop_pool  # noqa: PLC0415

    threads = max(1, (os.cpu_count() or 1) // workers)
    rows: list[StudyRow | None] = [None] * len(cases)
    pool = ProcessPoolExecutor(max_workers=min(workers, len(cases)), mp_context=multiprocessing.get_context("spawn"),
                               initializer=pool_worker_init, initargs=(os.getpid(), threads))
    try:
        futures = {pool.submit(study_row, case, base, options): i for i, case in enumerate(cases)}
        for fut in as_completed(futures):
            row = fut.result()  # study_row records a plate's own failure; a dead worker stops the study
            rows[futures[fut]] = row
            if progress is not None:
                progress(futures[fut], row)
    except BaseException:  # interrupted: stop the plates running, never wait for them to finish
        stop_pool(pool)
        raise
    pool.shutdown()
    yield from rows


def study_csv(rows: list[StudyRow]) -> str:
    """The study's rows as CSV text (every column of any row, ``StudyRow.to_dict``)."""
    dicts = [r.to_dict() for r in rows]
    keys = list(dict.fromkeys(k for r in dicts for k in r))
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=keys, extrasaction="ignore")
    w.writeheader()
    w.writerows(dicts)
    return buf.getvalue()


def write_study(out: Path, cases: list[StudyCase], base: SampleConfig, overwrite: bool = False, progress=None,
                settings: dict | None = None, l_bends_deg=(), workers: int = 1, resume: bool = False,
                options: SensingOptions = SensingOptions()) -> StudyResult:
    """Run the study (``run_study``) and write ``out/study.json`` and ``out/study.csv``; the folder
    appears complete or not at all (``bench.io.outputs.output_dir``: checked and locked before the first plate).
    Each finished plate's row goes to the journal beside it (``bench.run.journal``) at once, so an
    interrupted study keeps them; ``resume``: reuse the journal's rows of plates still to run.
    ``options``: the sensing loop's (each plate's working distance set from its case).
    Returns the study (``StudyResult``; study.json is its form, ``encode``)."""
    settings = dict(settings or {})
    header = {"version": __version__, "code": code_digest(), "l_bends_deg": list(l_bends_deg),
              **{k: v for k, v in settings.items() if k != "workers"}}
    keys = [case_key(c, c.config(base), options) for c in cases]
    journal = StudyJournal(out, header)
    with output_dir(out, "study", overwrite=overwrite) as stage:
        kept = journal.start(resume, overwrite)
        try:
            done = {i: StudyRow.from_dict(kept[k]) for i, k in enumerate(keys) if k in kept}
            result = run_study(cases, base, options, progress=progress, settings=settings, l_bends_deg=l_bends_deg,
                               workers=workers, done=done,
                               record=lambda i, row: journal.record(keys[i], row.to_dict()))
            write_json(stage / "study.json", encode(result))
            write_text(stage / "study.csv", study_csv(list(result.rows)))
        finally:
            journal.close(remove=False)
    journal.close(remove=True)  # the study is in place
    return result
