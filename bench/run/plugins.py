"""Plug-in methods: any function from a sample's inputs to one of four kinds of output.

The interface
-------------
A plug-in is one function ``method(inputs: MethodInputs) -> Disparity | Depth | Points | Mesh``.
``MethodInputs`` holds what a camera system would give it (never the ground truth): the four
camera images (``left_passive``, ``right_passive``: plate under ambient light; ``left_active``,
``right_active``: the projected square grid), the calibration (stereo rig: OpenCV K, R, t per
camera, baseline; the projector's model) and the projected pattern. It returns, in the left
camera's image or the world frame:

* ``Disparity(disparity)``: (H, W) px, d = u_left - u_right; +inf or NaN = no estimate;
* ``Depth(depth)``: (H, W) z-depth in metres along the left optical axis;
* ``Points(points)``: (N, 3) world frame, metres;
* ``Mesh(mesh)``: a ``trimesh.Trimesh`` in the world frame, metres.

Each may carry ``metrics``: the method's own figures (name -> number, units in the names, e.g.
``matched_count``), which go to the results table prefixed ``method_``. The bench scores the
output against the truth with the metrics of its kind (``evaluation.field_scores``), writes it
to the method's reconstruction directory (``bench.io.method_outputs.OUTPUT_FILES``) with
``score.json``, and adds a row to the results table.

Discovery
---------
``bench.run.methods.get_method(name)`` finds a plug-in, in this order: the built-in methods;
an entry point ``name`` in the group ``platebench.methods`` of any installed distribution
(``[project.entry-points."platebench.methods"] my-method = "my_package.module:function"``);
or ``name`` written as ``module:function`` (importable from the Python path). Resolution is
lazy: a Dask worker that receives only the name resolves it the same way.
"""
from __future__ import annotations

import importlib
import inspect
import time
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable, Mapping

import numpy as np

from platebench.bench.io.atomic import staged_directory, write_json
from platebench.bench.io.field_truth import load_field_truth
from platebench.bench.io.method_outputs import (
    OUTPUT_FILES,
    write_depth,
    write_disparity,
    write_mesh,
    write_points,
)
from platebench.bench.io.sample_files import Calibration, load_inputs
from platebench.errors import UserValueError
from platebench.evaluation.field_scores import (
    FieldTruth,
    score_depth,
    score_disparity,
    score_mesh,
    score_point_cloud,
)
from platebench.evaluation.metrics_row import MetricsRow
from platebench.scenes.pattern import Pattern

if TYPE_CHECKING:
    import trimesh  # annotations only: importing trimesh takes a second

__all__ = ["ENTRY_POINT_GROUP", "MethodInputs", "Disparity", "Depth", "Points", "Mesh", "OUTPUT_KINDS",
           "PluginError", "method_inputs", "resolve_plugin", "plugin_names", "score_output", "run_plugin",
           "write_output", "jsonable"]

ENTRY_POINT_GROUP = "platebench.methods"


class PluginError(UserValueError):
    """A plug-in cannot be found, imported, or returned something else than an output kind."""


@dataclass(frozen=True)
class MethodInputs:
    """What a method may see of a sample: ``images`` name -> (H, W) uint8/uint16 camera output
    (``left_passive``, ``right_passive``, ``left_active``, ``right_active``); ``calibration``
    (``.rig``: the stereo pair, ``.projector_camera``: the projector); ``pattern``: the projected
    image and its features (projector pixels)."""

    images: Mapping[str, np.ndarray]
    calibration: Calibration
    pattern: Pattern

    @property
    def rig(self):
        return self.calibration.rig


@dataclass(frozen=True)
class Disparity:
    """(H, W) left-view disparity, px (d = u_left - u_right; +inf or NaN: no estimate; the Middlebury metrics
    clip any other value to [0, ndisp], as the Middlebury SDK does; ETH3D's and the implied depth skip <= 0)."""

    disparity: np.ndarray
    metrics: Mapping[str, float] = field(default_factory=dict)
    kind = "disparity"


@dataclass(frozen=True)
class Depth:
    """(H, W) left-view z-depth, metres (non-finite or <= 0: no estimate)."""

    depth: np.ndarray
    metrics: Mapping[str, float] = field(default_factory=dict)
    kind = "depth"


@dataclass(frozen=True)
class Points:
    """(N, 3) world points, metres."""

    points: np.ndarray
    metrics: Mapping[str, float] = field(default_factory=dict)
    kind = "points"


@dataclass(frozen=True)
class Mesh:
    """A surface mesh (``trimesh.Trimesh``), world frame, metres."""

    mesh: trimesh.Trimesh
    metrics: Mapping[str, float] = field(default_factory=dict)
    kind = "mesh"


OUTPUT_KINDS = (Disparity, Depth, Points, Mesh)


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


