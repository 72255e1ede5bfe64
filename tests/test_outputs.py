"""The output rule (bench/io/outputs.py) on every command: nothing the user did not hand over is replaced.

Each command's --out is tried against a user's folder (--overwrite), the working directory, the
file-system root, its own input (equal, inside, holding; relative, absolute, trailing-slash, '..'
and linked spellings), a link, a file where a folder goes and a folder where a file goes; what was
there must be byte for byte what it was. The commands run in this process (``main``): every refusal
comes before any render, so no test here renders.
"""
from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import pytest

from platebench.bench.cli.main import main
from platebench.bench.io.atomic import write_bytes
from platebench.bench.io.outputs import (
    STAMP,
    OutputRefusedError,
    check_output,
    foreign_entries,
    output_dir,
    write_stamp,
)

TINY = ["--width", "64", "--height", "48", "--spp", "1"]
SPEC = "[sweep]\nname = \"t\"\n[base.scene]\nwidth = 64\nheight = 48\n[grid]\nbend_deg = [0]\n"


def tree(root: Path) -> dict:
    """relative path -> sha256 (files) or 'dir', links as their target text: what must not change."""
    out = {}
    for dirpath, dirnames, filenames in os.walk(root):
        for name in dirnames + filenames:
            p = Path(dirpath) / name
            rel = str(p.relative_to(root))
            out[rel] = ("link:" + os.readlink(p)) if p.is_symlink() else (
                "dir" if p.is_dir() else hashlib.sha256(p.read_bytes()).hexdigest())
    return out


def run(capsys, *argv) -> tuple[int, str]:
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err
    return code, err


def one_line(code: int, err: str, *needles: str) -> None:
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and lines[0].startswith("platebench: error: "), err
    for n in needles:
        assert n in lines[0], (n, lines[0])
    assert "~" not in lines[0] and ".tmp" not in lines[0], lines[0]  # never a staging name


@pytest.fixture
def place(tmp_path, monkeypatch):
    """A working directory holding what the commands read: a sample-like folder, a recon-like folder,
    a spec, a config, and a user's folder 'victim'."""
    monkeypatch.chdir(tmp_path)
    s = tmp_path / "s1"
    (s / "images").mkdir(parents=True)
    (s / "sample.json").write_text(json.dumps({"layout_version": 1, "config": {}, "images": {}}))
    (s / "images" / "left_passive.png").write_bytes(b"not really")
    r = tmp_path / "r1"
    r.mkdir()
    (r / "recon.json").write_text(json.dumps({"n_points": 0, "false_boundary": {}, "input_checksums": {}}))
    (r / "points.csv").write_text("x,y,z\n")
    (tmp_path / "spec.toml").write_text(SPEC)
    (tmp_path / "cfg.toml").write_text("[scene]\nwidth = 64\nheight = 48\n")
    (tmp_path / "victim").mkdir()
    (tmp_path / "victim" / "precious.txt").write_text("mine")
    (tmp_path / "notes.txt").write_text("mine too")
    return tmp_path


COMMANDS = {  # command -> argv before --out (inputs as the fixture lays them out)
    "render": ["render", *TINY], "reconstruct": ["reconstruct", "s1"], "compare": ["compare", "s1"],
    "export": ["export", "s1", "--format", "middlebury"], "calibrate": ["calibrate", *TINY],
    "sense": ["sense", *TINY], "study": ["study", "false-boundary", "--limit", "1"],
    "sweep": ["sweep", "spec.toml", "--workers", "0"], "report": ["report", "s1"], "demo": ["demo", "--quick"],
}


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_overwrite_never_replaces_a_users_folder(place, capsys, command):
    before = tree(place)
    code, err = run(capsys, *COMMANDS[command], "--out", "victim", "--overwrite")
    one_line(code, err, "victim", "precious.txt")
    assert tree(place) == before


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_no_command_replaces_the_working_directory(place, capsys, command):
    (place / "sub").mkdir()
    before = tree(place)
    for out, cwd in ((".", place), ("..", place / "sub"), (str(place), place)):
        os.chdir(cwd)
        argv = [str(place / a) if (place / a).exists() else a for a in COMMANDS[command]]  # inputs absolute
        code, err = run(capsys, *argv, "--out", out, "--overwrite")
        one_line(code, err, "working directory")
    assert tree(place) == before


