"""``evaluation/`` owns all scoring (docs/architecture.md, "Layers"): read from the code, no module
outside it measures an estimate against ground truth or states a scoring statistic itself. Outside
``evaluation/`` no code

* ``distance``: calls trimesh's proximity queries or evaluation's point, mesh and polyline distance
  functions (the exact distances an error or an error map is made of);
* ``rms``: writes an RMS, ``sqrt(mean(x ** 2))`` or ``sqrt(mean(x * x))``;
* ``quantile``: calls ``quantile`` or ``percentile`` (numpy's, nan-aware ones too);
* ``bound``: defines the paper's bound (a name ``PAPER_..._MM``; ``evaluation.score`` holds it).

``reconstruction/`` is exempt from ``rms`` and ``quantile``: it never sees ground truth
(tests/test_layers.py), so its RMS values and quantiles are fit residuals and robust thresholds,
not scores. ``ALLOWED`` lists the few other places, each with its reason; the checker itself is
tested on planted sources.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
CHECKED_DIRS = ("plates", "scenes", "reconstruction", "bench")
ROOT_MODULES = ("__init__.py", "__main__.py", "api.py", "errors.py", "tolerances.py", "version.py")
RULES = ("distance", "rms", "quantile", "bound")
DISTANCE_FUNCTIONS = frozenset({"closest_point", "closest_point_on_mesh", "point_to_surface_distance",
                                "points_to_polyline_distance", "polyline_distance"})
QUANTILE_FUNCTIONS = frozenset({"quantile", "percentile", "nanquantile", "nanpercentile"})
BOUND_NAME = re.compile(r"^PAPER_\w*_MM$")
NO_GROUND_TRUTH = ("reconstruction/",)  # exempt from "rms" and "quantile" (module doc)

# (file, rule, enclosing function or None for anywhere in the file): why it is not scoring
ALLOWED = {
    ("bench/perf/benchmarks.py", "distance", "perf_score"):
        "times evaluation's exact distance search against trimesh's on the same points: a speed benchmark",
    ("bench/report/plots.py", "quantile", "_draw_surface_panel"):
        "the colour scale's upper end (a display range of the scored distances, not a figure)",
    ("bench/report/plots.py", "quantile", "plot_output_error_map"):
        "the colour scale's range (a display range of the scored errors, not a figure)",
    ("bench/report/plots.py", "quantile", "compare_error_figure"):
        "the colour scale's range (a display range of the compared errors, not a figure)",
    ("bench/run/realism.py", "rms", "measure_corner_noise"):
        "the corner detector's noise on rendered views: an input of the realism model, not a score",
}


def _dotted(node: ast.AST) -> str:
    """``a.b.c`` of a Name/Attribute chain ('' for anything else, e.g. a call's result)."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if isinstance(node, ast.Name):
        parts.append(node.id)
        return ".".join(reversed(parts))
    return ".".join(reversed(parts)) if parts else ""


def _is_call_to(node: ast.AST, names) -> bool:
    return isinstance(node, ast.Call) and _dotted(node.func).rsplit(".", 1)[-1] in names


def _squares(node: ast.AST) -> bool:
    """``x ** 2`` or ``x * x`` (the same expression twice)."""
    if not isinstance(node, ast.BinOp):
        return False
    if isinstance(node.op, ast.Pow):
        return isinstance(node.right, ast.Constant) and node.right.value == 2
    return isinstance(node.op, ast.Mult) and ast.dump(node.left) == ast.dump(node.right)


def _mean_of_squares(node: ast.AST) -> bool:
    """``mean(SQ)``, ``np.mean(SQ)`` or ``(SQ).mean()`` with SQ a square."""
    if not isinstance(node, ast.Call):
        return False
    name = _dotted(node.func).rsplit(".", 1)[-1]
    if isinstance(node.func, ast.Attribute) and node.func.attr == "mean" and not node.args:
        return _squares(node.func.value)
    return name == "mean" and bool(node.args) and _squares(node.args[0])


def scoring_outside_evaluation(source: str, rel: str) -> list[tuple[str, str | None, int, str]]:
    """(rule, enclosing function or None, line, code) of every scoring construct in ``source`` (the
    file ``rel``, repository-relative, outside evaluation/)."""
    tree = ast.parse(source)
    parents = {}
    for node in ast.walk(tree):
        for child in ast.iter_child_nodes(node):
            parents[child] = node

    def function_of(node):
        while node in parents:
            node = parents[node]
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                outer = function_of(node)
                return outer or node.name
        return None

    exempt = rel.startswith(NO_GROUND_TRUTH)
    found = []
    for node in ast.walk(tree):
        rule = None
        if isinstance(node, ast.Call):
            name = _dotted(node.func)
            if "proximity" in name.split(".") or name.rsplit(".", 1)[-1] in DISTANCE_FUNCTIONS:
                rule = "distance"
            elif not exempt and name.rsplit(".", 1)[-1] == "sqrt" and node.args and _mean_of_squares(node.args[0]):
                rule = "rms"
            elif not exempt and name.rsplit(".", 1)[-1] in QUANTILE_FUNCTIONS and "." in name:
                rule = "quantile"
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names = [n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name)]
            if any(BOUND_NAME.match(n) for n in names):
                rule = "bound"
        if rule:
            found.append((rule, function_of(node), node.lineno, ast.get_source_segment(source, node) or ""))
    return found


def _checked_files() -> list[Path]:
    files = [REPO / m for m in ROOT_MODULES if (REPO / m).is_file()]
    for d in CHECKED_DIRS:
        files += sorted(p for p in (REPO / d).rglob("*.py") if "__pycache__" not in p.parts)
    return files


