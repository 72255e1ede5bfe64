"""Renders in passes (``scenes.render.passes``): one call up to the pass size, the same bytes for the
same seed, the same distribution as one call when split, and a long render that answers a signal.

A split render cannot repeat the bytes of one Mitsuba call (its samples draw from other streams), so
the check is statistical: the per-pixel difference between a split render and a one-call render of the
same seed must have mean zero within its own standard error over the image's pixels (independent
pixels), and the per-pixel variance over several seeds must match one call's. The signal test runs
``platebench render`` at 320 x 240 px and spp 65536 (5.0e9 samples, more than one of Mitsuba's
wavefronts holds) and signals it just after a pass, the longest wait there is.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import threading
import time

import numpy as np
import pytest

from tools.faults.run_attacks import STATUS, cli_cmd, leftovers
from platebench.plates import CylindricalBend, PlateSpec, build_plate
from platebench.scenes.naming import image_seed
from platebench.scenes.render import runtime
from platebench.scenes.render.film import grey_to_host
from platebench.scenes.render.passes import PASS_SAMPLES, WAVEFRONT_LIMIT, pass_plan, pass_seed
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.scene_spec import RenderSettings, reference_scene

W, H, SPP = 64, 48, 64
FORCED = W * H * 8  # a pass size that splits the 64 x 48 render at spp 64 into 8 passes of 8
Z_MAX = 4.0  # |mean difference| over the image, in standard errors: 6e-5 two-sided for a true zero
SEEDS = 8  # renders per kind whose per-pixel variance is compared
SPREAD = (0.8, 1.25)  # a split render's per-pixel variance over one call's (one call against one call at
                      # other seeds differs by 4 % over 40 seeds each: heavy-tailed pixels)
SIGNAL_AFTER_S = 3.0  # the signal is sent this long after the start at the earliest, just after a pass
EXIT_WITHIN_S = 5.0  # ... and the command must have ended with 130 / 143 this long after it
PASSES_WITHIN = 1.5  # ... or, where a pass takes longer, within this many passes' time


def test_the_plan():
    assert pass_plan(640, 480, 4) == (4,)  # the benchmark's images: one call
    assert pass_plan(1280, 960, 16) == (16,)  # the reference experiment's: one call
    assert pass_plan(W, H, SPP, FORCED) == (8,) * 8
    assert pass_plan(W, H, 75, FORCED) == (8,) * 9 + (2, 1)  # the rest as powers of two
    assert pass_plan(8192, 8192, 3) == (1, 1, 1)  # a pass is at least one sample per pixel
    plan = pass_plan(320, 240, 65536)
    assert sum(plan) == 65536 and max(plan) * 320 * 240 <= PASS_SAMPLES and len(set(plan)) == 1
    assert all(sum(pass_plan(8192, 8192, s)) == s and max(pass_plan(8192, 8192, s)) * 8192 ** 2 <= WAVEFRONT_LIMIT
               for s in (1, 64, 65, 1025, 65536))
    seeds = [pass_seed(s, k) for s in range(8) for k in range(1, 40)]
    assert len(set(seeds)) == len(seeds) and not set(seeds) & set(range(64)) and pass_seed(5, 0) == 5


@pytest.fixture(scope="module")
def renderers():
    scene = reference_scene(width=W, height=H, f_px=100.0)
    plate = build_plate(PlateSpec(0.1165, 0.0735, deformation=CylindricalBend(np.radians(20.0))))
    return PlateRenderer(scene, plate), PlateRenderer(scene, plate, pass_samples=FORCED)


@pytest.mark.render
def test_a_render_within_the_pass_size_is_one_mitsuba_call(renderers):
    one, _ = renderers
    mi = one.mi
    got = one.render("left", "passive", RenderSettings(spp=SPP, seed=2))
    img = mi.render(one.scene, sensor=0, spp=SPP, seed=image_seed(2, "left", "passive"))
    assert np.array_equal(got.view(np.uint32), grey_to_host(mi, img).view(np.uint32))


@pytest.mark.render
@pytest.mark.parametrize("lighting", ["passive", "active"])
def test_a_split_render_repeats_its_bytes_and_matches_one_call_in_distribution(renderers, lighting):
    one, split = renderers
    passes = []
    a = split.render("left", lighting, RenderSettings(spp=SPP, seed=2), on_pass=lambda d, n: passes.append(d))
    assert passes == [8 * (k + 1) for k in range(8)]
    b = split.render("left", lighting, RenderSettings(spp=SPP, seed=2))
    assert a.dtype == np.float32 and a.shape == (H, W)
    assert np.array_equal(a.view(np.uint32), b.view(np.uint32))  # the same seed: the same bytes
    u = one.render("left", lighting, RenderSettings(spp=SPP, seed=2))
    v = one.render("left", lighting, RenderSettings(spp=SPP, seed=5))
    assert not np.array_equal(a, u)  # split: other streams than one call's
    # the same expected value: the per-pixel difference has mean zero within its standard error ...
    d, ref = (a - u).astype(np.float64).ravel(), (v - u).astype(np.float64).ravel()
    z = d.mean() / (d.std(ddof=1) / np.sqrt(d.size))
    assert abs(z) < Z_MAX, (z, a.mean(), u.mean(), v.mean())
    # ... and the image means differ by no more than two one-call renders at other seeds may
    assert abs(a.mean() - u.mean()) < Z_MAX * ref.std(ddof=1) / np.sqrt(ref.size)
    # the same variance: per pixel, over SEEDS seeds each
    seeds = range(10, 10 + SEEDS)
    var = [np.stack([r.render("left", lighting, RenderSettings(spp=SPP, seed=s)) for s in seeds]).astype(np.float64)
           .var(axis=0, ddof=1).mean() for r in (split, one)]
    assert SPREAD[0] < var[0] / var[1] < SPREAD[1], var


@pytest.mark.render
def test_a_split_pattern_render_keeps_its_channels_apart(renderers):
    """Three patterns in one launch, in passes: pattern c's image is still, bit for bit, that of
    pattern c alone (each pass's channel c is, and the passes are averaged per channel)."""
    _, split = renderers
    rng = np.random.default_rng(1)
    hp, wp = split.spec.projector.pattern.height, split.spec.projector.pattern.width
    pats = (rng.random((3, hp, wp)) > 0.5).astype(np.float32)
    three = split.render_patterns("left", pats, RenderSettings(spp=SPP, seed=4))
    alone = split.render_patterns("left", pats[:1], RenderSettings(spp=SPP, seed=4))
    assert np.array_equal(three[0], alone[0])


@pytest.mark.render
def test_ground_truth_cast_in_bands_is_the_same_bytes(renderers, monkeypatch):
    from platebench.scenes.render import ground_truth_device
    from platebench.scenes.render.ground_truth import GroundTruthCaster
    one, _ = renderers
    if one.variant.startswith("scalar"):
        pytest.skip("scalar variant: no device ground truth")
    whole = GroundTruthCaster(one).camera("left")
    monkeypatch.setattr(ground_truth_device, "BAND_PIXELS", 100)  # bands of a few rows of the plate's window
    banded = GroundTruthCaster(one).camera("left")
    assert whole.mask.sum() > 100
    for name in ("depth64", "points", "normals", "mask", "proj_uv", "feature"):
        a, b = getattr(whole, name), getattr(banded, name)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), name


