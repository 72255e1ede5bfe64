"""Plug-in methods: discovery by name and process isolation.

A plug-in is a method of the contract ``reconstruction.methods`` (one function ``MethodInputs ->
Disparity | Depth | Points | Mesh``; those types and the output checks live there and are re-exported
here) that PlateBench finds by name instead of by import. Its output is checked where it arrives
(``reconstruction.methods.check_output``), then scored, written and recorded as any method's is
(``bench.run.outputs``, re-exported here).

Discovery
---------
``find_method(name)`` finds a method, in this order: the registry (``reconstruction.methods``);
an entry point ``name`` in the group ``platebench.methods`` of any installed distribution
(``[project.entry-points."platebench.methods"] my-method = "my_package.module:function"``);
or ``name`` written as ``module:function`` (importable from the Python path). Resolution is
lazy: a Dask worker that receives only the name resolves it the same way. A plug-in found is added to
the registry as an isolated ``MethodEntry`` (its function a ``Plugin`` reference), so ``compare``, a
sweep and the benchmark's score resolve the name the same way afterwards.

Finding a plug-in runs none of its code (``resolve_plugin``): the calling process (``compare``, a
sweep's main process and its workers, a Dask worker) reads the entry points' metadata, checks the
name's form and looks its module up without importing it (``find_module``: the top-level name
through Python's import finders, each further part of a dotted name in its parent's folders, so
that no package's ``__init__`` runs either). The description shown in tables and help
(``Plugin.description``) is the function's docstring read from its source file with ``ast`` (never
executed), else the entry point's distribution's summary, else the name. A name that is not
``module:function`` or whose module is not on the Python path is refused (``PluginError``, one
line); everything the import itself can do is left to the plug-in's process.

Isolation
---------
A plug-in's code runs only in a process of its own (``bench.run.plugin_host``): its module is
imported there, within the time limit of the call that first needs it, and it is called there on
each sample, with a time limit (``METHOD_TIME_LIMIT_S`` unless the command sets another:
``compare`` and ``sweep`` take ``--method-time-limit-s``, a sweep spec
``sweep.method_time_limit_s``); the limit covers the import, reading the sample's inputs and the
call. Whatever it does, at import or when called: its ``sys.exit``, an exception, a crash, a loop
that never returns, a wrong return type, an array of complex, bool, text or Python objects, an
unusable mesh or a metric that is not a number, is that method's failure on that sample
(``PluginError``, one line): a sweep records it in the method's row, ``compare`` in the method's
entry, and both go on with the other methods. A module that fails at import fails again on every
sample (each failure starts a fresh process, which imports it again). Processes the plug-in starts
die with its process (``plugin_host``: its whole process group is killed).
"""
from __future__ import annotations

import ast
import contextlib
import importlib
import os
import pickle
import sys
import time
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from typing import Any, Callable

import numpy as np

from platebench.bench.io.atomic import staged_directory, write_json
from platebench.bench.io.field_truth import load_field_truth
from platebench.bench.io.sample_files import load_inputs
from platebench.bench.run.outputs import (
    jsonable,
    metrics_row,
    score_document,
    score_output,
    write_error_map,
    write_output,
)
from platebench.errors import UserValueError
from platebench.evaluation.field_scores import FieldTruth
from platebench.evaluation.metrics_row import MetricsRow
from platebench.reconstruction import peers as _builtin_peers  # noqa: F401  (importing it registers them)
from platebench.reconstruction.methods import (
    OUTPUT_KINDS,
    Depth,
    Disparity,
    Mesh,
    MethodEntry,
    MethodInputs,
    MethodOutputError,
    Points,
    add_method,
    check_output,
    checked_metrics,
    checked_notes,
    method_entry,
    output_noun,
)

__all__ = ["ENTRY_POINT_GROUP", "MethodInputs", "Disparity", "Depth", "Points", "Mesh", "OUTPUT_KINDS",
           "PluginError", "Plugin", "method_inputs", "find_method", "resolve_plugin", "load_plugin", "plugin_names",
           "score_output", "run_plugin", "call_plugin", "write_output", "jsonable", "METHOD_TIME_LIMIT_S",
           "check_time_limit", "find_module", "check_output", "score_document", "metrics_row"]

