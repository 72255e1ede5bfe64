"""``study --perturb``: the study's plates moved a little (bend axis, working distance), so that anyone
can check that its rates are no knife-edge results (axis +-1 degree, distance +-5 mm)."""
from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial import cKDTree

from platebench.bench.config import SampleConfig
from platebench.bench.run.sensing.study import AXIS_WRAP_SAFE, perturbed_cases, study_cases
from platebench.plates import CylindricalBend, PlateSpec, build_plate
from platebench.plates.spec import Fold
from tests.conftest import run_cli


def _vertices(deformation) -> np.ndarray:
    return np.asarray(build_plate(PlateSpec(0.1165, 0.0735, deformation=deformation)).mesh.vertices)


def test_only_a_centred_bend_may_have_its_axis_wrapped():
    """Reversing the bending coordinate (axis a -> a + 180 degrees) leaves a centred cylinder as it
    is, but moves a fold (anchored on one side of an off-centre band) to another plate."""
    cyl = CylindricalBend(math.radians(240), "down", 0.0)
    fold = Fold(math.radians(120), 0.015, 0.02, "down", 0.0)
    for d, same in ((cyl, True), (fold, False)):
        a, b = _vertices(d), _vertices(replace(d, axis_rad=math.pi - 1e-12))
        apart = cKDTree(b).query(a)[0].max()
        assert (apart < 1e-5) == same, (type(d).__name__, apart)
        assert isinstance(d, AXIS_WRAP_SAFE) == same


@pytest.mark.parametrize("axis_deg, distance_mm", [(-1.0, -5.0), (1.0, 5.0)])
def test_perturbed_cases_turn_every_axis_and_shift_every_distance(axis_deg, distance_mm):
    cases = study_cases()
    moved = perturbed_cases(cases, axis_deg, distance_mm)
    assert len(moved) == len(cases)
    kept = 0
    for c, m in zip(cases, moved):
        assert m.name.startswith(c.name + " perturbed") and f"distance {distance_mm:+g} mm" in m.name
        assert m.distance_m == pytest.approx(c.distance_m + distance_mm * 1e-3, abs=1e-12)
        if not hasattr(c.deformation, "axis_rad"):
            assert m.deformation == c.deformation and m.axis_deg == c.axis_deg and "axis" not in m.name[len(c.name):]
            continue
        turned = c.deformation.axis_rad + math.radians(axis_deg)
        if 0.0 <= turned < math.pi or isinstance(c.deformation, AXIS_WRAP_SAFE):
            turned %= math.pi  # a cylinder at axis 0 turned by -1 degree: 179
            assert m.deformation.axis_rad == pytest.approx(turned, abs=1e-12) and f"axis {axis_deg:+g}" in m.name
            if c.axis_deg is not None:
                assert m.axis_deg == pytest.approx(math.degrees(turned))
        else:  # a fold at axis 0 cannot turn to -1 degree without becoming another plate: kept, and said
            kept += 1
            assert m.deformation == c.deformation and "axis kept" in m.name
    assert kept == (7 if axis_deg < 0 else 0)  # the study's folds all lie at axis 0
    # bending is isometric: turning the axis keeps the boundary's length (and the spec's checks pass)
    def length(case):
        B = np.asarray(build_plate(case.config(SampleConfig()).plate).boundary)
        return np.linalg.norm(np.diff(np.vstack([B, B[:1]]), axis=0), axis=1).sum()

    for c, m in list(zip(cases, moved))[::7]:
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
    from platebench.bench.config.study import parse_perturb
    from platebench.errors import UserValueError

    assert parse_perturb("-1,-5") == (-1.0, -5.0) and parse_perturb(" 1 , 5 ") == (1.0, 5.0)
    for bad, words in (("11,0", "allowed -10 to 10"), ("0,-51", "allowed -50 to 50"), ("1;5", "AXIS_DEG,DISTANCE_MM"),
                       ("inf,0", "allowed -10 to 10")):
        with pytest.raises(UserValueError, match=words):
            parse_perturb(bad)
