"""README's code runs as written: its Python blocks are taken from README.md itself and run as a user
runs them (``python my_script.py`` in a folder holding ``examples/``, the plug-in as a module on the
path), its TOML parses, and every ``platebench`` command line of the shell blocks of README.md,
docs/*.md and docs/findings/*.md is accepted by the command's parser (a line starting with ``... ``
repeats the command above it with the options that follow). The guide's Python blocks are README's,
so they run too; README stays short (at most 200 lines). So the documents and the product cannot
drift apart.

A script that calls ``platebench.sweep`` at its top level, without the main guard, fails with the
reason: its spawned workers refuse to run the script again, and ``sweep`` raises instead of
returning over a dataset of failures."""
from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
import tomllib

import pytest

from platebench.bench.cli.main import build_parser
from tests.conftest import REPO

FENCE = re.compile(r"^```(\w*)\n(.*?)^```", re.M | re.S)


README_MAX_LINES = 200
DOCS = ("README.md", *sorted(p.relative_to(REPO).as_posix() for p in (REPO / "docs").glob("*.md")),
        *sorted(p.relative_to(REPO).as_posix() for p in (REPO / "docs" / "findings").glob("*.md")))


def doc_blocks(doc: str, lang: str) -> list[str]:
    return [body for kind, body in FENCE.findall((REPO / doc).read_text()) if kind == lang]


def readme_blocks(lang: str) -> list[str]:
    return doc_blocks("README.md", lang)


def readme_python_blocks() -> tuple[str, str, str]:
    """README's three Python blocks, found by what they are: the facade script, the plug-in, the reader."""
    py = readme_blocks("python")
    api = [b for b in py if "platebench.sweep(" in b]
    plugin = [b for b in py if b.startswith("# my_method.py")]
    reader = [b for b in py if "PlateBenchDataset(" in b and b not in api]
    assert len(py) == 3 and len(api) == len(plugin) == len(reader) == 1, [b.splitlines()[0] for b in py]
    return api[0], plugin[0], reader[0]


def _run(args, cwd, timeout=900, **env):
    e = {**os.environ, "MPLBACKEND": "Agg", "PLATEBENCH_DEBUG": "", **env}
    return subprocess.run(args, cwd=cwd, env=e, capture_output=True, text=True, timeout=timeout)


def test_readme_has_the_blocks_this_test_runs():
    api, _plugin, reader = readme_python_blocks()
    for block in (api, reader):  # scripts: their work is under the main guard
        assert 'if __name__ == "__main__":' in block


def test_readme_is_short():
    n = len((REPO / "README.md").read_text().splitlines())
    assert n <= README_MAX_LINES, f"README.md has {n} lines: at most {README_MAX_LINES} (the rest goes to docs/)"


def test_the_guides_python_blocks_are_readmes():
    # the guide shows README's blocks in full: the same text, so the run below checks both
    readme = set(readme_blocks("python"))
    guide = doc_blocks("docs/guide.md", "python")
    assert guide and all(b in readme for b in guide), [b.splitlines()[0] for b in guide if b not in readme]


