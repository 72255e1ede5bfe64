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
