"""One dataset sample on disk: write it (layout version 1) and read it back.

Layout (all world frame, metres; see README "Dataset sample layout")::

    SAMPLE/sample.json      every parameter, seed, package versions, layout version, timings
    SAMPLE/calib.json       left/right: K, R, t, width, height; baseline_m; projector: K, R, t, width, height, kind
    SAMPLE/calib.txt        Middlebury-style calibration of the left/right pair
    SAMPLE/pattern.png      the projected pattern; pattern.json its features
    SAMPLE/plate.ply        ground-truth mesh
    SAMPLE/boundary.npy     (N,3) closed true boundary
    SAMPLE/images/{left,right}_{passive,active}.png (camera DN) and .exr (linear radiance)
    SAMPLE/gt/{left,right}_depth.exr, _mask.png, _points.exr, _normal.exr, _proj.exr, _feature.png
    SAMPLE/gt/disp0GT.pfm   left disparity, inf where unknown
    SAMPLE/gt/visibility.json

The whole directory is staged and renamed into place: a sample exists complete or
not at all. Reconstruction reads only ``images/``, ``calib.json`` and ``pattern.json``
(see ``load_inputs``); ground truth is read by evaluation only.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from platebench.bench.files import JSON_MAX_BYTES, read_capped, require_dir
from platebench.bench.io.atomic import (
    staged_directory,
    write_bytes,
    write_json,
    write_text,
)
from platebench.bench.io.codecs import decode, encode
from platebench.bench.io.images import (
    DatasetError,
    check_ply,
    read_exr,
    read_npy,
    read_pfm,
    read_png,
    write_exr,
    write_pfm,
    write_png,
)
from platebench.bench.io.middlebury import calib_txt
from platebench.bench.io.outputs import write_stamp
from platebench.bench.io.versions import package_versions
from platebench.scenes.camera import Camera
from platebench.scenes.naming import CAMERAS, IMAGE_NAMES
from platebench.scenes.pattern import Feature, Pattern
from platebench.scenes.projector import Projector
from platebench.scenes.rig import PosedPair, StereoRig

if TYPE_CHECKING:
    import trimesh  # imported by read_mesh: a sample's images, calibration and pattern need none

LAYOUT_VERSION = 1


def calib_dict(rig: StereoRig, projector: Projector) -> dict:
    return {"left": encode(rig.left), "right": encode(rig.right), "baseline_m": rig.baseline_m,
            "projector": encode(projector), "frames": "OpenCV camera frames, x_cam = R x_world + t; "
            "world right-handed +Z up; metres; pixel centres at integers"}


def _mesh_ply_bytes(mesh: trimesh.Trimesh) -> bytes:
    return mesh.export(file_type="ply", encoding="binary")


def pair_disparity(gt_left, pair) -> np.ndarray:
    """Left disparity ``u_left - u_right`` (px, float32, inf off the plate) of a pair as really posed: each
    left pixel's true surface point projected into the true right camera (for a conventional rig this
    is ``f B / Z``; for a pair a robot took, the disparity its images really have)."""
    disp = np.full(gt_left.mask.shape, np.inf, np.float32)
    vv, uu = np.nonzero(gt_left.mask)
    uv_r = pair.right.project(gt_left.points[vv, uu].astype(np.float64))
    disp[vv, uu] = uu - uv_r[:, 0]
    disp[~np.isfinite(disp)] = np.inf
    return disp


def write_sample(out: Path, s, overwrite: bool = False, into: bool = False) -> Path:
    """Write a rendered sample (``bench.run.render.RenderedSample``) atomically; returns the sample
    directory. ``into``: ``out`` is an empty directory of an output that is already staged (a command
    stages its whole output first with ``staged_output``, so that a bad ``--out`` fails before the
    render): the files are written straight into it. Otherwise the sample gets its stamp
    (``bench.io.outputs.write_stamp``: the sha256 of its files, which readers check). Under realism
    (``s.told``), calib.json holds the rig the method is told and gt/cameras.json the cameras really posed."""
    out = Path(out)
    told = getattr(s, "told", None)
    rig = told if told is not None else s.scene.rig
    with (contextlib.nullcontext(out) if into else staged_directory(out, overwrite=overwrite)) as d:
        (d / "images").mkdir()
        (d / "gt").mkdir()
        for name in IMAGE_NAMES:
            write_png(d / "images" / f"{name}.png", s.digital[name])
            write_exr(d / "images" / f"{name}.exr", s.radiance[name])
        pattern = s.scene.projector.pattern
        write_png(d / "pattern.png", np.rint(pattern.image * 255).astype(np.uint8))
        write_json(d / "pattern.json", encode(pattern))
        write_json(d / "calib.json", calib_dict(rig, s.scene.projector))
        write_bytes(d / "plate.ply", _mesh_ply_bytes(s.plate.mesh))
        np.save(d / "boundary.npy", np.asarray(s.plate.boundary, np.float64))
        for cam in CAMERAS:
            g = s.gt[cam]
            write_exr(d / "gt" / f"{cam}_depth.exr", g.depth)
            write_png(d / "gt" / f"{cam}_mask.png", (g.mask * 255).astype(np.uint8))
            write_exr(d / "gt" / f"{cam}_points.exr", g.points)
            write_exr(d / "gt" / f"{cam}_normal.exr", g.normals)
            write_exr(d / "gt" / f"{cam}_proj.exr", g.proj_uv)
            write_png(d / "gt" / f"{cam}_feature.png", (g.feature + 1).astype(np.uint16))
        if told is None:
            disp = np.where(s.gt["left"].mask, rig.disparity(s.gt["left"].depth64), np.inf).astype(np.float32)
        else:
            disp = pair_disparity(s.gt["left"], s.scene.rig)
            write_json(d / "gt" / "cameras.json", {"left": encode(s.scene.rig.left),
                                                   "right": encode(s.scene.rig.right),
                                                   "what": "the cameras really posed (realism); calib.json holds "
                                                           "the rig the method is told"})
        write_pfm(d / "gt" / "disp0GT.pfm", disp)
        write_text(d / "calib.txt", calib_txt(rig, disp))
        write_json(d / "gt" / "visibility.json", {c: encode(v) for c, v in s.visibility.items()})
        meta = {"layout_version": LAYOUT_VERSION, "config": encode(s.config), "variant": s.variant,
                "packages": package_versions(), "timings_s": s.timings_s,
                "false_boundary_gt": any(v.false_boundary for v in s.visibility.values()),
                "images": {n: hashlib.sha256(s.digital[n].tobytes()).hexdigest() for n in IMAGE_NAMES}}
        if getattr(s, "acquisition", None) is not None:
            meta["acquisition"] = s.acquisition.to_dict()
        write_json(d / "sample.json", meta)
        if not into:  # a command's staged output gets its stamp when the whole output is complete
            write_stamp(d, "sample")
    return out


# -- reading ------------------------------------------------------------------
@dataclass(frozen=True)
class Calibration:
    """What calib.json holds: the stereo rig and the projector model (no pattern image)."""

    rig: StereoRig
    projector_camera: Camera
    projector_kind: str
    projector_cutoff_rad: float | None


@dataclass(frozen=True)
class ReconstructionInputs:
    """Everything the method under test may see: images, calibration, the pattern description."""

    images: dict  # name -> (H,W) uint8/uint16
    calibration: Calibration
    pattern: Pattern
    sample_dir: Path


def read_json(path: Path, kind: type = dict) -> dict:
    """A JSON file whose top level must be a ``kind`` (one-line DatasetError naming the file otherwise:
    missing, not a regular file, larger than ``JSON_MAX_BYTES``, not UTF-8, not JSON)."""
    path = Path(path)
    data = read_capped(path, JSON_MAX_BYTES, "JSON file", DatasetError, missing="file is missing")
    try:
        d = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: not a UTF-8 JSON file") from None
    except json.JSONDecodeError as e:
        raise DatasetError(f"{path}: invalid JSON ({e.msg} at line {e.lineno})") from None
    if not isinstance(d, kind):
        raise DatasetError(f"{path}: the top level is a {type(d).__name__}: allowed a JSON "
                           f"{'object' if kind is dict else kind.__name__}")
    return d


def _bad(path: Path, e: Exception, what: str) -> DatasetError:
    why = f"missing key {e}" if isinstance(e, KeyError) else (str(e).splitlines()[0] if str(e) else type(e).__name__)
    return DatasetError(f"{path}: {what} ({why})")


def load_calibration(sample_dir: Path) -> Calibration:
    path = Path(sample_dir) / "calib.json"
    d = read_json(path)
    try:
        left, right = decode(Camera, d["left"]), decode(Camera, d["right"])
        rig = StereoRig(left, right, float(d["baseline_m"]))
        p = d["projector"]
        return Calibration(rig, decode(Camera, p), p.get("kind", "pinhole"), p.get("cutoff_rad"))
    except (KeyError, ValueError, TypeError, AttributeError, IndexError) as e:
        raise _bad(path, e, "bad calibration") from None


def load_pattern(sample_dir: Path) -> Pattern:
    sample_dir = Path(sample_dir)
    path = sample_dir / "pattern.json"
    d = read_json(path)
    img = read_png(sample_dir / "pattern.png").astype(np.float32) / 255.0
    try:
        if not isinstance(d.get("features"), list):
            raise ValueError("'features' must be a list of feature objects")
        feats = tuple(decode(Feature, f) for f in d["features"])
        fmap = np.full(img.shape, -1, np.int32)
        for f in feats:  # rebuild ownership from the corners (square features)
            (u0, v0), (u1, v1) = f.corners[0], f.corners[2]
            if not all(np.isfinite([u0, v0, u1, v1])):
                raise ValueError(f"feature {f.id} has non-finite corners")
            fmap[int(np.ceil(v0)):int(np.floor(v1)) + 1, int(np.ceil(u0)):int(np.floor(u1)) + 1] = f.id
        return Pattern(img, feats, fmap, d.get("description", {}))
    except (KeyError, ValueError, TypeError, AttributeError, IndexError) as e:
        raise _bad(path, e, "bad pattern description") from None


def load_inputs(sample_dir: Path) -> ReconstructionInputs:
    """Read what reconstruction may see; never opens gt/, plate.ply, boundary.npy or sample.json."""
    sample_dir = require_dir(Path(sample_dir), "sample directory", DatasetError)
    calib = load_calibration(sample_dir)
    images = {}
    for name in IMAGE_NAMES:
        img = read_png(sample_dir / "images" / f"{name}.png")
        cam = calib.rig.left
        if img.shape != (cam.height, cam.width):
            raise DatasetError(f"{sample_dir / 'images' / (name + '.png')}: size {img.shape[1]}x{img.shape[0]} "
                               f"differs from calib.json's {cam.width}x{cam.height}")
        images[name] = img
    return ReconstructionInputs(images, calib, load_pattern(sample_dir), sample_dir)


@dataclass(frozen=True)
class GroundTruthFiles:
    """Ground truth of a written sample, for evaluation."""

    mesh: trimesh.Trimesh
    boundary: np.ndarray
    depth: dict
    mask: dict
    points: dict
    feature: dict
    proj_uv: dict
    disparity: np.ndarray
    visibility: dict
    meta: dict


def load_true_cameras(sample_dir: Path):
    """The cameras really posed (a ``PosedPair``) when they differ from calib.json's (realism), else None."""
    path = Path(sample_dir) / "gt" / "cameras.json"
    if not path.is_file():
        return None
    d = read_json(path)
    try:
        return PosedPair(decode(Camera, d["left"]), decode(Camera, d["right"]))
    except (KeyError, ValueError, TypeError, AttributeError, IndexError) as e:
        raise _bad(path, e, "bad camera poses") from None


