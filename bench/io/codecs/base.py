"""The codec registry: ``encode`` (one function per type) and ``decode`` (one reader per type); see
``bench.io.codecs``."""
from __future__ import annotations

from functools import singledispatch
from typing import Any, Callable, TypeVar

T = TypeVar("T")
_DECODERS: dict[type, Callable[..., Any]] = {}


@singledispatch
def encode(obj: Any) -> dict:
    """The JSON-safe dict of ``obj`` (a registered type)."""
    raise TypeError(f"no codec encodes {type(obj).__module__}.{type(obj).__qualname__}")


def decoder(cls: type[T]) -> Callable[[Callable[..., T]], Callable[..., T]]:
    """Register the function below as the reader of ``cls``'s form."""
    def register(fn: Callable[..., T]) -> Callable[..., T]:
        _DECODERS[cls] = fn
        return fn
    return register


def decode(cls: type[T], d: Any, *args: Any, **kwargs: Any) -> T:
    """``cls`` read back from its form ``d`` (extra arguments go to the type's decoder)."""
    try:
        fn = _DECODERS[cls]
    except KeyError:
        raise TypeError(f"no codec decodes {cls.__module__}.{cls.__qualname__}") from None
    return fn(d, *args, **kwargs)


__all__ = ["encode", "decode", "decoder"]
