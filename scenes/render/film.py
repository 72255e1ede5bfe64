"""From a Mitsuba film to host pixels: the channels reduced on the render's device, moved once.

A render is an RGB tensor (H, W, 3) in the device's memory (a GPU's for ``cuda_*``, drjit's
buffers for ``llvm_*``). The bench's image is the mean of the three channels (every light is
white and every diffuse material grey, so the channels agree; Mitsuba's conductors differ per
channel and the mean is their grey). ``grey_to_host`` computes that mean where the pixels are,
``((r + g) + b) / 3`` in float32 with a true division, which is numpy's ``mean(axis=2)`` of the
same tensor bit for bit (numpy sums a length-3 axis left to right, then divides), and copies
the (H, W) result to the host once: a third of the bytes of the RGB tensor, and no host-side
pass over it.

Subnormal floats (|x| < 2^-126 = 1.18e-38, not 0) are flushed to zero on the device. A
subnormal radiance is far below anything a sensor digitises (0 DN at any bit depth the bench
models), but on the host every float operation that reads one can cost a hundred times a
normal one (x86 processors without flush-to-zero / denormals-are-zero take a microcode assist
per subnormal operand), so a host step over an image holding them (a channel mean, the
sensor's float64 conversion, an EXR write) would pay for rendered values it cannot see.
``count_subnormal`` counts them in a host array (``platebench perf gpu`` reports it).

``channels_to_host`` keeps the channels apart: (H, W, 3) when each channel carries an image of
its own (three projector patterns rendered in one launch, ``PlateRenderer.render_patterns``).
"""
from __future__ import annotations

import numpy as np

__all__ = ["grey_to_host", "channels_to_host", "count_subnormal", "FLOAT32_TINY"]

FLOAT32_TINY = float(np.finfo(np.float32).tiny)  # 2^-126: the smallest normal float32


def _is_jit(mi) -> bool:
    import drjit as dr  # noqa: PLC0415  (scenes.render.runtime has chosen libLLVM already)
    return dr.is_jit_v(mi.Float)


def _flush(dr, x):
    """x with its subnormal entries set to +0 (on x's device)."""
    return dr.select(dr.abs(x) < FLOAT32_TINY, 0.0, x)


def _channel(dr, mi, flat, n: int, c: int, channels: int):
    return dr.gather(mi.Float, flat, dr.arange(mi.UInt32, n) * channels + c)


def grey_to_host(mi, img) -> np.ndarray:
    """(H, W) float32 host array: the channel mean of the Mitsuba render ``img`` ((H, W, C) tensor,
    C = 3), computed on its device with subnormals flushed to zero (module doc)."""
    H, W, C = (int(s) for s in img.shape)
    if not _is_jit(mi):  # scalar variants: the pixels are on the host already
        a = np.asarray(img, dtype=np.float32).mean(axis=2)
        a[np.abs(a) < FLOAT32_TINY] = 0.0
        return a
    import drjit as dr  # noqa: PLC0415
    flat, n = img.array, H * W
    acc = _channel(dr, mi, flat, n, 0, C)
    for c in range(1, C):
        acc = acc + _channel(dr, mi, flat, n, c, C)
    # an opaque divisor: drjit turns a division by a literal into a multiplication by its reciprocal,
    # which rounds differently; a true division gives numpy's bits
    grey = _flush(dr, acc / dr.opaque(mi.Float, float(C)))
    return np.array(mi.TensorXf(grey, shape=(H, W)), dtype=np.float32)


def channels_to_host(mi, img) -> np.ndarray:
    """(H, W, C) float32 host array of the render ``img``'s channels, each flushed of subnormals on
    its device (module doc)."""
    if not _is_jit(mi):
        a = np.array(img, dtype=np.float32)
        a[np.abs(a) < FLOAT32_TINY] = 0.0
        return a
    import drjit as dr  # noqa: PLC0415
    return np.array(mi.TensorXf(_flush(dr, img.array), shape=tuple(int(s) for s in img.shape)), dtype=np.float32)


def count_subnormal(a: np.ndarray) -> int:
    """Number of subnormal entries (0 < |x| < 2^-126) of a float32 array."""
    a = np.abs(np.asarray(a, np.float32))
    return int(np.count_nonzero((a > 0) & (a < FLOAT32_TINY)))
