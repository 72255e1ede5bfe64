"""The file boundary's codecs: every JSON form of a science type (``plates``, ``scenes``,
``reconstruction``, ``evaluation``) and of the bench's own records lives here, never on the type.

``encode(obj) -> dict`` gives the JSON-safe form of a registered type (one function per type, in the
module named after the type's package: ``codecs.plates``, ``codecs.scenes``, ...); ``decode(cls, d)``
reads that form back. The layouts are the files' layouts (``docs/reference.md``); units are in the keys,
as the files hold them. ``encode`` of a type with no codec raises ``TypeError`` naming the type;
``decode`` likewise. A decoder raises the error its type's validation raises (``PlateSpecError``,
``ValueError``) for a form it cannot read.

The codec modules import the science packages (scipy, trimesh); they are imported on the first
``encode`` or ``decode``, so that importing this package stays cheap for commands that refuse their
input before any work.
"""
from __future__ import annotations

import importlib
from typing import Any, TypeVar

from platebench.bench.io.codecs import base

T = TypeVar("T")
CODEC_MODULES = ("plates", "scenes", "reconstruction", "evaluation", "bench_records")
_loaded = False


def _load() -> None:
    global _loaded
    if not _loaded:
        for name in CODEC_MODULES:
            importlib.import_module(f"platebench.bench.io.codecs.{name}")
        _loaded = True


def encode(obj: Any, *args: Any, **kwargs: Any) -> dict:
    """The JSON-safe dict of ``obj`` (a type with a codec; extra arguments go to its encoder, such as the
    key prefix, unit suffix and scale of ``evaluation.stats.ErrorStats``)."""
    _load()
    return base.encode(obj, *args, **kwargs)


def has_codec(cls: type) -> bool:
    """Whether ``encode`` has a function for ``cls`` (or a base class of it)."""
    _load()
    return base.encode.dispatch(cls) is not base.encode.dispatch(object)


def decode(cls: type[T], d: Any, *args: Any, **kwargs: Any) -> T:
    """``cls`` read back from its form ``d`` (extra arguments go to the type's decoder)."""
    _load()
    return base.decode(cls, d, *args, **kwargs)


__all__ = ["encode", "decode", "has_codec", "CODEC_MODULES"]
