"""The public API in six functions (what ``import platebench`` gives; README, "Python API").

Each function imports what it needs when called, so ``import platebench`` stays cheap. Units:
metres and radians; frames as in DESIGN.md (world +Z up; OpenCV camera frames).
"""
from __future__ import annotations

from pathlib import Path


def render(config=None, *, renderer=None, progress=None):
    """Render one sample (4 images + exact ground truth) in memory.

    ``config``: a ``platebench.bench.config.SampleConfig``, a path to a TOML file, or None (the
    paper's reference experiment). ``renderer``: a ``PlateRenderer`` from an earlier call
    (``sample.renderer``), to reuse its compiled kernels. Returns a ``RenderedSample``.
    """
    from platebench.bench.config import SampleConfig, load_config
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
    from platebench.bench.run.paper_method import reconstruct_sample
    return reconstruct_sample(sample, options)


def score(sample, reconstruction):
    """Score a reconstruction against a sample's exact ground truth: a typed ``Score``.

    ``sample``: a ``RenderedSample`` or a sample directory; ``reconstruction``: a pipeline
    ``Reconstruction`` or a reconstruction directory.
    """
    from platebench.bench.run.score import score_any
    return score_any(sample, reconstruction)


def sense(config=None, out=None, *, overwrite: bool = False, **options):
    """The paper's three sensing stages, detectors and cures on one plate (a simulated robot).

    Returns the typed ``SensingResult``; with ``out`` also writes each stage and ``sensing.json``
    there (the output rule of ``platebench sense``: a new folder, or with ``overwrite`` a sensing
    run's). ``options``: fields of ``platebench.bench.run.sensing.SensingOptions``.
    """
    from platebench.bench.config import SampleConfig
    from platebench.bench.io.outputs import output_dir
    from platebench.bench.run.sensing import SensingOptions, run_sensing
    opts = SensingOptions(**options)
    if out is None:
        return run_sensing(config or SampleConfig(), None, opts)
    with output_dir(Path(out), "sensing run", overwrite=overwrite) as stage:
        return run_sensing(config or SampleConfig(), stage, opts)


def sweep(spec, out, *, workers: int = 1, scheduler: str | None = None, resume: bool = False,
          overwrite: bool = False):
    """Run a sweep spec (TOML path) into dataset directory ``out`` on ``workers`` local processes
    or a Dask ``scheduler`` (``tcp://HOST:PORT``). Returns the ``SweepSummary``."""
    from platebench.bench.io.outputs import guard_output
    from platebench.bench.sweep.executors import DaskExecutor, LocalExecutor, run_sweep
    from platebench.bench.sweep.spec import load_spec
    loaded = load_spec(Path(spec))
    if not resume:
        guard_output(out, inputs=[spec])
    executor = DaskExecutor(scheduler) if scheduler else LocalExecutor(workers)
    return run_sweep(loaded, Path(out), executor, resume=resume, overwrite=overwrite)


def report(path, out=None, *, overwrite: bool = False) -> Path:
    """Write the self-contained HTML report of a dataset, study, sensing run, sample or
    reconstruction (``out``: default ``path/report``; ``overwrite``: replace an earlier report);
    returns the path of ``index.html``."""
    from platebench.bench.report.html import write_report
    return write_report(Path(path), None if out is None else Path(out), overwrite=overwrite)