ENTRY_POINT_GROUP = "platebench.methods"
METHOD_TIME_LIMIT_S = 600.0  # default: the longest one plug-in may take on one sample (import included), seconds
SOURCE_READ_LIMIT_BYTES = 4 << 20  # a plug-in's source larger than this is not parsed for its description
TIME_LIMIT_RANGE_S = (1.0, 86400.0)


class PluginError(UserValueError):
    """A plug-in cannot be found, imported, or returned something else than an output kind."""


def method_inputs(sample_dir: Path) -> MethodInputs:
    """A written sample's inputs (images, calibration, pattern; never its ground truth)."""
    inp = load_inputs(Path(sample_dir))
    return MethodInputs(dict(inp.images), inp.calibration, inp.pattern)


# ----------------------------------------------------------------------------- discovery
def _entry_points() -> dict:
    return {ep.name: ep for ep in metadata.entry_points(group=ENTRY_POINT_GROUP)}


def plugin_names() -> tuple[str, ...]:
    """Names of the installed plug-ins (entry points of ``platebench.methods``)."""
    return tuple(sorted(_entry_points()))


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0][:300] if text else ""


def _raised(e: BaseException) -> str:
    """What an exception of a plug-in's code says, in a few words: ``SystemExit: 3``, ``ValueError: msg``."""
    if isinstance(e, SystemExit):
        code = e.code
        return f"sys.exit({code!r})" if code is None or isinstance(code, (int, str)) and len(repr(code)) < 200 \
            else f"sys.exit(<{type(code).__name__}>)"
    msg = _first_line(e)
    return f"{type(e).__name__}: {msg}" if msg else type(e).__name__


def load_plugin(name: str) -> Callable:
    """Import the plug-in called ``name`` (an entry point, or ``module:function``) and return its function.
    Runs the plug-in's module code: the bench calls it only in the plug-in's own process
    (``bench.run.plugin_host``). Raises ``PluginError`` (one line) whatever the import does."""
    ep = _entry_points().get(name)
    if ep is not None:
        try:
            fn = ep.load()
        except BaseException as e:  # noqa: BLE001  (any import error of someone else's package, sys.exit too)
            raise PluginError(f"method {name!r}: entry point {ep.value!r} cannot be loaded ({_raised(e)})") from None
        where = f"entry point {ep.value!r}"
    else:
        mod, _, attr = _split(name)
        try:
            module = importlib.import_module(mod)
        except BaseException as e:  # noqa: BLE001
            raise PluginError(f"method {name!r}: cannot import module {mod!r} ({_raised(e)})") from None
        fn = module
        for part in attr.split("."):
            fn = getattr(fn, part, None)
            if fn is None:
                raise PluginError(f"method {name!r}: module {mod!r} has no attribute {attr!r}")
        where = name
    if not callable(fn):
        raise PluginError(f"method {name!r}: {where} is not a function")
    return fn


def _split(name: str) -> tuple[str, str, str]:
    """(module, ":", attribute) of ``module:function``, both dotted Python names, else ``PluginError``."""
    mod, _, attr = name.partition(":")
    if not (_dotted(mod) and _dotted(attr)):
        raise PluginError(f"method {name!r}: write a plug-in as module:function (dotted Python names)")
    return mod, _, attr


def _dotted(text: str) -> bool:
    return bool(text) and all(part.isidentifier() for part in text.split("."))


def find_module(module: str):
    """The import spec of ``module`` as this process's Python path holds it, found without running any
    module's code; None when it is not there. The top-level name goes through ``importlib.util.find_spec``
    (the import finders only: for a top-level name it imports nothing); each further part of a dotted name
    is looked up in the folders of the package above it (``importlib.machinery.PathFinder``, the
    package's own ``__path__`` when it is already imported here), never by importing that package, so no
    ``__init__`` runs. A package that extends its ``__path__`` when imported is searched where it lies."""
    from importlib.machinery import PathFinder  # noqa: PLC0415
    from importlib.util import find_spec  # noqa: PLC0415

    parts = module.split(".")
    spec = None
    locations = None
    for i in range(len(parts)):
        full = ".".join(parts[: i + 1])
        loaded = sys.modules.get(full)
        try:
            if loaded is not None:
                spec = getattr(loaded, "__spec__", None)
                here = getattr(loaded, "__path__", None)
            else:
                spec = find_spec(full) if i == 0 else PathFinder.find_spec(full, list(locations))
                here = None
        except (ImportError, ValueError, AttributeError, TypeError):
            return None
        if spec is None:
            return None
        locations = here if here is not None else spec.submodule_search_locations
        if i < len(parts) - 1 and not locations:
            return None  # a module, not a package: it has no parts below it
    return spec


