"""ChArUco calibration board rendered by Mitsuba in several poses, seen by a stereo rig.

The board is OpenCV's own ``cv2.aruco.CharucoBoard`` image (generated at high
resolution) used as the albedo of a flat two-triangle mesh: a two-sided diffuse
surface lit by a uniform ``constant`` environment, rendered by the ``direct``
integrator with BSDF sampling only (a diffuse surface under a constant sky then has
no Monte Carlo variance: only pixel-footprint antialiasing varies with the seed,
and a stratified ``multijitter`` sampler keeps that small).
The background is black (``hide_emitters``). One Mitsuba scene serves every pose:
a pose only rewrites the mesh's vertex positions through ``mi.traverse`` (no
rebuild, no recompilation); a change of rig is a sensor ``to_world`` update.

Board frame (OpenCV's object-point frame): origin at the board's top-left outer
corner, x along the board image's columns, y along its rows, z = x cross y, pointing
*into* the board (away from a camera that sees the board image upright); chessboard
corner k is ``board.getChessboardCorners()[k]``. A pose is (R_wb, p_wb):
``x_world = R_wb @ x_board + p_wb``. Units: metres, radians; camera frames as in
``scenes.camera``; sensor transforms from ``scenes.render.mitsuba_convert`` only.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from platebench.scenes.naming import CAMERAS
from platebench.scenes.render import runtime
from platebench.scenes.render.film import grey_to_host
from platebench.scenes.render.lens_sensor import PLUGIN, configure_sensor, sensor_dict, sensor_kind
from platebench.scenes.render.passes import PASS_SAMPLES, render_in_passes
from platebench.scenes.rig import StereoRig
from platebench.scenes.scene_spec import RenderSettings
from platebench.scenes.sensor_model import SensorModel

# Stratified pixel sampling: edge pixels of the board converge ~1/spp instead of
# 1/sqrt(spp), so the ChArUco corners are located more accurately at the same spp.
SAMPLER = "multijitter"


@dataclass(frozen=True)
class BoardSpec:
    """A ChArUco board: squares, sizes (metres), ArUco dictionary, and how it is printed.

    Default 10 x 7 squares of 15 mm (0.15 x 0.105 m): nearly the width of the two
    cameras' common field at 0.40 m (0.156 m), which halves the scatter of the
    estimated focal length against a 0.12 x 0.09 m board (see ``calibration_poses``).
    120 texels per square: finer than the pixels (75 px per square at 0.40 m, f = 2000).
    """

    squares_x: int = 10  # 0.15 x 0.105 m: most of the two cameras' common field at 0.40 m
    squares_y: int = 7
    square_m: float = 0.015
    marker_m: float = 0.011
    dictionary: str = "DICT_5X5_100"
    texels_per_square: int = 120  # texture resolution (the board image OpenCV generates)
    margin_squares: float = 0.5  # white margin around the squares, in squares
    white_albedo: float = 0.8
    black_albedo: float = 0.04

    def __post_init__(self):
        if int(self.squares_x) != self.squares_x or int(self.squares_y) != self.squares_y \
                or min(self.squares_x, self.squares_y) < 3:
            raise ValueError(f"board squares {self.squares_x}x{self.squares_y} out of range: allowed integers >= 3")
        if not (0 < self.marker_m < self.square_m):
            raise ValueError(f"marker_m = {self.marker_m} out of range: allowed 0 < marker_m < square_m "
                             f"({self.square_m})")
        if not hasattr(cv2.aruco, self.dictionary):
            raise ValueError(f"dictionary {self.dictionary!r} is not an OpenCV ArUco dictionary")
        if int(self.texels_per_square) != self.texels_per_square or self.texels_per_square < 20:
            raise ValueError(f"texels_per_square = {self.texels_per_square} out of range: allowed >= 20")
        if not (0 <= self.black_albedo < self.white_albedo <= 1):
            raise ValueError("board albedos must satisfy 0 <= black < white <= 1")

    def board(self) -> "cv2.aruco.CharucoBoard":
        d = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))
        return cv2.aruco.CharucoBoard((self.squares_x, self.squares_y), self.square_m, self.marker_m, d)

    @property
    def size_m(self) -> tuple[float, float]:
        """Width and height of the squares area (metres), margins excluded."""
        return self.squares_x * self.square_m, self.squares_y * self.square_m

    @property
    def center_board(self) -> np.ndarray:
        """Centre of the squares area in the board frame (metres)."""
        w, h = self.size_m
        return np.array([w / 2.0, h / 2.0, 0.0])

    def _margin_px(self) -> int:
        return int(round(self.margin_squares * self.texels_per_square))

    def texture(self) -> np.ndarray:
        """(H,W) float32 albedo texture: OpenCV's board image, margins included."""
        s, m = self.texels_per_square, self._margin_px()
        size = (self.squares_x * s + 2 * m, self.squares_y * s + 2 * m)
        img = self.board().generateImage(size, marginSize=m, borderBits=1)
        a = img.astype(np.float32) / 255.0
        return (self.black_albedo + (self.white_albedo - self.black_albedo) * a).astype(np.float32)

    def texture_corners_board(self) -> np.ndarray:
        """(4,3) board-frame corners of the textured rectangle (TL, TR, BR, BL of the image)."""
        e = self._margin_px() / self.texels_per_square * self.square_m
        w, h = self.size_m
        return np.array([[-e, -e, 0.0], [w + e, -e, 0.0], [w + e, h + e, 0.0], [-e, h + e, 0.0]])

    def corners_board(self) -> np.ndarray:
        """(N,3) chessboard (ChArUco) corners in the board frame, indexed by ChArUco id."""
        return np.asarray(self.board().getChessboardCorners(), float).reshape(-1, 3)


