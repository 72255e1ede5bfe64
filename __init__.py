"""PlateBench: a physically based test bench for stereo and structured-light measurement of
smooth, deformed plates, built around Chen & Zheng, "Passive and Active Stereo Vision for Smooth
Surface Detection of Deformed Plates" (IEEE Trans. SMC, 1995).

One namespace, one direction of imports (a lower layer never imports a higher one)::

    platebench.plates          parametric bent plates with exact surfaces (numpy, trimesh)
    platebench.scenes          camera, rig, projector, patterns (plain numpy);
                               platebench.scenes.render: the Mitsuba renderer and ground truth
    platebench.reconstruction  the methods under test: paper/, peers/, calibration/, strategy/
    platebench.evaluation      ground-truth derivations and metrics (the typed Score)
    platebench.bench           config, files (io/), runs (run/), sweeps, reports, perf, CLI

This module is the short facade the README shows (see ``platebench.api``)::

    import platebench
    sample = platebench.render()                 # the reference experiment: 4 images + exact truth
    rec = platebench.reconstruct(sample)         # the paper's pipeline (images + calibration only)
    score = platebench.score(sample, rec)        # a typed Score against the truth
    platebench.sweep("examples/bend_sweep.toml", "ds", workers=2)
    platebench.report("ds")
    platebench.results("ds")                     # results table, typed (sample_id "0000" stays a string)
    for item in platebench.PlateBenchDataset("ds"): ...   # samples as numpy arrays (README)

The facade's functions first load the deformation families, metrics and cure rules that installed
packages declare by entry point (docs/extending.md); code that builds specs or runs sweeps through the
lower modules calls ``platebench.load_extensions()`` once for the same.

Importing ``platebench`` is cheap: nothing here imports Mitsuba until a function needs it.
"""
from __future__ import annotations

from platebench.api import reconstruct, render, report, results, score, sense, sweep

__all__ = ["__version__", "render", "reconstruct", "score", "sense", "sweep", "report", "results", "PlateBenchDataset",
           "load_extensions"]


def __getattr__(name: str):
    """``platebench.PlateBenchDataset`` (samples as numpy arrays), ``__version__`` (read from the package
    metadata) and ``load_extensions`` (the installed packages' families, metrics and cure rules, declared
    by entry point: ``bench.run.extensions``), imported on first use."""
    if name == "__version__":
        from platebench.version import __version__
        return __version__
    if name == "load_extensions":
        from platebench.bench.run.extensions import load_extensions
        return load_extensions
    if name == "PlateBenchDataset":
        from platebench.bench.io.dataset_reader import PlateBenchDataset
        return PlateBenchDataset
    raise AttributeError(f"module 'platebench' has no attribute {name!r}")
