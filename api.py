"""The public API in seven functions (what ``import platebench`` gives; README, "Python API").

Each function imports what it needs when called, so ``import platebench`` stays cheap. Units:
metres and radians; frames as in docs/architecture.md (world +Z up; OpenCV camera frames).

Sweeps run their samples in spawned worker processes, which import the main script again (as
Python's ``multiprocessing`` does): a script that calls these functions at its top level must
keep that code under ``if __name__ == "__main__":``. A call made while a worker imports the
script raises ``WorkerImportError`` there, saying so, instead of running the script's work again.
"""
from __future__ import annotations

import multiprocessing
import sys
from pathlib import Path

from platebench.errors import SamplesFailedError, WorkerImportError

GUARD_HINT = ('put the script\'s code under `if __name__ == "__main__":` (spawned worker processes import the '
              'main script again; see README, "Python API")')


def _not_in_worker_import(name: str) -> None:
    """Refuse a facade call made while this spawned process imports the main script (what
    ``multiprocessing`` itself checks before starting a process, with the same attribute)."""
    if getattr(multiprocessing.current_process(), "_inheriting", False):
        raise WorkerImportError(f"platebench.{name}() was called while a worker process imported the main script "
                                f"{getattr(sys.modules.get('__main__'), '__file__', '?')}: {GUARD_HINT}")


def _begin(name: str) -> None:
    """What every facade function does first: refuse a call during a worker's import of the main script
    (``_not_in_worker_import``), then load the installed packages' families, metrics and cure rules
    (``bench.run.extensions.load_extensions``: once per process; ``ExtensionError`` when one cannot be
    loaded)."""
    _not_in_worker_import(name)
    from platebench.bench.run.extensions import load_extensions
    load_extensions()


def render(config=None, *, renderer=None, progress=None):
    """Render one sample (4 images + exact ground truth) in memory.

    ``config``: a ``platebench.bench.config.SampleConfig``, a path to a TOML file, or None (the
    paper's reference experiment). ``renderer``: a ``PlateRenderer`` from an earlier call
    (``sample.renderer``), to reuse its compiled kernels. Returns a ``RenderedSample``.
    """
    _begin("render")
    from platebench.bench.config import SampleConfig
    from platebench.bench.io.config_files import load_config
    from platebench.bench.run.render import render_sample
    if config is None or isinstance(config, (str, Path)):
        config = load_config(None if config is None else Path(config))
    if not isinstance(config, SampleConfig):
        raise TypeError(f"config must be a SampleConfig, a TOML path or None, not {type(config).__name__}")
    sample, _ = render_sample(config, renderer, progress=progress)
    return sample


def reconstruct(sample, *, options=None):
    """The paper's pipeline on a rendered sample (in memory) or a sample directory.

    Reads only the images, the stereo calibration and the projector's feature rays, never the
    ground truth. Returns a ``platebench.reconstruction.paper.pipeline.Reconstruction`` (world
    frame, metres).
    """
    _begin("reconstruct")
    from platebench.bench.run.paper_method import reconstruct_sample
    return reconstruct_sample(sample, options)


def score(sample, reconstruction):
    """Score a reconstruction against a sample's exact ground truth: a typed ``Score``.

    ``sample``: a ``RenderedSample`` or a sample directory; ``reconstruction``: a pipeline
    ``Reconstruction`` or a reconstruction directory.
    """
    _begin("score")
    from platebench.bench.run.score import score_any
    return score_any(sample, reconstruction)


def sense(config=None, out=None, *, overwrite: bool = False, **options):
    """The paper's three sensing stages, detectors and cures on one plate (a simulated robot).

    Returns the typed ``SensingResult``; with ``out`` also writes each stage and ``sensing.json``
    there (the output rule of ``platebench sense``: a new folder, or with ``overwrite`` a sensing
    run's). ``options``: fields of ``platebench.bench.run.sensing.SensingOptions``.
    """
    _begin("sense")
    from platebench.bench.config import SampleConfig
    from platebench.bench.io.outputs import output_dir
    from platebench.bench.run.sensing import SensingOptions, run_sensing
    opts = SensingOptions(**options)
    if out is None:
        return run_sensing(config or SampleConfig(), None, opts)
    with output_dir(Path(out), "sensing run", overwrite=overwrite) as stage:
        return run_sensing(config or SampleConfig(), stage, opts)


def sweep(spec, out, *, workers: int = 1, scheduler: str | None = None, resume: bool = False,
          overwrite: bool = False, check: bool = True):
    """Run a sweep spec (TOML path) into dataset directory ``out`` on ``workers`` local processes
    (spawned: see the module doc) or a Dask ``scheduler`` (``tcp://HOST:PORT``). Returns the
    ``SweepSummary`` (``ok``, ``failed``, ``results``: each sample's status and error).

    A sample that fails is recorded in the dataset (status "failed") and the others go on; then,
    with ``check`` (default), ``SamplesFailedError`` is raised naming how many failed and the first
    error (its ``summary`` holds the rest), so a script never goes on quietly over failed samples.
    ``check=False`` returns the summary whatever failed."""
    _begin("sweep")
    from platebench.bench.io.outputs import guard_output
    from platebench.bench.sweep.executors import DaskExecutor, LocalExecutor, run_sweep
    from platebench.bench.sweep.spec import load_spec
    loaded = load_spec(Path(spec))
    if not resume:
        guard_output(out, inputs=[spec])
    executor = DaskExecutor(scheduler) if scheduler else LocalExecutor(workers)
    summary = run_sweep(loaded, Path(out), executor, resume=resume, overwrite=overwrite)
    if check and summary.failed:
        failed = sorted((r for r in summary.results.values() if r.status == "failed"), key=lambda r: r.index or 0)
        first = failed[0]
        hint = ""
        if all(str(r.error or "").startswith("WorkerLost") for r in failed) and \
                getattr(sys.modules.get("__main__"), "__file__", None) and not scheduler:
            hint = f"; if this runs as a script whose code is not under a main guard: {GUARD_HINT}"
        raise SamplesFailedError(f"sweep {Path(out)}: {summary.failed} of {summary.total} samples failed (first: "
                                 f"{first.sample_id}: {first.error}); the dataset keeps them with "
                                 f"status failed; pass check=False to get the summary instead{hint}", summary)
    return summary


def results(dataset):
    """A sweep dataset's results table as a pandas DataFrame, one row per sample and method, with
    each column's type: ``sample_id`` stays a string ("0000", not the number 0), flags are
    booleans, metrics floats (units in the names). Read from ``results.parquet`` (typed), else from
    ``results.csv`` with the column types of the dataset's layout."""
    from platebench.bench.io.images import DatasetError
    from platebench.bench.report.inputs import load_results
    frame, _ = load_results(Path(dataset))
    if frame is None:
        raise DatasetError(f"{dataset}: holds no results.parquet or results.csv (not a sweep dataset, or its sweep "
                           "has not written a row yet)")
    return frame


def report(path, out=None, *, overwrite: bool = False) -> Path:
    """Write the self-contained HTML report of a dataset, study, sensing run, sample or
    reconstruction (``out``: default ``path/report``; ``overwrite``: replace an earlier report);
    returns the path of ``index.html``."""
    _begin("report")
    from platebench.bench.report.html import write_report
    return write_report(Path(path), None if out is None else Path(out), overwrite=overwrite)
