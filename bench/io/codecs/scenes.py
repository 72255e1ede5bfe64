"""Codecs of the `scenes` types (see `bench.io.codecs`): cameras and projectors as cameras.json,
rig.json and calibration.json hold them (OpenCV camera frames, metres, pixels), the projector
pattern's pattern.json, the lens, sensor and calibration board settings, and the true boundary's
visibility (visibility.json)."""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from platebench.bench.io.codecs.base import decoder, encode
from platebench.scenes.camera import Camera
from platebench.scenes.lens import BrownConrady
from platebench.scenes.pattern import Feature, Pattern, SquareGridLayout
from platebench.scenes.projector import Projector
from platebench.scenes.render.board_renderer import BoardPose, BoardSpec
from platebench.scenes.render.ground_truth import BoundaryVisibility, HiddenRun
from platebench.scenes.sensor_model import SensorModel


@encode.register(Feature)
def _(x: Feature) -> dict:
    return {"id": x.id, "row": x.row, "col": x.col,
            "center": list(x.center), "corners": [list(c) for c in x.corners]}


@decoder(Feature)
def _(d: Mapping[str, Any]) -> Feature:
    return Feature(int(d["id"]), int(d["row"]), int(d["col"]), tuple(d["center"]),
                   tuple(tuple(c) for c in d["corners"]))


@encode.register(Pattern)
def _(x: Pattern) -> dict:
    """pattern.json: the pattern's size (px), its description and its features (the image is
    pattern.png)."""
    return {"width": x.width, "height": x.height, "description": x.description,
            "features": [encode(f) for f in x.features]}


@encode.register(SquareGridLayout)
def _(x: SquareGridLayout) -> dict:
    return {"kind": "square_grid", "rows": x.rows, "cols": x.cols, "square_px": x.square_px,
            "gap_x_px": x.gap_x_px, "gap_y_px": x.gap_y_px, "x0": x.x0, "y0": x.y0}


@decoder(SquareGridLayout)
def _(d: Mapping[str, Any]) -> SquareGridLayout:
    """A square grid's description (a ``Pattern.description``); ValueError for another pattern's."""
    if d.get("kind") != "square_grid":
        raise ValueError(f"pattern description of kind {d.get('kind')!r} is not a square grid's")
    return SquareGridLayout(int(d["rows"]), int(d["cols"]), int(d["square_px"]), int(d["gap_x_px"]),
                            int(d["gap_y_px"]), int(d["x0"]), int(d["y0"]))


@encode.register(BrownConrady)
def _(x: BrownConrady) -> dict:
    return {"k1": x.k1, "k2": x.k2, "p1": x.p1, "p2": x.p2, "k3": x.k3}


@decoder(BrownConrady)
def _(d: Mapping[str, Any]) -> BrownConrady:
    """The model of its coefficients by name (missing ones 0); ValueError naming an unknown key."""
    unknown = sorted(set(d) - {"k1", "k2", "p1", "p2", "k3"})
    if unknown:
        raise ValueError(f"unknown distortion key {unknown[0]}: allowed k1, k2, p1, p2, k3")
    return BrownConrady(**{k: float(v) for k, v in d.items()})


@encode.register(Camera)
def _(x: Camera) -> dict:
    """K, R, t (world -> camera), the image size and, for a distorted camera, OpenCV's
    (k1, k2, p1, p2, k3)."""
    d = {"K": x.K.tolist(), "R": x.R.tolist(), "t": x.t.tolist(),
         "width": x.width, "height": x.height}
    if x.distortion is not None:
        d["distortion_k1_k2_p1_p2_k3"] = x.distortion.as_opencv().tolist()
    return d


@decoder(Camera)
def _(d: Mapping[str, Any]) -> Camera:
    dist = d.get("distortion_k1_k2_p1_p2_k3")
    return Camera(np.array(d["K"]), np.array(d["R"]), np.array(d["t"]), d["width"], d["height"],
                  None if dist is None else BrownConrady.from_opencv(dist))


@encode.register(Projector)
def _(x: Projector) -> dict:
    """Its camera's form, with its ``kind`` and, where set, its ``cutoff_rad``."""
    d = encode(x.camera)
    d["kind"] = x.kind
    if x.cutoff_rad is not None:
        d["cutoff_rad"] = x.cutoff_rad
    return d


@encode.register(SensorModel)
def _(x: SensorModel) -> dict:
    d = {"bit_depth": x.bit_depth, "radiance_full_scale": x.radiance_full_scale, "gamma": x.gamma,
         "full_well_e": x.full_well_e, "read_noise_dn": x.read_noise_dn}
    if x.line_jitter_px > 0:  # recorded only when on: a record without it reads as no jitter
        d["line_jitter_px"] = x.line_jitter_px
    return d


@encode.register(BoardSpec)
def _(x: BoardSpec) -> dict:
    return {"squares_x": x.squares_x, "squares_y": x.squares_y, "square_m": x.square_m,
            "marker_m": x.marker_m, "dictionary": x.dictionary,
            "texels_per_square": x.texels_per_square, "margin_squares": x.margin_squares}


@encode.register(BoardPose)
def _(x: BoardPose) -> dict:
    return {"name": x.name, "R_wb": np.asarray(x.R_wb).tolist(), "p_wb_m": np.asarray(x.p_wb).tolist()}


@encode.register(HiddenRun)
def _(x: HiddenRun) -> dict:
    return {"start": x.start, "end": x.end, "count": x.count, "length_m": x.length_m}


@encode.register(BoundaryVisibility)
def _(x: BoundaryVisibility) -> dict:
    return {"visible_fraction": x.visible_fraction,
            "hidden_segments": [encode(h) for h in x.hidden_segments],
            "false_boundary": x.false_boundary, "n_points": int(x.visible.size),
            "n_visible": int(x.visible.sum())}