@pytest.mark.parametrize("argv, needle", [
    (["reconstruct", "s1", "--out", "s1", "--overwrite"], "is the input s1"),
    (["reconstruct", "s1", "--out", "s1/images", "--overwrite"], "is inside the input s1"),
    (["reconstruct", "s1", "--out", "s1/", "--overwrite"], "is the input"),
    (["reconstruct", "./s1", "--out", "victim/../s1", "--overwrite"], "is the input"),
    (["reconstruct", "{abs}/s1", "--out", "s1", "--overwrite"], "is the input"),
    (["reconstruct", "s1", "--out", "{abs}/s1/.", "--overwrite"], "is the input"),
    (["reconstruct", "link_to_s1", "--out", "s1", "--overwrite"], "is the input"),
    (["reconstruct", "s1", "--out", "linked_parent/s1", "--overwrite"], "is the input"),
    (["reconstruct", "s1", "--out", "{abs}", "--overwrite"], "working directory"),
    (["compare", "s1", "--out", "s1", "--overwrite"], "is the input s1"),
    (["compare", "s1", "--recon", "r1", "--out", "r1", "--overwrite"], "is the input r1"),
    (["export", "s1", "--format", "kitti", "--out", "s1/kitti"], "is inside the input s1"),
    (["export", "s1", "--format", "kitti", "--out", "s1", "--overwrite"], "is the input s1"),
    (["evaluate", "s1", "r1", "--out", "s1/sample.json"], "is inside the input s1"),
    (["evaluate", "s1", "r1", "--out", "s1"], "s1: is the input s1"),
    (["evaluate", "s1", "r1", "--out", "r1/points.csv", "--overwrite"], "is inside the input r1"),
    (["evaluate", "s1", "--points", "r1/points.csv", "--out", "r1/points.csv", "--overwrite"], "is the input"),
    (["evaluate", "s1", "--disparity", "s1/gt/disp0GT.pfm", "--out", "s1/gt/disp0GT.pfm"], "inside the input s1"),
    (["evaluate", "s1", "r1", "--out", "notes.txt"], "already exists"),
    (["evaluate", "s1", "r1", "--out", "notes.txt", "--overwrite"], "not a PlateBench score"),
    (["evaluate", "s1", "r1", "--out", "victim", "--overwrite"], "is a directory"),
    (["report", "s1", "--out", "s1", "--overwrite"], "is the input s1"),
    (["report", "s1", "--out", "s1/images", "--overwrite"], "is inside the input s1"),
    (["report", "s1", "--out", ".", "--overwrite"], "working directory"),
    (["sweep", "victim/spec.toml", "--out", "victim", "--overwrite"], "holds the input"),
    (["render", *TINY, "--config", "victim/cfg.toml", "--out", "victim", "--overwrite"], "holds the input"),
    (["render", *TINY, "--out", "link_to_s1", "--overwrite"], "symbolic link"),
    (["render", *TINY, "--out", "notes.txt", "--overwrite"], "not a directory"),
    (["render", *TINY, "--out", "notes.txt/s"], "notes.txt is a file, not a directory"),
    (["render", *TINY, "--out", "r1", "--overwrite"], "is a PlateBench reconstruction (recon.json), not a PlateBench "
                                                       "sample"),
    (["render", *TINY, "--out", "/", "--overwrite"], "file-system root"),
    (["perf", "reconstruct", "--json", "notes.txt"], "already exists"),
    (["perf", "variants", "--save", "notes.txt"], "ending in .npz"),
])
def test_an_output_never_replaces_an_input_or_what_is_not_ours(place, capsys, argv, needle):
    os.symlink(place / "s1", place / "link_to_s1")
    os.symlink(place, place / "linked_parent")
    (place / "victim" / "spec.toml").write_text(SPEC)
    (place / "victim" / "cfg.toml").write_text("[scene]\nwidth = 64\nheight = 48\n")
    before = tree(place)
    code, err = run(capsys, *[a.replace("{abs}", str(place)) for a in argv])
    one_line(code, err, needle)
    assert tree(place) == before


