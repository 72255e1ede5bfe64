"""perf variants: the same scene by one variant twice (saved, then compared) agrees pixel for pixel;
another variant (scalar_rgb, other random streams) differs by about its seed noise, not more."""
import numpy as np
import pytest

from platebench.bench.perf.variants import compare_images, perf_variants

pytestmark = pytest.mark.render


def test_a_variant_agrees_with_its_saved_images_and_scalar_within_seed_noise(tmp_path):
    saved = tmp_path / "llvm.npz"
    a = perf_variants(["llvm_ad_rgb"], 160, 120, spp=2, repeat=1, save=saved, log=lambda *_: None)
    assert a["variants"][0]["correct_match_count"] == 16
    b = perf_variants(["llvm_ad_rgb", "scalar_rgb"], 160, 120, spp=2, repeat=1, against=saved, log=lambda *_: None)
    same = b["variants"][0]["images_vs_saved"]
    assert set(same) == {"left_passive", "right_passive", "left_active", "right_active"}
    assert all(c["frac_pixels_equal"] == 1.0 and c["max_abs_diff"] == 0.0 for c in same.values())
    other = b["variants"][1]["images_vs_first"]
    for c in other.values():  # independent samples: |diff| ~ the seed noise (ratio ~1), never far above it
        assert 0.5 < c["mean_abs_diff"] / c["mean_abs_seed_noise"] < 2.0
    assert b["variants"][1]["throughput_ratio_vs_first"] > 0


def test_compare_images_counts_pixels_within_the_tolerance():
    ref = {"x": np.zeros((2, 2), np.float32)}
    noise = {"x": np.full((2, 2), 0.1, np.float32)}
    img = {"x": np.array([[0, 0], [0, 1e-3]], np.float32)}
    c = compare_images(img, ref, noise)["x"]
    assert c["frac_pixels_equal"] == 0.75 and np.isclose(c["max_abs_diff"], 1e-3)
    assert np.isclose(c["mean_abs_seed_noise"], 0.1)


def test_perf_gpu_runs_every_section_on_a_machine_without_a_gpu_and_says_so(tmp_path, capsys):
    """``platebench perf gpu`` (what the GPU machine is measured with) runs on the CPU too: every
    section (host pixels, whole sample, variants, the sweep pipeline) measured with its baseline,
    written to JSON, and the missing GPU said; tiny images so that it stays a test."""
    import json

    from platebench.bench.cli.main import main
    from platebench.scenes.render import runtime
    out = tmp_path / "gpu.json"
    assert main(["perf", "gpu", "--width", "160", "--height", "120", "--spp", "1", "--repeat", "1",
                 "--sweep-samples", "2", "--workers", "1", "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    fig = doc["figures"]
    assert doc["target"] == "gpu" and not fig["errors"], fig["errors"]
    gpu = runtime.has_cuda()
    assert fig["gpu_present"] == gpu and fig["variants"][-1] == "llvm_ad_rgb"
    sub = fig["subnormal"]["llvm_ad_rgb"]["passive"]
    assert len(sub["subnormal_per_channel"]) == 3 and sub["mean_axis2_render_s"] > 0 and sub["pixels"] == 160 * 120
    s = fig["sample"]["llvm_ad_rgb"]
    assert s["raw_4_images_s"] > 0 and s["whole_sample_s"] > 0 and s["second_sample_kernel_compiles"] == 0
    assert fig["variants_compared"]["variants"][0]["correct_match_count"] == 16
    sw = fig["sweep"]
    assert sw["pipeline"]["ok"] == 2 and sw["one_worker"]["ok"] == 2 and sw["pipeline"]["samples_per_s"] > 0
    printed = capsys.readouterr().out
    if not gpu:
        assert "no GPU present" in printed and "study false-boundary: not run" in printed
