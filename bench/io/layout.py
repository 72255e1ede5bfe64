"""The sweep dataset's layout on disk: file and folder names, format tags (one source).

::

    DATASET/manifest.json            MANIFEST: spec, status, checksums of every sample
    DATASET/spec.toml                SPEC_COPY: the sweep spec as run
    DATASET/results.csv|.parquet     RESULTS_CSV / RESULTS_PARQUET: one row per (sample, method)
    DATASET/results.sha256.json      RESULTS_CHECKSUMS: each table's sha256 (bench.io.table_checksums)
    DATASET/samples/<id>/result.json RESULT: the sample's record
    DATASET/samples/<id>/sample/     the rendered sample (bench.io.sample_files)
    DATASET/samples/<id>/recon/<m>/  a method's output, <m> = method_folder(method name)

The sweep (``bench.sweep.dataset``) writes it; the report, the exporter and ``PlateBenchDataset``
read it.
"""
from __future__ import annotations

import re

from platebench.scenes.naming import IMAGE_NAMES

FORMAT = "platebench-sweep"
VERSION = 1
RESULT_FORMAT = "platebench-sweep-result"
MANIFEST = "manifest.json"
SPEC_COPY = "spec.toml"
RESULTS_CSV = "results.csv"
RESULTS_PARQUET = "results.parquet"
RESULTS_CHECKSUMS = "results.sha256.json"  # the sha256 of each results table, written after them
SAMPLES = "samples"
RESULT = "result.json"
SAMPLE = "sample"
RECON = "recon"
# the files of a sample the paper's method reads (``platebench reconstruct``): the four images, the
# calibration and the pattern, never ground truth
METHOD_INPUTS = (*(f"images/{n}.png" for n in IMAGE_NAMES), "calib.json", "pattern.json")

_UNSAFE = re.compile(r"[^A-Za-z0-9._+-]")


def method_folder(method: str) -> str:
    """The folder name of a method's output under ``recon/``: the name with every character outside
    letters, digits and ``. _ + -`` replaced by ``_`` (a plug-in ``pkg.mod:func`` gives ``pkg.mod_func``),
    so that it is one path component on every file system and in a URL. Raises ValueError for a name
    that leaves nothing usable (empty, ``.`` or ``..``)."""
    name = _UNSAFE.sub("_", str(method))
    if name.strip("._") == "":
        raise ValueError(f"method name {method!r} gives no usable folder name")
    return name


__all__ = ["FORMAT", "VERSION", "RESULT_FORMAT", "MANIFEST", "SPEC_COPY", "RESULTS_CSV", "RESULTS_PARQUET", "RESULTS_CHECKSUMS",
           "SAMPLES", "RESULT", "SAMPLE", "RECON", "method_folder"]
