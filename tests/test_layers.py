"""The architecture, read from the code: every module's imports go down the layers, never up, and
nothing imports in a cycle. Also: the installed package is one namespace (no generic top-level
names), and every folder with an ``__init__.py`` is listed in pyproject.toml.

Layers (docs/architecture.md, "Layers"): plates < scenes < reconstruction, evaluation < bench. Inside scenes, the
plain-numpy scene description knows no renderer (``scenes.render`` is the only Mitsuba user);
inside bench, cli > run/sweep/report/perf > io/config. Reconstruction never sees ground truth:
it imports neither ``scenes.render`` (renderer, ground-truth caster) nor ``evaluation``.

Each rule is a function of an import graph (``{module: {modules it imports}}``) that returns its
violations; every rule is run on the code's graph, which must have none, and on a copy with one
planted edge, which it must report:

* ``layer_violations``: no module imports a higher layer;
* ``module_cycles``: no import cycle between modules;
* ``cli_violations``: the command line is argparse and printing: a ``bench.cli`` module imports only
  ``CLI_MAY_IMPORT`` (the bench's own packages, ``errors``, ``tolerances``, ``version``), a command
  module imports no other command module (shared argument groups are private helpers, such as
  ``bench.cli._args``, which import no command), and only ``bench.cli.main`` names the commands;
* ``science_violations``: ``plates``, ``scenes``, ``reconstruction`` and ``evaluation`` know nothing
  of the bench (files, the command line, runs): they import nothing from ``bench`` nor the facade;
* ``sibling_cycles``: no cycle between sibling packages: under each package, its subpackages and its
  own modules are siblings (the own modules of one layer count as one), each subpackage standing for
  every module inside it.
"""
from __future__ import annotations

import ast
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE_DIRS = ("plates", "scenes", "reconstruction", "evaluation", "bench")
ROOT_MODULES = ("__init__", "__main__", "api", "errors", "tolerances", "version")


def _module_name(path: Path) -> str:
    rel = path.relative_to(REPO).with_suffix("")
    parts = [p for p in rel.parts if p != "__init__"]
    return ".".join(["platebench", *parts]) if parts else "platebench"


def _modules() -> dict[str, Path]:
    out = {}
    for d in PACKAGE_DIRS:
        for p in (REPO / d).rglob("*.py"):
            out[_module_name(p)] = p
    for m in ROOT_MODULES:
        out[_module_name(REPO / f"{m}.py")] = REPO / f"{m}.py"
    return out


MODULES = _modules()


