"""The architecture, read from the code: every module's imports go down the layers, never up, and
nothing imports in a cycle. Also: the installed package is one namespace (no generic top-level
names), and every folder with an ``__init__.py`` is listed in pyproject.toml.

Layers (docs/architecture.md, "Layers"): plates < scenes < reconstruction, evaluation < bench. Inside scenes, the
plain-numpy scene description knows no renderer (``scenes.render`` is the only Mitsuba user);
inside bench, cli > run/sweep/report/perf > io/config. Reconstruction never sees ground truth:
it imports neither ``scenes.render`` (renderer, ground-truth caster) nor ``evaluation``.
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


def test_the_module_graph_is_read():
    assert len(MODULES) > 60
    assert "platebench.reconstruction.paper.pipeline" in GRAPH["platebench.bench.run.paper_method"]
    # lazy imports (inside functions) count too
    assert any("platebench.bench.run" in m for m in GRAPH["platebench.api"])


def test_no_module_imports_a_higher_layer():
    bad = []
    for name, deps in GRAPH.items():
        for dep in deps:
            (a, ai), (b, bi) = layer(name), layer(dep)
            same_package = name.split(".")[:2] == dep.split(".")[:2]
            if b > a or (same_package and b == a and bi > ai):
                bad.append(f"{name} -> {dep}")
    assert not bad, "imports that go up the layers:\n" + "\n".join(sorted(bad))


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
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def strong(v):  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in GRAPH[v]:
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
            if len(comp) > 1:
                cycles.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in GRAPH:
        if v not in index:
            strong(v)
    # a package __init__ re-exporting its own modules is not a cycle of the code
    cycles = [c for c in cycles if not all(m.startswith(c[0].rsplit(".", 1)[0]) and
                                           any(MODULES[x].name == "__init__.py" for x in c) for m in c)]
    assert not cycles, cycles


def test_a_lower_layer_importing_a_higher_one_is_caught(tmp_path):
    """The checker itself can fail: a plates module importing bench is reported."""
    GRAPH_COPY = dict(GRAPH)
    GRAPH_COPY["platebench.plates.spec"] = GRAPH["platebench.plates.spec"] | {"platebench.bench.config"}
    bad = [(n, d) for n, deps in GRAPH_COPY.items() for d in deps if layer(d)[0] > layer(n)[0]]
    assert ("platebench.plates.spec", "platebench.bench.config") in bad


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
                                         "platebench.bench.run.study", "mitsuba", "trimesh"), tmp_path)
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