def _docstring(spec, attr: str) -> str | None:
    """The first line of the docstring of ``attr`` (``function`` or ``Class.method``) as the source file of
    ``spec`` defines it (its last top-level definition of that name), parsed with ``ast`` and never executed;
    None when there is no such source, definition or docstring."""
    origin = getattr(spec, "origin", None)
    if not isinstance(origin, str) or not origin.endswith(".py"):
        return None
    try:
        path = Path(origin)
        if path.stat().st_size > SOURCE_READ_LIMIT_BYTES:
            return None
        tree = ast.parse(path.read_bytes(), filename=origin)
    except (OSError, SyntaxError, ValueError, RecursionError, MemoryError):
        return None
    body, node = tree.body, None
    for part in attr.split("."):
        defs = [n for n in body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
                and n.name == part]
        if not defs:
            return None
        node = defs[-1]
        body = node.body
    doc = (ast.get_docstring(node) or "").strip()
    return doc.splitlines()[0].strip()[:300] if doc else None


def _summary(ep) -> str | None:
    """The one-line summary of the distribution that declares entry point ``ep`` (its metadata, no import)."""
    try:
        text = (ep.dist.metadata["Summary"] or "").strip()
    except Exception:  # noqa: BLE001  (no distribution, unreadable metadata)
        return None
    return text.splitlines()[0][:300] if text and text != "UNKNOWN" else None


@dataclass(frozen=True)
class Plugin:
    """A plug-in found by name (``resolve_plugin``): ``name`` as written (an entry point's name or
    ``module:function``) and ``description`` (module doc, "Discovery": read without importing it)."""

    name: str
    description: str


def resolve_plugin(name: str) -> Plugin | None:
    """The plug-in called ``name`` (an entry point, or ``module:function``), found without running any of its
    code (module doc, "Discovery"); None if ``name`` is neither. Raises ``PluginError`` (one line) when the
    name is not ``module:function`` or its module is not on the Python path. Its import happens on its first
    call, in its own process, within that call's time limit: what the import does is the call's failure."""
    ep = _entry_points().get(name)
    if ep is not None:
        try:
            mod, attr, target = ep.module, ep.attr or "", ep.value
        except AttributeError:  # a value that is not module:attribute
            raise PluginError(f"method {name!r}: entry point value {ep.value!r} is not module:function") from None
        if not _dotted(mod):
            raise PluginError(f"method {name!r}: entry point value {ep.value!r} is not module:function")
        where = f"entry point {ep.value!r}: "
    else:
        if ":" not in name:
            return None
        mod, _, attr = _split(name)
        target, where = name, ""
    spec = find_module(mod)
    if spec is None:
        raise PluginError(f"method {name!r}: {where}cannot import module {mod!r} (not found on the Python path)")
    doc = _docstring(spec, attr) if attr else None
    if doc is None and ep is not None:
        doc = _summary(ep)
    return Plugin(name, doc or f"plug-in {target}")


def find_method(name: str) -> MethodEntry | None:
    """The registry's entry ``name`` (``reconstruction.methods``), else the plug-in of that name found now
    without importing it (``resolve_plugin``) and added to the registry as an isolated entry; None when
    ``name`` is neither. Raises ``PluginError`` as ``resolve_plugin`` does."""
    entry = method_entry(name)
    if entry is not None:
        return entry
    plugin = resolve_plugin(name)
    if plugin is None:
        return None
    return add_method(MethodEntry(name, plugin.description, plugin, isolated=True))


