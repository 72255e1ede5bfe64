"""Fast checks of the reliability building blocks: bounded ranges, staged outputs and locks, owner-
tagged temporary names, a dataset killed before its first manifest."""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from platebench.bench.config.ranges import RangeError, expand_range, parse_range_text
from platebench.bench.io.atomic import (
    OutputExistsError,
    OutputLock,
    OutputLockedError,
    staged_output,
    sweep_stale,
    temp_owner,
)


@pytest.mark.parametrize("text, needle", [("0:1e12:1e-3", "1e+15 values: allowed at most 100000"),
                                          ("0:10:0", "step = 0.0"), ("0:inf:1", "stop = inf"),
                                          ("1,nan", "value = nan"), ("a:b", "START:STOP:STEP"),
                                          ("0:400:100", "400 is out of range: allowed 0 to 350")])
def test_ranges_are_counted_before_they_are_expanded(text, needle):
    with pytest.raises(RangeError) as e:
        parse_range_text(text, "--bend", 0, 350)
    assert needle in str(e.value) and str(e.value).startswith("--bend")


def test_ranges_include_the_stop_and_round():
    assert parse_range_text("0:180:20", "--bend", 0, 350) == [0, 20, 40, 60, 80, 100, 120, 140, 160, 180]
    assert expand_range("k", 0, 0.3, step=0.1) == [0.0, 0.1, 0.2, 0.3]
    assert expand_range("k", 0, 10, step=5, integers=True) == [0, 5, 10]
    assert parse_range_text("150,165", "--bend", 0, 350) == [150.0, 165.0]


def test_staged_output_replaces_only_when_complete_and_only_with_overwrite(tmp_path):
    target = tmp_path / "out"
    with staged_output(target) as d:
        (d / "a").write_text("1")
    with pytest.raises(OutputExistsError):
        with staged_output(target):
            raise AssertionError("no work may start")
    with pytest.raises(RuntimeError):
        with staged_output(target, overwrite=True) as d:
            (d / "a").write_text("2")
            raise RuntimeError("the work failed")
    assert (target / "a").read_text() == "1" and sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    with staged_output(target, overwrite=True) as d:
        (d / "b").write_text("3")
    assert sorted(p.name for p in target.iterdir()) == ["b"] and sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_a_held_lock_names_its_holder_and_a_dead_ones_is_taken_over(tmp_path):
    target = tmp_path / "ds"
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time; from platebench.bench.io.atomic import "
                               f"OutputLock; OutputLock({str(target)!r}).acquire(); print('held', flush=True); "
                               "time.sleep(60)"], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(OutputLockedError) as e:
            OutputLock(target).acquire()
        assert f"PID {holder.pid} on host {os.uname().nodename}" in str(e.value)
    finally:
        holder.kill()
        holder.wait()
    lock = OutputLock(target).acquire()  # the kernel released the dead holder's flock
    assert lock.stale["pid"] == holder.pid and "no longer running" in lock.stale_note()
    lock.release()
    assert not (tmp_path / ".ds.lock").exists()


def test_stale_temporary_names_of_dead_owners_are_swept_live_ones_kept(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    dead_pid = int(dead.stdout)
    host = os.uname().nodename
    (tmp_path / f".tmp-x~{host}~{dead_pid}~ab12").mkdir()
    (tmp_path / f".tmp-x~{host}~{os.getpid()}~cd34").mkdir()
    (tmp_path / f".f.json~{host}~{dead_pid}~ef56.tmp").write_text("half")
    assert temp_owner(f".tmp-x~{host}~{dead_pid}~ab12") == (host, dead_pid)
    assert sweep_stale(tmp_path) == 2
    assert [p.name for p in tmp_path.iterdir()] == [f".tmp-x~{host}~{os.getpid()}~cd34"]


def test_an_existing_empty_folder_takes_a_sweep_and_a_folder_with_files_does_not(tmp_path):
    """An empty folder (a mount point made for the dataset) holds nothing to lose: the sweep writes
    into it. A folder with anything in it needs --resume or --overwrite."""
    from platebench.bench.sweep.dataset import DatasetLayoutError, check_dataset
    from platebench.bench.sweep.spec import parse_spec
    spec = parse_spec({"base": {"scene": {"width": 64, "height": 48}}, "grid": {"bend_deg": [0]}})
    out = tmp_path / "ds"
    assert check_dataset(out, spec, resume=False, overwrite=False) is None  # new: created by the sweep
    out.mkdir()
    assert check_dataset(out, spec, resume=False, overwrite=False) is None
    (out / "notes.txt").write_text("mine")
    with pytest.raises(DatasetLayoutError, match="already exists"):
        check_dataset(out, spec, resume=False, overwrite=False)
    assert (out / "notes.txt").read_text() == "mine"


def test_a_sweep_killed_before_its_first_manifest_can_be_resumed(tmp_path):
    from platebench.bench.sweep.dataset import check_dataset
    from platebench.bench.sweep.spec import parse_spec
    spec = parse_spec({"base": {"scene": {"width": 64, "height": 48}}, "grid": {"bend_deg": [0]}})
    out = tmp_path / "ds"
    (out / "samples" / f".tmp-0000~{os.uname().nodename}~1~aa").mkdir(parents=True)
    (out / "results.csv").write_text("sample_id\n")
    assert check_dataset(out, spec, resume=True, overwrite=False) is None
    (out / "samples" / "0000").mkdir()
    (out / "samples" / "0000" / "result.json").write_text(json.dumps({}))
    with pytest.raises(Exception, match="no valid manifest.json"):
        check_dataset(out, spec, resume=True, overwrite=False)
