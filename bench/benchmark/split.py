"""A benchmark split: its definition file, read and expanded into the samples of one sweep.

A split is a TOML file in ``splits/`` named by its version (``splits/v1.toml``), beside the checksums
of its ground truth (``splits/v1.sha256.json``, written by ``platebench benchmark build --record``).
The file is the definition: its sha256 is the split's identity, recorded in every dataset built from
it and every results table scored on it, and a changed file is a new version.

Format::

    [benchmark]
    name = "v1"                    # the version; equals the file's stem
    description = "..."
    build_methods = ["paper"]      # the methods the build runs (its own check of every sample)

    [base]                         # a sample configuration (the tables of `platebench render --config`)
    ...

    [[part]]                       # one or more parts; each is a sweep spec's [base] and [grid]
    name = "cyl"                   # letters and digits; the sample ids are "<name>-<index in the part>"
    [part.base] ...                # merged over [base] (tables merged key by key)
    [part.grid] ...                # grid axes (docs/reference.md, the sweep spec format)

The split's samples are the parts' samples in file order. Two parts that give the same sample
configuration are refused (a sample is in the split once).
"""
from __future__ import annotations

import copy
import hashlib
import math
import re
from dataclasses import dataclass, replace
from importlib import resources
from pathlib import Path

from platebench.bench.config import ConfigError, read_toml_text
from platebench.bench.sweep.spec import SamplePlan, SpecError, SweepSpec, parse_spec
from platebench.errors import UserValueError

__all__ = ["Split", "SplitError", "SplitSample", "load_split", "split_names", "split_path", "split_checksums_path"]

_TOP_KEYS = ("benchmark", "base", "part")
_BENCHMARK_KEYS = ("name", "description", "build_methods")
_PART_KEYS = ("name", "base", "grid")
_NAME = re.compile(r"[a-z][a-z0-9]{0,15}")


class SplitError(UserValueError):
    """A split's definition is unknown or invalid; the message names the key."""


@dataclass(frozen=True)
class SplitSample:
    """One sample of a split: its id, its part, and its descriptors for the breakdowns.

    ``bend_deg``: the bend (cylinder, fold, S-curve) or twist angle in degrees, None for a family
    without one; ``direction``: "up" (convex) / "down" (concave), "" where the family has none;
    ``axis_deg``: the bend axis in degrees, None where the family has none; ``distance_m``: the rig's
    height above the plate centre (m); ``material``: "diffuse" or "roughconductor"; ``realism``: the
    realism preset ("ideal" when none)."""

    sample_id: str
    part: str
    family: str
    bend_deg: float | None
    direction: str
    axis_deg: float | None
    distance_m: float
    material: str
    realism: str


@dataclass(frozen=True)
class Split:
    """A parsed split: its name (the version), its definition's text and sha256, and ``spec``, the
    one sweep spec of all its samples (sample ids ``<part>-<index>``)."""

    name: str
    description: str
    text: str
    sha256: str
    spec: SweepSpec
    samples: tuple[SplitSample, ...]
    path: Path | None = None  # the definition file (its checksums: the same stem, .sha256.json)

    def sample(self, sample_id: str) -> SplitSample:
        for s in self.samples:
            if s.sample_id == sample_id:
                return s
        raise KeyError(sample_id)


def split_names() -> tuple[str, ...]:
    """The versions shipped with the package, e.g. ("v1",)."""
    d = resources.files("platebench.bench.benchmark") / "splits"
    return tuple(sorted(p.name[:-5] for p in d.iterdir() if p.name.endswith(".toml")))


def split_path(name: str) -> Path:
    """The definition file of a shipped version."""
    if name not in split_names():
        raise SplitError(f"split {name!r} is not known: allowed {', '.join(split_names())}, or a split file (.toml)")
    return Path(str(resources.files("platebench.bench.benchmark") / "splits" / f"{name}.toml"))


def split_checksums_path(split: "Split") -> Path:
    """Where the ground-truth checksums of a split are kept: beside its definition, ``<name>.sha256.json``
    (``splits/v1.sha256.json`` for the shipped v1)."""
    if split.path is None:
        raise SplitError(f"split {split.name} has no definition file")
    return split.path.with_name(f"{split.name}.sha256.json")


def _merge(a: dict, b: dict) -> dict:
    out = copy.deepcopy(a)
    for k, v in b.items():
        out[k] = _merge(out.get(k, {}), v) if isinstance(v, dict) and isinstance(out.get(k), dict | None) \
            else copy.deepcopy(v)
    return out


