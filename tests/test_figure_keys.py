"""Figures cross module boundaries as typed records, not as dicts of loose keys.

A *read of a figure key by string* is a subscript load ``x["..."]`` or a call ``x.get("...")`` whose
constant string key ends in a unit suffix (``_mm``, ``_m``, ``_s``, ``_px``, ``_pct``, ``_frac``,
``_deg``, ``_rad``) or starts with ``false_boundary``. Writes (``x["k_mm"] = v``) and dict literals
are not reads and are not counted.

Scanned: every ``.py`` file of the package (``plates``, ``scenes``, ``reconstruction``,
``evaluation``, ``bench`` and the root modules) except ``bench/io/``, which is the file boundary
where records meet their on-disk dicts. ``tests/`` and ``tools/`` are outside the package and not
scanned.

A record's codec is the file boundary wherever the record lives, so a pure codec's reads are exempt:
the reads inside the ``return`` statement of a method named ``to_dict`` or ``from_dict`` defined in a
class body, where each value read flows straight into the object the method returns. (The science
packages' types, such as a calibration or a plate, have their codecs in ``bench/io/codecs/``, which
is exempt.) A read anywhere else in such a method (an assignment, a
condition, a loop) is counted like any other, as is every read in a function of another name or in
a module-level function.

The limit is ``MAX_FIGURE_KEY_READS``; the failure message lists every offending read.
"""
from __future__ import annotations

import ast
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PACKAGE_DIRS = ("plates", "scenes", "reconstruction", "evaluation", "bench")
ROOT_MODULES = ("__init__", "__main__", "api", "errors", "tolerances", "version")
EXEMPT_DIRS = (("bench", "io"),)
UNIT_SUFFIXES = ("_mm", "_m", "_s", "_px", "_pct", "_frac", "_deg", "_rad")
MAX_FIGURE_KEY_READS = 3
CODEC_NAMES = ("to_dict", "from_dict")


def is_figure_key(key: object) -> bool:
    """True for a string key that names a figure: a unit suffix or the false-boundary prefix."""
    return isinstance(key, str) and (key.endswith(UNIT_SUFFIXES) or key.startswith("false_boundary"))


def _key_of(node: ast.AST) -> str | None:
    """The figure key ``node`` reads by string, or None."""
    if isinstance(node, ast.Subscript) and isinstance(node.ctx, ast.Load):
        key = node.slice
        if isinstance(key, ast.Constant) and is_figure_key(key.value):
            return key.value
    elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "get"
          and node.args and isinstance(node.args[0], ast.Constant) and is_figure_key(node.args[0].value)):
        return node.args[0].value
    return None


def _codec_returns(tree: ast.AST) -> set[int]:
    """ids of every node inside the ``return`` statements of a pure codec's method (module doc)."""
    inside = set()
    for cls in ast.walk(tree):
        if not isinstance(cls, ast.ClassDef):
            continue
        for fn in cls.body:
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)) and fn.name in CODEC_NAMES:
                for ret in ast.walk(fn):
                    if isinstance(ret, ast.Return):
                        inside.update(id(n) for n in ast.walk(ret))
    return inside


def figure_key_reads(source: str) -> list[tuple[int, str]]:
    """(line, key) of every read of a figure key by string in Python ``source`` (pure codecs exempt)."""
    tree = ast.parse(source)
    exempt = _codec_returns(tree)
    out = [(node.lineno, key) for node in ast.walk(tree)
           if (key := _key_of(node)) is not None and id(node) not in exempt]
    return sorted(out)


def product_files() -> list[Path]:
    """The package's Python files that are scanned (everything but the file boundary ``bench/io``)."""
    files = [REPO / f"{m}.py" for m in ROOT_MODULES]
    for d in PACKAGE_DIRS:
        for p in sorted((REPO / d).rglob("*.py")):
            rel = p.relative_to(REPO).parts
            if not any(rel[:len(e)] == e for e in EXEMPT_DIRS):
                files.append(p)
    return files


def scan() -> dict[str, list[tuple[int, str]]]:
    """Relative path -> reads of figure keys in that file (files without any are left out)."""
    out = {}
    for p in product_files():
        reads = figure_key_reads(p.read_text())
        if reads:
            out[str(p.relative_to(REPO))] = reads
    return out


def test_the_checker_counts_a_planted_read():
    planted = ('def f(res, row):\n'
               '    a = res["timings_s"]["render_s"]\n'
               '    b = row.get("rms_mm", 0.0)\n'
               '    c = row["false_boundary"]\n'
               '    row["written_mm"] = a\n'
               '    d = {"literal_mm": 1}\n'
               '    e = row["name"], row.get("label")\n')
    assert figure_key_reads(planted) == [(2, "render_s"), (2, "timings_s"), (3, "rms_mm"),
                                         (4, "false_boundary")]


def test_a_codec_is_exempt_only_where_its_reads_flow_into_what_it_returns():
    planted = ('class A:\n'
               '    @classmethod\n'
               '    def from_dict(cls, d):\n'
               '        if d.get("gap_mm") is None:\n'
               '            raise ValueError("no gap")\n'
               '        return cls(d["gap_mm"], float(d.get("depth_mm", 0.0)))\n'
               '    def other(self, d):\n'
               '        return d["gap_mm"]\n'
               'def from_dict(d):\n'
               '    return d["size_px"]\n')
    assert figure_key_reads(planted) == [(4, "gap_mm"), (8, "gap_mm"), (10, "size_px")]


def test_the_scan_sees_the_package_but_not_the_file_boundary():
    files = {str(p.relative_to(REPO)) for p in product_files()}
    assert "bench/sweep/tasks.py" in files and "evaluation/score.py" in files
    assert not any(f.startswith("bench/io/") for f in files)


def over_the_limit(found: dict) -> str | None:
    """The failure message when ``found`` (file -> reads) holds more than ``MAX_FIGURE_KEY_READS``; else None."""
    total = sum(map(len, found.values()))
    if total <= MAX_FIGURE_KEY_READS:
        return None
    per_file = Counter({f: len(r) for f, r in found.items()})
    listing = "\n".join(f"{f}:{line}  {key!r}" for f in sorted(found) for line, key in found[f])
    summary = "\n".join(f"{n:4d}  {f}" for f, n in per_file.most_common())
    return (f"{total} reads of figure keys by string outside bench/io (limit {MAX_FIGURE_KEY_READS}); "
            f"read a record's field instead:\n{summary}\n{listing}")


def test_a_planted_violation_fails_the_limit():
    one_more = {"planted.py": figure_key_reads("\n".join(f'x = r["k{i}_mm"]' for i in range(MAX_FIGURE_KEY_READS + 1)))}
    assert over_the_limit(one_more) is not None
    assert over_the_limit({"planted.py": one_more["planted.py"][:MAX_FIGURE_KEY_READS]}) is None


def test_figure_keys_are_read_by_string_at_most_the_limit():
    message = over_the_limit(scan())
    assert message is None, message
