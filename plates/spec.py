"""Plate specifications: frozen, validated, of JSON-safe values (their file form is
``bench/io/codecs/plates.py``'s).

Units: metres and radians (degrees appear only inside error messages).

Frames. World frame: right-handed, +Z up; the undeformed plate lies in z = 0,
centred on the origin, length along X, width along Y. Material (flat-plate)
coordinates uv: u in [-L/2, L/2] along X, v in [-W/2, W/2] along Y, metres.
The deformation describes the TOP surface of the plate (the side facing +Z when
flat); a plate with thickness_m > 0 has its bottom surface offset by thickness_m
along the negative top normal.

Bending coordinate (CylindricalBend, Fold). ``axis_rad`` is the in-plane direction
of the bend (cylinder) axis, measured from +Y toward -X: the axis direction in uv is
g = (-sin a, cos a) and the plate bends along e = (cos a, sin a). So axis_rad = 0
puts the axis along the width (Y) and the plate curls along its length (the paper's
case); axis_rad = pi/2 puts the axis along the length. The bending coordinate is
s = u cos a + v sin a, ranging over [-S/2, S/2] with S = L|cos a| + W|sin a|.

Directions: "up" means the bent part rises toward +Z (concave side facing +Z, the
camera side); "down" is the mirror image.
"""

from __future__ import annotations

import abc
import inspect
import math
import numbers
from dataclasses import dataclass, field, is_dataclass
from typing import Any, ClassVar

from platebench.errors import RegistrationError, UserValueError

from .surfaces import arc, height_field, ruled_frame

__all__ = [
    "PlateSpecError", "Flat", "CylindricalBend", "Fold", "Twist", "Dome", "Dent", "SCurve",
    "Deformation", "DeformationFamily", "PlateSpec", "reference_spec", "FAMILIES", "SweepKey", "Ruling",
    "family_class", "family_sweep_keys", "register_family",
]

MAX_BEND_RAD = math.radians(350.0)
MAX_FOLD_RAD = math.radians(180.0)
MAX_TWIST_RAD = math.radians(90.0)
MAX_S_CURVE_RAD = math.radians(180.0)  # each half of an S-curve a half circle at most
# The smallest bend a bent family takes other than 0 (a flat plate): a circular arc's radius grows as
# 1 / angle, and below this the mesh's arc spacing can no longer be told from 0 in float64 (a bend of
# 1e-6 deg lifts a 10 m plate's centre by 0.2 um: give 0 for a flat plate).
MIN_BEND_DEG = 1e-6
MIN_BEND_RAD = math.radians(MIN_BEND_DEG)
# A plate's sides: 1 mm to 10 m (the rigs view it from 0.05 to 5 m; the mesh's facet error is absolute).
MIN_SIDE_M = 1e-3
MAX_SIDE_M = 10.0
DIRECTIONS = ("up", "down")
DEFAULT_ANGLE_RAD = math.radians(10.0)  # a family's default bend or twist (the paper's plate: 10 degrees)


class PlateSpecError(UserValueError):
    """A plate specification is invalid; the message names field, value and range."""


def _deg(x: float) -> str:
    return f"{math.degrees(x):.2f} deg"


def _fmt(x: float) -> str:
    return f"{x:.6g}"


