"""Render a sequence of projector patterns for both cameras with one renderer, at the cost of a few images.

Peer structured-light methods (Gray code, phase shifting) project many frames. Two exact
properties of the scene's light transport make most of those renders unnecessary:

* **Linearity.** Along one set of camera paths (one seed), a pixel's radiance is
  ``A + sum_s w_s P(x_s)``: the ambient light's part ``A`` plus, for each path vertex ``s`` that
  connects to the projector, a weight times the pattern's value where that connection leaves
  it. The paths do not depend on the pattern (the projector is a point light reached by
  next-event estimation and is not importance-sampled by its image; emitter selection uses
  fixed weights), so the image of the complement ``1 - G`` of a pattern ``G`` is
  ``I(white) + I(black) - I(G)``, to float32 rounding. A sequence that holds complementary
  pairs (OpenCV's Gray code: every bit plane and its inverse, then black and white) renders
  only one frame of each pair.
* **Channels.** With a grey plate (and white lights) the renderer's three colour channels are
  three independent renders along the same paths; ``PlateRenderer.render_patterns`` puts three
  patterns in one launch, each image to the last bit what a render of that pattern alone gives
  in that channel.

So the frames that must be rendered (``SequencePlan.rendered``: the sequence's frames less the
complements, plus black and white if the sequence lacks them and has more complements than
that) are rendered three per launch (one for a conductor), all with the sequence's one render
seed, and the complements follow. A 22-frame sub-pixel Gray-code sequence costs 4 launches per
camera instead of 22; OpenCV's 42-frame sequence 8 instead of 42 (``platebench perf
sequences``). Nothing is rebuilt between launches: the projector's texture is swapped by a
parameter update and the scene's own pattern comes back at the next image.

Seeds: every frame of camera c is rendered along the paths of render seed
``image_seed(frame_seed(base, 0), c, "active")`` (one path set per camera, as linearity needs);
frame i's sensor noise has its own seed ``image_seed(frame_seed(base, i), c, "active")``, so
every frame carries independent camera noise, and the same base seed gives the same bytes.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from platebench.scenes.naming import CAMERAS, image_seed
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.scene_spec import RenderSettings
from platebench.scenes.sensor_model import SensorModel

__all__ = ["RenderedSequence", "SequencePlan", "frame_seed", "plan_sequence", "render_pattern_sequence"]

_SEED_SPAN = 1 << 28  # image_seed multiplies by 4: stay below 2**31


def frame_seed(base_seed: int, index: int) -> int:
    """Distinct reproducible seed of frame ``index`` (differs from the sample's own seed)."""
    return int((base_seed * 1_000_003 + 7919 * (index + 1)) % _SEED_SPAN)


@dataclass(frozen=True)
class RenderedSequence:
    """Digitized captures of a pattern sequence: camera -> (N, H, W) uint8/uint16, the seconds its
    renders and its derivation and digitization took, and ``launches`` (renders per camera the sequence
    took)."""

    name: str
    images: dict
    n_frames: int
    render_s: float
    derive_and_digitize_s: float
    launches: int = 0

    @property
    def timings_s(self) -> dict:
        """The timings as written to files: {"render_s", "derive_and_digitize_s"} in seconds."""
        return {"render_s": self.render_s, "derive_and_digitize_s": self.derive_and_digitize_s}

    def __getitem__(self, camera: str) -> np.ndarray:
        return self.images[camera]


@dataclass(frozen=True)
class SequencePlan:
    """How a sequence's frames are obtained: ``rendered`` (pattern index: a frame of the sequence, or
    -1 black and -2 white when the sequence lacks them), and ``complement[i] = j``: frame i is
    the complement of frame j (``I(white) + I(black) - I(j)``); ``black``/``white``: their
    positions in ``rendered`` (None when no frame needs them)."""

    rendered: tuple
    complement: dict
    black: int | None
    white: int | None


def _full_scale(frames: np.ndarray) -> float:
    if frames.dtype == np.uint8:
        return 255.0
    if frames.dtype == np.uint16:
        return 65535.0
    return 1.0


def plan_sequence(frames: np.ndarray) -> SequencePlan:
    """Which frames of ``frames`` ((N, Hp, Wp)) must be rendered and which are exact complements of
    another frame (module doc). Frames are compared in their own integer (or float) values."""
    full = _full_scale(frames)
    flat = frames.reshape(len(frames), -1)
    black = [i for i in range(len(frames)) if not flat[i].any()]
    white = [i for i in range(len(frames)) if np.all(flat[i] == full)]
    complement, basis = {}, []
    for i in range(len(frames)):
        if i in black or i in white:
            continue
        inv = full - flat[i]
        j = next((j for j in basis if np.array_equal(flat[j], inv.astype(flat.dtype))), None)
        if j is not None:
            complement[i] = j
        else:
            basis.append(i)
    missing = int(not black) + int(not white)
    if complement and len(complement) <= missing:  # cheaper to render the complements themselves
        basis = sorted(basis + list(complement))
        complement = {}
    rendered = list(basis) + black[:1] + white[:1]
    b = w = None
    if complement:
        if not black:
            rendered.append(-1)
        if not white:
            rendered.append(-2)
        b = rendered.index(black[0] if black else -1)
        w = rendered.index(white[0] if white else -2)
    rendered += black[1:] + white[1:]  # repeated black/white frames are rendered as given
    return SequencePlan(tuple(rendered), complement, b, w)


def _pattern_values(frames: np.ndarray, index: int) -> np.ndarray:
    """Frame ``index`` (or -1 black, -2 white) as float32 values in [0, 1]."""
    shape = frames.shape[1:]
    if index == -1:
        return np.zeros(shape, np.float32)
    if index == -2:
        return np.ones(shape, np.float32)
    return np.asarray(frames[index]).astype(np.float32) / np.float32(_full_scale(frames))


def render_pattern_sequence(renderer: PlateRenderer, frames, settings: RenderSettings = RenderSettings(),
                            sensor: SensorModel = SensorModel(), cameras=CAMERAS, name: str = "sequence",
                            progress=None) -> RenderedSequence:
    """Render every frame (projector image, (N, Hp, Wp) uint8/uint16 or float in [0, 1]) for ``cameras``.

    Uses the renderer's current scene (rig, lighting, plate) and only swaps the projector's image
    (module doc); ``progress(i, n)`` is called after each launch. Returns the digitized stacks."""
    frames = np.asarray(frames)
    n = len(frames)
    if n == 0:
        raise ValueError("render_pattern_sequence: no frames to render")
    spec = renderer.spec
    pw, ph = spec.projector.pattern.width, spec.projector.pattern.height
    if frames.ndim != 3 or frames.shape[1:] != (ph, pw):
        raise ValueError(f"frames are {frames.shape[1:][::-1]} px; the projector is {pw}x{ph}")
    plan = plan_sequence(frames)
    k = renderer.patterns_per_launch
    groups = [plan.rendered[i:i + k] for i in range(0, len(plan.rendered), k)]
    builds_before = renderer.scene_builds
    dtype = np.uint8 if sensor.bit_depth == 8 else np.uint16
    H, W = spec.rig.left.height, spec.rig.left.width
    out = {cam: np.empty((n, H, W), dtype) for cam in cameras}
    rs = RenderSettings(spp=settings.spp, seed=frame_seed(settings.seed, 0))
    t_render = t_derive = 0.0
    try:
        for cam in cameras:
            rendered = {}
            for g in groups:
                t = time.perf_counter()
                imgs = renderer.render_patterns(cam, np.stack([_pattern_values(frames, i) for i in g]), rs)
                rendered.update(zip(g, imgs))
                t_render += time.perf_counter() - t
                if progress is not None:
                    progress(len(rendered), len(plan.rendered))
            t = time.perf_counter()
            if plan.complement:
                base = rendered[plan.rendered[plan.white]] + rendered[plan.rendered[plan.black]]
                for i, j in plan.complement.items():
                    rendered[i] = base - rendered[j]
            for i in range(n):
                out[cam][i] = sensor.digitize(rendered[i], seed=image_seed(frame_seed(settings.seed, i), cam, "active"))
            t_derive += time.perf_counter() - t
    finally:
        renderer.set_lighting("active")  # the scene's own pattern back in the projector
    if renderer.scene_builds != builds_before:
        raise RuntimeError("swapping the projector pattern rebuilt the Mitsuba scene (structure changed)")
    for a in out.values():
        a.setflags(write=False)
    return RenderedSequence(name, out, n, t_render, t_derive, len(groups))