def _signalled(tmp_path, sig) -> tuple[int, float, float, str]:
    """``platebench render`` at 320 x 240 px, spp 65536, sent ``sig`` just after its second pass (at least
    SIGNAL_AFTER_S after its start): (exit status, seconds from the signal to the exit, seconds of its
    second pass, stderr)."""
    out = tmp_path / f"s-{signal.Signals(sig).name}"
    env = dict(os.environ, PLATEBENCH_PROGRESS="1")
    t0 = time.monotonic()
    p = subprocess.Popen(cli_cmd("render", "--out", out, "--width", "320", "--height", "240", "--spp", "65536"),
                         cwd=tmp_path, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    err, passes, two = [], {}, threading.Event()

    def read():  # the progress bar's "render left_passive DONE/65536 spp", and when each DONE was first shown
        while chunk := os.read(p.stderr.fileno(), 4096):
            err.append(chunk.decode(errors="replace"))
            for done in re.findall(r"(\d+)/65536 spp", "".join(err[-2:])):
                passes.setdefault(int(done), time.monotonic())
            if len(passes) >= 2:
                two.set()
    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        assert two.wait(120), "no two passes were reported: " + "".join(err)[-2000:]
        time.sleep(max(0.0, SIGNAL_AFTER_S - (time.monotonic() - t0)))
        first, second = sorted(passes.values())[:2]
        sent = time.monotonic()
        p.send_signal(sig)
        try:
            rc = p.wait(timeout=max(EXIT_WITHIN_S, PASSES_WITHIN * (second - first)))
        except subprocess.TimeoutExpired:
            rc = None
        took = time.monotonic() - sent
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
        reader.join(5)
    assert rc == STATUS[sig], (rc, took, "".join(err)[-2000:])
    assert not out.exists() and not leftovers(tmp_path), (sorted(tmp_path.iterdir()))
    return rc, took, second - first, "".join(err)


@pytest.mark.render
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_long_render_answers_a_signal_within_seconds(tmp_path, sig):
    """Within EXIT_WITHIN_S of the signal; on a machine so busy that one pass takes longer than that, within
    PASSES_WITHIN passes (the pass under way, then the way out)."""
    rc, took, pass_s, err = _signalled(tmp_path, sig)
    assert took < max(EXIT_WITHIN_S, PASSES_WITHIN * pass_s) and "Traceback" not in err, (took, pass_s, err[-2000:])
