"""Codecs of the `plates` types (see `bench.io.codecs`): a plate specification as sample.json's
``config.plate`` and a sample TOML's ``[plate]`` hold it (metres, radians).

A deformation's form is its family key under "family" and then its dataclass fields by name, in
field order; the one codec serves every family ``plates.spec.register_family`` adds."""
from __future__ import annotations

from dataclasses import MISSING, fields
from typing import Any, Mapping

from platebench.bench.io.codecs.base import decode, decoder, encode
from platebench.plates.spec import DeformationFamily, PlateSpec, PlateSpecError, family_class


def _check_keys(owner: str, d: Mapping[str, Any], allowed: set[str], required: set[str]) -> None:
    """PlateSpecError naming the first key of ``d`` outside ``allowed``, or the first of ``required``
    that ``d`` lacks."""
    for key in d:
        if key not in allowed:
            raise PlateSpecError(
                f"{owner} key {key!r} is unknown: allowed keys " + ", ".join(sorted(allowed)))
    for key in sorted(required):
        if key not in d:
            raise PlateSpecError(f"{owner} key {key!r} is missing: required keys " + ", ".join(sorted(required)))


@encode.register(DeformationFamily)
def _(x: DeformationFamily) -> dict[str, Any]:
    """JSON-safe dict with a "family" key (what a ``PlateSpec``'s form nests)."""
    return {"family": x.family, **{f.name: getattr(x, f.name) for f in fields(x)}}


@decoder(DeformationFamily)
def _(d: Any) -> DeformationFamily:
    """The registered family of ``d["family"]`` built from the other keys (its fields); PlateSpecError
    for a form that is not a mapping, an unknown family, an unknown key or a missing required field."""
    if not isinstance(d, Mapping):
        raise PlateSpecError(f"PlateSpec.deformation = {d!r} is not a mapping")
    cls = family_class(d.get("family"))
    names = {f.name for f in fields(cls)}
    required = {f.name for f in fields(cls) if f.default is MISSING and f.default_factory is MISSING}
    _check_keys(cls.__name__, d, names | {"family"}, required)
    return cls(**{k: v for k, v in d.items() if k != "family"})


@encode.register(PlateSpec)
def _(x: PlateSpec) -> dict[str, Any]:
    """JSON-safe dict; the deformation is a nested dict with a "family" key."""
    return {"length_m": x.length_m, "width_m": x.width_m,
            "thickness_m": x.thickness_m, "deformation": encode(x.deformation)}


@decoder(PlateSpec)
def _(d: Mapping[str, Any]) -> PlateSpec:
    """The spec of its form (no "deformation": a flat sheet; no "thickness_m": 0); unknown or missing
    keys and unknown families raise PlateSpecError."""
    if not isinstance(d, Mapping):
        raise PlateSpecError(f"PlateSpec dict = {d!r} is not a mapping")
    _check_keys("PlateSpec", d, {"length_m", "width_m", "thickness_m", "deformation"},
                required={"length_m", "width_m"})
    deformation = decode(DeformationFamily, d.get("deformation", {"family": "flat"}))
    return PlateSpec(d["length_m"], d["width_m"], d.get("thickness_m", 0.0), deformation)