def _number(owner: str, name: str, value: Any, allowed: str) -> float:
    """Coerce a real number to float; reject bools, strings, NaN and inf."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise PlateSpecError(f"{owner}.{name} = {value!r} is not a number: allowed {allowed}")
    value = float(value)
    if not math.isfinite(value):
        raise PlateSpecError(f"{owner}.{name} = {value} is not a finite number: allowed {allowed}")
    return value


def _check(obj: Any, name: str, lo: float, hi: float, *, unit: str = "m",
           lo_open: bool = False, hi_open: bool = False, allowed: str | None = None) -> float:
    """Validate field ``name`` of ``obj`` against [lo, hi] (open ends as flagged), store as float."""
    owner = type(obj).__name__
    if allowed is None:
        if unit == "rad":
            allowed = f"{math.degrees(lo):g} to {math.degrees(hi):g} deg"
            allowed += f" ({math.degrees(hi):g} excluded)" if hi_open else ""
        elif math.isinf(hi):
            allowed = f"{'> ' if lo_open else '>= '}{_fmt(lo)} m"
        else:
            allowed = f"{_fmt(lo)} to {_fmt(hi)} m"
    value = _number(owner, name, getattr(obj, name), allowed)
    bad = value < lo or value > hi or (lo_open and value == lo) or (hi_open and value == hi)
    if bad:
        shown = f"{_fmt(value)} ({_deg(value)})" if unit == "rad" else _fmt(value)
        raise PlateSpecError(f"{owner}.{name} = {shown} is out of range: allowed {allowed}")
    object.__setattr__(obj, name, value)
    return value


def _check_bend(obj: Any, hi: float) -> None:
    """``angle_rad`` of a bent family: 0 (flat), or ``MIN_BEND_RAD`` to ``hi``."""
    _check(obj, "angle_rad", 0.0, hi, unit="rad")
    if 0.0 < obj.angle_rad < MIN_BEND_RAD:
        raise PlateSpecError(f"{type(obj).__name__}.angle_rad = {_fmt(obj.angle_rad)} ({math.degrees(obj.angle_rad):.3g} "
                             f"deg) is out of range: allowed 0 (flat) or {MIN_BEND_DEG:g} to {math.degrees(hi):g} deg")


def _check_direction(obj: Any) -> None:
    if obj.direction not in DIRECTIONS:
        raise PlateSpecError(
            f"{type(obj).__name__}.direction = {obj.direction!r} is not allowed: allowed 'up' or 'down'")


@dataclass(frozen=True)
class SweepKey:
    """A sweep-spec axis of one family: its key (unit in the name), the deformation field it sets,
    its help text, and whether the spec gives it in degrees (the field is in radians)."""

    name: str
    field: str
    help: str
    degrees: bool = False


@dataclass(frozen=True)
class Ruling:
    """A ruled family's meshing layout (``meshing`` "strips"): the bend axis (radians, as
    ``CylindricalBend.axis_rad``), the curved band of the bending coordinate s ((lo, hi) metres;
    None when nothing is curved), its breaks in curvature (s values, metres) and its smallest
    radius of curvature (metres; inf when flat)."""

    axis_rad: float
    curved_m: tuple[float, float] | None = None
    breaks_m: tuple[float, ...] = ()
    radius_m: float = math.inf

    @property
    def curvature_per_m(self) -> float:
        """The largest curvature (1/m): 1 / ``radius_m``, 0 when flat."""
        return 0.0 if math.isinf(self.radius_m) else 1.0 / self.radius_m


class DeformationFamily(abc.ABC):
    """What the bench asks of a deformation family; every family's frozen dataclass derives from it
    and ``register_family`` adds it to ``FAMILIES``, in the order tables show them.

    Class attributes: ``family`` (its key in configs, specs, tables), ``label`` (its name in
    words), ``layout`` ("strips": ruled along a bend axis, meshed by ``ruling``; "grid": meshed on
    a tensor grid over ``curved_support``), ``sweep_keys`` (its own sweep-spec axes, applied in
    this order after the shared bend_deg / direction / axis_deg), ``by_bend`` (tables per bend
    angle: the family's plates differ by ``angle_rad``), ``in_default_study`` (the false-boundary
    study's default plates include ``study_examples``). A family missing one of them, or one of
    the abstract methods (its exact ``surface`` among them), cannot be defined, registered or made
    (never a silent default); a "strips" family must also give its ``ruling``."""

    family: ClassVar[str]
    label: ClassVar[str]
    layout: ClassVar[str]
    sweep_keys: ClassVar[tuple[SweepKey, ...]] = ()
    by_bend: ClassVar[bool] = False
    in_default_study: ClassVar[bool] = True
    LAYOUTS: ClassVar[tuple[str, ...]] = ("strips", "grid")

    def __init_subclass__(cls, **kw):
        super().__init_subclass__(**kw)
        for name in ("family", "label", "layout"):
            if not isinstance(getattr(cls, name, None), str):
                raise TypeError(f"deformation family {cls.__name__} does not set {name!r}")
        if cls.layout not in cls.LAYOUTS:
            raise TypeError(f"deformation family {cls.__name__}.layout = {cls.layout!r}: allowed "
                            + ", ".join(cls.LAYOUTS))

    @abc.abstractmethod
    def max_curvature_per_m(self, length_m: float, width_m: float) -> float:
        """Upper bound (1/m) on the top surface's principal curvatures on an L x W plate."""

    @classmethod
    @abc.abstractmethod
    def defaults(cls, length_m: float, width_m: float) -> "DeformationFamily":
        """The family with default parameters for an L x W plate (a sweep switching to it)."""

    @abc.abstractmethod
    def surface(self, length_m: float, width_m: float, u, v, xp):
        """The exact top surface of an L x W plate (metres) at material coords (u, v) (arrays of one
        shape, metres): (r, r_u, r_v), the point and its partial derivatives along u and v, each a
        tuple of 3 world-frame components, computed with the array operations ``xp``
        (``plates.deformations.NumpyOps`` or an object of the same methods; building blocks in
        ``plates.surfaces``). The mesh, the ground truth and the renderer's device all use it."""

    def check_fit(self, length_m: float, width_m: float) -> None:
        """Raise PlateSpecError when the deformation does not fit an L x W plate."""

    def ruling(self, length_m: float, width_m: float) -> Ruling:
        """The strips layout of a ruled family (``layout`` "strips")."""
        raise TypeError(f"deformation family {self.family!r} is not ruled (layout {self.layout!r})")

    def curved_support(self, length_m: float, width_m: float) -> tuple[tuple[float, float], tuple[float, float]]:
        """((u0, u1), (v0, v1)) metres: the part of an L x W plate that is curved (grid layout)."""
        return (-length_m / 2, length_m / 2), (-width_m / 2, width_m / 2)

    def study_label(self) -> str:
        """The family a plate of this deformation counts under in the study's tables (a key of
        ``FAMILIES``; a cylinder bent 0 degrees is flat)."""
        return self.family

    def bend_deg(self) -> float | None:
        """The bend angle the study's tables show (degrees), None for a family without one."""
        angle = getattr(self, "angle_rad", None)
        return None if angle is None else round(math.degrees(angle), 9)

    @classmethod
    def study_examples(cls) -> tuple[tuple[str, "DeformationFamily"], ...]:
        """Named plates of this family for the false-boundary study (families the study does not
        sweep by bend: cylinders and folds are built from its --bend list)."""
        return ()


# every registered family by its key, in the order tables show them (``register_family``)
FAMILIES: dict[str, type[DeformationFamily]] = {}


def register_family(cls: type[DeformationFamily]) -> type[DeformationFamily]:
    """Class decorator: add the family ``cls`` to ``FAMILIES`` under ``cls.family`` (after those
    registered before it), so that plate specs, sweep specs, the study and the tables know it.

    Raises TypeError when ``cls`` is not a frozen dataclass deriving from ``DeformationFamily``,
    leaves an abstract method (``surface``, ...) undefined, or has layout "strips" without its
    own ``ruling``; ``RegistrationError`` (a ValueError) when its key is registered already."""
    if not (isinstance(cls, type) and issubclass(cls, DeformationFamily)):
        raise TypeError(f"{cls!r} is not a DeformationFamily subclass")
    if not is_dataclass(cls) or not cls.__dataclass_params__.frozen:
        raise TypeError(f"deformation family {cls.__name__} is not a frozen dataclass")
    if inspect.isabstract(cls):
        raise TypeError(f"deformation family {cls.__name__} does not define "
                        + ", ".join(sorted(cls.__abstractmethods__)))
    if cls.layout == "strips" and cls.ruling is DeformationFamily.ruling:
        raise TypeError(f"deformation family {cls.__name__} has layout 'strips' but no ruling")
    if cls.family in FAMILIES:
        raise RegistrationError(f"deformation family {cls.family!r} is registered already "
                         f"(by {FAMILIES[cls.family].__name__})")
    FAMILIES[cls.family] = cls
    return cls


def _up_sign(d) -> float:
    """+1 for a bend "up", -1 for "down"."""
    return 1.0 if d.direction == "up" else -1.0


def _arcs_ruling(d, length_m: float, width_m: float, arcs: int) -> Ruling:
    """The ruling of a bend of ``arcs`` equal circular arcs over the whole plate, each turning by
    ``d.angle_rad`` (a cylinder: 1; an S-curve: 2, meeting at s = 0): radius S / (arcs angle)."""
    if d.angle_rad == 0:
        return Ruling(d.axis_rad)
    S = bending_extent_m(length_m, width_m, d.axis_rad)
    breaks = tuple(-S / 2 + S * k / arcs for k in range(1, arcs))
    return Ruling(d.axis_rad, (-S / 2, S / 2), breaks, S / (arcs * d.angle_rad))


@register_family
@dataclass(frozen=True)
class Flat(DeformationFamily):
    """No deformation: the plate stays in z = 0."""

    family: ClassVar[str] = "flat"
    label: ClassVar[str] = "flat plate"
    layout: ClassVar[str] = "strips"
    by_bend: ClassVar[bool] = True

    def max_curvature_per_m(self, length_m: float, width_m: float) -> float:
        return 0.0

    @classmethod
    def defaults(cls, length_m: float, width_m: float) -> "Flat":
        return cls()

    def ruling(self, length_m: float, width_m: float) -> Ruling:
        return Ruling(0.0)

    def surface(self, length_m: float, width_m: float, u, v, xp):
        return height_field(u, v, xp.zeros_like(u), xp.zeros_like(u), xp.zeros_like(u), xp)

    def bend_deg(self) -> float | None:
        return 0.0


@register_family
@dataclass(frozen=True)
class CylindricalBend(DeformationFamily):
    """Uniform cylindrical bend, arc length preserved.

    angle_rad: angle between the end tangents of the extreme material lines, 0 (flat) or
    ``MIN_BEND_DEG`` to 350 deg. The signed curvature is +-angle_rad / S (S: the plate's extent along the
    bending coordinate, see module docstring). The plate centre (u, v) = (0, 0)
    stays at the origin with normal +Z. direction: "up" (ends rise toward +Z) or
    "down". axis_rad: bend-axis direction in [0, pi), 0 = axis along the width (Y).
    """

    angle_rad: float
    direction: str = "up"
    axis_rad: float = 0.0
    family: ClassVar[str] = "cylinder"
    label: ClassVar[str] = "cylindrical bend"
    layout: ClassVar[str] = "strips"
    by_bend: ClassVar[bool] = True

    def __post_init__(self) -> None:
        _check_bend(self, MAX_BEND_RAD)
        _check_direction(self)
        _check(self, "axis_rad", 0.0, math.pi, unit="rad", hi_open=True)

    def max_curvature_per_m(self, length_m: float, width_m: float) -> float:
        return _arcs_ruling(self, length_m, width_m, 1).curvature_per_m

    @classmethod
    def defaults(cls, length_m: float, width_m: float) -> "CylindricalBend":
        return cls(DEFAULT_ANGLE_RAD, "up", 0.0)

    def ruling(self, length_m: float, width_m: float) -> Ruling:
        return _arcs_ruling(self, length_m, width_m, 1)

    def bend_profile(self, length_m: float, width_m: float, s, xp):
        """(p, z, phi) of the bent section at bending coordinate s (``surfaces.ruled_frame``): one
        circular arc of curvature +-angle_rad / S through the plate centre."""
        k = xp.const(_up_sign(self) * self.angle_rad / bending_extent_m(length_m, width_m, self.axis_rad))
        p, z = arc(s, k, xp)
        return p, z, k * s

    def surface(self, length_m: float, width_m: float, u, v, xp):
        return ruled_frame(self.axis_rad, lambda s: self.bend_profile(length_m, width_m, s, xp), u, v, xp)

    def study_label(self) -> str:
        return "flat" if self.angle_rad == 0 else self.family


@register_family
@dataclass(frozen=True)
class Fold(DeformationFamily):
    """Off-centre fold: a circular arc of total angle angle_rad inside a band.

    The band has width band_m and is centred at bending coordinate position_m; the
    plate is flat on both sides of it and C1 continuous (arc length preserved).
    Anchoring: the part with s < position_m - band_m/2 stays fixed in the z = 0
    plane (identity map); the band and the flap beyond it move. angle_rad 0 or
    ``MIN_BEND_DEG`` to 180 deg (beyond that the flap would cut through the fixed part). direction and
    axis_rad as in CylindricalBend. The band must lie inside the plate (checked by
    PlateSpec, which knows the plate size).
    """

    angle_rad: float
    position_m: float
    band_m: float
    direction: str
    axis_rad: float = 0.0
    family: ClassVar[str] = "fold"
    label: ClassVar[str] = "fold"
    layout: ClassVar[str] = "strips"
    by_bend: ClassVar[bool] = True
    sweep_keys: ClassVar[tuple[SweepKey, ...]] = (SweepKey("fold_position_m", "position_m", "fold band centre, m"),
                                                 SweepKey("fold_band_m", "band_m", "fold band width, m"))

    def __post_init__(self) -> None:
        _check_bend(self, MAX_FOLD_RAD)
        _check(self, "position_m", -math.inf, math.inf, allowed="a finite number of metres")
        _check(self, "band_m", 0.0, math.inf, lo_open=True)
        _check_direction(self)
        _check(self, "axis_rad", 0.0, math.pi, unit="rad", hi_open=True)

    def max_curvature_per_m(self, length_m: float, width_m: float) -> float:
        return self.angle_rad / self.band_m

    @classmethod
    def defaults(cls, length_m: float, width_m: float) -> "Fold":
        return cls(DEFAULT_ANGLE_RAD, 0.0, 0.25 * length_m, "up", 0.0)

    def check_fit(self, length_m: float, width_m: float) -> None:
        size = _size(length_m, width_m)
        S = bending_extent_m(length_m, width_m, self.axis_rad)
        if self.band_m > S:
            raise PlateSpecError(
                f"Fold.band_m = {_fmt(self.band_m)} is out of range for {size}: allowed > 0 to "
                f"{_fmt(S)} m (the plate's extent along the bending direction)")
        lim = 0.5 * (S - self.band_m)
        if abs(self.position_m) > lim:
            raise PlateSpecError(
                f"Fold.position_m = {_fmt(self.position_m)} is out of range for band_m = "
                f"{_fmt(self.band_m)} on {size}: allowed {_fmt(-lim)} to {_fmt(lim)} m")

    def ruling(self, length_m: float, width_m: float) -> Ruling:
        if self.angle_rad == 0:
            return Ruling(self.axis_rad)
        band = (self.position_m - self.band_m / 2, self.position_m + self.band_m / 2)
        return Ruling(self.axis_rad, band, band, self.band_m / self.angle_rad)

    def bend_profile(self, length_m: float, width_m: float, s, xp):
        """(p, z, phi) of the bent section at bending coordinate s (``surfaces.ruled_frame``): the
        identity before the band, an arc of curvature +-angle_rad / band_m inside it, a straight
        continuation beyond."""
        k = xp.const(_up_sign(self) * self.angle_rad / self.band_m)
        s0 = xp.const(self.position_m - 0.5 * self.band_m)
        dist = s - s0
        inside = xp.clip(dist, 0.0, xp.const(self.band_m))
        phi = k * inside
        p_arc, z_arc = arc(inside, k, xp)
        rest = dist - inside
        return s0 + p_arc + rest * xp.cos(phi), z_arc + rest * xp.sin(phi), phi

    def surface(self, length_m: float, width_m: float, u, v, xp):
        return ruled_frame(self.axis_rad, lambda s: self.bend_profile(length_m, width_m, s, xp), u, v, xp)


@register_family
@dataclass(frozen=True)
class Twist(DeformationFamily):
    """Helicoidal twist about the X axis: (u, v cos(k u), v sin(k u)), k = angle_rad / L.

    angle_rad is the signed total twist between the two ends (u = -L/2 and u = +L/2),
    -90 to 90 deg; positive turns the +u end counter-clockwise about +X. Not
    arc-length preserving (edges away from v = 0 stretch).
    """

    angle_rad: float
    family: ClassVar[str] = "twist"
    label: ClassVar[str] = "twist"
    layout: ClassVar[str] = "grid"

    def __post_init__(self) -> None:
        _check(self, "angle_rad", -MAX_TWIST_RAD, MAX_TWIST_RAD, unit="rad")

    def max_curvature_per_m(self, length_m: float, width_m: float) -> float:
        return abs(self.angle_rad) / length_m

    def surface(self, length_m: float, width_m: float, u, v, xp):
        k = xp.const(self.angle_rad / length_m)
        c, s = xp.cos(k * u), xp.sin(k * u)
        return (u, v * c, v * s), (xp.ones_like(u), -k * v * s, k * v * c), (xp.zeros_like(u), c, s)

    @classmethod
    def defaults(cls, length_m: float, width_m: float) -> "Twist":
        return cls(DEFAULT_ANGLE_RAD)

    @classmethod
    def study_examples(cls):
        return (("twist 45", cls(math.radians(45.0))), ("twist -80", cls(math.radians(-80.0))))


@register_family
@dataclass(frozen=True)
class Dome(DeformationFamily):
    """Spherical cap as a height field over the flat plate: z = z(u, v), (x, y) = (u, v).

    The sphere touches z = 0 at the plate centre (normal +Z there). sag_m is the
    height of the centre above the corners: sag_m > 0 a dome (convex toward +Z,
    corners at z = -sag_m), sag_m < 0 a bowl (corners at z = +|sag_m|). Allowed
    |sag_m| <= D/4 with D the half-diagonal sqrt(L^2 + W^2)/2 (checked by PlateSpec).
    Not arc-length preserving.
    """

    sag_m: float
    family: ClassVar[str] = "dome"
    label: ClassVar[str] = "dome or bowl"
    layout: ClassVar[str] = "grid"
    sweep_keys: ClassVar[tuple[SweepKey, ...]] = (SweepKey("sag_m", "sag_m", "dome sag, m"),)

    def __post_init__(self) -> None:
        _check(self, "sag_m", -math.inf, math.inf, allowed="a finite number of metres")

    def max_curvature_per_m(self, length_m: float, width_m: float) -> float:
        return abs(self.sphere_curvature_per_m(length_m, width_m))

    def sphere_curvature_per_m(self, length_m: float, width_m: float) -> float:
        """Signed sphere curvature c (1/m) on an L x W plate: positive for a dome, negative for a bowl."""
        sag = self.sag_m
        half_diag_sq = 0.25 * (length_m**2 + width_m**2)
        return 2.0 * sag / (half_diag_sq + sag**2)

    def surface(self, length_m: float, width_m: float, u, v, xp):
        c = xp.const(self.sphere_curvature_per_m(length_m, width_m))
        rho_sq = u * u + v * v
        w = xp.sqrt(1.0 - c * c * rho_sq)
        z = -c * rho_sq / (1.0 + w)
        return height_field(u, v, z, -c * u / w, -c * v / w, xp)

    @classmethod
    def defaults(cls, length_m: float, width_m: float) -> "Dome":
        return cls(0.02 * math.hypot(length_m, width_m))

    def check_fit(self, length_m: float, width_m: float) -> None:
        lim = 0.125 * math.hypot(length_m, width_m)
        if abs(self.sag_m) > lim:
            raise PlateSpecError(
                f"Dome.sag_m = {_fmt(self.sag_m)} is out of range for {_size(length_m, width_m)}: allowed "
                f"{_fmt(-lim)} to {_fmt(lim)} m (a quarter of the half-diagonal)")

    @classmethod
    def study_examples(cls):
        return (("dome 12 mm", cls(0.012)), ("bowl 12 mm", cls(-0.012)))


@register_family
@dataclass(frozen=True)
class Dent(DeformationFamily):
    """Local smooth dent in -Z as a height field: z = -depth_m (1 - r^2/R^2)^3 for r < R.

    r is the material distance from (centre_u_m, centre_v_m), R = radius_m; the
    profile is C2 (zero slope and curvature at r = R) and 0 outside. depth_m in
    (0, radius_m / 2] and at most a twentieth of the smaller plate side; the centre
    must lie on the plate (both checked by PlateSpec, which knows the plate size).
    """

    depth_m: float
    radius_m: float
    centre_u_m: float = 0.0
    centre_v_m: float = 0.0
    family: ClassVar[str] = "dent"
    label: ClassVar[str] = "dent"
    layout: ClassVar[str] = "grid"
    sweep_keys: ClassVar[tuple[SweepKey, ...]] = (SweepKey("dent_depth_m", "depth_m", "dent depth, m"),
                                                 SweepKey("dent_radius_m", "radius_m", "dent radius, m"))

    def __post_init__(self) -> None:
        _check(self, "radius_m", 0.0, math.inf, lo_open=True)
        _check(self, "depth_m", 0.0, 0.5 * self.radius_m, lo_open=True,
               allowed=f"> 0 to {_fmt(0.5 * self.radius_m)} m (half of radius_m)")
        _check(self, "centre_u_m", -math.inf, math.inf, allowed="a finite number of metres")
        _check(self, "centre_v_m", -math.inf, math.inf, allowed="a finite number of metres")

    def max_curvature_per_m(self, length_m: float, width_m: float) -> float:
        return 6.0 * self.depth_m / self.radius_m**2

    def surface(self, length_m: float, width_m: float, u, v, xp):
        du = u - xp.const(self.centre_u_m)
        dv = v - xp.const(self.centre_v_m)
        r2 = xp.const(self.radius_m**2)
        one_minus_q = xp.maximum(1.0 - (du * du + dv * dv) / r2, 0.0)
        depth = xp.const(self.depth_m)
        z = -depth * one_minus_q**3
        slope = 6.0 * depth * one_minus_q**2 / r2
        return height_field(u, v, z, slope * du, slope * dv, xp)

    @classmethod
    def defaults(cls, length_m: float, width_m: float) -> "Dent":
        s = min(length_m, width_m)
        return cls(0.02 * s, 0.25 * s, 0.0, 0.0)

    def check_fit(self, length_m: float, width_m: float) -> None:
        size = _size(length_m, width_m)
        lim = 0.05 * min(length_m, width_m)
        if self.depth_m > lim:
            raise PlateSpecError(
                f"Dent.depth_m = {_fmt(self.depth_m)} is out of range for {size}: allowed > 0 to "
                f"{_fmt(lim)} m (a twentieth of the smaller side)")
        for name, half in (("centre_u_m", length_m / 2), ("centre_v_m", width_m / 2)):
            value = getattr(self, name)
            if abs(value) > half:
                raise PlateSpecError(
                    f"Dent.{name} = {_fmt(value)} is out of range for {size}: allowed "
                    f"{_fmt(-half)} to {_fmt(half)} m")

    def curved_support(self, length_m: float, width_m: float):
        u0, u1 = self.centre_u_m - self.radius_m, self.centre_u_m + self.radius_m
        v0, v1 = self.centre_v_m - self.radius_m, self.centre_v_m + self.radius_m
        return (max(u0, -length_m / 2), min(u1, length_m / 2)), (max(v0, -width_m / 2), min(v1, width_m / 2))

    @classmethod
    def study_examples(cls):
        return (("dent 3 mm centre", cls(0.003, 0.02)), ("dent 3 mm off-centre", cls(0.003, 0.015, 0.03, 0.015)))


@register_family
@dataclass(frozen=True)
class SCurve(DeformationFamily):
    """S-curve: two circular arcs of opposite curvature meeting at the plate's middle, arc length
    preserved, ruled along the bend axis like ``CylindricalBend``.

    On the bending coordinate s the curvature is +-k for s > 0 and -+k for s < 0, k =
    2 angle_rad / S (S: the plate's extent along s), so the tangent turns by angle_rad from the
    middle to either end and the two ends stay parallel: the profile is point-symmetric about
    the plate centre, which stays at the origin with normal +Z (a C1 curve, its curvature
    jumping at s = 0). angle_rad 0 or ``MIN_BEND_DEG`` to 180 deg (at 180 each half is a half circle).
    direction: "up" (the s > 0 half rises toward +Z, the other falls) or "down"; axis_rad as
    in CylindricalBend.
    """

    angle_rad: float
    direction: str = "up"
    axis_rad: float = 0.0
    family: ClassVar[str] = "s_curve"
    label: ClassVar[str] = "S-curve"
    layout: ClassVar[str] = "strips"
    in_default_study: ClassVar[bool] = False  # not among the study's 61 default plates: study --families s_curve

    def __post_init__(self) -> None:
        _check_bend(self, MAX_S_CURVE_RAD)
        _check_direction(self)
        _check(self, "axis_rad", 0.0, math.pi, unit="rad", hi_open=True)

    def max_curvature_per_m(self, length_m: float, width_m: float) -> float:
        return _arcs_ruling(self, length_m, width_m, 2).curvature_per_m

    @classmethod
    def defaults(cls, length_m: float, width_m: float) -> "SCurve":
        return cls(DEFAULT_ANGLE_RAD, "up", 0.0)

    def ruling(self, length_m: float, width_m: float) -> Ruling:
        return _arcs_ruling(self, length_m, width_m, 2)

    def bend_profile(self, length_m: float, width_m: float, s, xp):
        """(p, z, phi) of the bent section at bending coordinate s (``surfaces.ruled_frame``): the
        arc of curvature +-2 angle_rad / S on |s|, odd in s."""
        k = xp.const(_up_sign(self) * 2.0 * self.angle_rad / bending_extent_m(length_m, width_m, self.axis_rad))
        a, odd = xp.abs(s), xp.sign(s)
        p, z = arc(a, k, xp)
        return odd * p, odd * z, k * a

    def surface(self, length_m: float, width_m: float, u, v, xp):
        return ruled_frame(self.axis_rad, lambda s: self.bend_profile(length_m, width_m, s, xp), u, v, xp)

    @classmethod
    def study_examples(cls):
        return (("s-curve 60 up axis 0", cls(math.radians(60.0), "up", 0.0)),
                ("s-curve 120 down axis 90", cls(math.radians(120.0), "down", math.radians(90.0))),
                ("s-curve 170 up axis 30", cls(math.radians(170.0), "up", math.radians(30.0))))


Deformation = Flat | CylindricalBend | Fold | Twist | Dome | Dent | SCurve  # the built-in families


def family_class(family: str) -> type[DeformationFamily]:
    """The family's dataclass; PlateSpecError naming the known families for any other name."""
    if family not in FAMILIES:
        raise PlateSpecError(f"deformation family = {family!r} is unknown: allowed families " + ", ".join(FAMILIES))
    return FAMILIES[family]


def family_sweep_keys() -> tuple[tuple[str, SweepKey], ...]:
    """(family, key) of every family's own sweep-spec axes, families in ``FAMILIES`` order, each
    family's keys in its order (a key two families share is listed once, under the first)."""
    out, seen = [], set()
    for name, cls in FAMILIES.items():
        for k in cls.sweep_keys:
            if k.name not in seen:
                seen.add(k.name)
                out.append((name, k))
    return tuple(out)


def bending_extent_m(length_m: float, width_m: float, axis_rad: float) -> float:
    """Extent S (metres) of an L x W plate along the bending coordinate s = u cos a + v sin a."""
    return length_m * abs(math.cos(axis_rad)) + width_m * abs(math.sin(axis_rad))


def max_curvature_per_m(spec: "PlateSpec") -> float:
    """Upper bound (1/m) on the top surface's principal curvatures; 0 for a flat plate (the
    family's own ``max_curvature_per_m``)."""
    return spec.deformation.max_curvature_per_m(spec.length_m, spec.width_m)


def _size(length_m: float, width_m: float) -> str:
    return f"a {_fmt(length_m)} m x {_fmt(width_m)} m plate"


@dataclass(frozen=True)
class PlateSpec:
    """A rectangular plate: length_m along X, width_m along Y, thickness_m (0 = sheet).

    length_m and width_m from ``MIN_SIDE_M`` to ``MAX_SIDE_M`` (1 mm to 10 m).
    thickness_m from 0 to a tenth of the smaller side and, for a curved plate, to half
    the smallest radius of curvature (so the bottom offset surface stays smooth).
    deformation: one of the registered families of ``FAMILIES`` (Flat, CylindricalBend, Fold, Twist,
    Dome, Dent, SCurve and any added by ``register_family``).
    """

    length_m: float
    width_m: float
    thickness_m: float = 0.0
    deformation: Deformation = field(default_factory=Flat)

    def __post_init__(self) -> None:
        _check(self, "length_m", MIN_SIDE_M, MAX_SIDE_M)
        _check(self, "width_m", MIN_SIDE_M, MAX_SIDE_M)
        _check(self, "thickness_m", 0.0, math.inf)
        if not isinstance(self.deformation, DeformationFamily) or type(self.deformation) not in FAMILIES.values():
            raise PlateSpecError(
                f"PlateSpec.deformation = {self.deformation!r} is not a deformation: allowed "
                + ", ".join(c.__name__ for c in FAMILIES.values()))
        self._check_fit()
        limit = 0.1 * min(self.length_m, self.width_m)
        why = "a tenth of the smaller plate side"
        kappa = max_curvature_per_m(self)
        if kappa > 0 and 0.5 / kappa < limit:
            limit, why = 0.5 / kappa, "half the smallest radius of curvature of this deformation"
        if self.thickness_m > limit:
            raise PlateSpecError(
                f"PlateSpec.thickness_m = {_fmt(self.thickness_m)} is out of range: allowed 0 to "
                f"{_fmt(limit)} m ({why})")

    def _check_fit(self) -> None:
        """Cross-field checks: the deformation must fit this plate size (the family's ``check_fit``)."""
        self.deformation.check_fit(self.length_m, self.width_m)


def reference_spec() -> PlateSpec:
    """The paper's plate (section V): 116.5 mm x 73.5 mm sheet bent 10 deg up along its length."""
    return PlateSpec(0.1165, 0.0735, 0.0, CylindricalBend(math.radians(10.0), "up", 0.0))
