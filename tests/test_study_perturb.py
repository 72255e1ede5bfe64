"""``study --perturb``: the study's plates moved a little (bend axis, working distance), so that anyone
can check that its rates are no knife-edge results (issue 12: axis +-1 degree, distance +-5 mm)."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from platebench.bench.config import SampleConfig
from platebench.bench.run.study import perturbed_cases, study_cases
from platebench.plates import build_plate
from tests.conftest import run_cli


def test_perturbed_cases_turn_every_axis_and_shift_every_distance():
    cases = study_cases()
    moved = perturbed_cases(cases, -1.0, -5.0)
    assert len(moved) == len(cases)
    for c, m in zip(cases, moved):
        assert m.name.startswith(c.name) and m.name != c.name and "axis -1" in m.name and "-5 mm" in m.name
        assert m.distance_m == pytest.approx(c.distance_m - 0.005, abs=1e-12)
        if hasattr(c.deformation, "axis_rad"):
            turned = (c.deformation.axis_rad - math.radians(1.0)) % math.pi  # axis 0 becomes 179 degrees
            assert m.deformation.axis_rad == pytest.approx(turned, abs=1e-12)
            assert 0.0 <= m.deformation.axis_rad < math.pi and m.axis_deg == pytest.approx(math.degrees(turned))
        else:
            assert m.deformation == c.deformation and m.axis_deg == c.axis_deg
    # every moved plate is a valid plate (the spec's range checks pass) with the same boundary length
    def length(case):
        B = np.asarray(build_plate(case.config(SampleConfig()).plate).boundary)
        return np.linalg.norm(np.diff(np.vstack([B, B[:1]]), axis=0), axis=1).sum()

    for c, m in list(zip(cases, moved))[::7]:  # bending is isometric: turning the axis keeps the length
        assert length(m) == pytest.approx(length(c), rel=1e-3)
    assert perturbed_cases(cases, 0.0, 0.0) == cases
    with pytest.raises(ValueError, match="not positive"):
        perturbed_cases(cases[:1], 0.0, -1000.0)


@pytest.mark.slow
def test_a_perturbed_study_runs_and_records_the_shift(tmp_path):
    out = tmp_path / "st"
    r = run_cli("study", "false-boundary", "--families", "cylinder", "--bend", "60", "--limit", "1",
                "--perturb", "1,5", "--seed", "3", "--width", "320", "--out", out)
    assert r.returncode == 0, r.stderr[-2000:]
    doc = json.loads((out / "study.json").read_text())
    assert doc["settings"]["perturb_axis_deg"] == 1.0 and doc["settings"]["perturb_distance_mm"] == 5.0
    assert doc["settings"]["seed"] == 3
    row, = doc["rows"]
    assert row["case"] == "cylinder 60 down axis 0 perturbed axis +1 distance +5 mm"
    assert row["axis_deg"] == pytest.approx(1.0) and row["distance_m"] == pytest.approx(0.405)
    assert row["outcome"] == "clean"  # a 60-degree bend hides nothing, moved or not


def test_perturb_flag_parses_signed_shifts_and_refuses_large_ones():
    from platebench.bench.cli.study import parse_perturb
    from platebench.errors import UserValueError

    assert parse_perturb("-1,-5") == (-1.0, -5.0) and parse_perturb(" 1 , 5 ") == (1.0, 5.0)
    for bad, words in (("11,0", "allowed -10 to 10"), ("0,-51", "allowed -50 to 50"), ("1;5", "AXIS_DEG,DISTANCE_MM"),
                       ("inf,0", "allowed -10 to 10")):
        with pytest.raises(UserValueError, match=words):
            parse_perturb(bad)
