"""The accuracy study (``platebench study accuracy``, ``bench.run.accuracy``) as typed records, and
its file form (accuracy.json; accuracy.csv holds the trials' flat columns).

Field names are the JSON keys, units in the names (``_mm`` millimetres, ``_m`` metres, ``_px``
pixels, ``_rad`` radians, ``_frac`` a fraction 0..1, ``_s`` seconds); ``to_dict`` writes a record
and ``from_dict`` reads it back (``bench.io.records.Record``).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

from platebench.bench.config.realism import Realism
from platebench.bench.io.codecs import decode, encode
from platebench.bench.io.realism_records import DrawReport
from platebench.bench.io.records import Record, records_from

__all__ = ["AccuracySettings", "AccuracyTrial", "ErrorStats", "ConfigSummary", "AccuracyPaper", "AccuracyCamera",
           "AccuracyTargetBlock", "AccuracyRobot", "AccuracyStudy", "MEASURES"]

MEASURES = ("depth", "xy")  # the error's depth (z) and its larger of |x| and |y|


@dataclass(frozen=True)
class AccuracySettings:
    """What the study runs: the realism preset, the number of draws (seeds ``seed0 .. seed0 + draws -
    1``), the targets, whether to run the error budget (else only every source on), samples per pixel,
    the Mitsuba variant."""

    realism: Realism
    draws: int = 30
    targets: tuple = ("block",)
    budget: bool = True
    spp: int = 16
    seed0: int = 0
    variant: str | None = None
    # how the block's corners are located (``bench.run.accuracy.CORNER_METHODS``): "edges", the
    # intersections of lines fitted to the square's edges (sub-pixel); "pixels", the vertices of the
    # polygon of its binary outline, on the pixel grid (the paper's contour and corner method, its [11])
    corners: str = "edges"

    def to_dict(self) -> dict:
        return {"realism": encode(self.realism), "draws": self.draws, "targets": list(self.targets),
                "budget": self.budget, "spp": self.spp, "seed0": self.seed0, "variant": self.variant,
                "corners": self.corners}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "AccuracySettings":
        return cls(decode(Realism, dict(d["realism"])), int(d["draws"]), tuple(d["targets"]), bool(d["budget"]),
                   int(d["spp"]), int(d["seed0"]), d.get("variant"), str(d.get("corners", "edges")))


_MEASURED = ("points", "worst_depth_mm", "worst_xy_mm", "rms_depth_mm", "rms_xy_mm", "mean_depth_mm", "errors_mm")


@dataclass(frozen=True)
class AccuracyTrial(Record):
    """One trial: the target ("block" or "plate"), the budget row (``config``: its label, ``kind``,
    realism and sources on), the draw's seed, its status ("ok"/"failed") and one-line error; for a
    trial that measured: the points measured, the worst point in depth and in x/y, the RMS of each,
    the mean signed depth error and every point's error (x, y, z; mm); the trial's seconds and what
    the draw's estimates missed by (``acquisition``; None: a draw whose estimates could not be used)."""

    target: str
    config: str
    kind: str
    realism: str
    sources: str
    seed: int
    status: str = "failed"
    error: str | None = None
    points: int | None = None
    worst_depth_mm: float | None = None
    worst_xy_mm: float | None = None
    rms_depth_mm: float | None = None
    rms_xy_mm: float | None = None
    mean_depth_mm: float | None = None
    errors_mm: tuple = ()
    time_s: float | None = None
    acquisition: DrawReport | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def to_dict(self) -> dict:
        """The trial's keys (a failed trial has no measured ones)."""
        d = super().to_dict()
        return d if self.ok else {k: v for k, v in d.items() if k not in _MEASURED}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "AccuracyTrial":
        d = dict(d)
        acq = d.get("acquisition")
        return super().from_dict({**d, "errors_mm": tuple(tuple(e) for e in d.get("errors_mm") or ()),
                                  "acquisition": None if acq is None else DrawReport.from_dict(acq)})


@dataclass(frozen=True)
class ErrorStats(Record):
    """One measure's statistics over a budget row's trials (mm): the median of the trials' worst
    points and its quantiles (``"q05"`` .. ``"q95"``), over every point of every trial the RMS, the
    95th percentile and the maximum, the share of trials within the paper's bound, and (depth only)
    the mean signed error."""

    worst_median_mm: float
    worst_quantiles_mm: Mapping[str, float]
    rms_mm: float
    p95_mm: float
    max_mm: float
    within_paper_frac: float
    mean_signed_mm: float | None = None

    def to_dict(self) -> dict:
        d = super().to_dict()
        if self.mean_signed_mm is None:
            del d["mean_signed_mm"]
        return d


