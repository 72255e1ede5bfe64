"""The false-boundary study: its plate set, its scores (pure), and one small run through the CLI
and the report."""
from __future__ import annotations

import json
from dataclasses import replace

import pytest

from platebench.bench.io.records import StudyRow
from platebench.bench.run.sensing.study import (
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
    assert {c.family for c in cases} == {f for f, cls in FAMILIES.items() if cls.in_default_study}
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


def test_axes_aspect_and_families_choose_plates_outside_the_default_set():
    """--axes, --aspect and --families give other plates: every cylinder about the given axes, every
    plate of the main set at the given aspect (the second aspect's and second distance's few plates
    keep theirs), a family's own examples at that aspect."""
    from platebench.bench.run.sensing.study import REFERENCE_ASPECT
    cases = study_cases((150.0, 270.0), ["cylinder", "fold", "dome"], (15.0, 50.0, 80.0), 2.2)
    cyl = [c for c in cases if c.family == "cylinder" and c.aspect == 2.2]
    assert len(cyl) == 12 and {c.axis_deg for c in cyl} == {15.0, 50.0, 80.0}
    assert {c.aspect for c in cases} == {2.2, OTHER_ASPECT, REFERENCE_ASPECT}
    assert all(c.distance_m == OTHER_DISTANCE_M for c in cases if c.aspect == REFERENCE_ASPECT)
    assert [c.name for c in cases if c.family == "dome"] == ["dome 12 mm aspect 2.2", "bowl 12 mm aspect 2.2"]
    from platebench.bench.config import SampleConfig
    plate = cyl[0].config(SampleConfig()).plate
    assert plate.length_m / plate.width_m == pytest.approx(2.2) and len({c.name for c in cases}) == len(cases)


def _row(family, bend, hidden, reachable, outcome, verifiable=None, **det):
    return StudyRow(f"{family} {bend}", family, bend_deg=bend, gt_hidden_first=hidden, gt_reachable=reachable,
                    gt_verifiable=verifiable, outcome=outcome, detectors=det)


def test_targets_and_detector_scores_count_against_ground_truth():
    rows = [_row("cylinder", 240.0, True, True, "cured", counting_test=True),
            _row("cylinder", 240.0, True, True, "unconfirmed", counting_test=False),
            _row("cylinder", 300.0, True, False, "honest", counting_test=True),
            _row("dome", None, False, True, "clean", counting_test=False),
            _row("dome", None, False, True, "false_alarm", counting_test=True),
            StudyRow("fold 170", "fold", bend_deg=170.0, outcome="error", error="x")]
    rows[0] = replace(rows[0], gt_verifiable=True)  # a pair of reachable poses could verify the cured one
    t = targets(rows)
    assert (t.silent, t.errors, t.curable, t.cured_of_curable) == (0, 1, 2, 1)
    assert t.cured_frac == 0.5 and t.false_alarm_frac == 0.5
    assert (t.seen_all_of_curable, t.seen_all_frac) == (2, 1.0)  # cured as the study's first target counts it
    assert (t.verifiable, t.cured_of_verifiable) == (1, 1)
    assert t.met == {"silent = 0": True, "errors = 0": False, "cured >= 90 %": True,
                        "verified >= 90 % of the verifiable": True, "false alarms <= 2 %": False}
    rows[0] = replace(rows[0], gt_verifiable=False)
    rows[1] = replace(rows[1], gt_verifiable=True, outcome="honest")  # still hidden at the end: cured by neither count
    t = targets(rows)
    assert (t.seen_all_of_curable, t.verifiable, t.cured_of_verifiable) == (1, 1, 0)
    assert t.met["cured >= 90 %"] is False and t.met["verified >= 90 % of the verifiable"] is False
    s = detector_scores(rows)
    ct = s["all"]["counting_test"]
    assert (ct.true_positive, ct.false_positive, ct.false_negative, ct.true_negative) == (2, 1, 1, 1)
    assert ct.precision == pytest.approx(2 / 3) and ct.recall == pytest.approx(2 / 3)
    assert s["by_bend"]["240"]["counting_test"].recall == 0.5
    assert s["by_family"]["dome"]["counting_test"].precision == 0.0
    assert outcome_counts(rows)["error"] == 1


def test_detection_score_skips_unknown_cases():
    d = detection_score([True, False, None, True], [True, None, True, False])
    assert (d.true_positive, d.false_positive, d.false_negative, d.true_negative) == (1, 0, 1, 0)
    assert d.precision == 1.0 and d.recall == 0.5 and detection_score([], []).precision is None


def test_study_cli_refuses_bad_flags_and_writes_nothing(tmp_path):
    for flags, msg in ((["--bend", "0:400:10"], "--bend value 360 is out of range: allowed 0 to 350"),
                       (["--families", "cube"], "--families value 'cube' is unknown"),
                       (["--limit", "0"], "--limit = 0 is out of range"),
                       (["--workers", "0"], "--workers = 0 is out of range: allowed 1 to 64"),
                       (["--aspect", "20"], "--aspect = 20.0 is out of range: allowed 0.25 to 8"),
                       (["--axes", "0,180"], "--axes value 180 is out of range"),
                       (["--verify-grid", "9x9@0"], "--verify-grid SQUARE_PX = 0 is out of range")):
        p = run_cli("study", "false-boundary", "--out", tmp_path / "t", *flags)
        assert p.returncode == 2 and msg in p.stderr, p.stderr
    assert not (tmp_path / "t").exists()


@pytest.mark.render
def test_a_small_study_runs_and_reports(tmp_path):
    """Two plates through the CLI at 320 x 240, two at a time (worker processes): the flat plate is
    clean; study.json holds the rows in case order, outcome counts, detector scores and targets,
    each row as the same plate run alone in this process gives it; the report draws the study
    section."""
    out = tmp_path / "study"
    p = run_cli("study", "false-boundary", "--out", out, "--families", "flat,dome", "--limit", "2",
                "--width", "320", "--spp", "2", "--workers", "2")
    assert p.returncode == 0, p.stderr
    doc = json.loads((out / "study.json").read_text())
    assert [r["family"] for r in doc["rows"]] == ["flat", "dome"]
    flat = doc["rows"][0]
    assert flat["outcome"] == "clean" and flat["cures"] == 0 and flat["gt_hidden_first"] is False
    assert doc["outcomes"]["error"] == 0 and doc["targets"]["silent"] == 0
    assert set(doc["detectors"]["all"]) == {"counting_test", "arrays_disagree", "viewpoint_consistency",
                                            "occluding_contour", "end_tangents"}
    assert "time:" in p.stdout and "2 workers" in p.stdout and "targets:" in p.stdout and (out / "study.csv").is_file()
    assert doc["settings"]["workers"] == 2
    from platebench.bench.run.sensing.records import auto_verify_grid
    assert doc["settings"]["verify_grid"] == auto_verify_grid(320) == "6x12@24" and "paper" in doc["settings"]["grid"]
    from platebench.bench.config import SampleConfig, SceneParams
    from platebench.bench.run.sensing.study import run_study
    from platebench.scenes.scene_spec import RenderSettings
    base = SampleConfig(scene=SceneParams(width=320, height=240), render=RenderSettings(spp=2, seed=0))
    alone = run_study([c for c in study_cases() if c.family == "dome"][:1], base, workers=1).rows[0]
    pooled = doc["rows"][1]
    for k in ("case", "outcome", "cures", "views", "boundary_verified", "gt_visible_final_frac",
              "merged_boundary_mean_mm", "merged_surface_rms_mm", "merged_points"):
        assert pooled[k] == getattr(alone, k), (k, pooled[k], getattr(alone, k))
    from platebench.bench.report.sensing import study_section
    sec = study_section(out, tmp_path / "plots")
    assert sec["figures"][0] == {"label": "plates", "value": 2}
    assert [t["title"] for t in sec["tables"]][:3] == ["Outcomes per family", "Outcomes per bend",
                                                       "Detectors: precision and recall"]
    # every plot is drawn, or left out with the one line that says why (no empty figure)
    assert all((tmp_path / "plots" / pl["file"]).is_file() if pl["file"] else pl["left_out"] for pl in sec["plots"])
    assert any(pl["file"] for pl in sec["plots"])


@pytest.mark.render
def test_an_interrupt_stops_the_plates_running_in_the_worker_processes():
    """An interrupt while plates run in worker processes stops them: the pool's processes are gone
    within seconds, not when their plates would have finished (Python's exit joins a process pool,
    and a SIGTERM to the study alone left its workers computing). The interrupt is raised from the
    progress callback as the flat plate finishes (a few poses); the other, a 240-degree curl at 0.5 m
    that takes 30 poses or so, is still running then (at 320 x 240, spp 2, alone: the flat plate's run
    about 4 s, the curl's about 20 s)."""
    import multiprocessing
    import time

    from platebench.bench.config import SampleConfig, SceneParams
    from platebench.bench.run.sensing import SensingOptions
    from platebench.bench.run.sensing.study import _study_rows, study_cases
    from platebench.scenes.scene_spec import RenderSettings
    cases = [c for c in study_cases() if c.name in ("flat (cylinder 0)", "cylinder 240 down axis 0 distance_m 0.5")]
    assert len(cases) == 2
    base = SampleConfig(scene=SceneParams(width=320, height=240), render=RenderSettings(spp=2))
    before = set(multiprocessing.active_children())
    workers, finished = [], []

    def progress(k, row):
        finished.append(row.case)
        workers.extend(p for p in multiprocessing.active_children() if p not in before and p.is_alive())
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        list(_study_rows(cases, base, SensingOptions(), progress, workers=2))
    assert workers, "no worker process was running when the first plate finished"
    assert finished == ["flat (cylinder 0)"], finished  # the curl was still running when the interrupt came
    deadline = time.monotonic() + 5.0
    while any(p.is_alive() for p in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(p.is_alive() for p in workers), [p.pid for p in workers if p.is_alive()]


@pytest.mark.render
def test_an_interrupted_study_keeps_its_finished_plates_and_resume_runs_the_rest(tmp_path):
    """SIGTERM as the first plate's progress line arrives (its row is in the journal by then): exit 143,
    no output folder, the finished plate kept (and said so). Without --resume or --overwrite the
    journal is refused; with other settings it is refused; --resume runs only the other plates and
    writes the same rows a study run at once writes; the journal is then gone.

    The signal is sent on the progress line (read as it is written: the study flushes each one), not
    on a poll of the journal, and two plates are still to run then, so the study cannot finish
    between the test seeing the plate and the signal (a poll every 0.2 s once missed a 5 s window on
    a loaded CI machine, and the study ended with exit 0)."""
    import signal
    import subprocess
    import sys

    from platebench.bench.run.journal import journal_path
    out = tmp_path / "study"
    flags = ["--families", "flat,dome", "--limit", "3", "--width", "320", "--spp", "2", "--workers", "1"]
    proc = subprocess.Popen([sys.executable, "-m", "platebench", "study", "false-boundary", "--out", str(out), *flags],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    journal = journal_path(out)
    first = proc.stdout.readline()  # blocks until the first plate is done (or the study ends)
    assert first.startswith("flat"), (first, proc.stderr.read() if proc.poll() is not None else "")
    assert proc.poll() is None, "the study ended before it could be interrupted"
    assert len(journal.read_text().splitlines()) == 2  # the header and the plate just finished
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert "1 finished plates are kept in" in err and "--resume" in err
    assert not out.exists() and journal.is_file()
    p = run_cli("study", "false-boundary", "--out", out, *flags)
    assert p.returncode == 2 and "finished plates of an interrupted study" in p.stderr and "--resume" in p.stderr
    p = run_cli("study", "false-boundary", "--out", out, *flags[:-4], "--spp", "4", "--resume")
    assert p.returncode == 2 and "other settings" in p.stderr and "spp" in p.stderr, p.stderr
    p = run_cli("study", "false-boundary", "--out", out, *flags, "--resume")
    assert p.returncode == 0, p.stderr
    assert "resumed         1 plates" in p.stdout
    doc = json.loads((out / "study.json").read_text())
    assert doc["resumed_plates"] == 1 and doc["plates_run"] == 2
    assert [r["family"] for r in doc["rows"]] == ["flat", "dome", "dome"]
    assert "time: " in p.stdout and "for 2 plates" in p.stdout and "1 more from the journal" in p.stdout
    assert not journal.exists()
    whole = tmp_path / "whole"
    assert run_cli("study", "false-boundary", "--out", whole, *flags).returncode == 0
    again = json.loads((whole / "study.json").read_text())
    for a, b in zip(doc["rows"], again["rows"]):
        assert {k: v for k, v in a.items() if k != "time_s"} == {k: v for k, v in b.items() if k != "time_s"}


def test_axes_and_families_restrict_every_set_of_plates():
    """--axes 0 --families cylinder: every plate, the second aspect's and second distance's too, is a
    cylinder about axis 0; the default set keeps its axes 0 and 90 there (61 plates)."""
    cases = study_cases(families=["cylinder"], axes_deg=(0.0,))
    assert cases and {c.family for c in cases} == {"cylinder"} and {c.axis_deg for c in cases} == {0.0}
    assert {c.aspect for c in cases} >= {OTHER_ASPECT} and {c.distance_m for c in cases} >= {OTHER_DISTANCE_M}
    assert len({c.name for c in cases}) == len(cases)
    default = study_cases()
    assert len(default) == 61
    other = [c for c in default if c.family == "cylinder" and (c.aspect == OTHER_ASPECT or c.distance_m == OTHER_DISTANCE_M)]
    assert {c.axis_deg for c in other} == {0.0, 90.0}
    few = study_cases((30.0,), ["fold"])  # the second aspect's fold only where the set's folds reach it
    assert [c.bend_deg for c in few] == [60.0, 60.0]


def test_dry_run_lists_the_plates_the_flags_select_and_writes_nothing(tmp_path):
    p = run_cli("study", "false-boundary", "--axes", "0", "--families", "cylinder", "--bend", "60,240",
                "--dry-run", "--out", tmp_path / "t")
    assert p.returncode == 0, p.stderr
    lines = p.stdout.strip().splitlines()
    plates = lines[1:-1]
    assert plates and all(" axis 0" in line and "axis 90" not in line for line in plates), lines
    assert lines[-1].startswith(f"{len(plates)} plates") and not (tmp_path / "t").exists()


def _help(*argv) -> str:
    import contextlib
    import io

    from platebench.bench.cli.main import build_parser
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), pytest.raises(SystemExit):
        build_parser(list(argv)).parse_args(list(argv))
    return buf.getvalue()


def test_each_study_kind_has_its_own_help():
    import re

    def flags(h):
        return set(re.findall(r"^  (--[\w-]+)", h, re.M))
    fb, acc, cut = (_help("study", k, "--help") for k in ("false-boundary", "accuracy", "cut-squares"))
    common = {"--out", "--overwrite", "--seed", "--spp"}
    assert flags(fb) >= common | {"--families", "--perturb", "--workers", "--realism", "--dry-run"}
    assert flags(acc) >= common | {"--draws", "--corners", "--targets", "--realism"}
    assert flags(cut) >= common | {"--distances", "--bend", "--axes", "--width"}
    assert not flags(fb) & {"--draws", "--corners", "--distances"} and not flags(acc) & {"--families", "--perturb"}
    assert not flags(cut) & {"--families", "--draws", "--realism", "--perturb", "--workers"}
    top = _help("study", "--help")
    assert all(k in top for k in ("false-boundary", "accuracy", "cut-squares")) and not flags(top) - {"--help"}


def _fa_row(**kw) -> StudyRow:
    from platebench.reconstruction.strategy.detectors import DETECTORS
    base = dict(case="cylinder 60 down axis 0", family="cylinder", bend_deg=60.0, outcome="false_alarm",
                boundary_verified=True, cures=1, views=5, detectors=dict.fromkeys(DETECTORS, False),
                gt_visible_first_frac=1.0, gt_visible_final_frac=1.0, gt_hidden_first=False, gt_hidden_final=False,
                gt_reachable=True, gt_verifiable=True, merged_boundary_mean_mm=0.3, merged_surface_coverage_frac=0.9,
                time_s=2.0, verdict="the confirmed pieces close into one loop")
    return StudyRow(**{**base, **kw})


def test_a_false_alarm_and_its_verdict_never_read_as_a_contradiction():
    """A false alarm whose boundary the loop's poses confirmed (it applied a cure nothing hidden called
    for) is said so; the verdict line never reads as a bare "boundary verified: yes"."""
    text = _fa_row().verdict_text(with_reason=True)
    assert "confirmed the whole boundary" in text and "1 cure that nothing hidden called for" in text
    assert "false alarm" in text and text.endswith(": the confirmed pieces close into one loop")
    assert "verified: yes" not in text.lower() and "verified = true" not in text.lower()
    assert "false alarm" in _fa_row(boundary_verified=False, cures=0).verdict_text()
    assert "false alarm" not in _fa_row(outcome="clean", cures=0).verdict_text()
    assert "silent" in _fa_row(outcome="silent", cures=0, gt_hidden_first=True, gt_hidden_final=True).verdict_text()
    assert "none" in _fa_row(outcome="error").verdict_text()


def test_the_study_table_explains_its_columns():
    from platebench.bench.report.text import table_lines
    from platebench.bench.run.sensing.study import StudyResult
    lines = table_lines(StudyResult((_fa_row(),), {}, 2.0))
    head = lines[0]
    legend = " ".join(line for line in lines if line.startswith(("columns:", "  ")))
    for col in ("cur", "vws", "cnt", "arr", "vpc", "occ", "end", "GT vis 1st", "final", "reach", "pairs", "bnd mm",
                "cover", "time s"):
        assert col in head and f"{col}:" in legend, col
    assert "false_alarm: nothing was hidden" in legend
    assert "  cylinder 60 down axis 0: loop's verdict (no ground truth): its poses confirmed the whole boundary, " \
           "after 1 cure that nothing hidden called for" in "\n".join(lines)