@dataclass(frozen=True)
class BoardPose:
    """World-from-board rigid transform: ``x_world = R_wb @ x_board + p_wb`` (metres)."""

    R_wb: np.ndarray
    p_wb: np.ndarray
    name: str = ""

    def to_world(self, pts_board) -> np.ndarray:
        return np.atleast_2d(np.asarray(pts_board, float)) @ np.asarray(self.R_wb).T + np.asarray(self.p_wb)


def _rot(axis: str, a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def board_pose(rig: StereoRig, spec: BoardSpec, target, tilt_x_deg=0.0, tilt_y_deg=0.0, roll_deg=0.0,
               shift_m=(0.0, 0.0), dz_m=0.0, name: str = "") -> BoardPose:
    """A pose relative to the rig: the board faces the rig (board axes = left camera axes),
    turned by ``roll`` about the optical axis, then tilted about the camera x and y axes
    (degrees), its centre at ``target`` moved by ``shift_m`` along the camera (x, y) axes and
    ``dz_m`` along the optical axis (positive: farther away)."""
    R = rig.left.R  # rows: camera axes in the world
    R_local = _rot("y", np.radians(tilt_y_deg)) @ _rot("x", np.radians(tilt_x_deg)) @ _rot("z", np.radians(roll_deg))
    R_wb = R.T @ R_local
    c = np.asarray(target, float) + R.T @ np.array([shift_m[0], shift_m[1], dz_m])
    return BoardPose(R_wb, c - R_wb @ spec.center_board, name)


def calibration_poses(rig: StereoRig, spec: BoardSpec, target=(0.0, 0.0, 0.0)) -> list[BoardPose]:
    """The default set of 20 poses. Pose 0 lies flat, centred on ``target`` (the
    registration pose: in the plate's plane for the reference rig); the others are
    tilted 15-35 degrees about the image axes and diagonals, rolled up to 90 degrees,
    shifted across the field and moved -4 to +10 cm in depth (parts of the board may
    leave an image: ChArUco corners are identified individually). Shifts and depth
    offsets scale with the rig's distance to ``target`` (designed at 0.40 m).
    Simulated on the reference rig at 640 x 480 with 0.04 px corner noise, these 20
    poses with the default 10 x 7 board give 0.4 px scatter of f and 0.2 px of the
    principal point, against 1.1 px and 0.5 px for 12 poses of an 8 x 6 board."""
    k = float(np.linalg.norm(rig.center - np.asarray(target, float))) / 0.40
    table = [  # name, tilt_x, tilt_y, roll (deg), shift x, shift y, dz (m at 0.40 m)
        ("flat", 0, 0, 0, 0.0, 0.0, 0.0),
        ("tilt+x", 35, 0, 0, 0.0, 0.0, 0.03),
        ("tilt-x", -35, 0, 0, 0.0, 0.0, 0.03),
        ("tilt+y", 0, 35, 0, 0.0, 0.0, 0.03),
        ("tilt-y", 0, -35, 0, 0.0, 0.0, 0.03),
        ("diag++", 25, 25, 0, 0.0, 0.0, 0.03),
        ("diag+-", 25, -25, 0, 0.0, 0.0, 0.03),
        ("diag-+", -25, 25, 0, 0.0, 0.0, 0.03),
        ("diag--", -25, -25, 0, 0.0, 0.0, 0.03),
        ("down+", 15, -15, 10, 0.01, 0.035, 0.0),
        ("up-", -15, 15, -10, -0.01, -0.035, 0.0),
        ("down-far", -20, 10, 20, 0.0, 0.035, 0.06),
        ("up-far", 20, -10, -20, 0.0, -0.035, 0.06),
        ("roll45", 10, 10, 45, 0.0, 0.0, 0.10),
        ("near", -10, -10, -30, 0.0, 0.0, -0.04),
        ("right", 0, 30, 0, 0.01, 0.0, 0.08),
        ("left", 0, -30, 0, -0.01, 0.0, 0.08),
        ("low", 30, 0, 5, 0.0, 0.03, 0.05),
        ("high", -30, 0, -5, 0.0, -0.03, 0.05),
        ("roll90", 0, 0, 90, 0.0, 0.0, 0.05),
    ]
    return [board_pose(rig, spec, target, tx, ty, rl, (sx * k, sy * k), dz * k, name)
            for name, tx, ty, rl, sx, sy, dz in table]


def board_seed(base_seed: int, pose_index: int, camera: str) -> int:
    """Distinct, reproducible seed of each board image (render and sensor noise)."""
    return ((base_seed * 1009 + pose_index) * 2 + CAMERAS.index(camera)) % 2**31


class BoardRenderer:
    """One Mitsuba scene: the board mesh, a constant sky, the rig's two sensors."""

    def __init__(self, rig: StereoRig, spec: BoardSpec = BoardSpec(), variant: str | None = None,
                 sensor: SensorModel = SensorModel(), aperture_radius_m: float = 0.0,
                 focus_distance_m: float | None = None):
        """``aperture_radius_m`` > 0: thin-lens sensors as ``PlateRenderer`` builds them (defocus
        blur), focused at ``focus_distance_m`` (default: the left camera's depth of the origin)."""
        self.mi = mi = runtime.mitsuba(variant)
        self.variant = mi.variant()
        self.pass_samples = PASS_SAMPLES  # the most samples of one mi.render call (scenes.render.passes)
        self.spec = spec
        self.sensor_model = sensor
        self.rig = rig
        tex = spec.texture()
        props = mi.Properties()
        props["bsdf"] = mi.load_dict({"type": "twosided", "material": {
            "type": "diffuse", "reflectance": {"type": "bitmap", "data": mi.TensorXf(tex[..., None]), "raw": True,
                                               "filter_type": "bilinear", "wrap_mode": "clamp"}}})
        self._mesh = mi.Mesh("board", 4, 2, has_vertex_normals=False, has_vertex_texcoords=True, props=props)
        mp = mi.traverse(self._mesh)
        # Texture (u, v): u along the image columns, v along its rows from the first row;
        # Mitsuba's bitmap puts v = 0 at the first stored row (checked by the corners test).
        mp["vertex_texcoords"] = type(mp["vertex_texcoords"])(np.array([0, 0, 1, 0, 1, 1, 0, 1], np.float32))
        mp["faces"] = type(mp["faces"])(np.array([0, 1, 2, 0, 2, 3], np.uint32))
        mp["vertex_positions"] = type(mp["vertex_positions"])(np.zeros(12, np.float32))
        mp.update()
        cam = rig.left
        film = {"type": "hdrfilm", "width": cam.width, "height": cam.height, "rfilter": {"type": "box"},
                "pixel_format": "rgb", "sample_border": False}
        self._aperture = float(aperture_radius_m)
        self._focus = (focus_distance_m or float(max(rig.left.depth(np.zeros((1, 3)))[0], 0.01))
                       if aperture_radius_m > 0 else None)
        self._kind = sensor_kind(rig.cameras.values(), self._aperture)
        sensors = {name: sensor_dict(mi, c, name, self._kind, film, {"type": SAMPLER}, self._aperture, self._focus)
                   for name, c in rig.cameras.items()}
        self.scene = mi.load_dict({
            "type": "scene",
            "integrator": {"type": "direct", "emitter_samples": 0, "bsdf_samples": 1, "hide_emitters": True},
            "left": sensors["left"], "right": sensors["right"],
            "board": self._mesh,
            "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [1.0] * 3}},
        })
        self.params = mi.traverse(self.scene)
        self._size = (cam.width, cam.height)
        self.pose: BoardPose | None = None
        self._sensors = dict(zip(CAMERAS, self.scene.sensors()))
        if self._kind == PLUGIN:  # the plugin takes its camera as parameters after loading
            self.set_rig(rig)

    def set_rig(self, rig: StereoRig) -> None:
        """Move the sensors (same image size, lens model kind and aperture): a parameter update."""
        if (rig.left.width, rig.left.height) != self._size:
            raise ValueError("BoardRenderer.set_rig: image size differs; build a new BoardRenderer")
        if sensor_kind(rig.cameras.values(), self._aperture) != self._kind:
            raise ValueError("BoardRenderer.set_rig: the lens model kind differs; build a new BoardRenderer")
        for name, c in rig.cameras.items():
            configure_sensor(self.mi, self.params, self._sensors[name], c, name, self._kind, self._aperture,
                             self._focus)
        self.params.update()
        self.rig = rig

    def set_pose(self, pose: BoardPose) -> None:
        """Place the board: rewrite its four vertices (mi.traverse; kernels are reused)."""
        v = pose.to_world(self.spec.texture_corners_board()).astype(np.float32).ravel()
        key = "board.vertex_positions"
        self.params[key] = type(self.params[key])(v)
        self.params.update()
        self.pose = pose

    def render(self, camera: str, settings: RenderSettings = RenderSettings(), pose_index: int = 0) -> np.ndarray:
        """Linear radiance (H,W) float32 of the board in its current pose, in passes of at most
        ``pass_samples`` samples (``scenes.render.passes``)."""
        if camera not in CAMERAS:
            raise ValueError(f"camera = {camera!r} is not allowed: choose one of {CAMERAS}")
        if self.pose is None:
            raise ValueError("BoardRenderer.render: call set_pose first")
        return render_in_passes(self.mi, self.scene, CAMERAS.index(camera), settings.spp,
                                board_seed(settings.seed, pose_index, camera), grey_to_host, self.pass_samples)

    def render_poses(self, poses, settings: RenderSettings = RenderSettings(), progress=None) -> list[dict]:
        """Camera images (the sensor model's digital numbers: uint8 by default) per pose per
        camera: ``[{"left": (H,W), "right": (H,W)}, ...]``."""
        out = []
        for i, pose in enumerate(poses):
            self.set_pose(pose)
            pair = {}
            for cam in CAMERAS:
                if progress:
                    progress(f"board {pose.name or i} {cam}")
                pair[cam] = self.sensor_model.digitize(self.render(cam, settings, i),
                                                       seed=board_seed(settings.seed, i, cam))
            out.append(pair)
        return out


def visible_corner_fraction(rig: StereoRig, spec: BoardSpec, pose: BoardPose, margin_px: float = 2.0) -> dict:
    """Fraction of the ChArUco corners inside each camera's image (a pose-design check)."""
    pts = pose.to_world(spec.corners_board())
    out = {}
    for name, cam in rig.cameras.items():
        uv = cam.project(pts)
        out[name] = float(np.mean(cam.in_image(uv, margin_px)))
    return out
