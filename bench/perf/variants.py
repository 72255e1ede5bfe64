"""Benchmark ``variants``: the same scene rendered by two Mitsuba variants (e.g. ``cuda_ad_rgb`` on a
GPU beside ``llvm_ad_rgb`` on its CPU), compared pixel by pixel and in throughput.

For each variant: the reference experiment's 4 images at ``width x height``, ``spp`` (seed 0),
timed (best of ``repeat`` after a warm-up), the throughput in camera samples per second
(4 images x spp x W x H / render seconds), the whole sample's time (renders + ground truth), and
the paper's pipeline scored on it. Each image of a variant is compared with the FIRST variant's:
the fraction of pixels within 1e-5 of it, the mean and largest absolute difference, against the
first variant's own seed noise (seed 1 vs seed 0, mean absolute difference) as the yardstick.
Throughput ratios are against the first variant, measured in the same run.

A machine without one of the variants can save its images (``--save F.npz``) and another compare
with them (``--against F.npz``): then the pixels are compared across machines, the timings not.
"""
from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from platebench.bench.config import SampleConfig, SceneParams
from platebench.bench.io.atomic import write_bytes
from platebench.bench.io.report_records import RunTimings
from platebench.bench.run.render import render_sample
from platebench.reconstruction.paper.plate_region import ReconstructionError
from platebench.scenes.scene_spec import RenderSettings
from platebench.tolerances import tol

EQUAL_WITHIN = 1e-5  # radiance units: pixels this close count as equal


def _one(variant: str, width: int, height: int, spp: int, repeat: int, log) -> tuple[dict, dict, dict, float]:
    """(figures, seed-0 images, seed-1 images, samples per second of its renders) of one variant: float32
    (H, W) radiance per image name."""
    from platebench.bench.run.paper_method import reconstruct_sample  # noqa: PLC0415
    from platebench.bench.run.score import score_in_memory  # noqa: PLC0415
    from platebench.evaluation.metrics_row import MetricsRow  # noqa: PLC0415

    def cfg(seed):
        return SampleConfig(scene=SceneParams(width=width, height=height), render=RenderSettings(spp=spp, seed=seed),
                            variant=variant)
    sample, renderer = render_sample(cfg(0))  # warm-up: kernels compiled or loaded
    best, total, gt = np.inf, None, None
    for _ in range(repeat):
        sample, renderer = render_sample(cfg(0), renderer)
        timings = RunTimings.from_dict(sample.timings_s)
        if timings.renders_s < best:
            best, total, gt = timings.renders_s, timings.total_s, timings.ground_truth_s
    other, renderer = render_sample(cfg(1), renderer)
    samples_per_s = 4 * spp * width * height / best
    fig = {"variant": renderer.variant, "render_4_images_s": best, "samples_per_s": samples_per_s,
           "whole_sample_s": total, "ground_truth_s": gt}
    try:
        row = MetricsRow.from_score(score_in_memory(sample, reconstruct_sample(sample)))
        fig.update(centres_depth_rms_mm=row.centres_depth_rms_mm, correct_match_count=row.correct_match_count,
                   boundary_mean_mm=row.boundary_mean_mm)
        scored = (f"centres depth RMS {row.centres_depth_rms_mm:.4f} mm  boundary mean {row.boundary_mean_mm:.4f} mm  "
                  f"correct {row.correct_match_count}")
    except ReconstructionError as e:  # too small an image for the pipeline: say so, time the renders anyway
        fig["paper_error"] = scored = f"paper's pipeline: {e}"
    log(f"{renderer.variant:14s} 4 images {best:7.3f} s  {samples_per_s / 1e6:8.1f} M samples/s  "
        f"whole sample {total:6.2f} s  {scored}")

    def radiance(s):
        return {k: np.asarray(v, np.float32) for k, v in s.radiance.items()}
    return fig, radiance(sample), radiance(other), samples_per_s


def compare_images(imgs: dict, ref: dict, ref_seed1: dict) -> dict:
    """Per image name: agreement of ``imgs`` with ``ref`` against ``ref``'s own seed noise."""
    out = {}
    for k, v in imgs.items():
        d = np.abs(v - ref[k])
        out[k] = {"frac_pixels_equal": float(np.mean(d < EQUAL_WITHIN)), "mean_abs_diff": float(d.mean()),
                  "max_abs_diff": float(d.max()), "mean_abs_seed_noise": float(np.abs(ref_seed1[k] - ref[k]).mean())}
    return out


def perf_variants(variants: list[str], width: int = 640, height: int = 480, spp: int = 16, repeat: int = 2,
                  save=None, against=None, log=print) -> dict:
    """Render and compare ``variants`` (module doc); ``save``/``against``: an .npz of the first
    variant's images for a comparison across machines."""
    out, ref = {"image_size_px": [width, height], "spp": spp, "variants": []}, None
    first_rate = None  # the first variant's samples per second
    for i, v in enumerate(variants):
        fig, imgs, seed1, rate = _one(v, width, height, spp, repeat, log)
        if i == 0:
            ref, first_rate = (imgs, seed1), rate
            if save is not None:
                buf = io.BytesIO()  # written whole and atomically (bench.io.atomic), never half a file
                np.savez_compressed(buf, **imgs, **{f"seed1_{k}": a for k, a in seed1.items()})
                write_bytes(Path(save), buf.getvalue())
            if against is not None:
                with np.load(against) as z:
                    other = {k: z[k] for k in imgs}, {k: z[f"seed1_{k}"] for k in imgs}
                fig["images_vs_saved"] = compare_images(imgs, *other)
        else:
            fig["images_vs_first"] = compare_images(imgs, *ref)
            fig["throughput_ratio_vs_first"] = rate / first_rate
        for what, cmp in (("first", fig.get("images_vs_first")), ("saved", fig.get("images_vs_saved"))):
            if cmp:
                eq = min(c["frac_pixels_equal"] for c in cmp.values())
                worst = max(c["mean_abs_diff"] / max(c["mean_abs_seed_noise"], tol.tiny) for c in cmp.values())
                log(f"{'':14s} vs {what}: >= {eq * 100:.3f} % of pixels within {EQUAL_WITHIN:g}; mean |diff| at most "
                    f"{worst:.2g} x the seed noise" + (f"; throughput x{fig['throughput_ratio_vs_first']:.2f}"
                                                       if what == "first" else ""))
        out["variants"].append(fig)
    return out


__all__ = ["perf_variants", "compare_images", "EQUAL_WITHIN"]
