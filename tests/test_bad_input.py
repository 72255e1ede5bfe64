"""Every bad input a user can fix ends in one line naming the file, key or value and what is allowed,
exit 2, no traceback, nothing left behind, and no data lost (the harness ``bench/perf/bad_inputs.py``
and the cases its ``bad_inputs_*`` modules add, each case in a fresh ``platebench`` process;
destructive ones in a directory of their own). The unreadable and unwritable cases run as user
nobody; where nobody cannot reach this checkout (a clone under a directory closed to others) they
are skipped, with the reason."""
from __future__ import annotations

import pytest

from platebench.bench.perf import run_attacks
from platebench.bench.perf.bad_inputs import base_cases, cases, failed, nobody_blocker, run_all, table

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def outcomes():
    blocker = nobody_blocker()
    # the attacks on runs the harness tries after these cases have their own tests (test_interrupts.py,
    # test_plugin_isolation.py, test_run_errors.py): left out here, to keep the suite's time
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(run_attacks, "run_attacks", lambda select, work: [])
        # its own scratch directory under /tmp (pytest's tmp_path is closed to the user nobody)
        return blocker, {o.case: o for o in run_all(as_nobody=blocker is None)}


def test_every_bad_input_is_one_clean_line_with_nothing_lost_or_left_behind(outcomes):
    _, got = outcomes
    names = [c.name for c in cases()]
    assert len(names) == len(set(names)) and len(names) >= len(base_cases()) + 60
    assert any(c.scratch for c in cases())  # the destructive cases run apart
    mine = [got[c.name] for c in cases() if not c.as_nobody]
    assert len(mine) == sum(not c.as_nobody for c in cases())
    bad = [o for o in mine if failed(o)]
    assert not bad, table(bad)
    assert not any(o.lost or o.exit0_on_failure for o in mine)


def test_unreadable_and_unwritable_paths_as_user_nobody(outcomes):
    blocker, got = outcomes
    if blocker:
        pytest.skip(blocker)
    theirs = [got[c.name] for c in cases() if c.as_nobody]
    assert len(theirs) >= 5
    bad = [o for o in theirs if failed(o)]
    assert not bad, table(bad)
    assert not any(o.lost or o.exit0_on_failure for o in theirs)
