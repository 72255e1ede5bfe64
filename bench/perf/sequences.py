"""Benchmark ``sequences``: what a structured-light peer's sample costs against a paper sample.

In one run, on one renderer (kernels compiled by a warm-up), best of ``repeat`` each, timed
alternately so that a busy machine slows all alike, in wall-clock and CPU seconds (all threads
of the process: the steadier figure on a shared machine):

* a **paper sample**: the sample (4 images + all ground truth, ``render_sample``), the paper's
  pipeline and its score, as a sweep makes one;
* a **Gray-code sample**: the same sample, the sub-pixel Gray-code sequence (10 column bit
  planes, their inverses, black and white: 22 frames per camera) rendered by
  ``render_pattern_sequence`` (patterns three to a launch, inverses by linearity), decoded
  (``graycode.decode_subpixel``) and scored (``field_scores.score_disparity``);
* the **sequence frame by frame**, the baseline of its rendering: the same 22 frames per camera,
  one launch each, each with a seed of its own (a sequence rendered frame by frame);
* the **phase-shift sequence** (4 fringes + 7 Gray-code planes, no complements: 4 launches per
  camera) for its launch count and time.

Ratios: Gray-code sample / paper sample (target <= 3), the sequence's renders / the paper
sample's 4 raw renders, frame-by-frame / packed.
"""
from __future__ import annotations

import time

import numpy as np

from platebench.bench.config import SampleConfig
from platebench.bench.perf.benchmarks import _raw_renders
from platebench.bench.run.pattern_sequences import plan_sequence, render_pattern_sequence
from platebench.bench.run.render import render_sample
from platebench.bench.run.score import score_in_memory
from platebench.scenes.scene_spec import RenderSettings

__all__ = ["perf_sequences", "GRAY_TARGET"]

GRAY_TARGET = 3.0  # a Gray-code sample costs at most this many paper samples


def _timed(fn) -> tuple[float, float]:
    """(wall s, CPU s) of one call."""
    c, t = time.process_time(), time.perf_counter()
    fn()
    return time.perf_counter() - t, time.process_time() - c


