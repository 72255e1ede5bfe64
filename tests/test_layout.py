"""The dataset layout's names (bench/io/layout.py): one source, used by the sweep and the report."""
import pytest

from platebench.bench.io import layout
from platebench.bench.report import inputs
from platebench.bench.sweep import dataset


def test_method_folder_is_one_safe_path_component():
    assert layout.method_folder("paper") == "paper"
    assert layout.method_folder("blockmatch-points") == "blockmatch-points"
    assert layout.method_folder("pkg.mod:func") == "pkg.mod_func"
    assert layout.method_folder("a/../b c") == "a_.._b_c"
    for bad in ("", "..", ".", "//"):
        with pytest.raises(ValueError, match="no usable folder name"):
            layout.method_folder(bad)


def test_sweep_and_report_read_the_same_names():
    assert dataset.MANIFEST == inputs.MANIFEST == layout.MANIFEST
    assert dataset.RESULTS_CSV == inputs.RESULTS_CSV and dataset.SAMPLES == inputs.SAMPLES
    assert inputs.DATASET_FORMAT == dataset.FORMAT == layout.FORMAT