def _keys(where: str, d, allowed) -> None:
    if not isinstance(d, dict):
        raise SplitError(f"{where or 'the split'} must be a table")
    bad = sorted(set(d) - set(allowed))
    if bad:
        raise SplitError(f"unknown key {where}{bad[0]}: allowed keys are {', '.join(allowed)}")


def _descriptors(plan: SamplePlan, part: str) -> SplitSample:
    cfg = plan.config
    dfm = cfg.plate.deformation
    fields_ = getattr(dfm, "__dataclass_fields__", {})
    angle = getattr(dfm, "angle_rad", None) if "angle_rad" in fields_ else None
    axis = getattr(dfm, "axis_rad", None) if "axis_rad" in fields_ else None
    direction = getattr(dfm, "direction", "") if "direction" in fields_ else ""
    d = plan.config_dict
    material = (d["scene"].get("material") or {}).get("kind") or "diffuse"
    realism = (d.get("realism") or {}).get("preset") or "ideal"
    return SplitSample(plan.sample_id, part, type(dfm).family, None if angle is None else math.degrees(angle),
                       direction or "", None if axis is None else math.degrees(axis),
                       float(cfg.scene.distance_m), str(material), str(realism))


def parse_split(doc: dict, text: str, name: str) -> Split:
    """Validate a parsed split definition and expand it (raises SplitError; nothing is written)."""
    _keys("", doc, _TOP_KEYS)
    bench = doc.get("benchmark")
    if bench is None:
        raise SplitError("[benchmark] is missing: a split names itself there (name = ...)")
    _keys("benchmark.", bench, _BENCHMARK_KEYS)
    if bench.get("name") != name:
        raise SplitError(f"benchmark.name = {bench.get('name')!r} differs from the file's name {name!r}")
    methods = bench.get("build_methods", ["paper"])
    parts = doc.get("part")
    if not isinstance(parts, list) or not parts:
        raise SplitError("no [[part]]: a split has at least one part")
    base = doc.get("base", {})
    _keys("base.", base, ("plate", "scene", "render", "sensor", "realism"))
    plans: list[SamplePlan] = []
    samples: list[SplitSample] = []
    seen: dict[str, str] = {}
    first = None
    for i, part in enumerate(parts):
        _keys(f"part[{i}].", part, _PART_KEYS)
        pname = part.get("name")
        if not isinstance(pname, str) or not _NAME.fullmatch(pname):
            raise SplitError(f"part[{i}].name = {pname!r} is not allowed: 1 to 16 lower-case letters and digits, "
                             "a letter first")
        if any(s.part == pname for s in samples):
            raise SplitError(f"part[{i}].name = {pname!r} is used twice")
        sweep_doc = {"sweep": {"name": f"{name}-{pname}", "methods": methods},
                     "base": _merge(base, part.get("base", {})), "grid": part.get("grid", {})}
        try:
            spec = parse_spec(sweep_doc, methods=None)
        except SpecError as e:
            raise SplitError(f"part {pname!r}: {e}") from None
        first = first or spec
        for plan in spec.samples:
            sid = f"{pname}-{plan.index:04d}"
            if plan.config_sha256 in seen:
                raise SplitError(f"sample {sid} is the same sample as {seen[plan.config_sha256]}: a split holds "
                                 "each sample once")
            seen[plan.config_sha256] = sid
            p = replace(plan, index=len(plans), sample_id=sid)
            plans.append(p)
            samples.append(_descriptors(p, pname))
    spec = replace(first, name=f"platebench-{name}", mode="grid", seed=0, count=None, seed_per_sample=False,
                   axes=(), samples=tuple(plans), doc=doc, text=text,
                   description=str(bench.get("description", "")), ignored={}, duplicates=0)
    return Split(name, str(bench.get("description", "")), text, hashlib.sha256(text.encode()).hexdigest(), spec,
                 tuple(samples))


def load_split(which: str | Path) -> Split:
    """A shipped version by name ("v1"), or a split file (``*.toml``) by path."""
    p = Path(which)
    if p.suffix == ".toml":
        path, name = p, p.stem
    else:
        path, name = split_path(str(which)), str(which)
    try:
        doc, text = read_toml_text(path, "split")
    except ConfigError as e:
        raise SplitError(str(e)) from None
    try:
        return replace(parse_split(doc, text, name), path=path)
    except SplitError as e:
        raise SplitError(f"{path.name}: {e}") from None
