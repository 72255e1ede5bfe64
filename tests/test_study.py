"""The false-boundary study: its plate set, its scores (pure), and one small run through the CLI
and the report."""
from __future__ import annotations

import json

import pytest

from platebench.bench.run.study import (
    OTHER_ASPECT,
    OTHER_DISTANCE_M,
    detector_scores,
    outcome_counts,
    study_cases,
    targets,
)
from platebench.evaluation.detection import detection_score
from platebench.plates import build_plate
from platebench.plates.spec import FAMILIES
from tests.conftest import run_cli


def test_the_default_plate_set_covers_every_family_axis_direction_aspect_and_distance():
    cases = study_cases()
    assert len(cases) >= 60 and len({c.name for c in cases}) == len(cases)
    assert {c.family for c in cases} == set(FAMILIES)
    cyl = [c for c in cases if c.family == "cylinder"]
    assert {c.axis_deg for c in cyl} == {0.0, 30.0, 60.0, 90.0} and {c.direction for c in cyl} == {"up", "down"}
    assert min(c.bend_deg for c in cyl) <= 60 and max(c.bend_deg for c in cyl) == 300
    assert max(c.bend_deg for c in cases if c.family == "fold") == 170
    assert {c.aspect for c in cases} >= {OTHER_ASPECT} and len({c.aspect for c in cases}) == 2
    assert {c.distance_m for c in cases} == {0.40, OTHER_DISTANCE_M}
    from platebench.bench.config import SampleConfig
    for c in cases:  # every plate of the set is a valid plate
        build_plate(c.config(SampleConfig()).plate)


def test_bend_list_chooses_the_cylinders():
    cases = study_cases((200.0,))
    assert {c.bend_deg for c in cases if c.family == "cylinder"} == {200.0}
    assert not any(c.family == "flat" and c.bend_deg == 0 for c in cases if c.family == "cylinder")


def _row(family, bend, hidden, reachable, outcome, **det):
    return {"family": family, "bend_deg": bend, "gt_hidden_first": hidden, "gt_reachable": reachable,
            "outcome": outcome, **{f"det_{k}": v for k, v in det.items()}}


def test_targets_and_detector_scores_count_against_ground_truth():
    rows = [_row("cylinder", 240.0, True, True, "cured", counting_test=True),
            _row("cylinder", 240.0, True, True, "unconfirmed", counting_test=False),
            _row("cylinder", 300.0, True, False, "honest", counting_test=True),
            _row("dome", None, False, True, "clean", counting_test=False),
            _row("dome", None, False, True, "false_alarm", counting_test=True),
            {"family": "fold", "bend_deg": 170.0, "outcome": "error", "error": "x"}]
    t = targets(rows)
    assert (t["silent"], t["errors"], t["curable"], t["cured_of_curable"]) == (0, 1, 2, 1)
    assert t["cured_frac"] == 0.5 and t["false_alarm_frac"] == 0.5
    assert t["met"] == {"silent = 0": True, "errors = 0": False, "cured >= 90 %": False, "false alarms <= 2 %": False}
    s = detector_scores(rows)
    ct = s["all"]["counting_test"]
    assert (ct["true_positive"], ct["false_positive"], ct["false_negative"], ct["true_negative"]) == (2, 1, 1, 1)
    assert ct["precision"] == pytest.approx(2 / 3) and ct["recall"] == pytest.approx(2 / 3)
    assert s["by_bend"]["240"]["counting_test"]["recall"] == 0.5
    assert s["by_family"]["dome"]["counting_test"]["precision"] == 0.0
    assert outcome_counts(rows)["error"] == 1


def test_detection_score_skips_unknown_cases():
    d = detection_score([True, False, None, True], [True, None, True, False])
    assert (d.true_positive, d.false_positive, d.false_negative, d.true_negative) == (1, 0, 1, 0)
    assert d.precision == 1.0 and d.recall == 0.5 and detection_score([], []).precision is None


def test_study_cli_refuses_bad_flags_and_writes_nothing(tmp_path):
    for flags, msg in ((["--bend", "0:400:10"], "--bend value 360 is out of range: allowed 0 to 350"),
                       (["--families", "cube"], "--families value 'cube' is unknown"),
                       (["--limit", "0"], "--limit = 0 is out of range")):
        p = run_cli("study", "false-boundary", "--out", tmp_path / "t", *flags)
        assert p.returncode == 2 and msg in p.stderr, p.stderr
    assert not (tmp_path / "t").exists()


@pytest.mark.render
def test_a_small_study_runs_and_reports(tmp_path):
    """Two plates through the CLI at 320 x 240: the flat plate is clean; study.json holds the rows,
    outcome counts, detector scores and targets; the report draws the study section."""
    out = tmp_path / "study"
    p = run_cli("study", "false-boundary", "--out", out, "--families", "flat,dome", "--limit", "2",
                "--width", "320", "--spp", "2")
    assert p.returncode == 0, p.stderr
    doc = json.loads((out / "study.json").read_text())
    assert [r["family"] for r in doc["rows"]] == ["flat", "dome"]
    flat = doc["rows"][0]
    assert flat["outcome"] == "clean" and flat["cures"] == 0 and flat["gt_hidden_first"] is False
    assert doc["outcomes"]["error"] == 0 and doc["targets"]["silent"] == 0
    assert set(doc["detectors"]["all"]) == {"counting_test", "arrays_disagree", "viewpoint_consistency",
                                            "occluding_contour", "end_tangents"}
    assert "time:" in p.stdout and "targets:" in p.stdout and (out / "study.csv").is_file()
    from platebench.bench.report.sensing import study_section
    sec = study_section(out, tmp_path / "plots")
    assert sec["figures"][0] == {"label": "plates", "value": 2}
    assert [t["title"] for t in sec["tables"]][:3] == ["Outcomes per family", "Outcomes per bend",
                                                       "Detectors: precision and recall"]
    assert all((tmp_path / "plots" / pl["file"]).is_file() for pl in sec["plots"])
