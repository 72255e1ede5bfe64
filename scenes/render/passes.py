"""Renders in passes of bounded size: the one pass plan of every Mitsuba render, and its loop.

A render of W x H pixels at ``spp`` samples per pixel traces N = W H spp samples in Mitsuba's
``mi.render``, one C++ call that a Python signal handler cannot interrupt: the handler runs, and a
Ctrl-C or SIGTERM is raised, only once the call returns. So a render is split into passes of at most
``PASS_SAMPLES`` samples each, and whatever waits on it (an interrupt, a progress bar) is served
between passes.

The plan (``pass_plan``):

* N <= ``PASS_SAMPLES``: one pass, the single call ``mi.render(spp=spp, seed=seed)``, whose bytes
  these renders are (every test's; the benchmark's, 640 x 480 at spp 4, 1.2 M samples; the reference
  experiment's, 1280 x 960 at spp 16, 19.7 M).
* N > ``PASS_SAMPLES``: passes of P samples per pixel, P the largest power of two with
  W H P <= ``PASS_SAMPLES`` (1 when a single sample per pixel exceeds it: then a pass is W H
  samples), ``spp // P`` of them, then the rest ``spp % P`` as its binary digits, largest first
  (every pass a power of two, so the passes reuse the kernels Mitsuba compiles for power-of-two
  sample counts). Pass k is seeded ``pass_seed(seed, k)``.
  Mitsuba's JIT variants trace at most ``WAVEFRONT_LIMIT`` = 2^32 - 1 samples in one call; every
  pass of this plan stays under it whenever W H does (``fits_wavefront``), so Mitsuba never splits
  a call itself.

What a split render is: each pass is an independent render (its own seed; Mitsuba's independent
sampler gives every sample of a pass a PCG32 stream keyed by the seed and the sample's index), the
image is the mean of the passes weighted by their samples per pixel, sum_k spp_k I_k / spp, taken in
float64 and rounded to float32 once (subnormals flushed to zero, as ``scenes.render.film`` does). It
is therefore the same estimator over the same number of samples as one call, equal to it in
distribution (per pixel: the same expected value and variance), but not bit for bit: one call's
sample j of pixel p draws from the stream of index p spp + j, a pass's from p spp_k + j. The same
seed and the same plan give the same bytes, run after run. Units: samples (counts), seeds uint32.
"""
from __future__ import annotations

import numpy as np

from platebench.scenes.render.film import FLOAT32_TINY

__all__ = ["PASS_SAMPLES", "WAVEFRONT_LIMIT", "pass_plan", "pass_seed", "fits_wavefront", "render_in_passes",
           "flush_subnormal"]

# Mitsuba's JIT variants trace at most 2^32 - 1 samples in one wavefront (SamplingIntegrator::render).
WAVEFRONT_LIMIT = 0xFFFFFFFF
# The most samples of one pass, the longest a signal or a progress bar waits on a render; above the
# reference render's 1280 x 960 x 16 = 19.7 M samples, which stays one call.
PASS_SAMPLES = 2 ** 25


def fits_wavefront(width: int, height: int) -> bool:
    """Whether one sample per pixel of a W x H image fits Mitsuba's ``WAVEFRONT_LIMIT`` (then every pass
    of ``pass_plan`` does)."""
    return int(width) * int(height) <= WAVEFRONT_LIMIT


def pass_plan(width: int, height: int, spp: int, max_samples: int = PASS_SAMPLES) -> tuple[int, ...]:
    """Samples per pixel of each pass of a W x H render at ``spp`` (module doc); they sum to ``spp``.
    ``(spp,)`` when W H spp <= ``max_samples``."""
    width, height, spp, max_samples = int(width), int(height), int(spp), int(max_samples)
    if spp < 1 or width < 1 or height < 1 or max_samples < 1:
        raise ValueError(f"pass_plan: width {width}, height {height}, spp {spp}, max_samples {max_samples}: "
                         "each must be at least 1")
    pixels = width * height
    if pixels * spp <= max_samples:
        return (spp,)
    per = max(1, max_samples // pixels)
    per = 1 << (per.bit_length() - 1)  # the largest power of two not above it
    full, rest = divmod(spp, per)
    digits = tuple(1 << b for b in range(rest.bit_length() - 1, -1, -1) if rest >> b & 1)
    return (per,) * full + digits


def pass_seed(seed: int, k: int) -> int:
    """Mitsuba seed (uint32) of pass ``k`` of a render seeded ``seed``: ``seed`` itself for the first,
    a hash of (seed, k) for the others, so that no two passes of a sample's images (whose seeds are
    consecutive integers, ``scenes.naming.image_seed``) share a stream."""
    if k == 0:
        return int(seed)
    return int(np.random.SeedSequence([int(seed), int(k)]).generate_state(1, np.uint32)[0])


def flush_subnormal(a: np.ndarray) -> np.ndarray:
    """``a`` (float32, in place) with its subnormal entries set to +0 (``scenes.render.film``)."""
    a[np.abs(a) < FLOAT32_TINY] = 0.0
    return a


def render_in_passes(mi, scene, sensor: int, spp: int, seed: int, to_host, max_samples: int = PASS_SAMPLES,
                     on_pass=None) -> np.ndarray:
    """The image of ``scene``'s sensor ``sensor`` at ``spp`` samples per pixel, rendered by the plan
    (module doc): ``to_host(mi, img)`` turns one pass's Mitsuba tensor into a float32 host array
    ((H, W) or (H, W, C)); a split render returns the weighted mean of the passes' arrays (float32,
    subnormals flushed). ``on_pass(done_spp, spp)`` is called after each pass (the first signal or
    progress point; an exception it raises ends the render)."""
    size = scene.sensors()[sensor].film().crop_size()
    plan = pass_plan(int(size[0]), int(size[1]), spp, max_samples)
    if len(plan) == 1:
        img = to_host(mi, mi.render(scene, sensor=sensor, spp=spp, seed=seed))
        if on_pass is not None:
            on_pass(spp, spp)
        return img
    acc, done = None, 0
    for k, n in enumerate(plan):
        part = to_host(mi, mi.render(scene, sensor=sensor, spp=n, seed=pass_seed(seed, k)))
        if acc is None:
            acc = np.zeros(part.shape, np.float64)
        acc += part.astype(np.float64) * n
        del part
        done += n
        if on_pass is not None:
            on_pass(done, spp)
    acc /= spp
    return flush_subnormal(acc.astype(np.float32))
