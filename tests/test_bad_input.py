"""Every bad input a user can fix ends in one line naming the file, key or value and what is allowed,
exit 2, no traceback, nothing left behind (``bench/perf/bad_inputs.py``, each case in a fresh
``platebench`` process). The unreadable and unwritable cases run as user nobody; where nobody cannot
reach this checkout (a clone under a directory closed to others) they are skipped, with the reason."""
from __future__ import annotations

import pytest

from platebench.bench.perf.bad_inputs import cases, nobody_blocker, run_all, table

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def outcomes():
    blocker = nobody_blocker()
    # its own scratch directory under /tmp (pytest's tmp_path is closed to the user nobody)
    return blocker, {o.case: o for o in run_all(as_nobody=blocker is None)}


def test_every_bad_input_is_one_clean_line_with_nothing_left_behind(outcomes):
    _, got = outcomes
    names = [c.name for c in cases()]
    assert len(names) == len(set(names)) and len(names) >= 60
    mine = [got[c.name] for c in cases() if not c.as_nobody]
    assert len(mine) == sum(not c.as_nobody for c in cases())
    bad = [o for o in mine if not o.clean or o.traceback or o.leftovers]
    assert not bad, table(bad)


def test_unreadable_and_unwritable_paths_as_user_nobody(outcomes):
    blocker, got = outcomes
    if blocker:
        pytest.skip(blocker)
    theirs = [got[c.name] for c in cases() if c.as_nobody]
    assert len(theirs) >= 5
    bad = [o for o in theirs if not o.clean or o.traceback or o.leftovers]
    assert not bad, table(bad)