def resolve_plugin(name: str) -> Callable | None:
    """The plug-in function called ``name`` (an entry point, or ``module:function``); None if ``name``
    is neither. Raises ``PluginError`` when it names one that cannot be loaded."""
    ep = _entry_points().get(name)
    if ep is not None:
        try:
            fn = ep.load()
        except Exception as e:  # noqa: BLE001  (any import error of someone else's package)
            raise PluginError(f"method {name!r}: entry point {ep.value!r} cannot be loaded "
                              f"({type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''})") from None
        where = f"entry point {ep.value!r}"
    elif ":" in name:
        mod, _, attr = name.partition(":")
        if not mod or not attr:
            raise PluginError(f"method {name!r}: write a plug-in as module:function")
        try:
            module = importlib.import_module(mod)
        except Exception as e:  # noqa: BLE001
            raise PluginError(f"method {name!r}: cannot import module {mod!r} "
                              f"({type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''})") from None
        fn = module
        for part in attr.split("."):
            fn = getattr(fn, part, None)
            if fn is None:
                raise PluginError(f"method {name!r}: module {mod!r} has no attribute {attr!r}")
        where = name
    else:
        return None
    if not callable(fn):
        raise PluginError(f"method {name!r}: {where} is not a function")
    return fn


def describe(fn: Callable) -> str:
    """First line of the plug-in's docstring (or its qualified name)."""
    doc = inspect.getdoc(fn) or ""
    return doc.splitlines()[0] if doc else f"plug-in {getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', '?')}"


# ----------------------------------------------------------------------------- running and scoring
def check_output(out: Any, name: str):
    if not isinstance(out, OUTPUT_KINDS):
        raise PluginError(f"method {name!r} returned {type(out).__name__}: return one of "
                          "platebench.bench.run.plugins.Disparity, Depth, Points or Mesh")
    return out


def score_output(out, truth: FieldTruth, what: str | None = None):
    """Score an output kind against the truth (``evaluation.field_scores``)."""
    what = what or f"{out.kind} output"
    if isinstance(out, Disparity):
        return score_disparity(out.disparity, truth, what=what)
    if isinstance(out, Depth):
        return score_depth(out.depth, truth, what=what)
    if isinstance(out, Points):
        return score_point_cloud(out.points, truth, what=what)
    return score_mesh(out.mesh, truth, what=what)


def write_output(directory: Path, out) -> Path:
    """Write an output kind into ``directory`` under ``OUTPUT_FILES[kind]``; returns the path."""
    path = Path(directory) / OUTPUT_FILES[out.kind]
    {"disparity": lambda: write_disparity(path, out.disparity), "depth": lambda: write_depth(path, out.depth),
     "points": lambda: write_points(path, out.points), "mesh": lambda: write_mesh(path, out.mesh)}[out.kind]()
    return path


def metrics_row(score, out) -> MetricsRow:
    """The score's row, with the method's own figures as ``method_<name>`` columns."""
    row = score.metrics_row()
    own = {f"method_{k}": v for k, v in dict(out.metrics or {}).items()}
    if not own:
        return row
    cols = row.columns()
    base = {k: cols[k] for k in cols if k not in row.extra}
    return MetricsRow(**base, extra={**row.extra, **own})


@dataclass(frozen=True)
class PluginRun:
    """One plug-in run on a sample: its output, the score, the row, and the times (seconds)."""

    output: Any
    score: Any
    row: MetricsRow
    time_recon_s: float
    time_eval_s: float


def run_plugin(fn: Callable, name: str, sample_dir: Path, recon_dir: Path | None = None,
               truth: FieldTruth | None = None) -> PluginRun:
    """Run plug-in ``fn`` on a written sample, score it, and (with ``recon_dir``) write its output and
    ``score.json`` there (staged: the directory appears complete or not at all)."""
    inputs = method_inputs(sample_dir)
    t0 = time.perf_counter()
    out = check_output(fn(inputs), name)
    t1 = time.perf_counter()
    truth = truth if truth is not None else load_field_truth(sample_dir)
    score = score_output(out, truth, f"method {name!r} {out.kind} output")
    row = metrics_row(score, out)
    t2 = time.perf_counter()
    if recon_dir is not None:
        with staged_directory(Path(recon_dir), overwrite=True) as d:
            write_output(d, out)
            write_json(d / "score.json", score_document(name, out.kind, score, sample_dir,
                                                        {"recon_s": t1 - t0, "eval_s": t2 - t1}, out.metrics))
    return PluginRun(out, score, row, t1 - t0, t2 - t1)


def score_document(name: str, kind: str, score, sample_dir: Path, timings: dict | None = None,
                   own: Mapping | None = None) -> dict:
    """score.json of a scored output: method, kind, sample, units, the score (units in every key)."""
    doc = {"method": name, "kind": kind, "sample": str(Path(sample_dir)),
           "units": "mm for lengths, px for disparities, pct = percent, frac = fraction, count = number",
           "score": score.to_dict()}
    if own:
        doc["method_metrics"] = dict(own)
    if timings:
        doc["timings_s"] = timings
    return jsonable(doc)


def jsonable(o):
    """``o`` with numpy scalars as Python numbers and NaN/inf as None (strict JSON)."""
    if isinstance(o, Mapping):
        return {str(k): jsonable(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [jsonable(v) for v in o]
    if isinstance(o, (bool, np.bool_)):
        return bool(o)
    if isinstance(o, (float, np.floating)):
        return float(o) if np.isfinite(o) else None
    if isinstance(o, np.integer):
        return int(o)
    return o
