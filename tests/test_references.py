"""The repository documents itself: every file path and module named in ``--help``, in ``examples/``,
in docstrings, comments, README and ``docs/`` exists in the repository (nothing points outside it);
every flag of every command says what it does; and the product states its definitions in its own
words (no history of how it was made in its output, files or documentation)."""
from __future__ import annotations

import argparse
import ast
import importlib
import io
import os
import re
import tokenize
from functools import cache
from pathlib import Path

import pytest

from platebench.bench.cli.main import build_parser
from tests.conftest import REPO

TOP = ("bench", "docs", "evaluation", "examples", "plates", "reconstruction", "scenes", "tests", ".ci")
PACKAGES = ("bench", "evaluation", "plates", "reconstruction", "scenes")
_SKIP_PARTS = {".venv", ".git", "__pycache__", "out", "platebench.egg-info"}
PATH_RE = re.compile(r"(?<![\w/.$~-])((?:\.\./)+[\w.-]+(?:/[\w.*<>{}-]*)*|(?:\.ci|[A-Za-z_][\w.-]*)(?:/[\w.*<>{}-]+)+/?"
                     r"|[\w-]+\.(?:py|md))(?![\w/])")
MODULE_RE = re.compile(r"(?<![\w./])((?:platebench\.)?(?:" + "|".join(PACKAGES) + r")(?:\.\w+)+)")


def _files(suffixes) -> list[Path]:
    return [p for p in _all_files() if p.suffix in suffixes]


@cache
def _all_files() -> tuple[Path, ...]:
    """Every file of the checkout, sorted, without descending into ``_SKIP_PARTS`` (the virtual
    environment alone holds tens of thousands of files)."""
    out = []
    for dirpath, dirnames, filenames in os.walk(REPO):
        dirnames[:] = [d for d in dirnames if d not in _SKIP_PARTS]
        out += [Path(dirpath) / f for f in filenames]
    return tuple(sorted(p for p in out if p.is_file()))


@cache
def _file_names() -> frozenset:
    return frozenset(p.name for p in _files({".py", ".md"}))


