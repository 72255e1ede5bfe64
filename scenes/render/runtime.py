"""The one place where the Mitsuba variant is chosen and drjit finds its libLLVM.

drjit's CPU backend needs libLLVM >= 16. With LLVM 15 the process is ABORTED at the
first kernel compile; with 14 the LLVM variants are silently unavailable. So, before
drjit is imported, we locate a good libLLVM (``DRJIT_LIBLLVM_PATH`` if it is good,
else the ``karellen-llvm-core`` wheel's ``<prefix>/lib/libLLVM.so.*``, else a system
libLLVM >= 16), check its version through the C API (``LLVMGetVersion`` exists
only from LLVM 16 on), and point ``DRJIT_LIBLLVM_PATH`` at it. If none is found we
point drjit at nothing (so it can never load the system's LLVM 15) and fall back to
``scalar_rgb`` with a one-line warning.

``PLATEBENCH_LLVM_CANDIDATES`` (colon-separated paths) replaces the search list.

Variant order: explicit argument > ``PLATEBENCH_VARIANT`` > ``cuda_ad_rgb`` when a
GPU is present > ``llvm_ad_rgb`` > ``scalar_rgb``.
"""
from __future__ import annotations

import ctypes
import glob
import os
import sys
from dataclasses import dataclass

from platebench.errors import PlateBenchError

_MIN_LLVM = 16
_NO_LLVM = "/nonexistent/platebench-found-no-libLLVM-16-or-newer"
_state: dict = {}


class RendererUnavailable(PlateBenchError, RuntimeError):
    """The requested Mitsuba variant cannot run on this machine."""


def llvm_version(path: str) -> tuple[int, int, int] | None:
    """Version of the libLLVM at ``path`` via LLVMGetVersion, or None if absent/older than 16."""
    try:
        lib = ctypes.CDLL(path)
    except OSError:
        return None
    fn = getattr(lib, "LLVMGetVersion", None)
    if fn is None:
        return None
    a, b, c = ctypes.c_uint(), ctypes.c_uint(), ctypes.c_uint()
    fn(ctypes.byref(a), ctypes.byref(b), ctypes.byref(c))
    return a.value, b.value, c.value


def _candidates() -> list[str]:
    override = os.environ.get("PLATEBENCH_LLVM_CANDIDATES")
    if override is not None:  # colon-separated list replacing the search (used by tests)
        return [p for p in override.split(":") if p]
    out = []
    for prefix in dict.fromkeys([sys.prefix, sys.base_prefix]):
        out += sorted(glob.glob(os.path.join(prefix, "lib", "libLLVM.so.*")), reverse=True)
    for d in ("/usr/lib/x86_64-linux-gnu", "/usr/lib/aarch64-linux-gnu", "/usr/lib64", "/usr/lib"):
        out += sorted(glob.glob(os.path.join(d, "libLLVM*.so*")), reverse=True)
    return out


@dataclass(frozen=True)
class LLVMChoice:
    path: str | None
    version: tuple[int, int, int] | None
    note: str


def find_libllvm() -> LLVMChoice:
    """Pick a libLLVM >= 16 for drjit without loading drjit."""
    user = os.environ.get("DRJIT_LIBLLVM_PATH")
    note = ""
    if user:
        v = llvm_version(user)
        if v and v[0] >= _MIN_LLVM:
            return LLVMChoice(user, v, f"DRJIT_LIBLLVM_PATH={user} (LLVM {v[0]}.{v[1]})")
        note = f"DRJIT_LIBLLVM_PATH={user} is not a libLLVM >= {_MIN_LLVM}; "
    for path in _candidates():
        v = llvm_version(path)
        if v and v[0] >= _MIN_LLVM:
            return LLVMChoice(path, v, note + f"using {path} (LLVM {v[0]}.{v[1]})")
    return LLVMChoice(None, None, note + f"no libLLVM >= {_MIN_LLVM} found "
                      "(fix: pip install karellen-llvm-core, or apt-get install libllvm19)")