def _imports(path: Path, name: str) -> set[str]:
    """Every platebench module ``path`` imports, at any depth of the file (lazy imports too)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([base] if base else []))
            for a in node.names:
                full = f"{base}.{a.name}"
                found.add(full if full in MODULES else base)
    out = set()
    for imp in found:
        while imp and imp not in MODULES:  # a name imported from a module -> the module
            imp = imp.rpartition(".")[0]
        if imp.startswith("platebench"):
            out.add(imp)
    out.discard(name)
    return out


GRAPH = {name: _imports(path, name) for name, path in MODULES.items()}


def layer(name: str) -> tuple[int, int]:
    """(layer across packages, layer inside bench or scenes) of a module; higher imports lower."""
    parts = name.split(".")
    top = parts[1] if len(parts) > 1 else ""
    if name in ("platebench.errors", "platebench.tolerances", "platebench.version"):
        return (0, 0)
    if name in ("platebench", "platebench.__main__", "platebench.api"):
        return (9, 0)  # the facade and the entry point sit on top
    rank = {"plates": 1, "scenes": 2, "reconstruction": 3, "evaluation": 3, "bench": 4}[top]
    sub = parts[2] if len(parts) > 2 else ""
    inner = 0
    if top == "scenes":
        inner = 1 if sub == "render" else 0
    elif top == "bench":
        inner = {"config": 0, "progress": 0, "io": 1, "run": 2, "sweep": 3, "report": 3, "perf": 4, "benchmark": 4,
                 "cli": 5}.get(sub, 0)
    return rank, inner


# ----------------------------------------------------------------------------- the rules, as functions of a graph
SCIENCE = ("plates", "scenes", "reconstruction", "evaluation")
CLI = "platebench.bench.cli"
CLI_MAIN = f"{CLI}.main"
CLI_MAY_IMPORT = tuple(f"platebench.bench.{p}" for p in (
    "config", "run", "sweep", "report", "io", "benchmark", "perf", "progress", "files", "interrupts")) + (
    "platebench.errors", "platebench.tolerances", "platebench.version")


def _under(name: str, prefixes) -> bool:
    """``name`` is one of ``prefixes`` or a module inside one of them."""
    return any(name == p or name.startswith(p + ".") for p in prefixes)


def _is_cli_helper(name: str) -> bool:
    """A private module of the command line (``bench.cli._args``): shared argument groups, no command."""
    return name.startswith(CLI + ".") and name.rsplit(".", 1)[1].startswith("_")


def _is_command(name: str) -> bool:
    """A command module: ``bench.cli.<name>``, neither the package, ``main`` nor a private helper."""
    return name.startswith(CLI + ".") and name != CLI_MAIN and not _is_cli_helper(name)


def layer_violations(graph: dict) -> list[str]:
    """Imports that go up the layers (``layer``), across packages or inside one package."""
    bad = []
    for name, deps in graph.items():
        for dep in deps:
            (a, ai), (b, bi) = layer(name), layer(dep)
            same_package = name.split(".")[:2] == dep.split(".")[:2]
            if b > a or (same_package and b == a and bi > ai):
                bad.append(f"{name} -> {dep}")
    return sorted(bad)


def module_cycles(graph: dict) -> list[list[str]]:
    """The import cycles between modules (strongly connected components of more than one module); a
    package ``__init__`` re-exporting its own modules is not a cycle of the code."""
    cycles = [c for c in _strong_components(graph) if len(c) > 1]
    return [c for c in cycles if not all(m.startswith(c[0].rsplit(".", 1)[0]) and
                                         any(MODULES.get(x) is not None and MODULES[x].name == "__init__.py"
                                             for x in c) for m in c)]


def cli_violations(graph: dict) -> list[str]:
    """Imports of the command line beyond argparse and printing (module doc)."""
    bad = []
    for name, deps in graph.items():
        if not (name == CLI or name.startswith(CLI + ".")):
            continue
        for dep in deps:
            if dep == CLI or dep.startswith(CLI + "."):
                ok = name == CLI_MAIN or (_is_cli_helper(dep) and dep != name)
                if _is_cli_helper(name) and not _is_cli_helper(dep):
                    ok = False
                if not ok:
                    bad.append(f"{name} -> {dep} (a command module imports no other command; shared flags are "
                               "private helpers)")
            elif not _under(dep, CLI_MAY_IMPORT):
                bad.append(f"{name} -> {dep} (not in CLI_MAY_IMPORT)")
    return sorted(bad)


def science_violations(graph: dict) -> list[str]:
    """Imports of the bench (its files, command line, runs) or of the facade by the science packages."""
    bad = []
    for name, deps in graph.items():
        if not _under(name, [f"platebench.{p}" for p in SCIENCE]):
            continue
        bad += [f"{name} -> {dep}" for dep in deps
                if _under(dep, ("platebench.bench",)) or dep in ("platebench", "platebench.api", "platebench.__main__")]
    return sorted(bad)


def _packages(graph: dict) -> set[str]:
    """The packages among the graph's modules: those with an ``__init__.py``, and every module's parent."""
    names = set(graph) | {d for deps in graph.values() for d in deps}
    return {n for n in names if MODULES.get(n) is not None and MODULES[n].name == "__init__.py"} | \
        {n.rsplit(".", 1)[0] for n in names if "." in n}


def _sibling(parent: str, name: str, packages: set[str]) -> str | None:
    """The sibling under ``parent`` that module ``name`` belongs to: the subpackage holding it, or, for
    one of ``parent``'s own modules, 'PARENT (own modules, layer L)'; None outside ``parent`` and for
    ``parent``'s ``__init__`` (the package's face)."""
    if not name.startswith(parent + "."):
        return None
    child = f"{parent}.{name[len(parent) + 1:].split('.')[0]}"
    if child in packages:
        return child
    return f"{parent} (own modules, layer {'.'.join(map(str, layer(name)))})"


def sibling_cycles(graph: dict, imports: list | None = None) -> list[list[str]]:
    """The cycles between sibling packages (module doc), each as the sorted siblings of one strongly
    connected component; ``imports``, when given, receives the module imports ('a -> b') that join
    the siblings of each cycle."""
    packages = _packages(graph)
    found = []
    for parent in sorted(packages):
        edges: dict = {}
        joins: dict = {}
        for name, deps in graph.items():
            a = _sibling(parent, name, packages)
            if a is None:
                continue
            edges.setdefault(a, set())
            for dep in deps:
                b = _sibling(parent, dep, packages)
                if b is not None and b != a:
                    edges[a].add(b)
                    edges.setdefault(b, set())
                    joins.setdefault((a, b), []).append(f"{name} -> {dep}")
        cycles = [c for c in _strong_components(edges) if len(c) > 1]
        found += cycles
        if imports is not None:
            imports += sorted(j for c in cycles for (a, b), js in joins.items() if a in c and b in c for j in js)
    return found


def _strong_components(graph: dict) -> list[list[str]]:
    """Tarjan's strongly connected components of ``graph`` (each sorted)."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def strong(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                comp.append(w)
                if w == v:
                    break
            out.append(sorted(comp))

    limit = sys.getrecursionlimit()
    sys.setrecursionlimit(max(limit, 10000))
    try:
        for v in list(graph):
            if v not in index:
                strong(v)
    finally:
        sys.setrecursionlimit(limit)
    return out


