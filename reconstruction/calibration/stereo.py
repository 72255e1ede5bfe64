"""Calibration from images (paper IV-A): stereo cameras from a ChArUco board, then the structured light.

Pure functions of images, a board definition (``cv2.aruco.CharucoBoard``), the
pattern's feature table and known target placements; no renderer, no ground truth.

Camera calibration (the bench's stand-in for the paper's hand/eye + two-plane
calibration): ChArUco corners (``cv2.aruco.CharucoDetector``, re-refined with
``cornerSubPix`` on a slightly blurred image, see ``detect_charuco``) ->
``cv2.calibrateCamera`` per camera -> ``cv2.stereoCalibrate`` for the pose of the
right camera relative to the left -> registration to the world frame with one board
view whose world placement is known (the paper's target block placed parallel to the
robot's x-y plane): its corners are triangulated with the
stereo calibration and rigidly aligned (Kabsch) with their known world positions.
Distortion is either fixed to zero (``fix_distortion=True``: the pinhole model) or free with
k3 fixed (k1, k2, p1, p2 estimated); ``distortion_is_needed`` chooses between them from the
images alone (the free model must explain ``DISTORTION_EXPLAINED_PX`` of the corners' RMS
displacement), and a calibration with distortion hands it to the pipeline (``to_rig``), which
undistorts the images.

The structured light's rays: ``reconstruction.paper.structured_light``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from platebench.errors import UserValueError
from platebench.reconstruction.calibration.serial import opencv_serial
from platebench.scenes.camera import Camera
from platebench.scenes.lens import BrownConrady
from platebench.scenes.rig import StereoRig
from platebench.tolerances import tol

__all__ = ["MIN_CORNERS", "DISTORTION_EXPLAINED_PX", "CalibrationError", "BoardDetection", "detect_charuco",
           "CameraCalibration", "calibrate_camera", "distortion_explained_px", "distortion_is_needed",
           "StereoCalibration", "stereo_calibrate"]

MIN_CORNERS = 6
OUTLIER_VIEW_PX = 1.0  # a view fitted worse than this (RMS, px) and ...
OUTLIER_VIEW_FACTOR = 5.0  # ... this many times the median view's is left out of a camera's calibration
REFINE_SIGMA_PX = 1.5
FIXED_DISTORTION_FLAGS = cv2.CALIB_FIX_K1 | cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
FREE_DISTORTION_FLAGS = cv2.CALIB_FIX_K3
# The free model is kept when its four coefficients explain at least this much of the board corners'
# RMS displacement, sqrt(rms_pinhole^2 - rms_free^2) (px): a real lens distortion explains several times
# this, none explains a small fraction of it (the extra terms then fit noise; docs/findings/design-record.md).
DISTORTION_EXPLAINED_PX = 0.05
_CRIT = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 200, tol.solver_eps)
# cv2.undistortPoints' fixed-point iteration run to convergence (its default stops after 5 steps)
UNDISTORT_CRITERIA = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 100, 1e-14)


class CalibrationError(UserValueError):
    """The calibration images do not allow a calibration (too few corners, squares missing...)."""


# -- ChArUco detection ------------------------------------------------------------
@dataclass(frozen=True)
class BoardDetection:
    """ChArUco corners found in one image: ids, pixel positions (N,2), board-frame points (N,3)."""

    ids: np.ndarray
    image_points: np.ndarray
    object_points: np.ndarray

    def __len__(self) -> int:
        return int(len(self.ids))

    def subset(self, ids) -> "BoardDetection":
        k = np.searchsorted(self.ids, ids)
        return BoardDetection(self.ids[k], self.image_points[k], self.object_points[k])


def detect_charuco(image: np.ndarray, board, refine: bool = True) -> BoardDetection | None:
    """ChArUco corners of ``board`` in an 8- or 16-bit image, sorted by id (None if < MIN_CORNERS).

    ``refine``: re-locate each corner with ``cornerSubPix`` on the image blurred by a
    Gaussian of REFINE_SIGMA_PX, window max(3, imaged square / 12) px. On noise-free
    renders (sharp, area-sampled edges) OpenCV's own ChArUco refinement is biased on
    tilted boards, and so is cornerSubPix on edges one pixel wide; the blur removes most
    of that bias (figures in docs/findings/design-record.md).
    """
    img = np.asarray(image)
    full = img.astype(np.float32)  # refinement works on all the bits
    if img.dtype == np.uint16:  # the ArUco detector takes 8 bits
        img = np.rint(img / 257.0).astype(np.uint8)
    if img.dtype != np.uint8 or img.ndim != 2:
        raise CalibrationError(f"detect_charuco needs a grey 8- or 16-bit image, got {img.dtype} {img.shape}")
    corners, ids, _, _ = cv2.aruco.CharucoDetector(board).detectBoard(img)
    if ids is None or len(ids) < MIN_CORNERS:
        return None
    ids = ids.ravel().astype(int)
    uv = corners.reshape(-1, 2).astype(np.float64)
    order = np.argsort(ids)
    ids, uv = ids[order], uv[order]
    if refine:
        d = np.linalg.norm(uv[:, None] - uv[None], axis=2)
        np.fill_diagonal(d, np.inf)
        win = max(3, int(np.median(d.min(axis=1)) // 12))
        blurred = cv2.GaussianBlur(full, (0, 0), REFINE_SIGMA_PX)
        uv = cv2.cornerSubPix(blurred, uv.astype(np.float32).reshape(-1, 1, 2), (win, win), (-1, -1),
                              (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, tol.subpixel_eps_px))
        uv = uv.reshape(-1, 2).astype(np.float64)
    obj = np.asarray(board.getChessboardCorners(), np.float64).reshape(-1, 3)[ids]
    return BoardDetection(ids, uv, obj)


# -- single camera ----------------------------------------------------------------
@dataclass(frozen=True)
class CameraCalibration:
    """``cv2.calibrateCamera`` result: K, distortion (k1 k2 p1 p2 k3), reprojection errors (px),
    board poses (board -> camera) of the views used (indices into the input list)."""

    K: np.ndarray
    dist: np.ndarray
    rms_px: float
    per_view_rms_px: np.ndarray
    rvecs: np.ndarray
    tvecs: np.ndarray
    views: tuple[int, ...]
    fix_distortion: bool


def _view_rms(obj, img, rvec, tvec, K, dist) -> float:
    proj, _ = cv2.projectPoints(obj, rvec, tvec, K, dist)
    return float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1))))


def calibrate_camera(detections, image_size: tuple[int, int], fix_distortion: bool = True) -> CameraCalibration:
    """Calibrate one camera from its board detections (None entries are skipped).

    ``image_size`` = (width, height). ``fix_distortion``: distortion held at zero
    (pinhole); else k1, k2, p1, p2 free and k3 fixed. A view the solution does not fit
    (reprojection RMS above ``OUTLIER_VIEW_PX`` and ``OUTLIER_VIEW_FACTOR`` times the median
    view's: a board seen by a few corners at the image's edge can pull the solver into a wrong
    pose) is left out and the camera calibrated again, as a practitioner drops such images;
    ``views`` lists the views kept.
    """
    views = tuple(i for i, d in enumerate(detections) if d is not None and len(d) >= MIN_CORNERS)
    if len(views) < 3:
        raise CalibrationError(f"camera calibration needs >= 3 board views with >= {MIN_CORNERS} corners, "
                               f"got {len(views)}")
    flags = FIXED_DISTORTION_FLAGS if fix_distortion else FREE_DISTORTION_FLAGS
    for _ in range(len(views)):
        obj = [detections[i].object_points.astype(np.float32) for i in views]
        img = [detections[i].image_points.astype(np.float32) for i in views]
        with opencv_serial():  # the same detections, the same bytes (``serial``)
            rms, K, dist, rvecs, tvecs = cv2.calibrateCamera(obj, img, tuple(int(v) for v in image_size), None,
                                                             np.zeros(5), flags=flags, criteria=_CRIT)
        dist = np.asarray(dist, float).ravel()[:5]
        per = np.array([_view_rms(o, m, r, t, K, dist) for o, m, r, t in zip(obj, img, rvecs, tvecs)])
        bad = (per > OUTLIER_VIEW_PX) & (per > OUTLIER_VIEW_FACTOR * np.median(per))
        if not bad.any() or len(views) - 1 < 3:
            break
        views = tuple(v for k, v in enumerate(views) if k != int(np.argmax(per)))  # the worst one, then again
    return CameraCalibration(np.asarray(K, float), dist, float(rms), per,
                             np.array([np.ravel(r) for r in rvecs]), np.array([np.ravel(t) for t in tvecs]),
                             views, fix_distortion)


def distortion_explained_px(fixed: CameraCalibration, free: CameraCalibration) -> float:
    """RMS (px) of the board corners' displacement the free distortion terms explain:
    sqrt(rms_pinhole^2 - rms_free^2)."""
    return float(np.sqrt(max(fixed.rms_px ** 2 - free.rms_px ** 2, 0.0)))


def distortion_is_needed(fixed: dict, free: dict) -> bool:
    """True when, for any camera (name -> ``CameraCalibration``), the free distortion terms explain
    at least ``DISTORTION_EXPLAINED_PX`` of the corners' displacement."""
    return any(distortion_explained_px(fixed[c], free[c]) >= DISTORTION_EXPLAINED_PX for c in fixed)