def _prepare_llvm() -> LLVMChoice:
    if "llvm" not in _state:
        if "drjit" in sys.modules and "llvm" not in _state:
            # drjit already imported by someone else: it has read the variable already.
            path = os.environ.get("DRJIT_LIBLLVM_PATH")
            v = llvm_version(path) if path else None
            _state["llvm"] = LLVMChoice(path, v, "drjit was imported before platebench chose libLLVM")
        else:
            choice = find_libllvm()
            # Never let drjit fall back to the system's default libLLVM (15 aborts).
            os.environ["DRJIT_LIBLLVM_PATH"] = choice.path or _NO_LLVM
            _state["llvm"] = choice
    return _state["llvm"]


def default_variant() -> str:
    """The variant platebench uses when none is requested (does not import Mitsuba)."""
    env = os.environ.get("PLATEBENCH_VARIANT")
    if env:
        return env
    choice = _prepare_llvm()
    import drjit as dr  # noqa: PLC0415  (import after DRJIT_LIBLLVM_PATH is set)
    if dr.has_backend(dr.JitBackend.CUDA):
        return "cuda_ad_rgb"
    if choice.path and choice.version and choice.version[0] >= _MIN_LLVM and dr.has_backend(dr.JitBackend.LLVM):
        return "llvm_ad_rgb"
    return "scalar_rgb"


def has_cuda() -> bool:
    """True when drjit finds a CUDA device (``cuda_*`` variants can render here)."""
    _prepare_llvm()
    import drjit as dr  # noqa: PLC0415  (import after DRJIT_LIBLLVM_PATH is set)
    return bool(dr.has_backend(dr.JitBackend.CUDA))


def mitsuba(variant: str | None = None):
    """Import Mitsuba with the chosen variant set and return the module.

    Raises RendererUnavailable with a one-line reason if the variant cannot run.
    """
    choice = _prepare_llvm()
    import drjit as dr  # noqa: PLC0415
    import mitsuba as mi  # noqa: PLC0415

    want = variant or default_variant()
    if want.startswith("llvm") and not (choice.version and choice.version[0] >= _MIN_LLVM):
        if variant:
            raise RendererUnavailable(f"variant {want} needs libLLVM >= {_MIN_LLVM}: {choice.note}")
        want = "scalar_rgb"
    if want.startswith("llvm") and not dr.has_backend(dr.JitBackend.LLVM):
        raise RendererUnavailable(f"variant {want}: drjit's LLVM backend is unavailable ({choice.note})")
    if want.startswith("cuda") and not dr.has_backend(dr.JitBackend.CUDA):
        raise RendererUnavailable(f"variant {want}: no CUDA device found")
    if want not in mi.variants():
        raise RendererUnavailable(f"variant {want!r} is not built: choose one of {mi.variants()}")
    if want == "scalar_rgb" and not variant and not _state.get("warned"):
        print(f"platebench: warning: falling back to scalar_rgb (slow): {choice.note}", file=sys.stderr)
        _state["warned"] = True
    if mi.variant() != want:
        mi.set_variant(want)
    return mi


def describe() -> dict:
    """What was chosen, for sample.json and `platebench info`."""
    choice = _prepare_llvm()
    return {"libllvm": choice.path, "llvm_version": ".".join(map(str, choice.version)) if choice.version else None,
            "note": choice.note, "variant": default_variant()}


def set_thread_count(n: int) -> None:
    """drjit's CPU thread pool size (sweep workers split the cores between them)."""
    _prepare_llvm()
    import drjit as dr  # noqa: PLC0415
    dr.set_thread_count(int(n))


class KernelCounter:
    """Counts drjit kernel compiles (cache misses), disk-cache loads and launches in a block."""

    def __init__(self):
        _prepare_llvm()
        import drjit as dr  # noqa: PLC0415
        self.dr = dr

    def __enter__(self):
        self.dr.kernel_history()  # clear
        self._old = self.dr.flag(self.dr.JitFlag.KernelHistory)
        self.dr.set_flag(self.dr.JitFlag.KernelHistory, True)
        return self

    def __exit__(self, *exc):
        hist = [e for e in self.dr.kernel_history() if e["type"] == self.dr.KernelType.JIT]
        self.dr.set_flag(self.dr.JitFlag.KernelHistory, self._old)
        self.launches = len(hist)
        self.compiled = sum(1 for e in hist if not e.get("cache_hit"))
        self.from_disk = sum(1 for e in hist if e.get("cache_disk"))
        return False
