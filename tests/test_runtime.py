"""libLLVM selection: a bad or missing libLLVM must never abort the process."""
from __future__ import annotations

import glob
import json

import pytest

from tests.conftest import run_cli

LLVM15 = sorted(glob.glob("/usr/lib/*-linux-gnu/libLLVM-15.so*")) + sorted(glob.glob("/usr/lib/libLLVM-15.so*"))


@pytest.mark.skipif(not LLVM15, reason="no system libLLVM-15 on this machine")
def test_user_pointing_at_llvm15_is_not_killed_and_gets_a_good_llvm(tmp_path):
    """DRJIT_LIBLLVM_PATH=libLLVM-15 would SIGABRT drjit; platebench must pick a good one."""
    p = run_cli("render", "--out", tmp_path / "s", "--width", "64", "--height", "48", "--spp", "1",
                env={"DRJIT_LIBLLVM_PATH": LLVM15[0]})
    assert p.returncode == 0, p.stderr
    assert json.loads((tmp_path / "s" / "sample.json").read_text())["variant"] == "llvm_ad_rgb"


@pytest.mark.skipif(not LLVM15, reason="no system libLLVM-15 on this machine")
def test_only_llvm15_available_falls_back_to_scalar_with_one_line_warning(tmp_path):
    p = run_cli("render", "--out", tmp_path / "s", "--width", "48", "--height", "36", "--spp", "1",
                env={"DRJIT_LIBLLVM_PATH": LLVM15[0], "PLATEBENCH_LLVM_CANDIDATES": LLVM15[0]})
    assert p.returncode == 0, p.stderr  # a signal would give a negative return code
    warnings = [line for line in p.stderr.splitlines() if line.startswith("platebench: warning")]
    assert len(warnings) == 1 and "scalar_rgb" in warnings[0] and "karellen-llvm-core" in warnings[0]
    assert json.loads((tmp_path / "s" / "sample.json").read_text())["variant"] == "scalar_rgb"


def test_explicit_llvm_variant_without_good_llvm_is_a_clear_error(tmp_path):
    p = run_cli("render", "--out", tmp_path / "s", "--width", "48", "--height", "36", "--variant", "llvm_ad_rgb",
                env={"DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM.so", "PLATEBENCH_LLVM_CANDIDATES": ""})
    assert p.returncode == 2
    assert "platebench: error: variant llvm_ad_rgb needs libLLVM >= 16" in p.stderr
    assert not (tmp_path / "s").exists()


def test_info_reports_the_chosen_llvm():
    p = run_cli("info")
    assert p.returncode == 0, p.stderr
    info = json.loads(p.stdout)
    assert int(info["renderer"]["llvm_version"].split(".")[0]) >= 16
    assert info["renderer"]["variant"] in ("llvm_ad_rgb", "cuda_ad_rgb")
