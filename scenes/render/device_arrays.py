"""Host arrays handed to drjit so that every sample compiles to the same kernels.

drjit's LLVM back-end maps a numpy array's memory instead of copying it, and marks the
variable *unaligned* when its address is not a multiple of the vector width (64 bytes for
float32 x 16): its kernels then load that input differently (and gathers from it fall back
from packet gathers), so the same computation compiles to one kernel per alignment pattern of
its inputs, and numpy's allocations fall on 16-byte boundaries at random. ``to_device`` copies
the array into a 64-byte aligned host buffer first: one kernel serves every sample
(``tests/test_kernel_reuse.py``). GPU variants copy to the device either way.
"""
from __future__ import annotations

import numpy as np

__all__ = ["aligned", "to_device"]

_ALIGN = 64  # bytes: drjit's widest LLVM vector (16 x float32, 8 x float64)


def aligned(a) -> np.ndarray:
    """A C-contiguous copy of ``a`` whose data starts on a 64-byte boundary."""
    a = np.ascontiguousarray(a)
    buf = np.empty(a.nbytes + _ALIGN, np.uint8)
    off = (-buf.ctypes.data) % _ALIGN
    out = buf[off:off + a.nbytes].view(a.dtype).reshape(a.shape)
    out[...] = a
    return out


def to_device(Type, a, dtype=None):
    """drjit array of ``Type`` holding ``a`` (raveled; converted to ``dtype`` first if given)."""
    a = np.asarray(a, dtype=dtype).ravel()
    return Type(aligned(a))