def perf_sequences(cfg: SampleConfig, repeat: int = 2, log=print) -> dict:
    """The figures of the module doc for the sample of ``cfg``."""
    from platebench.evaluation.field_scores import FieldTruth, score_disparity  # noqa: PLC0415
    from platebench.reconstruction.paper.pipeline import projector_feature_rays, reconstruct  # noqa: PLC0415
    from platebench.reconstruction.peers import graycode, phase_shift  # noqa: PLC0415

    sample, renderer = render_sample(cfg)
    proj = sample.scene.projector
    pw, ph = proj.pattern.width, proj.pattern.height
    gray = graycode.graycode_sequence(pw, ph).columns_only()
    phase = phase_shift.phase_shift_sequence(pw, ph)
    rig, rays = sample.scene.rig, projector_feature_rays(proj.camera, proj.pattern)

    def paper_sample():
        s, _ = render_sample(cfg, renderer)
        score_in_memory(s, reconstruct(s.digital, rig, rays, proj.pattern))

    def gray_sample():
        s, _ = render_sample(cfg, renderer)
        cap = render_pattern_sequence(renderer, gray.images, cfg.render, cfg.sensor, name="graycode")
        res = graycode.decode_subpixel(cap["left"], cap["right"], gray, rig)
        g, plate = s.gt, s.plate
        truth = FieldTruth.from_maps(rig, g["left"].depth64, g["left"].mask, g["left"].points, g["right"].depth64,
                                     g["right"].mask, plate.mesh, plate.top_faces)
        score_disparity(np.where(res.valid, res.disparity, np.inf), truth, what="graycode-subpx disparity")

    def frame_by_frame():
        frames = gray.images.astype(np.float32) / np.float32(255.0)
        for cam in ("left", "right"):
            for i in range(len(frames)):
                renderer.render_patterns(cam, frames[i:i + 1], RenderSettings(spp=cfg.render.spp, seed=cfg.render.seed + i))

    jobs = {"paper_sample": paper_sample, "graycode_sample": gray_sample, "raw_4_images": _raw_renders(renderer, cfg),
            "graycode_sequence": lambda: render_pattern_sequence(renderer, gray.images, cfg.render, cfg.sensor),
            "graycode_frame_by_frame": frame_by_frame,
            "phase_sequence": lambda: render_pattern_sequence(renderer, phase.images, cfg.render, cfg.sensor)}
    gray_sample()  # warm-up: the three-channel projector's kernels
    best = {k: [np.inf, np.inf] for k in jobs}
    for _ in range(repeat):
        for k, fn in jobs.items():
            wall, cpu = _timed(fn)
            best[k] = [min(best[k][0], wall), min(best[k][1], cpu)]
    per_launch = renderer.patterns_per_launch
    launches = {name: -(-len(plan_sequence(seq.images).rendered) // per_launch)
                for name, seq in (("graycode", gray), ("phase", phase))}
    out = {"image_size_px": [cfg.scene.width, cfg.scene.height], "spp": cfg.render.spp, "variant": renderer.variant,
           "patterns_per_launch": renderer.patterns_per_launch, "graycode_frames_per_camera": int(gray.n_images),
           "graycode_launches_per_camera": launches["graycode"], "phase_frames_per_camera": int(len(phase.images)),
           "phase_launches_per_camera": launches["phase"], "ratio_target": GRAY_TARGET}
    for k, (wall, cpu) in best.items():
        out[f"{k}_s"], out[f"{k}_cpu_s"] = wall, cpu
    for what, i in (("", 0), ("_cpu", 1)):
        out[f"ratio_graycode_sample_over_paper_sample{what}"] = best["graycode_sample"][i] / best["paper_sample"][i]
        out[f"ratio_graycode_sequence_over_raw_4_images{what}"] = best["graycode_sequence"][i] / best["raw_4_images"][i]
        out[f"ratio_frame_by_frame_over_sequence{what}"] = best["graycode_frame_by_frame"][i] / best["graycode_sequence"][i]
    r, rc = out["ratio_graycode_sample_over_paper_sample"], out["ratio_graycode_sample_over_paper_sample_cpu"]
    out["ratio_met"] = bool(rc <= GRAY_TARGET)
    log(f"paper sample (4 images + GT, pipeline, score)   {best['paper_sample'][0]:7.2f} s  CPU {best['paper_sample'][1]:7.2f} s")
    log(f"Gray-code sample (+ {gray.n_images} frames x 2 cameras in "
        f"{2 * launches['graycode']} launches, decode, score) {best['graycode_sample'][0]:7.2f} s  CPU "
        f"{best['graycode_sample'][1]:7.2f} s   ratio {r:.2f}, CPU {rc:.2f} (target <= {GRAY_TARGET:g}: "
        f"{'met' if out['ratio_met'] else 'NOT met'})")
    log(f"Gray-code sequence alone                         {best['graycode_sequence'][0]:7.2f} s  CPU "
        f"{best['graycode_sequence'][1]:7.2f} s   {out['ratio_graycode_sequence_over_raw_4_images_cpu']:.2f} x the "
        "paper sample's 4 raw renders (CPU)")
    log(f"same frames one launch each (baseline)           {best['graycode_frame_by_frame'][0]:7.2f} s  CPU "
        f"{best['graycode_frame_by_frame'][1]:7.2f} s   x{out['ratio_frame_by_frame_over_sequence_cpu']:.1f} the "
        "packed sequence (CPU)")
    log(f"phase-shift sequence ({len(phase.images)} frames x 2 cameras in {2 * launches['phase']} launches) "
        f"{best['phase_sequence'][0]:7.2f} s  CPU {best['phase_sequence'][1]:7.2f} s")
    return out