@dataclass(frozen=True)
class ConfigSummary(Record):
    """One budget row of one target: its kind and sources on, its draws and failed draws, and each
    measure's statistics (``ErrorStats``; None when every draw failed)."""

    kind: str
    sources: tuple
    draws: int
    failed: int
    depth: ErrorStats | None = None
    xy: ErrorStats | None = None

    def stats(self, measure: str) -> ErrorStats | None:
        """The statistics of ``measure`` ("depth" or "xy")."""
        if measure not in MEASURES:
            raise ValueError(f"measure {measure!r} is not allowed: choose one of {', '.join(MEASURES)}")
        return self.depth if measure == "depth" else self.xy

    def to_dict(self) -> dict:
        return {k: v for k, v in super().to_dict().items() if v is not None or k not in MEASURES}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "ConfigSummary":
        d = dict(d)
        return super().from_dict({**d, **{m: None if d.get(m) is None else ErrorStats.from_dict(d[m])
                                           for m in MEASURES}})


@dataclass(frozen=True)
class AccuracyPaper(Record):
    """The paper's bound (section V-D): depth and x/y (mm) of one trial's worst corner, at its
    sensing distance (m), and what it measured."""

    depth_mm: float
    xy_mm: float
    distance_m: float
    what: str


@dataclass(frozen=True)
class AccuracyCamera(Record):
    """The camera of the study's realism: its name, image size (px), focal lengths (px), the
    baseline and sensing distance (m), its lens (OpenCV k1, k2, p1, p2, k3; None: none), aperture
    radius (m), line jitter (px), full well (e-), read noise (DN), bit depth."""

    name: str
    width_px: int
    height_px: int
    fx_px: float
    fy_px: float
    baseline_m: float
    distance_m: float
    distortion_k1_k2_p1_p2_k3: tuple | None
    aperture_radius_m: float
    line_jitter_px: float
    full_well_e: float
    read_noise_dn: float
    bit_depth: int


@dataclass(frozen=True)
class AccuracyTargetBlock(Record):
    """The hand/eye target block: its squares, their side (m), its yaw in the cell (rad)."""

    squares_x: int
    squares_y: int
    square_m: float
    yaw_rad: float


@dataclass(frozen=True)
class AccuracyRobot(Record):
    """The robot of the study's realism, and its error model's joint (rad) and kinematic (rad, m)
    standard deviations (None: no error model)."""

    name: str
    description: str
    joint_sigma_rad: float | None = None
    kinematic_sigma_angle_rad: float | None = None
    kinematic_sigma_length_m: float | None = None

    def to_dict(self) -> dict:
        return {k: v for k, v in super().to_dict().items() if v is not None}


@dataclass(frozen=True)
class AccuracyStudy(Record):
    """The study: its settings, the paper's bound, the camera, the target block, the robot (None:
    none), the corner noise of each budget row's calibration views (px per axis), the sources'
    descriptions, per target and budget row the statistics (``ConfigSummary``), every trial and
    the study's seconds."""

    settings: AccuracySettings
    paper: AccuracyPaper
    camera: AccuracyCamera
    target_block: AccuracyTargetBlock
    robot: AccuracyRobot | None
    corner_noise_px: Mapping[str, float]
    sources: Mapping[str, str]
    summary: Mapping[str, Mapping[str, ConfigSummary]]
    rows: tuple[AccuracyTrial, ...]
    time_s: float
    study: str = field(default="accuracy")

    def to_dict(self) -> dict:
        d = super().to_dict()
        return {"study": d.pop("study"), **d}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "AccuracyStudy":
        d = dict(d)
        return super().from_dict({
            **d, "settings": AccuracySettings.from_dict(d["settings"]), "paper": AccuracyPaper.from_dict(d["paper"]),
            "camera": AccuracyCamera.from_dict(d["camera"]), "target_block": AccuracyTargetBlock.from_dict(d["target_block"]),
            "robot": None if d.get("robot") is None else AccuracyRobot.from_dict(d["robot"]),
            "summary": {t: records_from(ConfigSummary, s) for t, s in (d.get("summary") or {}).items()},
            "rows": tuple(AccuracyTrial.from_dict(r) for r in d.get("rows") or ())})
