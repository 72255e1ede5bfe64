"""Messages that name the real problem, and printing that never fails a command: a PFM longer than its
header, a lens checked at the size asked for, a full disk under the lock, standard output that cannot
be written, a name the terminal's encoding cannot show, a name that is not UTF-8."""
from __future__ import annotations

import errno
import os
import subprocess
import sys

import numpy as np
import pytest

from tests.conftest import REPO, run_cli

TINY = ("--width", "160", "--height", "120", "--spp", "1")


def _cli(args, cwd=REPO, env=None, stdout=subprocess.PIPE):
    """``platebench ARGS`` in a fresh process; arguments may be bytes (a file name as the OS gives it)."""
    e = {**os.environ, "PLATEBENCH_DEBUG": "", **(env or {})}
    return subprocess.run([sys.executable, "-m", "platebench.bench.cli.main", *args], cwd=cwd, env=e,
                          stdout=stdout, stderr=subprocess.PIPE, timeout=600)


# ----------------------------------------------------------------------------- PFM
def _pfm(path, declared_wh, values: int) -> None:
    w, h = declared_wh
    path.write_bytes(f"Pf\n{w} {h}\n-1\n".encode() + np.zeros(values, "<f4").tobytes())


def test_a_pfm_longer_than_its_header_is_called_longer_not_truncated(tmp_path):
    from platebench.bench.io.images import DatasetError, read_pfm

    _pfm(tmp_path / "long.pfm", (4, 3), 24)
    with pytest.raises(DatasetError) as e:
        read_pfm(tmp_path / "long.pfm")
    text = str(e.value)
    assert "longer than its header declares" in text and "truncated" not in text and "\n" not in text
    assert "96 bytes of data" in text and "48 bytes" in text  # what the file holds, what the header says
    _pfm(tmp_path / "short.pfm", (4, 3), 6)
    with pytest.raises(DatasetError, match=r"truncated PFM \(24 of 48 bytes"):
        read_pfm(tmp_path / "short.pfm")
    _pfm(tmp_path / "ok.pfm", (4, 3), 12)
    assert read_pfm(tmp_path / "ok.pfm").shape == (3, 4)


# ----------------------------------------------------------------------------- lens at the size asked for
def test_the_lens_is_checked_and_named_at_the_size_asked_for(tmp_path):
    """A configuration's lens is checked at --width x --height, not at the file's (default) size: a
    lens that folds over only in the wider field of 1280 x 960 px is accepted at 160 x 120 with the
    file's focal length, and a lens that folds at the size asked for is refused naming that size."""
    from platebench.bench.config.sample_config import ConfigError
    from platebench.bench.io.config_files import load_config

    narrow = tmp_path / "narrow.toml"  # f fixed: 160 x 120 px see a tenth of the field 1280 x 960 px see
    narrow.write_text("[scene]\nf_px = 2000.0\n[scene.distortion]\nk1 = -5.0\n")
    with pytest.raises(ConfigError, match="1280x960"):
        load_config(narrow)
    assert load_config(narrow, 160, 120).scene.width == 160
    folds = tmp_path / "folds.toml"  # f scales with the width: the same field at every size
    folds.write_text("[scene.distortion]\nk1 = -5.0\n")
    p = run_cli("render", "--config", folds, *TINY, "--out", tmp_path / "s")
    assert p.returncode == 2, p.stderr
    line = p.stderr.strip().splitlines()[-1]
    assert "160x120" in line and "1280x960" not in line and "Traceback" not in p.stderr
    assert not (tmp_path / "s").exists()


# ----------------------------------------------------------------------------- the lock on a full disk
def test_a_full_disk_while_taking_the_lock_names_the_lock_file(tmp_path, monkeypatch):
    from platebench.bench.cli.main import _one_line
    from platebench.bench.io import atomic

    def full(fd, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    lock = atomic.OutputLock(tmp_path / "out")
    with monkeypatch.context() as m:
        m.setattr(atomic.os, "write", full)
        with pytest.raises(OSError) as e:
            lock.acquire()
    assert e.value.errno == errno.ENOSPC and e.value.filename == str(lock.path)
    assert _one_line(e.value) == f"{lock.path}: no space left on device"
    assert not lock.held and not lock.path.exists()  # no lock file left behind
    with atomic.OutputLock(tmp_path / "out") as again:  # and the next run takes it
        assert again.held


# ----------------------------------------------------------------------------- names and printing
def test_a_name_that_is_not_utf8_is_refused_before_any_work(tmp_path):
    p = _cli(["render", "--out", b"out\xff", *TINY], cwd=tmp_path)
    err = p.stderr.decode("utf-8", "backslashreplace").strip().splitlines()
    assert p.returncode == 2 and len(err) == 1, err
    assert "not UTF-8 text" in err[0] and "out\\xff" in err[0] and "allowed" in err[0]
    assert os.listdir(tmp_path) == []  # nothing written, not even a lock


@pytest.mark.render
def test_a_name_the_terminal_cannot_show_is_printed_escaped_and_the_output_stays(tmp_path):
    out = tmp_path / "sé"
    p = _cli(["render", "--out", out, *TINY], env={"LC_ALL": "C", "PYTHONIOENCODING": "ascii"})
    text = p.stdout.decode("ascii")  # ascii it is: the name's é went out as an escape
    assert p.returncode == 0, p.stderr.decode(errors="replace")
    assert "s\\xe9" in text and "UnicodeEncodeError" not in p.stderr.decode(errors="replace")
    assert (out / "sample.json").is_file()


@pytest.mark.render
@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full")
def test_a_summary_that_cannot_be_printed_keeps_the_output_and_the_status(tmp_path):
    """stdout on a full device: the sample is written and kept, the status is the work's (0), one note
    on stderr says the summary was not printed; it is no refusal (2)."""
    with open("/dev/full", "w") as full:
        p = _cli(["render", "--out", tmp_path / "s", *TINY], stdout=full)
    err = p.stderr.decode(errors="replace")
    assert p.returncode == 0, err
    assert "platebench: note: the summary was not printed" in err and "error" not in err.lower()
    assert (tmp_path / "s" / "sample.json").is_file()