def _planted(graph: dict, name: str, dep: str) -> dict:
    """A copy of ``graph`` with one more import, ``name`` -> ``dep``."""
    out = {k: set(v) for k, v in graph.items()}
    out.setdefault(name, set()).add(dep)
    out.setdefault(dep, set())
    return out


def test_the_module_graph_is_read():
    assert len(MODULES) > 60
    assert "platebench.reconstruction.paper.pipeline" in GRAPH["platebench.bench.run.paper_method"]
    # lazy imports (inside functions) count too
    assert any("platebench.bench.run" in m for m in GRAPH["platebench.api"])


def test_no_module_imports_a_higher_layer():
    bad = layer_violations(GRAPH)
    assert not bad, "imports that go up the layers:\n" + "\n".join(bad)


def test_reconstruction_never_sees_ground_truth_or_the_renderer():
    bad = [f"{n} -> {d}" for n, deps in GRAPH.items() if n.startswith("platebench.reconstruction")
           for d in deps if d.startswith(("platebench.scenes.render", "platebench.evaluation", "platebench.bench"))]
    assert not bad, bad


def test_only_scenes_render_imports_mitsuba_or_drjit():
    users = []
    for name, path in MODULES.items():
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            mods = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            if any(m.split(".")[0] in ("mitsuba", "drjit") for m in mods):
                users.append(name)
    assert users and all(u.startswith("platebench.scenes.render") for u in users), users


def test_there_is_no_import_cycle():
    cycles = module_cycles(GRAPH)
    assert not cycles, cycles


def test_the_command_line_is_argparse_and_printing():
    """``bench.cli`` imports only the bench's packages, ``errors``, ``tolerances`` and ``version``; a command
    module imports no other command module (module doc, ``cli_violations``)."""
    assert any(_is_command(n) for n in GRAPH) and CLI_MAIN in GRAPH
    bad = cli_violations(GRAPH)
    assert not bad, "\n".join(bad)


def test_the_science_packages_know_nothing_of_the_bench():
    """``plates``, ``scenes``, ``reconstruction`` and ``evaluation`` import nothing of ``bench`` (its files,
    its command line, its runs) nor the facade (``science_violations``)."""
    assert all(any(n.startswith(f"platebench.{p}.") for n in GRAPH) for p in SCIENCE)
    bad = science_violations(GRAPH)
    assert not bad, "\n".join(bad)


def test_no_cycle_between_sibling_packages():
    """Under each package its subpackages and its own modules import one another in one direction only
    (``sibling_cycles``): e.g. ``reconstruction.paper`` uses ``reconstruction.calibration`` and not back."""
    imports: list = []
    cycles = sibling_cycles(GRAPH, imports)
    assert not cycles, f"{cycles}, joined by:\n" + "\n".join(imports)


