"""Render a sequence of projector patterns for both cameras with one renderer.

Peer structured-light methods (Gray code, phase shifting) project many frames. Each
frame is rendered by swapping the projector's pattern through
``PlateRenderer.set_scene`` (a parameter update: no scene rebuild, no kernel
recompilation), rendered under "active" lighting, and digitized by the sample's
``SensorModel``. The renderer's scene is restored afterwards.

Seeds: frame i of camera c uses the Monte Carlo seed ``frame_seed(base, i)`` (through
``image_seed`` inside the renderer, so the two cameras differ) and the sensor-noise
seed ``image_seed(frame_seed(base, i), c, "active")``: every frame carries its own
noise, and the same base seed gives the same bytes.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np

from platebench.scenes.naming import CAMERAS, image_seed
from platebench.scenes.pattern import Pattern
from platebench.scenes.render.renderer import PlateRenderer
from platebench.scenes.scene_spec import RenderSettings
from platebench.scenes.sensor_model import SensorModel

__all__ = ["RenderedSequence", "frame_seed", "render_pattern_sequence"]

_SEED_SPAN = 1 << 28  # image_seed multiplies by 4: stay below 2**31


def frame_seed(base_seed: int, index: int) -> int:
    """Distinct reproducible render seed of frame ``index`` (differs from the sample's own seed)."""
    return int((base_seed * 1_000_003 + 7919 * (index + 1)) % _SEED_SPAN)


@dataclass(frozen=True)
class RenderedSequence:
    """Digitized captures of a pattern sequence: camera -> (N, H, W) uint8/uint16, plus timings."""

    name: str
    images: dict
    n_frames: int
    timings_s: dict

    def __getitem__(self, camera: str) -> np.ndarray:
        return self.images[camera]


def _as_pattern(frame) -> Pattern:
    img = np.asarray(frame)
    if img.dtype == np.uint8:
        img = img.astype(np.float32) / 255.0
    elif img.dtype == np.uint16:
        img = img.astype(np.float32) / 65535.0
    return Pattern(np.asarray(img, np.float32), (), None, {"kind": "sequence frame"})


def render_pattern_sequence(renderer: PlateRenderer, frames, settings: RenderSettings = RenderSettings(),
                            sensor: SensorModel = SensorModel(), cameras=CAMERAS, name: str = "sequence",
                            progress=None) -> RenderedSequence:
    """Render every frame (projector image, (N, Hp, Wp) uint8/uint16 or float in [0, 1]) for ``cameras``.

    Uses the renderer's current scene (rig, lighting, plate) and only swaps the pattern;
    ``progress(i, n)`` is called after each frame. Returns the digitized stacks.
    """
    frames = list(frames) if not isinstance(frames, np.ndarray) else frames
    n = len(frames)
    if n == 0:
        raise ValueError("render_pattern_sequence: no frames to render")
    spec = renderer.spec
    pw, ph = spec.projector.pattern.width, spec.projector.pattern.height
    builds_before = renderer.scene_builds
    dtype = np.uint8 if sensor.bit_depth == 8 else np.uint16
    H, W = spec.rig.left.height, spec.rig.left.width
    out = {cam: np.empty((n, H, W), dtype) for cam in cameras}
    t_render = t_swap = 0.0
    try:
        for i in range(n):
            pat = _as_pattern(frames[i])
            if (pat.width, pat.height) != (pw, ph):
                raise ValueError(f"frame {i} is {pat.width}x{pat.height} px; the projector is {pw}x{ph}")
            t = time.perf_counter()
            renderer.set_scene(dataclasses.replace(spec, projector=spec.projector.with_pattern(pat)))
            t_swap += time.perf_counter() - t
            fs = frame_seed(settings.seed, i)
            rs = RenderSettings(spp=settings.spp, seed=fs)
            for cam in cameras:
                t = time.perf_counter()
                rad = renderer.render(cam, "active", rs)
                out[cam][i] = sensor.digitize(rad, seed=image_seed(fs, cam, "active"))
                t_render += time.perf_counter() - t
            if progress is not None:
                progress(i + 1, n)
    finally:
        renderer.set_scene(spec)
    if renderer.scene_builds != builds_before:
        raise RuntimeError("swapping the projector pattern rebuilt the Mitsuba scene (structure changed)")
    for a in out.values():
        a.setflags(write=False)
    return RenderedSequence(name, out, n, {"render_s": t_render, "pattern_swap_s": t_swap})
