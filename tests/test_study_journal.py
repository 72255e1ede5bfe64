"""The study's journal (``bench.run.journal``): rows kept as they finish, reused only by the same
study (settings and code), a half-written last line ignored. Pure file tests; the interrupted
study itself is in ``tests/test_study.py``."""
from __future__ import annotations

import pytest

from platebench.bench.run.journal import StudyJournal, code_digest, journal_path
from platebench.errors import UserValueError

HEADER = {"version": "1", "code": "abc", "spp": 2, "bends_deg": [60.0, 120.0]}


def _interrupted(out, rows=2, torn=True):
    j = StudyJournal(out, HEADER)
    assert j.start(resume=False, overwrite=False) == {}
    for k in range(rows):
        j.record(f"key{k}", {"case": f"plate {k}", "value": k + 0.1})
    j.close(remove=False)
    if torn:  # the line a killed process was writing
        with open(journal_path(out), "a") as f:
            f.write('{"key": "key9", "row": {"ca')


def test_a_resumed_journal_gives_back_its_finished_rows_and_keeps_appending(tmp_path):
    out = tmp_path / "st"
    _interrupted(out)
    j = StudyJournal(out, dict(HEADER))
    rows = j.start(resume=True, overwrite=False)
    assert rows == {"key0": {"case": "plate 0", "value": 0.1}, "key1": {"case": "plate 1", "value": 1.1}}
    j.record("key2", {"case": "plate 2", "value": 2.1})
    j.close(remove=False)
    assert set(StudyJournal(out, HEADER).read()[1]) == {"key0", "key1", "key2"}
    StudyJournal(out, HEADER).close(remove=True)
    assert not journal_path(out).exists()


@pytest.mark.parametrize("change, message", [({"spp": 4}, "other settings (spp: 2 there, 4 now)"),
                                             ({"bends_deg": [60.0]}, "other settings (bends_deg"),
                                             ({"code": "abd"}, "written by other code")])
def test_a_journal_of_another_study_is_refused(tmp_path, change, message):
    out = tmp_path / "st"
    _interrupted(out)
    with pytest.raises(UserValueError, match="--overwrite to start again") as e:
        StudyJournal(out, {**HEADER, **change}).start(resume=True, overwrite=False)
    assert message in str(e.value)


def test_a_leftover_journal_is_refused_without_resume_and_replaced_with_overwrite(tmp_path):
    out = tmp_path / "st"
    _interrupted(out, rows=3)
    with pytest.raises(UserValueError, match="holds 3 finished plates of an interrupted study"):
        StudyJournal(out, HEADER).start(resume=False, overwrite=False)
    j = StudyJournal(out, HEADER)
    assert j.start(resume=False, overwrite=True) == {}
    j.close(remove=False)
    assert StudyJournal(out, HEADER).read() == (HEADER, {})


def test_the_code_digest_is_the_package_source_and_stable():
    d = code_digest()
    assert len(d) == 40 and d == code_digest()


def test_only_a_torn_last_line_gets_a_newline(tmp_path):
    out = tmp_path / "st"
    _interrupted(out, rows=1, torn=False)
    before = journal_path(out).read_text()
    j = StudyJournal(out, HEADER)
    j.start(resume=True, overwrite=False)
    j.close(remove=False)
    assert journal_path(out).read_text() == before  # nothing added to a clean journal