def _violations() -> tuple[list[str], set]:
    bad, used = [], set()
    for path in _checked_files():
        rel = path.relative_to(REPO).as_posix()
        for rule, fn, line, code in scoring_outside_evaluation(path.read_text(), rel):
            key = next((k for k in ((rel, rule, fn), (rel, rule, None)) if k in ALLOWED), None)
            if key is None:
                bad.append(f"{rel}:{line} ({rule}, in {fn or 'the module'}): {code.splitlines()[0][:100]}")
            else:
                used.add(key)
    return bad, used


def test_no_module_outside_evaluation_scores():
    bad, _ = _violations()
    assert not bad, "scoring outside evaluation/ (move it into evaluation/ and call it):\n" + "\n".join(bad)


def test_every_allowance_is_still_needed():
    _, used = _violations()
    stale = sorted(set(ALLOWED) - used)
    assert not stale, f"allowances that match nothing (remove them): {stale}"


def test_evaluation_holds_the_papers_bound_once():
    from platebench.evaluation import accuracy, score
    assert (score.PAPER_DEPTH_MM, score.PAPER_XY_MM) == (2.0, 1.0)
    assert accuracy.PAPER_DEPTH_MM is score.PAPER_DEPTH_MM and accuracy.PAPER_XY_MM is score.PAPER_XY_MM
    defined = [p.relative_to(REPO).as_posix() for p in (REPO / "evaluation").rglob("*.py")
               if any(isinstance(n, ast.Assign) and any(isinstance(t, ast.Tuple | ast.Name) and
                                                         any(isinstance(x, ast.Name) and BOUND_NAME.match(x.id)
                                                             for x in ast.walk(t)) for t in n.targets)
                      for n in ast.parse(p.read_text()).body)]
    assert defined == ["evaluation/score.py"], defined


PLANTED = {
    "distance": "import trimesh\ndef f(mesh, p):\n    return trimesh.proximity.closest_point(mesh, p)[1]\n",
    "distance_evaluation": ("from platebench.evaluation.point_metrics import point_to_surface_distance\n"
                            "def err(p, mesh):\n    return point_to_surface_distance(p, mesh) * 1e3\n"),
    "rms": "import numpy as np\ndef f(e):\n    return float(np.sqrt(np.mean(e[:, 2] ** 2)))\n",
    "rms_product": "import math\nimport numpy as np\ndef f(d):\n    return math.sqrt(np.mean(d * d))\n",
    "rms_method": "import numpy as np\ndef f(d):\n    return np.sqrt((d ** 2).mean())\n",
    "quantile": "import numpy as np\ndef f(w):\n    return np.quantile(w, 0.95)\n",
    "percentile": "import numpy as np\ndef f(w):\n    return np.percentile(w, 95)\n",
    "bound": "PAPER_DEPTH_MM = 2.0\n",
    "bound_tuple": "PAPER_DEPTH_MM, PAPER_XY_MM = 2.0, 1.0\n",
}


def _planted_in(folder: str) -> str:
    """The repository-relative name of a planted module (no such file exists) in ``folder``."""
    return f"{folder}/{PLANTED_MODULE}"


PLANTED_MODULE = "planted_module.py"


@pytest.mark.parametrize("name", sorted(PLANTED))
def test_the_checker_finds_planted_scoring(name):
    rule = name.split("_")[0].replace("percentile", "quantile")
    found = scoring_outside_evaluation(PLANTED[name], _planted_in("bench/run"))
    assert [r for r, *_ in found] and {r for r, *_ in found} == {rule}, found


def test_the_checker_leaves_what_is_not_scoring_alone():
    clean = ("import numpy as np\n"
             "def f(x, w):\n"
             "    a = np.sqrt(np.mean(x))  # not a mean of squares\n"
             "    b = np.sqrt(np.mean(x * w))  # not a square\n"
             "    c = np.median(w)  # a summary of scored figures across samples\n"
             "    return a, b, c, np.linalg.norm(x)\n"
             "PAPER_NAME = 'Chen and Zheng'\n")
    assert scoring_outside_evaluation(clean, _planted_in("bench/report")) == []
    residual = "import numpy as np\ndef fit(r):\n    return np.sqrt(np.mean(r ** 2)), np.percentile(r, 90)\n"
    assert scoring_outside_evaluation(residual, _planted_in("reconstruction")) == []  # no ground truth there
    assert {r for r, *_ in scoring_outside_evaluation(residual, _planted_in("bench/run"))} == {"rms", "quantile"}


def test_the_scored_per_point_errors_are_written_and_read_back_exactly():
    """What the report's error map draws is what was scored: score.json's ``per_point`` section reads back as
    the same errors: in millimetres, as the file holds them, to the last bit (metres are those divided by 1000)."""
    import json

    import numpy as np

    from platebench.bench.io.codecs import decode, encode
    from platebench.evaluation.score import PerPointErrors

    rng = np.random.default_rng(0)
    per = PerPointErrors(rng.random(16) * 1e-3, rng.random(16) > 0.3, rng.random(500) * 1e-3)
    back = decode(PerPointErrors, json.loads(json.dumps(encode(per))))
    assert np.array_equal(back.centre_error_m * 1e3, per.centre_error_m * 1e3)
    assert np.array_equal(back.surface_distance_m * 1e3, per.surface_distance_m * 1e3)
    assert np.array_equal(back.centre_known, per.centre_known)
    assert decode(PerPointErrors, encode(PerPointErrors(np.zeros(0), np.zeros(0, bool)))).surface_distance_m is None
