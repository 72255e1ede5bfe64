"""Every bad input a user can fix ends in one line naming the file, key or value and what is allowed,
exit 2, no traceback, nothing left behind, and no data lost (the harness ``bench/perf/bad_inputs.py``
and the cases its ``bad_inputs_*`` modules add, each case in a fresh ``platebench`` process;
unreadable/unwritable cases run as user nobody, destructive ones in a directory of their own)."""
from __future__ import annotations

import pytest

from platebench.bench.perf.bad_inputs import base_cases, cases, failed, run_all, table

pytestmark = pytest.mark.slow
OTHERS: set = set()  # every case, study --bend included (bench.config.ranges)


def test_every_bad_input_is_one_clean_line_with_nothing_lost_or_left_behind(monkeypatch):
    from platebench.bench.perf import run_attacks
    names = [c.name for c in cases()]
    assert len(names) == len(set(names)) and len(names) >= len(base_cases()) + 60
    assert any(c.scratch for c in cases())  # the destructive cases run apart
    # the attacks on runs the harness tries after these cases have their own tests (test_interrupts.py,
    # test_plugin_isolation.py, test_run_errors.py): left out here, to keep the suite's time
    monkeypatch.setattr(run_attacks, "run_attacks", lambda select, work: [])
    # its own scratch directory under /tmp (pytest's tmp_path is closed to the user nobody)
    outcomes = [o for o in run_all() if o.case not in OTHERS]
    bad = [o for o in outcomes if failed(o)]
    assert not bad, table(bad)
    assert not any(o.lost or o.exit0_on_failure for o in outcomes)