@pytest.mark.parametrize("check, name, dep", [
    (layer_violations, "platebench.plates.spec", "platebench.bench.config"),
    (layer_violations, "platebench.bench.io.atomic", "platebench.bench.run.render"),
    (module_cycles, "platebench.reconstruction.paper.squares", "platebench.reconstruction.paper.pipeline"),
    (cli_violations, "platebench.bench.cli.render", "platebench.scenes.scene_spec"),
    (cli_violations, "platebench.bench.cli.demo", "platebench.reconstruction.paper.pipeline"),
    (cli_violations, "platebench.bench.cli.study", "platebench.bench.cli.sense"),
    (cli_violations, "platebench.bench.cli._args", "platebench.bench.cli.render"),
    (science_violations, "platebench.evaluation.score", "platebench.bench.io.atomic"),
    (science_violations, "platebench.plates.spec", "platebench.bench.cli.main"),
    (science_violations, "platebench.reconstruction.paper.pipeline", "platebench.api"),
    (sibling_cycles, "platebench.reconstruction.calibration.hand_eye", "platebench.reconstruction.paper.squares"),
    (sibling_cycles, "platebench.scenes.naming", "platebench.scenes.render.runtime"),
    (sibling_cycles, "platebench.bench.config.ranges", "platebench.bench.io.atomic"),
])
def test_each_rule_reports_a_planted_violation(check, name, dep):
    """Every rule can fail: the code's graph with one planted import is reported by the rule's checker,
    which reports nothing of the code's own graph beyond what the test of that rule allows (none)."""
    assert name in GRAPH and dep in MODULES, (name, dep)
    assert dep not in GRAPH[name]
    before = check(GRAPH)
    after = check(_planted(GRAPH, name, dep))
    assert len(after) > len(before) or after != before, (check.__name__, name, dep)
    text = str(after)
    assert name.rsplit(".", 1)[0] in text or name in text, (check.__name__, after)


def test_pyproject_lists_every_package_folder():
    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    folders = {_module_name(p) for d in PACKAGE_DIRS for p in (REPO / d).rglob("__init__.py")}
    assert folders - listed == set(), f"add to pyproject.toml packages: {sorted(folders - listed)}"
    assert all(p == "platebench" or p.startswith("platebench.") for p in listed)


def _run(args, cwd):
    return subprocess.run(args, cwd=cwd, capture_output=True, text=True, timeout=120)


def test_installed_as_one_namespace_with_version_and_module_entry_point(tmp_path):
    py = sys.executable
    r = _run([py, "-c", "import platebench, importlib.util as u; print(platebench.__version__); "
                        "print([m for m in ('bench', 'plates', 'evaluation', 'scenes', 'reconstruction') "
                        "if u.find_spec(m)])"], tmp_path)
    assert r.returncode == 0, r.stderr
    version, tops = r.stdout.split("\n")[:2]
    assert version.count(".") >= 2 and tops == "[]"
    r = _run([py, "-m", "platebench", "--help"], tmp_path)
    assert r.returncode == 0 and "render" in r.stdout and "sweep" in r.stdout, r.stderr
    r = _run([str(Path(py).parent / "platebench"), "--version"], tmp_path)
    assert r.returncode == 0 and r.stdout.strip() == f"platebench {version}"


def test_import_platebench_does_not_load_the_renderer(tmp_path):
    r = _run([sys.executable, "-c", "import sys, platebench; print([m for m in sys.modules "
              "if m.split('.')[0] in ('mitsuba', 'drjit')])"], tmp_path)
    assert r.returncode == 0 and r.stdout.strip() == "[]", r.stderr


def _cli_in_fresh_python(argv: list, heavy: tuple, cwd) -> tuple[str, str]:
    """Run ``platebench`` ``argv`` in a fresh Python: ("EXIT [the modules of ``heavy`` it imported]",
    its stderr and stdout on one line)."""
    code = ("import sys, contextlib, io\n"
            "from platebench.bench.cli.main import main\n"
            "err, out = io.StringIO(), io.StringIO()\n"
            "with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):\n"
            "    try:\n"
            f"        rc = main({[str(a) for a in argv]!r})\n"
            "    except SystemExit as e:\n"
            "        rc = e.code\n"
            f"print(rc, [m for m in {heavy!r} if m in sys.modules])\n"
            "print(' '.join((err.getvalue() + out.getvalue()).split()))\n")
    r = _run([sys.executable, "-c", code], cwd)
    assert r.returncode == 0, r.stderr
    status, text = r.stdout.split("\n", 1)
    return status, text


