"""Shared fixtures: small real renders, made once per test session."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def small_config():
    """The reference experiment at 480x360 (f scaled to keep the field of view), spp 8."""
    from platebench.bench.config import SampleConfig, SceneParams
    from platebench.scenes.scene_spec import RenderSettings
    return SampleConfig(scene=SceneParams(width=480, height=360), render=RenderSettings(spp=8, seed=3))


@pytest.fixture(scope="session")
def small_sample(small_config):
    """(RenderedSample, renderer) of the small reference experiment."""
    from platebench.bench.run.render import render_sample
    return render_sample(small_config)


@pytest.fixture(scope="session")
def small_sample_dir(small_sample, tmp_path_factory):
    from platebench.bench.io.sample_files import write_sample
    out = tmp_path_factory.mktemp("samples") / "ref10"
    return write_sample(out, small_sample[0])


def run_cli(*args, env=None, timeout=600):
    """Run ``platebench`` in a fresh process (as a user would); returns CompletedProcess."""
    e = dict(os.environ)
    e.update(env or {})
    return subprocess.run([sys.executable, "-m", "platebench.bench.cli.main", *map(str, args)], cwd=REPO, env=e,
                          capture_output=True, text=True, timeout=timeout)


def record_tables(dataset) -> None:
    """Record the sha256 of the results tables a test wrote by hand in ``dataset``, as a sweep does
    (``bench.io.table_checksums``), so that readers take them."""
    from platebench.bench.io.layout import RESULTS_CSV, RESULTS_PARQUET
    from platebench.bench.io.table_checksums import write_table_checksums
    d = Path(dataset)
    write_table_checksums(d, {n: (d / n).read_bytes() for n in (RESULTS_CSV, RESULTS_PARQUET) if (d / n).is_file()})