def _python_prose(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every docstring and comment of a Python file."""
    src = path.read_text()
    out = []
    for node in ast.walk(ast.parse(src)):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and node.body:
            first = node.body[0]
            if isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant) \
                    and isinstance(first.value.value, str):
                out.append((first.lineno, first.value.value))
    for tok in tokenize.generate_tokens(io.StringIO(src).readline):
        if tok.type == tokenize.COMMENT:
            out.append((tok.start[0], tok.string))
    return out


def _parsers(parser: argparse.ArgumentParser, name: str = "platebench"):
    """(command name, parser) of the program and every sub-command, recursively."""
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub_name, sub in action.choices.items():
                yield from _parsers(sub, f"{name} {sub_name}")


def _help_texts() -> list[tuple[str, str]]:
    return [(f"'{name} --help'", p.format_help()) for name, p in _parsers(build_parser())]


def _prose() -> list[tuple[str, str]]:
    """(where, text) of everything a reader is shown: --help, examples/, docstrings and comments,
    README and docs/."""
    out = _help_texts()
    for p in _files({".toml", ".py", ".md", ".txt"}):
        rel = p.relative_to(REPO).as_posix()
        if rel.startswith("examples/") or p.suffix == ".md":
            out.append((rel, p.read_text()))
        elif p.suffix == ".py":
            out += [(f"{rel}:{line}", text) for line, text in _python_prose(p)]
    for p in _files({".html", ".css"}):
        out.append((p.relative_to(REPO).as_posix(), p.read_text()))
    return out


def _path_problem(token: str) -> str | None:
    if token.startswith("../"):
        return "points outside the repository"
    if "/" not in token:  # a bare file name: a module or a document of the repository
        if token.endswith(".md") or token.endswith(".py"):
            return None if token in _file_names() or token.startswith(("my_", "test_")) else "no such file in the repository"
        return None
    first = token.split("/")[0]
    if first not in TOP:
        return None  # an output's layout (SAMPLE/gt/..., ds/report/...), not a file of the repository
    pattern = re.sub(r"<[^>]*>", "*", token).replace("{", "").replace("}", "").rstrip("/")
    found = list(REPO.glob(pattern)) if "*" in pattern else [REPO / pattern] if (REPO / pattern).exists() else []
    return None if found else "no such path"


@cache
def _module(name: str):
    try:
        return importlib.import_module(name)
    except ImportError:
        return None


def _module_problem(token: str) -> str | None:
    parts = token.split(".")
    parts = parts[1:] if parts[0] == "platebench" else parts
    for k in range(len(parts), 0, -1):
        mod = _module("platebench." + ".".join(parts[:k]))
        if mod is not None:
            rest = parts[k:]
            if rest and not hasattr(mod, rest[0]):
                return f"platebench.{'.'.join(parts[:k])} has no {rest[0]!r}"
            return None
    return "no such module"


def test_every_path_and_module_named_to_a_reader_exists():
    stale = []
    for where, text in _prose():
        for m in PATH_RE.finditer(text):
            token = m.group(1).rstrip(".,;:)")
            problem = _path_problem(token)
            if problem:
                stale.append(f"{where}: {token} ({problem})")
        for m in MODULE_RE.finditer(text):
            problem = _module_problem(m.group(1).rstrip("."))
            if problem:
                stale.append(f"{where}: {m.group(1)} ({problem})")
    assert not stale, f"{len(stale)} stale references:\n" + "\n".join(stale)


def test_the_checker_finds_stale_references():
    # the rules above, on references that moved or point outside
    moved = "bench/" + "sweep_spec.py"  # in pieces: this file is scanned for stale paths too
    assert _path_problem(moved) and _path_problem("../shared/DESIGN.md")
    assert _path_problem("DESIGN.md") and _module_problem("bench.perf_sweep")
    assert _module_problem("platebench.scenes.mitsuba_convert")
    assert not _path_problem("bench/sweep/spec.py") and not _path_problem("docs/architecture.md")
    assert not _module_problem("platebench.scenes.render.mitsuba_convert") and not _path_problem("SAMPLE/gt/x.exr")
    assert not _path_problem("recon/<method>/") and not _path_problem("examples/*.toml")


def test_every_flag_of_every_command_says_what_it_does():
    bare = [f"{name} {'/'.join(a.option_strings) or a.dest}" for name, p in _parsers(build_parser())
            for a in p._actions if not isinstance(a, (argparse._HelpAction, argparse._VersionAction))
            and not (a.help and a.help.strip())]
    assert not bare, "flags without help text: " + ", ".join(bare)


# Words of the product's history, not of the product: what made it (a tracker of work items, a harness that
# is not in the repository, a person stopping a run) has no place in what users read.
# The words are written in pieces, so that this file, scanned like any other, does not say them itself.
TRACKER, HARNESS, STOPPED = "iss" + "ue", "dev " + "harness", "where I " + "stopped"
HISTORY = re.compile(rf"\b{TRACKER}s?\b|{HARNESS}|{STOPPED}|\bitems? \d+\b", re.IGNORECASE)


def test_the_product_speaks_of_itself_not_of_its_history():
    said = []
    for p in _files({".py", ".md", ".toml", ".html", ".css", ".txt"}) + [REPO / "Makefile", REPO / ".ci" / "run"]:
        rel = p.relative_to(REPO).as_posix()
        for i, line in enumerate(p.read_text().splitlines(), 1):
            if HISTORY.search(line):
                said.append(f"{rel}:{i}: {line.strip()[:120]}")
    assert not said, "\n".join(said)


@pytest.mark.parametrize("line", [f"cured, as the {TRACKER} counts it", f"the {TRACKER}'s targets", f"({HARNESS}, renders)",
                                  f"{TRACKER.title()} 13, it" "em 9: bad inputs", f"{STOPPED} that run"])
def test_history_words_are_caught(line):
    assert HISTORY.search(line)


# ----------------------------------------------------------------------------- docstrings state contracts
# A docstring or comment of the product says what the code does: its purpose, units, frames, array shapes, what
# it raises, and the source of a model's number. What a run measured, how the code came to be and the
# alternatives it rejected are findings: they live in docs/findings/ (the sensing loop's in
# docs/findings/design-record.md), each figure beside the command that reproduces it.
_NUM = r"[-+]?\d[\d,]*(?:\.\d+)?"
_UNIT = r"(?:%|mm|cm|um|µm|px|m|s|ms|deg|degrees?|cures?|plates?|points?|views?|poses?|outcomes?)"
NOTEBOOK = {
    "a past figure ('was N', 'were N')": r"\b(?:was|were)\s+(?:about\s+|~|≈)?[-+]?\d",
    "a figure set against the one before a change":
        rf"{_NUM}\s*{_UNIT}\s+before\b|\bbefore\s*\)|\b(?:until|before|without)\s+(?:this|the)\s+(?:rule|change|fix)\b",
    "a delta between figures ('N -> M')": r"\d\s*%?\s*(?:->|→|=>)\s*[-+~≈]?\d",
    "a measured time ('12.3 s', '8 min', 'took 3', '5x slower')":
        r"(?<![\w.-])(?<!<= )(?<!≤ )(?<!at most )(?<!within )(?<!limit )(?<!after )(?<!every )(?<!random )"
        r"\d+(?:\.\d+)?(?:\s*-\s*\d+(?:\.\d+)?)?\s*(?:s|ms|us|µs|min|mins|minutes?|seconds?|hours?|h|CPU-seconds?)"
        r"(?![\w+*/^])(?!\s*(?:at most|limit|timeout|by default))"
        r"|\btook\s+(?:about\s+|only\s+)?\d|\d\s*[x×]\s+(?:slower|faster)\b",
    "a measurement reported ('Measured on ...', '(measured: ...)', 'measured 0.2 px')":
        r"(?:^|[.(;]\s*|#\s*)(?-i:M)easured\s+(?:on|with|over|at|against|under|in)\b"
        r"|\(\s*measured\s*(?::|here\b)|\bmeasured\s+\d"
        r"|\bmeasured\s+(?:on|over|with|in|under)\s+(?:the\s+)?(?:false-boundary\s+)?"
        r"(?:study|\d+\s+(?:study\s+)?plates)\b",
    "a study result (a count out of a total, a rate of cured plates, what the study found)":
        r"\b\d+\s+of\s+(?:the\s+)?\d[\d,]*\b|\b(?:cured|alarms?|silent|verified|perturbed)\s+\d+\s*/\s*\d+"
        r"|\b(?:in|on)\s+the\s+study(?:'s\s+(?:renders|plates|runs|views|\d+\s+plates))?\b(?!')"
        r"|\bthe\s+study\s+found\b|\bstudy\s+plates\b|\bnot\s+traced\b",
    "a history word ('previously', 'used to be', 'no longer is', 'now gives', 'the first version')":
        r"\b(?:previously|formerly|originally)\b|\bused\s+to\s+(?:be|have|take|give|run|cost|read|fail|confirm|cure)\b"
        r"|\bno\s+longer\s+(?:is|are|does|do|needs?|uses?|takes?|gives?|counts?|applies|fails?)\b"
        r"|\bnow\s+(?:uses?|gives?|takes?|reads?|counts?|confirms?|cures?|runs?)\b|\bonce\s+had\b"
        r"|\b(?:an?|the|earlier|previous|older)\s+commit\b|\bthe\s+first\s+version\b",
}
NOTEBOOK_RE = {what: re.compile(p, re.IGNORECASE) for what, p in NOTEBOOK.items()}


def _notebook(text: str) -> list[str]:
    """What of ``NOTEBOOK`` a docstring or comment says (the text's line breaks read as spaces)."""
    flat = re.sub(r"\s*\n\s*", " ", text)
    return [f"{what}: ...{flat[max(0, m.start() - 40):m.end() + 20]}..." for what, r in NOTEBOOK_RE.items()
            for m in r.finditer(flat)]


def _prose_blocks(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every docstring of a Python file and of every run of comments on consecutive lines
    (a sentence may wrap from one comment line to the next)."""
    blocks, last = [], None
    for line, text in sorted(_python_prose(path)):
        if text.startswith("#") and last is not None and line == last + 1 and blocks[-1][1].startswith("#"):
            blocks[-1] = (blocks[-1][0], blocks[-1][1] + " " + text.lstrip("#").strip())
        else:
            blocks.append((line, text))
        last = line if text.startswith("#") else None
    return blocks


def _product_python() -> list[Path]:
    """The product's Python files: the package's modules and examples/ (not tests/, docs/ or tools)."""
    return [p for p in _files({".py"}) if p.relative_to(REPO).parts[0] in PACKAGES + ("examples",)
            or len(p.relative_to(REPO).parts) == 1]


def test_docstrings_and_comments_state_contracts_not_findings():
    said = [f"{p.relative_to(REPO)}:{line}: {hit}" for p in _product_python()
            for line, text in _prose_blocks(p) for hit in _notebook(text)]
    assert not said, ("move these to docs/findings/ and say the contract instead:\n" + "\n".join(said))


def test_the_notebook_guard_reads_docstrings_and_wrapped_comments(tmp_path):
    planted = tmp_path / "planted.py"
    planted.write_text(('"""A module.\n\nThe_fold_took_3_cures\n(was_7)."""\n\n'
                        "X = 1  #_merged_RMS_0.65_->_0.58_mm\nZ = 3\n"
                        "#_a_threshold_set_on_renders_(16_mm,_Measured\n#_on_the_study_with_the_lead_rule)\nY = 2\n"
                        ).replace("_", " "))  # "_" for each space of the planted prose (see below)
    hits = [(line, hit.split(":")[0]) for line, text in _prose_blocks(planted) for hit in _notebook(text)]
    assert {line for line, _ in hits} == {1, 6, 8}, hits  # the comment wrapped over lines 8-9 as one


# The planted findings are written with "_" for each space, so that this file holds none of them as
# prose; the test reads them with their spaces.
@pytest.mark.parametrize("text", [
    "(the_120-degree_fold_up:_3_cures,_was_7)", "the_S-curves_4_and_18_(were_14_and_18)",
    "``CAP``_12_(8_before)", "1.01_mm_on_a_fold,_1.23_mm_before_registration",
    "(two_cures_before)", "Until_this_rule,_the_turn_was_taken_about_the_3D_direction",
    "stray_points_2531_of_227,165_->_1285_of_216,738", "on_that_curl_105_->_5", "97.0_->_95.6_%_on_average",
    "RMS_median_0.65_→_0.58_mm", "polylines_take_about_0.1-0.3_s.", "(scipy.ndimage_takes_0.25_s_to_import)",
    "so_about_3_to_4_minutes_of_wall_time", "a_sample_takes_12.3_s", "8_min_on_2_cores",
    "it_costs_every_other_command_30-50_ms", "the_fold_took_1_cure", "it_is_also_about_5x_slower",
    "Measured_on_the_study:_a_baseline", "#_Measured_on_the_centres_of_a_170-degree_fold",
    "1/sqrt(spp)_(measured:_corner_error_0.10_px)", "measured_329_CPU-seconds_in_all",
    "measured_over_the_false-boundary_study's_61_plates", "(Measured_with_``platebench_study_false-boundary``",
    "6_of_31_plates_with_nothing_hidden", "cured_14/23_and_false_alarms_1/31", "a_silent_wrong_verdict_in_the_study.",
    "the_study_found_such_pieces", "Measured_on_3_study_plates", "by_1-3_outcomes,_a_difference_not_traced",
    "the_refinement_previously_ran_twice", "the_loop_used_to_take_cures_there", "the_planner_no_longer_needs_it",
    "the_verdict_now_confirms_corners", "The_planner's_model_once_had_a_membrane",
    "renders_cached_from_an_earlier_commit",
    "The_first_version_cut_the_rays_with_the_plane",
])
def test_the_notebook_guard_catches(text):
    text = text.replace("_", " ")
    assert _notebook(text), text


@pytest.mark.parametrize("text", [
    "World frame, metres, radians.", "spp 16 default", "the 1.0 mm tolerance (``tol.confirm_m``)", "in metres",
    "ABB IRB 1600, measured: \"unidirectional position repeatability better than 37 um\" (Slamani et al. 2012)",
    "a six-axis PUMA, measured against a CMM (0.02 mm)", "(N, 2) -> (N, 3) pixels", "name -> module exposing HELP",
    "0.5 -> '0_5', 1.0 -> '1_0'", "(2,) -> (3,)", "exits with status 2 before any work", "checked before any render",
    "the output rule before the first render", "wait (10 s at most each) until they are gone",
    "Target on a GPU: whole sample <= 0.15 s.", "the time limit, seconds (``timeout_s``)", "the measured outline",
    "corner noise measured on renders at the start of the run", "a trial that measured: the points measured",
    "Measured surface points (S,3) with unit normals", "a robot took the pair", "stretches no longer than LINK_M",
    "a working directory that no longer exists", "from now on a signal is recorded", "stop now",
    "every 30 degrees of azimuth at 20, 40 and 60 degrees", "exit status 130 / 143", "a 2/3-inch sensor",
    "the study's tables", "the false-boundary study's cylinders", "edge length used to fit the curves",
    "1/4000 of the shorter boundary", "(N, 2h+1, 2)", "``platebench study false-boundary`` (61 plates, 640 x 480)",
    "leftovers of earlier runs", "a file committed once", "the paper's 16 squares at 0.4 m",
    "each point's error (measured minus true, metres)", "then a random 0-6 s, then kill -9",
])
def test_the_notebook_guard_lets_contracts_pass(text):
    assert not _notebook(text), _notebook(text)


# ----------------------------------------------------------------------------- one source for each tolerance
def _package_sources() -> list[Path]:
    return [p for p in _files({".py"}) if p.relative_to(REPO).parts[0] not in ("tests", "docs")
            and p.name != "tolerances.py"]


def test_no_bare_tolerance_outside_tolerances_py():
    # a float below 1e-4 written inline (not a named module constant) is a tolerance without a name
    bare = []
    for p in _package_sources():
        tree = ast.parse(p.read_text())
        named = {id(c) for n in tree.body if isinstance(n, (ast.Assign, ast.AnnAssign)) for c in ast.walk(n)}
        bare += [f"{p.relative_to(REPO)}:{c.lineno}: {c.value!r}" for c in ast.walk(tree)
                 if isinstance(c, ast.Constant) and isinstance(c.value, float) and 0 < abs(c.value) < 1e-4
                 and id(c) not in named]
    assert not bare, "route these through platebench.tolerances.tol:\n" + "\n".join(bare)


def test_every_tolerance_is_used_and_none_is_retyped():
    from dataclasses import fields

    from platebench.tolerances import Tolerances
    names = [f.name for f in fields(Tolerances)]
    text = {p: p.read_text() for p in _package_sources()}
    unused = [n for n in names if not any(re.search(rf"\b(tol|TOL)\.{n}\b", t) for t in text.values())
              and not re.search(rf"\btol\.{n}\b", (REPO / "tolerances.py").read_text().split("tol = Tolerances()")[1])]
    assert not unused, f"fields of Tolerances used nowhere: {unused}"
    retyped = [f"{p.relative_to(REPO)}: {m.group(1)}" for p, t in text.items()
               for m in re.finditer(r"^_*([A-Z][A-Z0-9_]*)\s*[:=]", t, re.M) if m.group(1).lower() in names]
    assert not retyped, f"a tolerance defined again outside tolerances.py: {retyped}"