@pytest.mark.parametrize("argv, words", [
    (["sense", "--max-cures", "-1"], "--max-cures = -1 is out of range"),
    (["sense", "--verify-grid", "dense"], "is not ROWSxCOLS@SQUARE_PX"),
    (["study", "false-boundary", "--limit", "0"], "--limit = 0 is out of range"),
    (["study", "false-boundary", "--seed", "-1"], "--seed = -1 is out of range"),
    (["study", "false-boundary", "--verify-grid", "9x9@0"], "SQUARE_PX = 0 is out of range"),
    (["study", "false-boundary", "--grid", "4x4"], "is not ROWSxCOLS@SQUARE_PX"),
    (["study", "false-boundary", "--realism", "1995", "--width", "100"], "--width = 100 is out of range"),
    (["sense", "--help"], "cure poses at most (default 24; allowed 0 to 48)"),
    (["study", "--help"], "default 0,60,120,180,240,300"),
])
def test_sense_and_study_check_their_flags_before_loading_the_loop(tmp_path, argv, words):
    """A bad flag of ``sense`` or ``study`` (and their --help, with the loop's own defaults) is answered
    without importing the sensing loop, the planner or the renderer (their defaults are plain values:
    ``bench.config.sensing``, ``reconstruction.strategy.budget``)."""
    status, text = _cli_in_fresh_python(argv if "--help" in argv else [*argv, "--out", tmp_path / "o"],
                                        ("platebench.bench.run.sensing", "platebench.reconstruction.strategy.planner",
                                         "platebench.bench.run.sensing.study", "mitsuba", "trimesh"), tmp_path)
    assert status == ("0 []" if "--help" in argv else "2 []"), (status, text)
    assert " ".join(words.split()) in text, text
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("spec, words", [
    ("[grid]\nwidth_px = [160.5]\n", "grid.width_px = 160.5 is not an integer"),
    ("[grid]\nbend_deg = {start = 0, stop = 1e12, step = 1e-3}\n", "allowed at most 100000"),
    ("[sweep]\nname = 'x'\nmethods = ['nope']\n[grid]\nbend_deg = [10]\n", "nope"),
])
def test_sweep_refuses_a_bad_spec_before_loading_its_executors(tmp_path, spec, words):
    """A bad sweep spec is refused from the spec alone: neither the executors (Dask), the renderer nor
    scipy.ndimage (the lens undistortion's resampler, 0.25 s to import) is loaded, and nothing is written."""
    (tmp_path / "spec.toml").write_text(spec)
    status, text = _cli_in_fresh_python(["sweep", tmp_path / "spec.toml", "--out", tmp_path / "o"],
                                        ("platebench.bench.sweep.executors", "dask", "distributed", "mitsuba",
                                         "scipy.ndimage"), tmp_path)
    assert status == "2 []", (status, text)
    assert words in text and len(text.strip().splitlines()) == 1, text
    assert not (tmp_path / "o").exists()


def test_the_in_memory_pipeline_does_not_load_openexr(tmp_path):
    """OpenEXR is read and written only where an EXR file is (bench/io/images.py, bench/io/method_outputs.py)."""
    mods = ("platebench.bench.run.paper_method", "platebench.bench.run.score", "platebench.bench.sweep.tasks",
            "platebench.bench.io.sample_files")
    r = _run([sys.executable, "-c", f"import sys, importlib; [importlib.import_module(m) for m in {mods!r}]; "
              "print('OpenEXR' in sys.modules)"], tmp_path)
    assert r.returncode == 0 and r.stdout.strip() == "False", r.stderr


@pytest.mark.slow
def test_the_wheel_installs_only_the_platebench_namespace(tmp_path):
    """A regular (non-editable) wheel: every file under platebench/, the examples as package data."""
    import shutil
    import zipfile
    src = tmp_path / "src"  # build from a copy: setuptools writes build/ into the source tree
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(".venv", ".git", "build", "out", "__pycache__", "*.egg-info",
                                                             ".pytest_cache"))
    r = _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(src)], tmp_path)
    assert r.returncode == 0, r.stderr
    wheel = next(tmp_path.glob("platebench-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    tops = {n.split("/")[0] for n in names if not n.split("/")[0].endswith(".dist-info")}
    assert tops == {"platebench"}, tops
    for must in ("platebench/__init__.py", "platebench/bench/cli/main.py", "platebench/plates/spec.py",
                 "platebench/examples/demo_sweep.toml"):
        assert must in names, must
