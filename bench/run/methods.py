"""How the bench runs a registered method on a written sample (a sweep, the benchmark's score).

The methods are those of the registry ``reconstruction.methods`` (built-in methods and peers, plug-ins
found by name: ``bench.run.plugins.find_method``). ``get_method(name)`` gives the runner of a name: a
function ``run(ctx: MethodContext) -> MethodOutput`` that reads the sample's images and calibration
(``ctx.sample_dir``; never its ground truth), writes what it made to ``ctx.recon_dir`` and returns its
``MetricsRow`` (scored against the truth by the bench) with its timings. How it runs follows the entry:

* "paper": the paper's pipeline, its reconstruction written as ``platebench reconstruct`` writes it and
  scored with ``bench.run.score.score_files``;
* an isolated entry (a plug-in): in a process of its own with a time limit (``bench.run.plugin_host``;
  whatever it does is that method's failure on that sample), its output, its scored error map
  (``bench.io.error_map_files``) and ``score.json`` written;
* any other entry: in this process through ``compare`` (its projector sequence rendered with the worker's
  renderer), its ``score.json``, its output (``bench.run.outputs.write_output``, the file of its kind) and
  its scored error map written.

A plug-in found by name is registered once, so a sweep's spec validation, ``compare`` and every worker
(local or Dask) resolve the same name the same way. Finding one imports nothing of it
(``plugins.resolve_plugin``).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from platebench.bench.io.atomic import staged_directory, write_json
from platebench.bench.io.codecs import encode
from platebench.bench.io.error_map_files import ERROR_MAP_FILE, StoredErrorMap, write_error_map
from platebench.bench.io.recon_files import image_checksums, write_reconstruction
from platebench.bench.run.compare import compare_sample
from platebench.bench.run.paper_method import reconstruct_dir
from platebench.bench.run.outputs import jsonable, score_row, write_output
from platebench.bench.run.plugins import find_method, plugin_names, run_plugin
from platebench.bench.run.score import score_files
from platebench.errors import UserValueError
from platebench.evaluation.metrics_row import MetricsRow
from platebench.reconstruction import methods as registry
from platebench.reconstruction.methods import MethodEntry

__all__ = ["MethodContext", "MethodOutput", "Method", "get_method", "method_names"]


@dataclass(frozen=True)
class MethodContext:
    """What a method gets for one sample."""

    sample_dir: Path  # the written sample (a method reads only its images, calib.json, pattern.json)
    recon_dir: Path  # where the method writes its outputs (staged)
    renderer: object  # the worker's PlateRenderer (for methods that render their own pattern sequences)
    pose: dict | None  # the sweep's pose axes of this sample (None: the reference pose)
    time_limit_s: float | None = None  # the longest a plug-in may run on the sample (None: plugins' default)


@dataclass(frozen=True)
class MethodOutput:
    """A method's scored result for one sample (times in seconds)."""

    metrics: MetricsRow
    time_recon_s: float
    time_eval_s: float
    time_render_extra_s: float = 0.0  # renders of the method's own pattern sequences


@dataclass(frozen=True)
class Method:
    """The runner of one registry entry (module doc)."""

    entry: MethodEntry
    run: Callable[[MethodContext], MethodOutput]

    @property
    def name(self) -> str:
        return self.entry.name

    @property
    def description(self) -> str:
        return self.entry.description

    @property
    def rerenders_from_config(self) -> bool:
        """True when it re-creates the scene from sample.json (which holds no pose) to render its own sequence."""
        return self.entry.sequence is not None and not self.entry.isolated


_RUNNERS: dict[str, Method] = {}


def method_names() -> tuple[str, ...]:
    """The registered methods and the installed plug-ins (entry points), by name."""
    return tuple(dict.fromkeys((*registry.method_names(), *plugin_names())))


def get_method(name: str) -> Method:
    """The runner of the method called ``name``: a registered one, else an installed plug-in (entry point of
    ``platebench.methods``) or ``module:function``, found now without importing it and registered (see
    module doc). ``UserValueError`` for an unknown name, ``PluginError`` for a plug-in name that is not
    ``module:function`` or whose module is not on the Python path."""
    if not isinstance(name, str) or not name:
        raise UserValueError(f"method name {name!r} is empty: allowed {', '.join(method_names())}")
    entry = find_method(name)
    if entry is None:
        raise UserValueError(f"method {name!r} is not known: allowed {', '.join(method_names())}, or a plug-in "
                             "written as module:function")
    method = _RUNNERS.get(name)
    if method is None or method.entry is not entry:
        run = _run_paper if name == "paper" else _plugin_runner(entry) if entry.isolated else _peer_runner(name)
        method = _RUNNERS[name] = Method(entry, run)
    return method


def _plugin_runner(entry: MethodEntry) -> Callable[[MethodContext], MethodOutput]:
    def run(ctx: MethodContext) -> MethodOutput:
        r = run_plugin(entry.function, entry.name, ctx.sample_dir, ctx.recon_dir, time_limit_s=ctx.time_limit_s)
        return MethodOutput(r.row, r.time_recon_s, r.time_eval_s)
    return run


def _run_paper(ctx: MethodContext) -> MethodOutput:
    t0 = time.perf_counter()
    rec, inputs = reconstruct_dir(ctx.sample_dir)
    write_reconstruction(ctx.recon_dir, rec, ctx.sample_dir, image_checksums(inputs.images), overwrite=True)
    t1 = time.perf_counter()
    score = score_files(ctx.sample_dir, ctx.recon_dir)
    write_json(ctx.recon_dir / "score.json", encode(score))
    return MethodOutput(MetricsRow.from_score(score), t1 - t0, time.perf_counter() - t1)


def _finite(x) -> float | None:
    try:
        return jsonable(float(x))
    except (TypeError, ValueError):
        return None


def _peer_runner(name: str) -> Callable[[MethodContext], MethodOutput]:
    def run(ctx: MethodContext) -> MethodOutput:
        t0 = time.perf_counter()
        cmp = compare_sample(ctx.sample_dir, (name,), renderer=ctx.renderer)
        row = next(r for r in cmp.rows if r.name == name)
        wall = time.perf_counter() - t0
        with staged_directory(ctx.recon_dir, overwrite=True) as d:
            doc = {"method": name, "kind": row.kind, "description": row.description, "n_images": row.n_images,
                   "time_s": row.time_s, "render_s": row.render_s, "notes": list(row.notes) + list(cmp.notes),
                   "scores": encode(row.score), "figures": row.figures.to_dict()}
            write_json(d / "score.json", jsonable(doc))
            if row.output is not None:  # the output and its error map, scored by compare
                write_output(d, row.output)
                write_error_map(d / ERROR_MAP_FILE, StoredErrorMap.of(row.kind, row.error_map))
        render_s = _finite(row.render_s) or 0.0
        recon_s = _finite(row.time_s)
        return MethodOutput(score_row(row.score),
                            recon_s if recon_s is not None else wall - render_s,
                            max(wall - render_s - (recon_s or 0.0), 0.0), render_s)
    return run