# -- stereo pair --------------------------------------------------------------------
def _kabsch(src: np.ndarray, dst: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R and translation t minimising |R src + t - dst| (rows are points)."""
    cs, cd = src.mean(axis=0), dst.mean(axis=0)
    H = (src - cs).T @ (dst - cd)
    U, _, Vt = np.linalg.svd(H)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return R, cd - R @ cs


@dataclass(frozen=True)
class StereoCalibration:
    """A general calibrated stereo pair registered in the world.

    K/dist per camera; ``R, T``: left camera frame -> right camera frame (metres);
    ``R_world, t_world``: the left camera's world pose (x_left = R_world x_world + t_world).
    """

    K_left: np.ndarray
    K_right: np.ndarray
    dist_left: np.ndarray
    dist_right: np.ndarray
    R: np.ndarray
    T: np.ndarray
    R_world: np.ndarray
    t_world: np.ndarray
    width: int
    height: int
    rms_px: float = float("nan")
    per_view_rms_px: np.ndarray = field(default_factory=lambda: np.zeros(0))
    registration_rms_m: float = float("nan")
    model: str = "general"  # triangulation model the world registration was made with (the default below)

    @property
    def baseline_m(self) -> float:
        return float(np.linalg.norm(self.T))

    @classmethod
    def from_rig(cls, rig: StereoRig) -> "StereoCalibration":
        """The exact calibration of a (true) conventional rig, its lens distortion included."""
        R = rig.right.R @ rig.left.R.T
        T = rig.right.t - R @ rig.left.t

        def dist(cam):
            return np.zeros(5) if cam.distortion is None else cam.distortion.as_opencv()

        return cls(rig.left.K, rig.right.K, dist(rig.left), dist(rig.right), R, T, rig.left.R, rig.left.t,
                   rig.left.width, rig.left.height, 0.0, np.zeros(0), 0.0)

    def to_rig(self) -> StereoRig:
        """The conventional (parallel) rig the pipeline assumes: both cameras take the left
        camera's world rotation, the right one sits ``baseline_m`` = |T| along the left +x.
        Each camera keeps its own estimated K (``triangulate_rectified`` reads the left K
        only) and its estimated distortion (none for a fixed-distortion calibration): the
        pipeline undistorts the images with it. ``conventional_deviation`` says what this
        approximation ignores."""
        left = Camera(self.K_left, self.R_world, self.t_world, self.width, self.height,
                      BrownConrady.from_opencv(self.dist_left))
        right = Camera(self.K_right, self.R_world, self.t_world - np.array([self.baseline_m, 0.0, 0.0]),
                       self.width, self.height, BrownConrady.from_opencv(self.dist_right))
        return StereoRig(left, right, self.baseline_m)

    def conventional_deviation(self) -> dict:
        """How far the estimate is from conventional geometry (what ``to_rig`` ignores)."""
        ang = np.degrees(np.linalg.norm(cv2.Rodrigues(np.asarray(self.R, float))[0]))
        tdir = -np.asarray(self.T, float) / self.baseline_m
        off = np.degrees(np.arccos(np.clip(tdir[0], -1.0, 1.0)))
        return {"rotation_between_cameras_deg": float(ang), "baseline_off_x_axis_deg": float(off),
                "cx_right_minus_left_px": float(self.K_right[0, 2] - self.K_left[0, 2]),
                "cy_right_minus_left_px": float(self.K_right[1, 2] - self.K_left[1, 2]),
                "f_right_over_left": float(self.K_right[0, 0] / self.K_left[0, 0])}

    def triangulate_camera(self, uv_left, uv_right, model: str | None = None) -> np.ndarray:
        """(N,3) points in the LEFT camera frame from matched pixels (distortion removed first).

        ``model`` (default ``self.model``, the registration's) = "general": linear (DLT)
        triangulation with both K and R, T.
        ``model="conventional"``: what the pipeline computes with ``to_rig()``
        (``triangulate_rectified``): Z = fx_left |T| / (u_left - u_right), x and y from the
        left K at the mean row of the two pixels; R and the direction of T are ignored.
        """
        ul = cv2.undistortPoints(np.asarray(uv_left, np.float64).reshape(-1, 1, 2), self.K_left, self.dist_left,
                                 P=np.eye(3), criteria=UNDISTORT_CRITERIA)
        ur = cv2.undistortPoints(np.asarray(uv_right, np.float64).reshape(-1, 1, 2), self.K_right, self.dist_right,
                                 P=np.eye(3), criteria=UNDISTORT_CRITERIA)
        ul, ur = ul.reshape(-1, 2), ur.reshape(-1, 2)
        model = model or self.model
        if model == "conventional":
            K = self.K_left
            pl = ul @ K[:2, :2].T + K[:2, 2]  # undistorted pixels, both through the LEFT K
            pr = ur @ self.K_right[:2, :2].T + self.K_right[:2, 2]
            with np.errstate(divide="ignore", invalid="ignore"):
                z = K[0, 0] * self.baseline_m / (pl[:, 0] - pr[:, 0])
            v = 0.5 * (pl[:, 1] + pr[:, 1])
            return np.column_stack([(pl[:, 0] - K[0, 2]) * z / K[0, 0], (v - K[1, 2]) * z / K[1, 1], z])
        if model != "general":
            raise ValueError(f"triangulation model {model!r} is not allowed: choose 'general' or 'conventional'")
        P1 = np.hstack([np.eye(3), np.zeros((3, 1))])
        P2 = np.hstack([self.R, np.reshape(self.T, (3, 1))])
        X = cv2.triangulatePoints(P1, P2, ul.T, ur.T)
        return (X[:3] / X[3]).T

    def triangulate(self, uv_left, uv_right, model: str | None = None) -> np.ndarray:
        """(N,3) world points from matched pixels (``model`` as in ``triangulate_camera``)."""
        pc = self.triangulate_camera(uv_left, uv_right, model)
        return (pc - self.t_world) @ self.R_world


def stereo_calibrate(det_left, det_right, cal_left: CameraCalibration, cal_right: CameraCalibration,
                     image_size: tuple[int, int], registration_view: int, registration_pose,
                     joint: bool = True, registration_model: str = "conventional") -> StereoCalibration:
    """Relative pose of the right camera (``cv2.stereoCalibrate``) and the pair's world pose.

    ``det_left/det_right``: per-view detections (same views, None when missing); only
    corners seen in both images of a view are used. ``joint``: refine both cameras'
    intrinsics with R, T (``CALIB_USE_INTRINSIC_GUESS | CALIB_SAME_FOCAL_LENGTH``, distortion
    handled as in the per-camera runs); else intrinsics are fixed (``CALIB_FIX_INTRINSIC``).
    ``registration_pose`` = (R_wb, p_wb): the known world placement of the board in view
    ``registration_view`` (x_world = R_wb x_board + p_wb). ``registration_model``: how
    that view's corners are triangulated for the alignment (``triangulate_camera``). The
    default "conventional" registers the rig the pipeline will use (``to_rig``) with that
    rig's own triangulation, so the world pose absorbs what the conventional model
    ignores at the registration depth (a small estimated rotation between the cameras,
    left out by ``to_rig``, is a disparity offset when registered with the general model).
    """
    if cal_left.fix_distortion != cal_right.fix_distortion:
        raise CalibrationError("stereo_calibrate: both cameras must use the same distortion model")
    obj, il, ir, views = [], [], [], []
    kept = set(cal_left.views) & set(cal_right.views)
    for i, (a, b) in enumerate(zip(det_left, det_right)):
        if a is None or b is None or i not in kept:
            continue
        common = np.intersect1d(a.ids, b.ids)
        if len(common) < MIN_CORNERS:
            continue
        sa, sb = a.subset(common), b.subset(common)
        obj.append(sa.object_points.astype(np.float32))
        il.append(sa.image_points.astype(np.float32))
        ir.append(sb.image_points.astype(np.float32))
        views.append(i)
    if len(views) < 3:
        raise CalibrationError(f"stereo calibration needs >= 3 views seen by both cameras, got {len(views)}")
    if registration_view not in views:
        raise CalibrationError(f"registration view {registration_view} is not seen by both cameras "
                               f"(with >= {MIN_CORNERS} common corners)")
    dist_flags = FIXED_DISTORTION_FLAGS if cal_left.fix_distortion else FREE_DISTORTION_FLAGS
    flags = (cv2.CALIB_USE_INTRINSIC_GUESS | cv2.CALIB_SAME_FOCAL_LENGTH | dist_flags) if joint \
        else cv2.CALIB_FIX_INTRINSIC
    with opencv_serial():  # the same detections, the same bytes (``serial``)
        out = cv2.stereoCalibrate(obj, il, ir, cal_left.K.copy(), cal_left.dist.copy(), cal_right.K.copy(),
                                  cal_right.dist.copy(), tuple(int(v) for v in image_size), flags=flags,
                                  criteria=_CRIT)
    rms, K1, d1, K2, d2, R, T = out[:7]
    K1, K2 = np.asarray(K1, float), np.asarray(K2, float)
    d1, d2 = np.asarray(d1, float).ravel()[:5], np.asarray(d2, float).ravel()[:5]
    partial = StereoCalibration(K1, K2, d1, d2, np.asarray(R, float), np.asarray(T, float).ravel(),
                                np.eye(3), np.zeros(3), int(image_size[0]), int(image_size[1]), float(rms))
    per = []
    for o, a, b in zip(obj, il, ir):
        ok, rv, tv = cv2.solvePnP(o, a, K1, d1)
        e1 = _view_rms(o, a, rv, tv, K1, d1)
        Rb = cv2.Rodrigues(rv)[0]
        rv2 = cv2.Rodrigues(partial.R @ Rb)[0]
        tv2 = partial.R @ tv.ravel() + partial.T
        e2 = _view_rms(o, b, rv2, tv2, K2, d2)
        per.append(np.sqrt(0.5 * (e1 ** 2 + e2 ** 2)))
    # World registration: triangulate the registration view's corners, align with their known world points.
    k = views.index(registration_view)
    pc = partial.triangulate_camera(il[k], ir[k], registration_model)
    R_wb, p_wb = (np.asarray(a, float) for a in registration_pose)
    pw = obj[k].astype(np.float64) @ R_wb.T + p_wb
    Rw, tw = _kabsch(pw, pc)
    res = pc - (pw @ Rw.T + tw)
    reg_rms = float(np.sqrt(np.mean(np.sum(res ** 2, axis=1))))
    return StereoCalibration(K1, K2, d1, d2, partial.R, partial.T, Rw, tw, partial.width, partial.height,
                             float(rms), np.array(per), reg_rms, registration_model)


