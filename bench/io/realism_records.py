"""What a realism draw did to the acquisition (``bench.run.realism``) as typed records, and their
file form (sample.json's and sensing.json's ``acquisition``, accuracy.json's trials).

Field names are the JSON keys, units in the names (``_m`` metres, ``_rad`` radians, ``_px``
pixels, ``_deg`` degrees); ``to_dict`` writes a record and ``from_dict`` reads it back
(``bench.io.records.Record``). Parts a draw does not have (no estimated intrinsics, no hand/eye
calibration, cameras not moved) are left out of the file.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Mapping

from platebench.bench.io.records import Record, records_from

__all__ = ["ViewPoseError", "IntrinsicsEstimate", "HandEyeEstimate", "DrawReport", "RobotMove"]


@dataclass(frozen=True)
class ViewPoseError(Record):
    """How far a camera really stood from its commanded pose: position (m) and rotation (rad)."""

    position_error_m: float
    rotation_error_rad: float


@dataclass(frozen=True)
class IntrinsicsEstimate(Record):
    """The intrinsics the draw's calibration estimated, against the true ones: fx, fy and the
    principal point (estimate minus truth, px), its reprojection RMS (px), the views it used,
    whether it estimated a distortion and its coefficients (OpenCV k1, k2, p1, p2, k3)."""

    fx_error_px: float
    fy_error_px: float
    cx_error_px: float
    cy_error_px: float
    reprojection_rms_px: float
    views: int
    distortion_estimated: bool
    distortion_k1_k2_p1_p2_k3: tuple


@dataclass(frozen=True)
class HandEyeEstimate(Record):
    """The draw's hand/eye calibration against the truth: the camera's mount on the flange and the
    target block's pose (position m, rotation rad), the solution's rotation (rad) and translation
    (m) residual RMS, the views it used."""

    mount_position_error_m: float
    mount_rotation_error_rad: float
    target_position_error_m: float
    target_rotation_error_rad: float
    residual_rotation_rms_rad: float
    residual_translation_rms_m: float
    views: int


@dataclass(frozen=True)
class DrawReport(Record):
    """What a draw's estimates missed by (``exact``: the robot goes where it is told and the method
    is told the truth): its intrinsics (``calibration``) and hand/eye estimates (None: not
    estimated), the corner noise of its calibration views (px per axis; None: nothing estimated),
    and, once a pair is taken, how far each camera (``"left"``, ``"right"``) stood from its command
    (``views``; empty: the cameras stand where commanded)."""

    exact: bool = False
    calibration: IntrinsicsEstimate | None = None
    hand_eye: HandEyeEstimate | None = None
    corner_noise_px: float | None = None
    views: Mapping[str, ViewPoseError] = field(default_factory=dict)

    def with_views(self, views: Mapping[str, ViewPoseError]) -> "DrawReport":
        return replace(self, views=dict(views))

    def to_dict(self) -> dict:
        return {k: v for k, v in super().to_dict().items() if v is not None and v != {}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any] | None) -> "DrawReport":
        d = dict(d or {})
        return super().from_dict({
            **d, "calibration": None if d.get("calibration") is None else IntrinsicsEstimate.from_dict(d["calibration"]),
            "hand_eye": None if d.get("hand_eye") is None else HandEyeEstimate.from_dict(d["hand_eye"]),
            "views": records_from(ViewPoseError, d.get("views"))})


@dataclass(frozen=True)
class RobotMove(Record):
    """One move of a real rig in a sensing run: the view it was for, the turn of the cell that let
    the arm reach it (deg), and how far each camera really stood from its command (``views``;
    columns ``<camera>_position_error_m``, ``<camera>_rotation_error_rad`` in the file)."""

    view: str | None
    cell_turn_deg: float
    views: Mapping[str, ViewPoseError] = field(default_factory=dict)

    def to_dict(self) -> dict:
        return {"view": self.view, "cell_turn_deg": self.cell_turn_deg,
                **{f"{c}_{k}": v for c, e in self.views.items() for k, v in e.to_dict().items()}}

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> "RobotMove":
        cams = dict.fromkeys(k.split("_", 1)[0] for k in d if k.endswith(("_position_error_m", "_rotation_error_rad")))
        return cls(d.get("view"), float(d["cell_turn_deg"]),
                   {c: ViewPoseError(float(d[f"{c}_position_error_m"]), float(d[f"{c}_rotation_error_rad"]))
                    for c in cams})
