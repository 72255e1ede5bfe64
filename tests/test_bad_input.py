"""The fault-injection harness (``tools/faults/bad_inputs.py``, a developer tool outside the package)
states at least 400 cases, each in a fresh ``platebench`` process with what must happen; this test
runs a representative subset of them (a few of each family: bad flag values and types, damaged
files, outputs that would destroy data, datasets that lie, measured failure kinds, the user
``nobody``'s unreadable and unwritable paths) and asks each to be classified "ok": one clean line and
status 2 for a refusal, a recorded failure and status 1, or a correct result; no traceback, no
hang, no exit 0 on failure, no silent wrong result, no data lost, nothing left behind. The whole
harness runs with ``python -m tools.faults`` (docs/findings/failure-handling.md). The unreadable and
unwritable cases run as user nobody; where nobody cannot reach this checkout (a clone under a
directory closed to others) they are skipped, with the reason."""
from __future__ import annotations

from collections import Counter

import pytest

from tools.faults.bad_inputs import cases, failed, nobody_blocker, run_all, table

pytestmark = pytest.mark.slow

# a few cases of each family, chosen to reach every command and every kind of expectation
SUBSET = {
    "toml spp = inf", "toml not UTF-8", "config is a directory", "config unreadable", "render --out exists",
    "render --out unwritable", "spec huge range", "--scheduler closed port", "garbage image PNG",
    "truncated disp0GT.pfm", "recon.json is a list", "study --perturb 1,500", "spec unreadable",
    "flag: render --width 0", "flag: render --spp abc", "flag: sense --bend-deg nan", "flag: calibrate --grid 4x4",
    "flag: render --camera pinhole9", "flag: compare --method-time-limit-s 0", "flag: evaluate --radius-mm nan",
    "flag: sweep --workers -1", "flag: study false-boundary --aspect 0", "flag: study accuracy --draws 0",
    "flag: export --shift -1",
    "file: reconstruct sample images/right_passive.png swap-in", "file: reconstruct sample calib.json link-out",
    "file: evaluate sample gt/disp0GT.pfm empty", "file: evaluate recon points.csv folder",
    "render --overwrite a user's folder", "reconstruct --out its sample", "sweep --overwrite a dataset with a note",
    "export: images swapped between samples", "evaluate: PNG declaring 30000 x 30000",
    "measured: reconstruct an image swapped in from another sample", "measured: export --shift 63 (below the "
    "smallest disparity)", "measured: compare --recon nonexist", "measured: render --overwrite over an edited "
    "calib.json", "measured: render of a TOML nested 50000 deep", "measured: render a plate of length_m = 1e300",
    "measured: render --out a non-UTF-8 name", "measured: render from a deleted working directory",
    "measured: evaluate with the arguments swapped", "measured: an over-long PFM is not called truncated",
    "measured: render > /dev/full keeps its status and its output",
}


def test_the_harness_states_at_least_400_cases_of_every_family():
    every = cases()
    names = [c.name for c in every]
    assert len(names) == len(set(names)) and len(names) >= 400
    families = Counter(c.family for c in every)
    assert {"base", "flag-range", "flag-type", "damaged-file", "outputs", "readers", "measured"} <= set(families)
    assert SUBSET <= set(names), sorted(SUBSET - set(names))
    assert any(c.scratch for c in every) and any(c.signal for c in every) and any(c.check for c in every)


@pytest.fixture(scope="module")
def outcomes():
    blocker = nobody_blocker()
    # the attacks on runs have their own tests (test_interrupts.py, test_plugin_isolation.py, test_run_errors.py);
    # its own scratch directory under /tmp (pytest's tmp_path is closed to the user nobody)
    return blocker, {o.case: o for o in run_all(as_nobody=blocker is None, attacks=False, only=SUBSET)}


def test_a_representative_subset_is_handled_as_each_case_states(outcomes):
    _, got = outcomes
    mine = [got[c.name] for c in cases() if c.name in SUBSET and not c.as_nobody]
    assert len(mine) == sum(not c.as_nobody for c in cases() if c.name in SUBSET)
    bad = [o for o in mine if failed(o)]
    assert not bad, table(bad)


def test_unreadable_and_unwritable_paths_as_user_nobody(outcomes):
    blocker, got = outcomes
    if blocker:
        pytest.skip(blocker)
    theirs = [got[c.name] for c in cases() if c.name in SUBSET and c.as_nobody]
    assert len(theirs) >= 3
    bad = [o for o in theirs if failed(o)]
    assert not bad, table(bad)
