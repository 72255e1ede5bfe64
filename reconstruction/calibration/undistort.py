"""Undistorting a stereo pair's images with its calibration, before the paper's pipeline.

The paper's pipeline works on a pinhole conventional pair (row matching, ``Z = f B / d``); a
real lens bends the rows. As with Tsai-style calibration, the images are resampled to the
ideal pinhole camera of the same K: ``cv2.initUndistortRectifyMap(K, dist, None, K)`` gives,
for each pixel of the undistorted image, where to read the distorted one (OpenCV's forward
model, no iteration), and ``scipy.ndimage.map_coordinates`` reads it with exact bilinear
weights (``cv2.remap`` quantises positions to 1/32 px). Pixels whose source lies outside the
image are 0 (black, as the scene's background). Integer images stay integer (rounded), as a
frame grabber's undistorted frame would. The returned rig has the same K and poses and no
distortion, so everything downstream reads pinhole geometry.

Pure functions of images and a calibration (OpenCV pixel conventions, ``scenes.camera``).
"""
from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from platebench.scenes.camera import Camera
from platebench.scenes.rig import StereoRig

__all__ = ["undistortion_map", "undistort_image", "undistort_views"]


def undistortion_map(cam: Camera) -> tuple[np.ndarray, np.ndarray]:
    """(H,W) float32 source coordinates (u, v) in the distorted image of each pixel of the
    undistorted image (same K); identity for a pinhole camera."""
    dist = np.zeros(5) if cam.distortion is None else cam.distortion.as_opencv()
    mu, mv = cv2.initUndistortRectifyMap(cam.K, dist, None, cam.K, (cam.width, cam.height), cv2.CV_32FC1)
    return mu, mv


def undistort_image(image: np.ndarray, cam: Camera, maps=None) -> np.ndarray:
    """``image`` (H,W) taken through ``cam``'s lens, resampled to its pinhole (module doc).
    ``maps``: ``undistortion_map(cam)``, when several images share the camera."""
    img = np.asarray(image)
    if cam.distortion is None:
        return img
    if img.shape != (cam.height, cam.width):
        raise ValueError(f"undistort: image size {img.shape[::-1]} differs from the camera's "
                         f"{cam.width}x{cam.height}")
    mu, mv = maps if maps is not None else undistortion_map(cam)
    from scipy.ndimage import map_coordinates  # noqa: PLC0415  (scipy.ndimage is slow to import: loaded when needed)

    out = map_coordinates(img.astype(np.float64), [mv.astype(np.float64), mu.astype(np.float64)], order=1,
                          mode="constant", cval=0.0)
    if np.issubdtype(img.dtype, np.integer):
        info = np.iinfo(img.dtype)
        return np.clip(np.rint(out), info.min, info.max).astype(img.dtype)
    return out.astype(img.dtype)


def undistort_views(images: dict, rig: StereoRig) -> tuple[dict, StereoRig]:
    """Images keyed ``"<camera>_<anything>"`` (``left_passive``, ``right_active`` ...) resampled to
    their camera's pinhole, and the rig without distortion. Unchanged (the same objects) when
    neither camera has a distortion; other keys pass through."""
    if rig.left.distortion is None and rig.right.distortion is None:
        return images, rig
    cams = rig.cameras
    maps = {name: undistortion_map(cam) for name, cam in cams.items() if cam.distortion is not None}
    out = {}
    for key, img in images.items():
        name = str(key).split("_", 1)[0]
        cam = cams.get(name)
        out[key] = img if cam is None else undistort_image(img, cam, maps.get(name))
    return out, replace(rig, left=rig.left.pinhole, right=rig.right.pinhole)
