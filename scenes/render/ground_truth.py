"""Exact per-pixel ground truth by ray casting at pixel centres (not the ``aov`` integrator).

For each camera, Mitsuba casts the sensor's ray through every pixel centre
(``sensor.sample_ray`` at ((i + 0.5)/W, (j + 0.5)/H)) against a scene holding only the
plate, which tells which triangle each pixel sees. The hit is then recomputed in
float64 along the OpenCV model's ray (K, R, t) against that triangle, so depth and
points carry no float32 error; normals are the plate's analytic normals at the hit's
material coordinates. The conventions test proves the two rays agree.

Outputs (world frame, metres): z-depth (inf off the plate), 3D point and unit normal
(NaN off the plate), plate mask, projector coordinates (u, v in projector pixels,
NaN where the projector's light cannot reach) and the id of the pattern feature that
lights each pixel (-1 none), and the left disparity f B / Z (inf off the plate).
Boundary visibility: which true-boundary points each camera sees (in view, not
occluded by the plate, not back-facing): the truth behind the false-boundary problem.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from platebench.scenes.camera import Camera
from platebench.scenes.render.device_arrays import to_device
from platebench.tolerances import tol


@dataclass(frozen=True)
class CameraGroundTruth:
    """Ground-truth maps of one camera, (H, W) or (H, W, k) arrays."""

    depth: np.ndarray  # float32 z-depth, inf off the plate
    points: np.ndarray  # float32 (H,W,3) world, NaN off the plate
    normals: np.ndarray  # float32 (H,W,3) unit analytic normals of the top surface
    mask: np.ndarray  # bool, True on the plate
    proj_uv: np.ndarray  # float32 (H,W,2) projector pixel coordinates, NaN where unlit
    feature: np.ndarray  # int32 feature id lighting the pixel, -1 none
    depth64: np.ndarray | None = None  # float64 z-depth for exact comparisons (not written to disk)


@dataclass(frozen=True)
class HiddenRun:
    """A cyclic run of hidden points of the true boundary polyline: its first and last point's
    index, its points and its length along the boundary (m)."""

    start: int
    end: int
    count: int
    length_m: float


@dataclass(frozen=True)
class BoundaryVisibility:
    """Visibility of the true boundary polyline from one camera."""

    visible: np.ndarray  # (N,) bool per boundary point
    visible_fraction: float  # by arc length
    hidden_segments: tuple[HiddenRun, ...]  # cyclic index runs of hidden points
    false_boundary: bool


def _triangle_hits(origin, dirs, tri):
    """Float64 ray/plane intersection with given triangles (M,3,3); returns t and barycentrics."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    e1, e2 = b - a, c - a
    n = np.cross(e1, e2)
    denom = np.einsum("ij,ij->i", dirs, n)
    t = np.einsum("ij,ij->i", a - origin, n) / denom
    p = origin + dirs * t[:, None]
    # Barycentrics of p (least squares in the triangle plane).
    v2 = p - a
    d00 = np.einsum("ij,ij->i", e1, e1)
    d01 = np.einsum("ij,ij->i", e1, e2)
    d11 = np.einsum("ij,ij->i", e2, e2)
    d20 = np.einsum("ij,ij->i", v2, e1)
    d21 = np.einsum("ij,ij->i", v2, e2)
    den = d00 * d11 - d01 * d01
    w1 = (d11 * d20 - d01 * d21) / den
    w2 = (d00 * d21 - d01 * d20) / den
    return t, p, np.column_stack([1 - w1 - w2, w1, w2])