def test_overwrite_replaces_only_an_output_of_the_same_kind_that_holds_nothing_else(tmp_path):
    out = tmp_path / "o"
    with output_dir(out, "comparison") as d:
        (d / "compare.json").write_text(json.dumps({"methods": {}}))
        (d / "sub").mkdir()
        (d / "sub" / "x.bin").write_bytes(b"1")
    assert (out / STAMP).is_file() and foreign_entries(out, "comparison") == []
    with pytest.raises(OutputRefusedError, match="already exists"):
        check_output(out, "comparison")
    with pytest.raises(OutputRefusedError, match="is a PlateBench comparison .*not a PlateBench sample"):
        check_output(out, "sample", overwrite=True)
    check_output(out, "comparison", overwrite=True)  # ours: may be replaced
    # PlateBench outputs added later (a stamped report inside, a score JSON) keep it ours
    with output_dir(out / "report", "report") as d:
        (d / "index.html").write_text('<meta name="generator" content="platebench report">')
    (out / "sub" / "x.score.json").write_text(json.dumps({"method": "m", "kind": "depth", "score": {}, "units": ""}))
    assert foreign_entries(out, "comparison") == []
    # a user's file anywhere inside makes it foreign, named
    for rel in ("notes.txt", "sub/notes.txt", "report/notes.txt", "extra/deeper/notes.txt"):
        p = out / rel
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text("mine")
        with pytest.raises(OutputRefusedError, match=f"holds {rel}, which PlateBench did not write"):
            check_output(out, "comparison", overwrite=True)
        p.unlink()
    os.symlink("/etc/hostname", out / "sub" / "link")
    with pytest.raises(OutputRefusedError, match="holds sub/link"):
        check_output(out, "comparison", overwrite=True)
    (out / "sub" / "link").unlink()
    # a marker without a stamp (written by hand) is not enough
    (out / STAMP).unlink()
    with pytest.raises(OutputRefusedError, match="without the .* cannot be told"):
        check_output(out, "comparison", overwrite=True)
    # an empty folder may be replaced (nothing to lose), with --overwrite only
    (tmp_path / "empty").mkdir()
    with pytest.raises(OutputRefusedError, match="already exists"):
        check_output(tmp_path / "empty", "sample")
    check_output(tmp_path / "empty", "sample", overwrite=True)


def test_a_foreign_file_appearing_during_the_work_stops_the_swap(tmp_path):
    out = tmp_path / "o"
    with output_dir(out, "study") as d:
        (d / "study.json").write_text(json.dumps({"rows": []}))
    with pytest.raises(OutputRefusedError, match="late.txt"):
        with output_dir(out, "study", overwrite=True) as d:
            (d / "study.json").write_text(json.dumps({"rows": [1]}))
            (out / "late.txt").write_text("written by the user meanwhile")
    assert (out / "late.txt").read_text() == "written by the user meanwhile"
    assert json.loads((out / "study.json").read_text()) == {"rows": []}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o"]  # no staging folder, no lock


def test_a_users_file_where_a_lock_or_a_journal_goes_is_never_written_over(tmp_path):
    from platebench.bench.io.atomic import OutputLock, OutputLockedError
    from platebench.bench.run.journal import StudyJournal
    from platebench.errors import UserValueError

    (tmp_path / ".o.lock").write_text("my notes")
    with pytest.raises(OutputLockedError, match="not a platebench lock record"):
        OutputLock(tmp_path / "o").acquire()
    os.symlink(tmp_path / "target.txt", tmp_path / ".p.lock")
    with pytest.raises(OutputLockedError, match="symbolic link"):
        OutputLock(tmp_path / "p").acquire()
    (tmp_path / "o.journal.jsonl").write_text("my notes\n")
    with pytest.raises(UserValueError, match="not a study journal"):
        StudyJournal(tmp_path / "o", {"v": 1}).start(resume=False, overwrite=True)
    assert (tmp_path / ".o.lock").read_text() == "my notes"
    assert (tmp_path / "o.journal.jsonl").read_text() == "my notes\n"
    assert not (tmp_path / "target.txt").exists()


def test_write_errors_name_the_target_never_the_temporary_file(tmp_path, capsys):
    (tmp_path / "adir").mkdir()
    with pytest.raises(IsADirectoryError) as e:
        write_bytes(tmp_path / "adir", b"x")
    assert e.value.filename == str(tmp_path / "adir")
    (tmp_path / "ro").mkdir()
    from platebench.bench.io.atomic import target_of_temp
    inner = tmp_path / ".tmp-report~host~12~ab12" / "thumbs" / ".a.png~host~12~cd34.tmp"
    assert target_of_temp(inner) == tmp_path / "report" / "thumbs" / "a.png"


def test_a_stamp_lists_every_file_with_its_checksum(tmp_path):
    d = tmp_path / "x"
    (d / "a").mkdir(parents=True)
    (d / "a" / "f.bin").write_bytes(b"abc")
    (d / "g.txt").write_text("g")
    write_stamp(d, "export")
    st = json.loads((d / STAMP).read_text())
    assert st["kind"] == "export" and st["files"] == {
        "a/f.bin": hashlib.sha256(b"abc").hexdigest(), "g.txt": hashlib.sha256(b"g").hexdigest()}