@pytest.mark.slow
@pytest.mark.render
def test_readme_python_blocks_run_as_written(tmp_path):
    api, plugin, reader = readme_python_blocks()
    shutil.copytree(REPO / "examples", tmp_path / "examples")
    (tmp_path / "api_script.py").write_text(api)
    r = _run([sys.executable, "api_script.py"], tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert (tmp_path / "ds" / "report" / "index.html").is_file() and (tmp_path / "left_active.png").is_file()
    assert "4 samples ok" in r.stdout, r.stdout[-2000:]
    assert re.search(r"^\d+\s+0000\s+paper\s", r.stdout, re.M), r.stdout[-2000:]  # sample_id read as text

    (tmp_path / "reader_script.py").write_text(reader)
    r = _run([sys.executable, "reader_script.py"], tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]

    (tmp_path / "my_method.py").write_text(plugin)
    r = _run([sys.executable, "-m", "platebench", "compare", "ds/samples/0000/sample", "--methods",
              "my_method:my_matcher", "--out", "cmp"], tmp_path, PYTHONPATH=str(tmp_path))
    assert r.returncode == 0, r.stderr[-3000:]
    assert "my_method:my_matcher" in (tmp_path / "cmp" / "compare.json").read_text()


@pytest.mark.parametrize("doc", DOCS)
def test_toml_blocks_parse(doc):
    if doc == "README.md":
        assert readme_blocks("toml")
    for b in doc_blocks(doc, "toml"):
        tomllib.loads(b)


TIMED = "/usr/bin/time -v "


def _commands_of(text: str) -> list[list[str]]:
    """argv (without the program) of every ``platebench`` line of the text's shell blocks. A line
    ``... ARGS`` is the command line above it with ARGS appended (argparse: a later option replaces an
    earlier one); ``/usr/bin/time -v`` before a command is the timing, not the command."""
    out = []
    for kind, block in FENCE.findall(text):
        if kind != "sh":
            continue
        last = None
        for line in block.splitlines():
            line = line.split(" #")[0].strip()
            line = line[len(TIMED):] if line.startswith(TIMED) else line
            if re.search(r"\[|COMMAND", line):
                continue
            if line.startswith("platebench "):
                last = shlex.split(line)[1:]
            elif line.startswith("... ") and last is not None:
                last = last + shlex.split(line[4:])
            else:
                continue
            out.append(last)
    return out


def _command_lines(doc: str = "README.md") -> list[list[str]]:
    return _commands_of((REPO / doc).read_text())


def test_the_documents_show_commands():
    assert len(_command_lines("README.md")) >= 10
    assert sum(len(_command_lines(doc)) for doc in DOCS) >= 60


@pytest.mark.parametrize("doc", DOCS)
def test_command_lines_are_accepted_by_their_parsers(doc):
    bad = []
    for argv in _command_lines(doc):
        try:
            build_parser(argv).parse_args(argv)
        except SystemExit:
            bad.append(" ".join(argv))
    assert not bad, f"{doc}: command lines the parser refuses:\n" + "\n".join(bad)


def test_a_continuation_line_repeats_the_command_above():
    text = ("```sh\n/usr/bin/time -v platebench study false-boundary --out st   # timed\n... --seed 2 --out st2\n"
            "make demo\n```\n")
    assert _commands_of(text) == [["study", "false-boundary", "--out", "st"],
                                  ["study", "false-boundary", "--out", "st", "--seed", "2", "--out", "st2"]]


UNGUARDED = """
import platebench
platebench.sweep("tiny.toml", "ds", workers=1)
print("returned normally")
"""

TINY = """
[sweep]
name = "tiny"
methods = ["paper"]
[base.scene]
width = 160
height = 120
[base.render]
spp = 1
[grid]
bend_deg = [0]
"""


@pytest.mark.slow
def test_a_script_without_the_main_guard_fails_with_the_reason(tmp_path):
    (tmp_path / "tiny.toml").write_text(TINY)
    (tmp_path / "script.py").write_text(UNGUARDED)
    r = _run([sys.executable, "script.py"], tmp_path, timeout=600)
    assert r.returncode != 0 and "returned normally" not in r.stdout
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("platebench.errors.SamplesFailedError: sweep ds: 1 of 1 samples failed"), last
    assert 'if __name__ == "__main__":' in last
    # each worker said why it stopped: the call while it imported the script
    assert "WorkerImportError: platebench.sweep() was called while a worker process imported" in r.stderr
    # the dataset says so too
    assert '"failed": 1' in (tmp_path / "ds" / "manifest.json").read_text()


def test_readme_and_demo_help_give_the_same_demo_time():
    from platebench.bench.cli.demo import DEMO_TIME
    demo_line = next(ln for ln in readme_blocks("sh")[0].splitlines() if ln.startswith("make demo"))
    assert DEMO_TIME in demo_line, (DEMO_TIME, demo_line)
    help_text = " ".join(build_parser(["demo"])._subparsers._group_actions[0].choices["demo"].format_help().split())
    assert DEMO_TIME in help_text