def check_time_limit(seconds, what: str = "--method-time-limit-s") -> float:
    """A plug-in time limit in seconds, checked (``UserValueError`` naming ``what`` and the range)."""
    lo, hi = TIME_LIMIT_RANGE_S
    number = isinstance(seconds, (int, float, np.integer, np.floating)) and not isinstance(seconds, bool)
    v = float(seconds) if number else float("nan")
    if not lo <= v <= hi:
        raise UserValueError(f"{what} = {seconds!r} is {'out of range' if number else 'not a number'}: allowed "
                             f"{lo:g} to {hi:g} s")
    return v


# ----------------------------------------------------------------------------- running and scoring
# ----------------------------------------------------------------------------- running in a process of its own
def _checked(check, *args):
    """``check(*args)`` (an output check of ``reconstruction.methods``), its ``MethodOutputError`` as a
    ``PluginError`` (one line)."""
    try:
        return check(*args)
    except MethodOutputError as e:
        raise PluginError(str(e)) from None


@dataclass(frozen=True)
class PluginRun:
    """One plug-in run on a sample: its output, the score, the row, and the times (seconds)."""

    output: Any
    score: Any
    row: MetricsRow
    time_recon_s: float
    time_eval_s: float


def run_plugin(fn, name: str, sample_dir: Path, recon_dir: Path | None = None,
               truth: FieldTruth | None = None, time_limit_s: float | None = None) -> PluginRun:
    """Run plug-in ``fn`` (a ``Plugin``, or a function importable by reference) on a written sample in
    its own process (``call_plugin``), score it, and (with ``recon_dir``) write its output and
    ``score.json`` there, with its scored error map (``bench.run.outputs.write_error_map``) (staged: the directory appears complete or not at all). ``PluginError`` (one
    line) for anything the plug-in got wrong, ``FieldScoreError`` for an output that cannot be scored."""
    out, recon_s = call_plugin(fn, name, sample_dir, time_limit_s)
    t1 = time.perf_counter()
    truth = truth if truth is not None else load_field_truth(sample_dir)
    score = score_output(out, truth, f"method {name!r} {out.kind} output")
    row = metrics_row(score, out)
    t2 = time.perf_counter()
    if recon_dir is not None:
        with staged_directory(Path(recon_dir), overwrite=True) as d:
            write_output(d, out)
            write_error_map(d, out.kind, truth)
            write_json(d / "score.json", score_document(name, out.kind, score, sample_dir,
                                                        {"recon_s": recon_s, "eval_s": t2 - t1}, out.metrics))
    return PluginRun(out, score, row, recon_s, t2 - t1)


def _request(op: str, name: str, **more) -> dict:
    """A request to the plug-in's process: this process's import path and working directory go with it."""
    try:
        cwd = os.getcwd()
    except OSError:  # removed under this process: the plug-in's process keeps its own
        cwd = None
    return {"op": op, "name": name, "sys_path": list(sys.path), "cwd": cwd, **more}


def call_plugin(fn, name: str, sample_dir: Path, time_limit_s: float | None = None):
    """(the plug-in's output, checked; seconds its call took) for a written sample, run in the plug-in's own
    process (module doc) with at most ``time_limit_s`` (default ``METHOD_TIME_LIMIT_S``)."""
    from platebench.bench.run.plugin_host import HostFailure, host  # noqa: PLC0415
    more = {"sample_dir": str(Path(sample_dir).absolute())}
    if isinstance(fn, Plugin):
        more["load"] = fn.name
    else:
        try:
            more["function"] = pickle.dumps(fn)
        except Exception as e:  # noqa: BLE001  (a lambda, a nested function, an object pickle refuses)
            raise PluginError(f"method {name!r}: {getattr(fn, '__qualname__', type(fn).__name__)} cannot be run in a "
                              f"process of its own ({_raised(e)}): define it at the top level of a module") from None
    limit = METHOD_TIME_LIMIT_S if time_limit_s is None else float(time_limit_s)
    try:
        head, arrays = host().request(_request("call", name, **more), limit, f"method {name!r}")
    except HostFailure as e:
        raise PluginError(str(e)) from None
    if not head.get("ok"):
        raise PluginError(head.get("error") or f"method {name!r} failed")
    return _checked(check_output, _decode(head, arrays, name), name), float(head.get("seconds", float("nan")))