def load_ground_truth(sample_dir: Path) -> GroundTruthFiles:
    d = Path(sample_dir)
    meta = read_json(d / "sample.json")
    if meta.get("layout_version") != LAYOUT_VERSION:
        raise DatasetError(f"{d / 'sample.json'}: layout_version {meta.get('layout_version')!r} "
                           f"is not supported (expected {LAYOUT_VERSION})")
    for key, kind in (("config", dict), ("images", dict)):
        if key in meta and not isinstance(meta[key], kind):
            raise DatasetError(f"{d / 'sample.json'}: '{key}' is a {type(meta[key]).__name__}: allowed an object")
    mesh = read_mesh(d / "plate.ply")
    g = d / "gt"
    return GroundTruthFiles(
        mesh, read_npy(d / "boundary.npy", (None, 3)),
        {c: read_exr(g / f"{c}_depth.exr") for c in CAMERAS},
        {c: read_png(g / f"{c}_mask.png") > 0 for c in CAMERAS},
        {c: read_exr(g / f"{c}_points.exr") for c in CAMERAS},
        {c: read_png(g / f"{c}_feature.png").astype(np.int32) - 1 for c in CAMERAS},
        {c: read_exr(g / f"{c}_proj.exr") for c in CAMERAS},
        read_pfm(g / "disp0GT.pfm"),
        read_json(g / "visibility.json"), meta)


def read_mesh(path: Path) -> trimesh.Trimesh:
    """A triangle mesh (PLY) with finite vertices; one-line DatasetError naming the file otherwise."""
    import trimesh  # noqa: PLC0415

    path = Path(path)
    check_ply(path)  # missing, not a regular file, more declared than it holds: refused before trimesh reads it
    try:
        mesh = trimesh.load(path, process=False, force="mesh")
    except Exception as e:  # noqa: BLE001  (trimesh raises many kinds on a damaged file)
        raise _bad(path, e, "not a readable PLY mesh") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0 or not np.all(np.isfinite(mesh.vertices)):
        raise DatasetError(f"{path}: not a PLY triangle mesh with finite vertices")
    return mesh
