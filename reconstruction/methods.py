"""The method contract and the one registry of reconstruction methods.

The contract
------------
A method is one function ``method(inputs: MethodInputs) -> Disparity | Depth | Points | Mesh``.
``MethodInputs`` holds what a camera system gives it, never the ground truth: the four camera
images, the calibration, the projected pattern and, for a method that projects a sequence of its
own (``MethodEntry.sequence``), that sequence's captures. It returns one of four output kinds,
each in the left camera's image or in the world frame:

* ``Disparity``: (H, W) px of the left view, d = u_left - u_right; +inf or NaN = no estimate;
* ``Depth``: (H, W) z-depth along the left optical axis, metres; non-finite or <= 0 = no estimate;
* ``Points``: (N, 3) world frame, metres;
* ``Mesh``: a ``trimesh.Trimesh`` in the world frame, metres.

Each output may carry ``metrics`` (the method's own figures, name -> number, units in the names)
and ``notes`` (remarks for the reader, one line each). ``check_output`` refuses anything else
(``MethodOutputError``, one line): the bench checks every method's output with it.

The registry
------------
``METHODS`` maps a name to a ``MethodEntry`` (frozen): name, description, output kind, the images
it reads, the projector sequence it needs, the smallest image it accepts, the function, and
whether the bench runs it in a process of its own (``isolated``). Built-in methods register with
the ``register_method`` decorator in their own module of ``reconstruction.peers`` (importing that
package imports every module in it; the bench imports it before any look-up); the bench finds
plug-ins by name (an entry point or ``module:function``, ``bench.run.plugins``) and adds them with
``add_method`` as isolated entries. ``compare``, a sweep and the benchmark's score list and resolve
methods here.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Mapping

import numpy as np

from platebench.errors import UserValueError
from platebench.scenes.naming import IMAGE_NAMES
from platebench.scenes.pattern import Pattern

if TYPE_CHECKING:
    import trimesh  # annotations only: importing trimesh takes a second

__all__ = ["MethodInputs", "Disparity", "Depth", "Points", "Mesh", "OUTPUT_KINDS", "OUTPUT_KIND_NAMES",
           "IMAGE_NAMES", "Projection", "MethodEntry", "METHODS", "register_method", "add_method",
           "method_entry", "method_names", "builtin_names", "default_names", "MethodOutputError", "check_output",
           "checked_metrics", "checked_notes", "output_noun"]

OUTPUT_KIND_NAMES = ("disparity", "depth", "points", "mesh")


@dataclass(frozen=True)
class MethodInputs:
    """What a method may see of a sample.

    ``images``: name -> (H, W) uint8/uint16 camera output (``left_passive``, ``right_passive``: the plate
    under ambient light; ``left_active``, ``right_active``: under the projected square grid).
    ``calibration``: ``.rig`` (``scenes.rig.StereoRig``: OpenCV K, R, t per camera, baseline) and
    ``.projector_camera`` (``scenes.camera.Camera``: the projector's model, its width and height in px).
    ``pattern``: the projected image and its features (projector pixels).
    ``sequence``: the projector sequence the method asked for (``MethodEntry.sequence``), else None.
    ``captures``: camera (``left``, ``right``) -> (N, H, W) uint8 captures of ``sequence.images``, in order.
    ``depth_range_m``: (Z_min, Z_max) metres the command gives as a prior on the scene, else None.
    """

    images: Mapping[str, np.ndarray]
    calibration: Any
    pattern: Pattern
    sequence: Any = None
    captures: Mapping[str, np.ndarray] = field(default_factory=dict)
    depth_range_m: tuple[float, float] | None = None

    @property
    def rig(self):
        return self.calibration.rig


@dataclass(frozen=True)
class Disparity:
    """(H, W) left-view disparity, px (d = u_left - u_right; +inf or NaN: no estimate; the Middlebury metrics
    clip any other value to [0, ndisp], as the Middlebury SDK does; ETH3D's and the implied depth skip <= 0)."""

    disparity: np.ndarray
    metrics: Mapping[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    kind = "disparity"


@dataclass(frozen=True)
class Depth:
    """(H, W) left-view z-depth, metres (non-finite or <= 0: no estimate)."""

    depth: np.ndarray
    metrics: Mapping[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    kind = "depth"


@dataclass(frozen=True)
class Points:
    """(N, 3) world points, metres."""

    points: np.ndarray
    metrics: Mapping[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    kind = "points"


@dataclass(frozen=True)
class Mesh:
    """A surface mesh (``trimesh.Trimesh``), world frame, metres."""

    mesh: trimesh.Trimesh
    metrics: Mapping[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()
    kind = "mesh"


OUTPUT_KINDS = (Disparity, Depth, Points, Mesh)


@dataclass(frozen=True)
class Projection:
    """A projector sequence a method needs rendered: ``name`` labels its renders; ``make(width_px, height_px)``
    gives the sequence for a projector of that size (an object with ``images``: (N, Hp, Wp) frames)."""

    name: str
    make: Callable[[int, int], Any]


@dataclass(frozen=True)
class MethodEntry:
    """One registered method.

    ``function``: ``MethodInputs`` -> an output kind; for an isolated entry, a reference the bench loads in
    the method's own process (``bench.run.plugins.Plugin``). ``output``: its kind (``OUTPUT_KIND_NAMES``;
    None: known from what it returns). ``images``: the sample images it reads (None: any of the four).
    ``sequence``: the projector sequence it needs rendered (None: the sample's images only).
    ``min_image_px``: the smallest image width and height it accepts, px. ``default``: run by ``compare``
    when no method is named. ``isolated``: run in a process of its own with a time limit (plug-ins).
    """

    name: str
    description: str
    function: Callable[[MethodInputs], Any]
    output: str | None = None
    images: tuple[str, ...] | None = None
    sequence: Projection | None = None
    min_image_px: int = 1
    default: bool = False
    isolated: bool = False

    def exposures(self, inputs: MethodInputs) -> int:
        """Exposures per camera the method uses on ``inputs``: its sequence's frames, else the pairs it reads
        (all four images, two per camera, when it does not say)."""
        if self.sequence is not None and inputs.sequence is not None:
            return int(len(inputs.sequence.images))
        return max(1, len(self.images) // 2) if self.images else 2


METHODS: dict[str, MethodEntry] = {}


def add_method(entry: MethodEntry) -> MethodEntry:
    """Add ``entry`` to the registry (a name is registered once; ``UserValueError`` otherwise)."""
    if not isinstance(entry.name, str) or not entry.name or entry.name in METHODS:
        raise UserValueError(f"method name {entry.name!r} is empty or already registered")
    if entry.output is not None and entry.output not in OUTPUT_KIND_NAMES:
        raise UserValueError(f"method {entry.name!r}: output {entry.output!r} is not one of "
                             f"{', '.join(OUTPUT_KIND_NAMES)}")
    bad = [i for i in entry.images or () if i not in IMAGE_NAMES]
    if bad:
        raise UserValueError(f"method {entry.name!r}: image {bad[0]!r} is not one of {', '.join(IMAGE_NAMES)}")
    METHODS[entry.name] = entry
    return entry


def register_method(name: str, description: str, output: str, images: tuple[str, ...] | None = None,
                    sequence: Projection | None = None, min_image_px: int = 1, default: bool = False):
    """Decorator: register the decorated function ``MethodInputs -> output kind`` as method ``name``, run in
    the calling process (see module doc); the function is returned unchanged."""
    def register(fn):
        add_method(MethodEntry(name, description, fn, output, None if images is None else tuple(images), sequence,
                               int(min_image_px), default))
        return fn
    return register


def method_entry(name: str) -> MethodEntry | None:
    """The entry registered as ``name``, else None."""
    return METHODS.get(name)


def method_names() -> tuple[str, ...]:
    """Every registered name: the default methods first, then the others, each in order of registration
    (this module's, then ``reconstruction.peers``' modules by name, then what the bench adds)."""
    return tuple([n for n, e in METHODS.items() if e.default] + [n for n, e in METHODS.items() if not e.default])


def builtin_names() -> tuple[str, ...]:
    """The names of the methods that run in the calling process (``method_names`` order)."""
    return tuple(n for n in method_names() if not METHODS[n].isolated)


def default_names() -> tuple[str, ...]:
    """The names ``compare`` runs when none is given."""
    return tuple(n for n in method_names() if METHODS[n].default)


# ----------------------------------------------------------------------------- output checks
class MethodOutputError(UserValueError):
    """A method returned something other than an output kind holding what its kind needs."""


_DTYPE_WORDS = {"b": "bool (true/false, not numbers)", "c": "complex numbers", "U": "text", "S": "bytes",
                "O": "Python objects", "M": "dates", "m": "time spans", "V": "records"}


_NOUNS = {"disparity": "a disparity map", "depth": "a depth map", "points": "points"}


def output_noun(what: str) -> str:
    """How an error message names a part of an output (``"depth"`` -> ``"a depth map"``)."""
    return _NOUNS.get(what, what)


def _real(a: np.ndarray, name: str, what: str) -> np.ndarray:
    """``a`` if it holds real numbers (integer or float), else ``MethodOutputError`` naming its dtype."""
    if a.dtype.kind not in "iuf":
        words = _DTYPE_WORDS.get(a.dtype.kind, "not numbers")
        raise MethodOutputError(f"method {name!r} returned {output_noun(what)} of dtype {a.dtype} ({words}): "
                                "give real numbers (float or integer)")
    return a


def check_output(out: Any, name: str):
    """``out`` if it is an output kind holding what its kind needs (real-valued arrays of the right rank,
    a mesh with in-range faces, numeric metrics, notes as texts), else ``MethodOutputError`` (one line)."""
    if not isinstance(out, OUTPUT_KINDS):
        raise MethodOutputError(f"method {name!r} returned {type(out).__name__}: return one of "
                                "platebench.reconstruction.methods.Disparity, Depth, Points or Mesh")
    checked_metrics(out.metrics, name)
    checked_notes(out.notes, name)
    if isinstance(out, Mesh):
        v, f = (np.asarray(getattr(out.mesh, k, None)) for k in ("vertices", "faces"))
        _real(v, name, "mesh vertices")
        if f.dtype.kind not in "iu":
            raise MethodOutputError(f"method {name!r} returned a mesh whose faces are of dtype {f.dtype}: give "
                                    "integer vertex indices")
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
            raise MethodOutputError(f"method {name!r} returned a mesh with vertices {v.shape} and faces {f.shape}: "
                                    "give (N, 3) vertices and (M, 3) triangles")
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise MethodOutputError(f"method {name!r} returned a mesh whose faces index vertices {f.min()} to "
                                    f"{f.max()} of {len(v)}")
        return out
    a = _real(np.asarray(getattr(out, out.kind)), name, out.kind)
    if isinstance(out, Points):
        if a.ndim != 2 or a.shape[1] != 3:
            raise MethodOutputError(f"method {name!r} returned points of shape {a.shape}: give (N, 3) world points")
    elif not (a.ndim == 2 or (a.ndim == 3 and a.shape[2] == 1)):
        raise MethodOutputError(f"method {name!r} returned {output_noun(out.kind)} of shape {a.shape}: give an "
                                "(H, W) map of the left view")
    return out


def checked_notes(notes, name: str) -> tuple[str, ...]:
    """The output's notes as a tuple of one-line texts (at most 300 characters each), or ``MethodOutputError``."""
    if not isinstance(notes, (tuple, list)) or not all(isinstance(n, str) for n in notes):
        raise MethodOutputError(f"method {name!r} returned notes of type {type(notes).__name__}: give a tuple of "
                                "texts")
    return tuple(n.strip().splitlines()[0][:300] if n.strip() else "" for n in notes)


def checked_metrics(metrics, name: str) -> dict:
    """The method's own metrics as {str: bool | int | float}, or ``MethodOutputError``."""
    if metrics is None:
        return {}
    if not isinstance(metrics, Mapping):
        raise MethodOutputError(f"method {name!r} returned metrics of type {type(metrics).__name__}: give a "
                                "mapping name -> number")
    out = {}
    for k, v in metrics.items():
        if isinstance(v, np.generic):
            v = v.item()
        if not isinstance(k, str) or not k or not isinstance(v, (bool, int, float)):
            raise MethodOutputError(f"method {name!r} returned metric {str(k)[:60]!r} = {str(v)[:60]!r} "
                                    f"({type(v).__name__}): give names (text) and numbers")
        out[k] = v
    return out


@register_method("paper", "the paper's pipeline: projected squares + passive boundary (Chen & Zheng 1995)",
                 "points", IMAGE_NAMES, default=True)
def paper(inputs: MethodInputs) -> Points:
    """The paper's pipeline (``reconstruction.paper.pipeline``): the whole squares' centres, world frame, metres."""
    from platebench.reconstruction.paper.pipeline import (  # noqa: PLC0415
        PipelineOptions,
        projector_feature_rays,
        reconstruct,
    )
    rays = projector_feature_rays(inputs.calibration.projector_camera, inputs.pattern)
    rec = reconstruct(dict(inputs.images), inputs.rig, rays, inputs.pattern, PipelineOptions())
    return Points(np.asarray(rec.points, np.float64))
