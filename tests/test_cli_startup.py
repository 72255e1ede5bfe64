"""`platebench` answers --help and refuses a bad flag, configuration or path without importing the work's
heavy modules (trimesh, SciPy, pandas, Matplotlib, Mitsuba): each command imports them where it uses them,
and only the command named on the line gets its whole sub-parser (``bench.cli.main.build_parser``)."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from platebench.bench.cli.main import COMMANDS, build_parser
from tests.conftest import REPO

HEAVY = ("trimesh", "scipy", "pandas", "matplotlib", "mitsuba", "drjit", "platebench.reconstruction.paper.pipeline",
         "platebench.scenes.render.renderer", "platebench.bench.report.plots")

PROBE = """
import json, sys
from platebench.bench.cli.main import main
try:
    rc = main(sys.argv[1:])
except SystemExit as e:
    rc = e.code
print(json.dumps({"rc": rc, "modules": sorted(sys.modules)}))
"""


def _loaded(*argv) -> tuple[int, set]:
    p = subprocess.run([sys.executable, "-c", PROBE, *map(str, argv)], cwd=REPO, capture_output=True, text=True,
                       timeout=120)
    doc = json.loads(p.stdout.strip().splitlines()[-1])
    return doc["rc"], {m for m in doc["modules"] if any(m == h or m.startswith(h + ".") for h in HEAVY)}


def test_top_level_help_is_the_same_with_every_sub_parser_built():
    # each command's line comes from its HELP (stub) or from its add_parser (built): they must agree
    full = build_parser().format_help()
    assert build_parser([]).format_help() == full
    assert all(f"    {name}" in full for name in COMMANDS)


@pytest.mark.parametrize("argv, rc", [
    (("--help",), 0),
    (("render", "--help"), 0),
    (("reconstruct", "--help"), 0),
    (("evaluate", "--help"), 0),
    (("sweep", "--help"), 0),
    (("render", "--out", "{tmp}/s", "--width", "10"), 2),
    (("render", "--config", "{tmp}/none.toml", "--out", "{tmp}/s"), 2),
    (("reconstruct", "{tmp}/nothing", "--out", "{tmp}/r"), 2),
    (("evaluate", "{tmp}/nothing", "{tmp}/r"), 2),
    (("demo", "--quick", "--out", "{tmp}/file", "--overwrite"), 2),
])
def test_help_and_bad_input_import_nothing_heavy(tmp_path, argv, rc):
    (tmp_path / "file").write_text("x")
    got, heavy = _loaded(*(a.replace("{tmp}", str(tmp_path)) for a in argv))
    assert got == rc
    assert not heavy, sorted(heavy)
