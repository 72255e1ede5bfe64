"""Deformation families known in one place: each family's dataclass answers what the bench asks
(curvature, meshing layout, defaults, sweep keys, study label and examples), the sweep spec, the
study and the report ask ``FAMILIES``, and a family the bench does not know is an error.

Units: metres and radians; world frame +Z up, flat plate in z = 0 (see plates/spec.py).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import pytest

from platebench.bench.io.codecs import encode
from platebench.plates import PlateSpec, PlateSpecError, build_plate
from platebench.plates.spec import (
    FAMILIES,
    CylindricalBend,
    DeformationFamily,
    family_class,
    max_curvature_per_m,
)

L, W = 0.1165, 0.0735


def test_every_family_answers_what_the_bench_asks():
    """Each listed family: a key, a label, a meshing layout, defaults that make a valid plate of
    that family (what a sweep switching to it gets), a curvature bound, a study label that is a
    family, and its sweep keys are fields it has."""
    for name, cls in FAMILIES.items():
        d = cls.defaults(L, W)
        assert d.family == name and type(d) is cls and cls.label and cls.layout in ("strips", "grid")
        spec = PlateSpec(L, W, 0.0, d)
        assert d.study_label() in FAMILIES
        assert max_curvature_per_m(spec) >= 0.0
        assert build_plate(spec).facet_error_m() < 1e-6
        for k in cls.sweep_keys:
            assert hasattr(d, k.field), (name, k)
        assert family_class(name) is cls


def test_an_unknown_family_is_an_error_never_a_silent_default():
    with pytest.raises(PlateSpecError, match="family = 'saddle' is unknown: allowed families flat, cylinder"):
        family_class("saddle")
    with pytest.raises(TypeError, match="does not set 'layout'"):
        class NoLayout(DeformationFamily):  # noqa: F841
            family: ClassVar[str] = "x"
            label: ClassVar[str] = "x"

    @dataclass(frozen=True)
    class NoCurvature(DeformationFamily):
        family: ClassVar[str] = "no_curvature"
        label: ClassVar[str] = "no curvature"
        layout: ClassVar[str] = "grid"

        @classmethod
        def defaults(cls, length_m, width_m):
            return cls()
    with pytest.raises(TypeError, match="abstract method.*max_curvature_per_m"):
        NoCurvature()

    @dataclass(frozen=True)
    class Unlisted(CylindricalBend):
        family: ClassVar[str] = "unlisted"
    with pytest.raises(PlateSpecError, match="is not a deformation: allowed Flat, CylindricalBend"):
        PlateSpec(L, W, 0.0, Unlisted(0.3))
    from platebench.bench.sweep.spec import SpecError, family_defaults
    with pytest.raises(SpecError, match="family = 'saddle' is unknown"):
        family_defaults("saddle", L, W)


def test_sweep_study_and_report_ask_the_families():
    """The sweep spec's axes and family choices, the study's family order and cases, and the
    report's category order come from ``FAMILIES``: a family appears in each without being named
    there."""
    from platebench.bench.report.summary import CATEGORY_ORDER
    from platebench.bench.run.sensing.study import FAMILY_ORDER, study_cases
    from platebench.bench.sweep.spec import AXES, family_defaults, parse_spec
    assert FAMILY_ORDER == tuple(FAMILIES) == CATEGORY_ORDER["family"]
    for name, cls in FAMILIES.items():
        assert family_defaults(name, L, W) == encode(cls.defaults(L, W))
    names = list(AXES)
    assert names.index("axis_deg") < names.index("fold_position_m") < names.index("sag_m") < names.index("dent_depth_m")
    spec = parse_spec({"sweep": {"name": "s"}, "base": {"scene": {"width": 160, "height": 120}},
                       "grid": {"family": list(FAMILIES), "sag_m": 0.004}})
    assert {c.config.plate.deformation.family for c in spec.samples} == set(FAMILIES)
    assert {c.config.plate.deformation.sag_m for c in spec.samples if c.config.plate.deformation.family == "dome"} \
        == {0.004}
    assert len(study_cases()) == 61
    for name, cls in FAMILIES.items():  # a family outside the default set brings its own examples
        got = study_cases(families=[name])
        assert got and {c.family for c in got} <= {name, "flat"}
        if not cls.in_default_study:
            assert [c.name for c in got] == [label for label, _ in cls.study_examples()]