class GroundTruthCaster:
    """Casts ground-truth rays through a ``PlateRenderer``'s plate-only Mitsuba scene.

    In the JIT variants the dense maps are computed on the renderer's device
    (``scenes.render.ground_truth_device``); ``on_device=False`` computes them here in numpy from
    the same Mitsuba hits (the definitions below, which a scalar variant always uses)."""

    def __init__(self, renderer, on_device: bool = True):
        self.r = renderer
        self.mi = renderer.mi
        # Scalar variants trace one ray per Python call: use trimesh/embree instead.
        self._vectorised = not renderer.variant.startswith("scalar")
        self._on_device = self._vectorised and on_device
        self._device = None  # the plate's device buffers, made at the first dense map

    def _mesh_intersector(self):
        import trimesh  # noqa: PLC0415
        return trimesh.ray.ray_triangle.RayMeshIntersector(self.r.plate.mesh) \
            if not trimesh.ray.has_embree else trimesh.ray.ray_pyembree.RayMeshIntersector(self.r.plate.mesh)

    # -- Mitsuba queries ------------------------------------------------------
    def _first_hits(self, camera_name: str, cam: Camera) -> tuple[np.ndarray, np.ndarray]:
        """Triangle index hit by each pixel-centre ray (-1 none), via sensor.sample_ray."""
        mi = self.mi
        if not self._vectorised:
            W, H = cam.width, cam.height
            vv, uu = np.mgrid[0:H, 0:W]
            origin, dirs = cam.rays(np.column_stack([uu.ravel(), vv.ravel()]).astype(float))
            prim = self._mesh_intersector().intersects_first(np.repeat(origin[None], len(dirs), 0), dirs)
            return prim.reshape(H, W), None
        import drjit as dr  # noqa: PLC0415  (scenes.render.runtime has set up libLLVM already)
        W, H = cam.width, cam.height
        idx = dr.arange(mi.UInt32, W * H)
        x = mi.Float(idx % W)
        y = mi.Float(idx // W)
        pos = mi.Point2f((x + 0.5) / W, (y + 0.5) / H)
        sensor = self.r.sensors[camera_name]
        ray, _ = sensor.sample_ray(0.0, 0.0, pos, mi.Point2f(0.5, 0.5))
        si = self.r.gt_scene.ray_intersect(ray)
        valid = np.asarray(si.is_valid(), bool)
        prim = np.asarray(si.prim_index, np.int64)
        prim[~valid] = -1
        return prim.reshape(H, W), np.asarray(si.t, np.float64).reshape(H, W)

    def _occluded(self, origins: np.ndarray, targets: np.ndarray, slack: float) -> np.ndarray:
        """True where the plate blocks the segment origin -> target (short of target by ``slack``)."""
        mi = self.mi
        d = targets - origins
        dist = np.linalg.norm(d, axis=1)
        d = d / dist[:, None]
        o = origins + d * slack * 0.1
        if not self._vectorised:
            locs, ray_idx, _ = self._mesh_intersector().intersects_location(o, d, multiple_hits=True)
            hit_t = np.einsum("ij,ij->i", locs - o[ray_idx], d[ray_idx])
            blocked = np.zeros(len(o), bool)
            blocked[ray_idx[hit_t < (dist - slack - slack * 0.1)[ray_idx]]] = True
            return blocked
        ray = mi.Ray3f(mi.Point3f(*(to_device(mi.Float, o[:, k], np.float32) for k in range(3))),
                       mi.Vector3f(*(to_device(mi.Float, d[:, k], np.float32) for k in range(3))))
        ray.maxt = to_device(mi.Float, dist - slack, np.float32)
        return np.asarray(self.r.gt_scene.ray_test(ray), bool)

    # -- per camera -----------------------------------------------------------
    def camera(self, camera_name: str) -> CameraGroundTruth:
        if self._on_device:
            if self._device is None:
                from platebench.scenes.render.ground_truth_device import DeviceGroundTruth  # noqa: PLC0415
                self._device = DeviceGroundTruth(self.r)
            depth64, points, normals, mask, puv, feat = self._device.camera(camera_name, tol.occlusion_slack_m)
            return CameraGroundTruth(depth64.astype(np.float32), points, normals, mask, puv, feat, depth64)
        spec = self.r.spec
        plate = self.r.plate
        cam = spec.rig.cameras[camera_name]
        H, W = cam.height, cam.width
        prim, _ = self._first_hits(camera_name, cam)
        mask = prim >= 0
        vv, uu = np.nonzero(mask)
        faces = np.asarray(plate.mesh.faces)[prim[mask]]
        verts = np.asarray(plate.mesh.vertices, np.float64)
        origin, dirs = cam.rays(np.column_stack([uu, vv]).astype(float))
        t, p, bary = _triangle_hits(origin, dirs, verts[faces])
        depth64 = np.full((H, W), np.inf)
        depth64[mask] = t * (dirs @ cam.R[2])  # z-depth = ray length x cos(angle to the axis)
        points = np.full((H, W, 3), np.nan, np.float32)
        points[mask] = p
        normals = np.full((H, W, 3), np.nan, np.float32)
        n = self._normals(plate, prim[mask], faces, bary)
        normals[mask] = n
        proj_uv, feature = self._projector_maps(p, n)
        puv = np.full((H, W, 2), np.nan, np.float32)
        puv[mask] = proj_uv
        feat = np.full((H, W), -1, np.int32)
        feat[mask] = feature
        return CameraGroundTruth(depth64.astype(np.float32), points, normals, mask, puv, feat, depth64)

    def _normals(self, plate, prims, faces, bary):
        """Analytic top-surface normals at the hits' material coordinates (face normals elsewhere)."""
        uv_v = np.asarray(plate.mesh_uv, np.float64)
        uv = np.einsum("ij,ijk->ik", bary, uv_v[faces])
        n = np.asarray(plate.surface_normal(uv), np.float64)
        top = getattr(plate, "top_faces", None)
        if top is not None:
            top = np.asarray(top, bool)[prims]
            fn = np.asarray(plate.mesh.face_normals)[prims]
            n = np.where(top[:, None], n, fn)
        return n

    def _projector_maps(self, p: np.ndarray, normals: np.ndarray):
        """Projector (u, v) of each surface point (NaN if unreachable) and the feature lighting it."""
        proj = self.r.spec.projector
        pc = proj.camera
        uv = pc.project(p)
        reach = pc.in_image(uv) & np.isfinite(uv[:, 0])
        if proj.kind == "spot":
            local = pc.to_camera(p)
            ang = np.arccos(np.clip(local[:, 2] / np.linalg.norm(local, axis=1), -1, 1))
            reach &= ang < proj.cutoff_rad
        if reach.any():
            idx = np.nonzero(reach)[0]
            occl = self._occluded(np.repeat(pc.center[None], idx.size, 0), p[idx], tol.occlusion_slack_m)
            reach[idx[occl]] = False
        uv = uv.astype(np.float32)
        uv[~reach] = np.nan
        feature = proj.pattern.feature_at(uv)
        return uv, feature

    # -- boundary -------------------------------------------------------------
    def boundary_visibility(self, camera_name: str, require_in_view: bool = True) -> BoundaryVisibility:
        """Which points of the true boundary this camera sees (in view, unoccluded, front-facing).

        ``require_in_view=False`` ignores the image borders (an infinitely wide sensor): the
        geometric visibility the paper's L formula speaks about."""
        plate = self.r.plate
        cam = self.r.spec.rig.cameras[camera_name]
        P = np.asarray(plate.boundary, np.float64)
        uv = cam.project(P)
        in_view = np.isfinite(uv[:, 0]) & (cam.in_image(uv) if require_in_view else True)
        n = np.asarray(plate.surface_normal(np.asarray(plate.boundary_uv, np.float64)))
        facing = np.einsum("ij,ij->i", n, cam.center - P) > 0
        occluded = self._occluded(np.repeat(cam.center[None], len(P), 0), P, tol.occlusion_slack_m)
        visible = in_view & facing & ~occluded
        return summarise_visibility(P, visible)

    def all(self):
        """Ground truth of both cameras plus boundary visibility."""
        cams = {name: self.camera(name) for name in ("left", "right")}
        vis = {name: self.boundary_visibility(name) for name in ("left", "right")}
        return cams, vis


def summarise_visibility(P: np.ndarray, visible: np.ndarray) -> BoundaryVisibility:
    """Arc-length visible fraction and cyclic runs of hidden points of a closed polyline."""
    seg = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
    # Each point owns half of each adjacent segment.
    w = 0.5 * (seg + np.roll(seg, 1))
    frac = float(w[visible].sum() / w.sum()) if w.sum() > 0 else 0.0
    hidden = ~visible
    runs = []
    n = len(P)
    if hidden.all():
        runs.append(HiddenRun(0, n - 1, n, float(seg.sum())))
    elif hidden.any():
        start_idx = int(np.argmax(visible))  # rotate so we start on a visible point
        order = (np.arange(n) + start_idx) % n
        h = hidden[order]
        i = 0
        while i < n:
            if h[i]:
                j = i
                while j + 1 < n and h[j + 1]:
                    j += 1
                idx = order[i:j + 1]
                runs.append(HiddenRun(int(idx[0]), int(idx[-1]), int(idx.size), float(w[idx].sum())))
                i = j + 1
            else:
                i += 1
    return BoundaryVisibility(visible, frac, tuple(runs), bool(hidden.any()))


def combined_visibility(P: np.ndarray, visible: list[np.ndarray]) -> BoundaryVisibility:
    """Visibility of a closed boundary polyline (N,3) seen by any of several cameras: a point counts
    when any of the (N,) masks marks it (e.g. several poses' left cameras, each masked to the points
    its pair triangulated)."""
    v = np.zeros(len(P), bool)
    for m in visible:
        v |= np.asarray(m, bool)
    return summarise_visibility(np.asarray(P, float), v)
