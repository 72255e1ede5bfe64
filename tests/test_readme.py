"""README's code runs as written: its Python blocks are taken from README.md itself and run as a user
runs them (``python my_script.py`` in a folder holding ``examples/``, the plug-in as a module on the
path), its TOML parses, and every ``platebench`` command line of its shell blocks is accepted by
the command's parser. So README and the product cannot drift apart.

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


def readme_blocks(lang: str) -> list[str]:
    return [body for kind, body in FENCE.findall((REPO / "README.md").read_text()) if kind == lang]


def _run(args, cwd, timeout=900, **env):
    e = {**os.environ, "MPLBACKEND": "Agg", "PLATEBENCH_DEBUG": "", **env}
    return subprocess.run(args, cwd=cwd, env=e, capture_output=True, text=True, timeout=timeout)


def test_readme_has_the_blocks_this_test_runs():
    py = readme_blocks("python")
    assert len(py) == 3, [b.splitlines()[0] for b in py]
    assert "platebench.sweep(" in py[0] and py[1].startswith("# my_method.py") and "PlateBenchDataset(" in py[2]
    for block in (py[0], py[2]):  # scripts: their work is under the main guard
        assert 'if __name__ == "__main__":' in block


@pytest.mark.slow
@pytest.mark.render
def test_readme_python_blocks_run_as_written(tmp_path):
    api, plugin, reader = readme_blocks("python")
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


def test_readme_toml_blocks_parse():
    blocks = readme_blocks("toml")
    assert blocks
    for b in blocks:
        tomllib.loads(b)


def _command_lines() -> list[list[str]]:
    out = []
    for block in readme_blocks("sh"):
        for line in block.splitlines():
            line = line.split(" #")[0].strip()
            if not line.startswith("platebench ") or re.search(r"\[|COMMAND", line):
                continue
            out.append(shlex.split(line)[1:])
    return out


def test_readme_command_lines_are_accepted_by_their_parsers():
    lines = _command_lines()
    assert len(lines) >= 30
    bad = []
    for argv in lines:
        try:
            build_parser(argv).parse_args(argv)
        except SystemExit:
            bad.append(" ".join(argv))
    assert not bad, "README command lines the parser refuses:\n" + "\n".join(bad)


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