def _decode(head: dict, arrays: list, name: str):
    """The output kind an answer of the plug-in's process describes."""
    kind = {k.kind: k for k in OUTPUT_KINDS}.get(head.get("kind"))
    if kind is None or len(arrays) != (2 if kind is Mesh else 1):
        raise PluginError(f"method {name!r}: its process sent an answer of kind {head.get('kind')!r} with "
                          f"{len(arrays)} arrays")
    metrics = head.get("metrics") or {}
    notes = _checked(checked_notes, head.get("notes") or [], name)
    if kind is not Mesh:
        return kind(arrays[0], metrics=metrics, notes=notes)
    v, f = arrays
    _checked(check_output, Mesh(_Faces(v, f), metrics=metrics), name)
    import trimesh  # noqa: PLC0415
    return Mesh(trimesh.Trimesh(vertices=v, faces=f, process=False), metrics=metrics, notes=notes)


@dataclass(frozen=True)
class _Faces:
    """A mesh's arrays before they become a ``trimesh.Trimesh`` (checked first: trimesh indexes blindly)."""

    vertices: np.ndarray
    faces: np.ndarray


def serve_request(req: dict) -> tuple[dict, list]:
    """Answer one request in the plug-in's process (``bench.run.plugin_host``): (header, arrays). Whatever the
    plug-in's code raises, ``SystemExit`` and ``KeyboardInterrupt`` included, becomes the answer's one-line
    ``error``."""
    name = str(req.get("name"))
    try:
        with contextlib.suppress(OSError, TypeError):
            os.chdir(req["cwd"])
        sys.path[:] = req["sys_path"]
        if "function" in req:
            try:
                fn = pickle.loads(req["function"])
            except BaseException as e:  # noqa: BLE001
                raise PluginError(f"method {name!r} cannot be loaded in its process ({_raised(e)})") from None
        else:
            fn = load_plugin(req["load"])
        try:
            inputs = method_inputs(Path(req["sample_dir"]))
        except BaseException as e:  # noqa: BLE001
            raise PluginError(f"method {name!r}: the sample's inputs cannot be read ({_raised(e)})") from None
        t0 = time.perf_counter()
        try:
            out = fn(inputs)
        except BaseException as e:  # noqa: BLE001  (the plug-in's own code: everything it raises is its failure)
            raise PluginError(f"method {name!r} raised {_raised(e)}" if not isinstance(e, SystemExit)
                              else f"method {name!r} called {_raised(e)}") from None
        seconds = time.perf_counter() - t0
        head, arrays = _encode(out, name)
        head.update(ok=True, seconds=seconds)
        return head, arrays
    except PluginError as e:
        return {"ok": False, "error": _first_line(e)}, []
    except BaseException as e:  # noqa: BLE001  (an output whose attributes raise, ...)
        return {"ok": False, "error": f"method {name!r}: {_raised(e)}"}, []


def _encode(out, name: str) -> tuple[dict, list]:
    """(header, arrays) of an output kind, for the answer (checked again where it arrives)."""
    if not isinstance(out, OUTPUT_KINDS):
        _checked(check_output, out, name)
    if isinstance(out, Mesh):
        parts = [(f"mesh {k}", getattr(out.mesh, k, None)) for k in ("vertices", "faces")]
        if any(x is None for _, x in parts):
            raise PluginError(f"method {name!r} returned a Mesh holding {type(out.mesh).__name__}: give a "
                              "trimesh.Trimesh")
    else:
        parts = [(out.kind, getattr(out, out.kind))]
    arrays = []
    for what, x in parts:
        try:
            a = np.asarray(x)
        except Exception as e:  # noqa: BLE001  (a ragged list, an object numpy cannot read)
            raise PluginError(f"method {name!r} returned {output_noun(what)} that are not an array "
                              f"({_raised(e)})") from None
        if a.dtype.kind == "O":
            raise PluginError(f"method {name!r} returned {output_noun(what)} of dtype object (Python objects): "
                              "give real numbers (float or integer)")
        arrays.append(a)
    own = _checked(checked_metrics, out.metrics, name)
    return {"kind": out.kind, "metrics": own, "notes": list(_checked(checked_notes, out.notes, name))}, arrays
