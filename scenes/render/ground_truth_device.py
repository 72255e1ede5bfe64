"""Dense ground-truth maps computed where the renderer runs (drjit arrays on its device).

The same definitions as ``scenes.render.ground_truth`` (its module doc), evaluated in drjit
kernels of the renderer's JIT variant (the GPU for ``cuda_*``, the CPU's vector units and all
its cores for ``llvm_*``) instead of numpy on one core:

1. Mitsuba casts the sensor's ray through every pixel centre against the plate-only scene
   (``sensor.sample_ray``, the lens sensor's rays for a distorted camera) and names the
   triangle each pixel sees; the pixels that see the plate are compacted (``dr.compress``).
   Only the pixels of the plate's window (``plate_window``: its projected vertices' bounding
   box and a margin) are cast: no other pixel's ray can meet it.
2. For those pixels, in float64: the OpenCV model's ray (K^-1, then the exact inverse of the
   lens's Brown-Conrady distortion by Newton's method, the world direction), its intersection
   with that triangle (plane hit and barycentrics), the z-depth, the world point, the material
   coordinates and the plate's analytic top normal there (``plates.deformations.surface_frame``,
   the formulas the numpy path evaluates, run on drjit arrays) or the face normal off the top.
3. The projector's pixel coordinates of each point (through its lens, if any), whether its
   light reaches the point (in its image, inside a spot's cone, not blocked by the plate: a
   Mitsuba shadow-ray test) and the pattern feature there.
4. The per-hit values are copied to the host once each (compact: only the pixels that see the
   plate) and placed into full frames there. (Scattering into full frames on the device gives
   the same bytes but was slower with llvm_ad_rgb on 2 CPU cores.) Steps 1-3 run in bands of
   whole rows of the window (``BAND_PIXELS``), so that a signal is served between bands; every
   value is a function of its own pixel alone, so the maps are the same bytes for any band size.

Every camera, projector and plate parameter enters the kernels as an opaque value
(``dr.opaque``), and the mesh as data buffers: another sample's pose, lens, plate or bend
reuses the compiled kernels (``tests/test_kernel_reuse.py``). A plate family, a lens or its
absence, and the projector kind are kernel structure (compiled once each).
"""
from __future__ import annotations

import math

import numpy as np

from platebench.plates.deformations import surface_frame
from platebench.scenes.render.device_arrays import to_device
from platebench.tolerances import tol

__all__ = ["DrjitOps", "DeviceGroundTruth"]

# Pixels cast in one band of a camera's maps: each band is one set of kernel launches, and a signal
# (raised only between launches) waits at most one band; a whole 1280 x 960 window is one band.
BAND_PIXELS = 2 ** 22
_NEWTON_STEPS = 12  # float64 Newton on the lens inverse: quadratic, converged to rounding in 4-6 at the bench's lenses


class DrjitOps:
    """``plates.deformations.NumpyOps``'s operations for drjit float64 arrays; ``const`` makes a
    plate parameter an opaque kernel input."""

    def __init__(self, dr, Float64):
        self.dr, self.F = dr, Float64
        self.sin, self.cos, self.sqrt = dr.sin, dr.cos, dr.sqrt
        self.maximum, self.clip, self.abs = dr.maximum, dr.clip, dr.abs

    def sign(self, x):
        """-1, 0 or +1 (numpy's ``sign``)."""
        return self.dr.select(x > 0, 1.0, self.dr.select(x < 0, -1.0, 0.0))

    def sinc(self, x):
        """sin(pi x) / (pi x), 1 at x = 0 (numpy's ``sinc``)."""
        y = math.pi * x
        return self.dr.select(x == 0, 1.0, self.dr.sin(y) / y)

    def zeros_like(self, x):
        return self.dr.zeros(self.F, self.dr.width(x))

    def ones_like(self, x):
        return self.dr.full(self.F, 1.0, self.dr.width(x))

    def const(self, value: float):
        return self.dr.opaque(self.F, float(value))


def plate_window(cam, vertices) -> tuple[int, int, int, int]:
    """(u0, v0, width, height) of the pixels that can see the plate: the bounding box of its
    vertices' projections (a pinhole maps each triangle into the hull of its corners' images),
    widened by ``tol.plate_window_px`` and clipped to the image; the whole image when a vertex lies
    behind the camera. At least one pixel."""
    W, H = cam.width, cam.height
    V = np.asarray(vertices, np.float64)
    if not len(V) or np.any(cam.to_camera(V)[:, 2] <= 0):
        return 0, 0, W, H
    uv = cam.project(V)
    lo = np.floor(uv.min(axis=0)) - tol.plate_window_px
    hi = np.ceil(uv.max(axis=0)) + tol.plate_window_px
    u0, v0 = int(np.clip(lo[0], 0, W - 1)), int(np.clip(lo[1], 0, H - 1))
    u1, v1 = int(np.clip(hi[0], u0, W - 1)), int(np.clip(hi[1], v0, H - 1))
    return u0, v0, u1 - u0 + 1, v1 - v0 + 1


def _empty_frames(W: int, H: int):
    """The maps of a camera that does not see the plate."""
    nan3 = np.full((H, W, 3), np.nan, np.float32)
    return (np.full((H, W), np.inf), nan3, nan3.copy(), np.zeros((H, W), bool), np.full((H, W, 2), np.nan, np.float32),
            np.full((H, W), -1, np.int32))


class DeviceGroundTruth:
    """Per-plate device buffers of a ``PlateRenderer``'s plate, and the maps of one camera."""

    def __init__(self, renderer):
        import drjit as dr  # noqa: PLC0415  (scenes.render.runtime has chosen libLLVM already)
        self.dr, self.mi, self.r = dr, renderer.mi, renderer
        self.F = dr.float64_array_t(renderer.mi.Float)
        self.ops = DrjitOps(dr, self.F)
        plate = renderer.plate
        faces = np.asarray(plate.mesh.faces, np.uint32)
        top = getattr(plate, "top_faces", None)
        mi = renderer.mi
        self.buf = {
            "vertices": to_device(self.F, plate.mesh.vertices, np.float64),
            "faces": to_device(mi.UInt32, faces),
            "uv": to_device(self.F, plate.mesh_uv, np.float64),
            "face_normals": to_device(self.F, plate.mesh.face_normals, np.float64),
            "top": to_device(mi.UInt32, np.ones(len(faces)) if top is None else top, np.uint32),
        }

    # -- small helpers -----------------------------------------------------------------------
    def _c(self, v):
        return self.dr.opaque(self.F, float(v))

    def _gather3(self, buf, idx):
        dr, F = self.dr, self.F
        return tuple(dr.gather(F, buf, idx * 3 + k) for k in range(3))

    @staticmethod
    def _dot(a, b):
        return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]

    @staticmethod
    def _cross(a, b):
        return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])

    def _distort(self, cam, x, y):
        """Brown-Conrady (``scenes.lens.BrownConrady.distort``) of normalised (x, y): (x_d, y_d)
        and the pieces of its Jacobian."""
        d = cam.distortion
        k1, k2, p1, p2, k3 = (self._c(v) for v in (d.k1, d.k2, d.p1, d.p2, d.k3))
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2)
        j00 = radial + 2.0 * x * x * dradial + 2.0 * p1 * y + 6.0 * p2 * x
        j01 = 2.0 * x * y * dradial + 2.0 * p1 * x + 2.0 * p2 * y
        j11 = radial + 2.0 * y * y * dradial + 6.0 * p1 * y + 2.0 * p2 * x
        return xd, yd, j00, j01, j11

    def _normalised(self, cam, u, v):
        """Ideal normalised coordinates (X/Z, Y/Z) of the rays through pixels (u, v): K^-1, then the
        exact inverse of the distortion (``Camera.normalised``)."""
        K = cam.K
        y = (v - self._c(K[1, 2])) / self._c(K[1, 1])
        x = (u - self._c(K[0, 2]) - self._c(K[0, 1]) * y) / self._c(K[0, 0])
        if cam.distortion is None:
            return x, y
        dr = self.dr
        px, py = self.F(x), self.F(y)
        for _ in range(_NEWTON_STEPS):
            xd, yd, j00, j01, j11 = self._distort(cam, px, py)
            rx, ry = xd - x, yd - y
            det = j00 * j11 - j01 * j01
            px, py = px - (j11 * rx - j01 * ry) / det, py - (-j01 * rx + j00 * ry) / det
        xd, yd = self._distort(cam, px, py)[:2]
        worst = float(dr.max(dr.maximum(dr.abs(xd - x), dr.abs(yd - y)))[0]) if dr.width(x) else 0.0
        if not worst <= tol.lens_inverse_residual:
            raise ValueError(f"the lens inverse left a residual of {worst:.1e} (normalised) after {_NEWTON_STEPS} "
                             "Newton steps: the distortion does not map these pixels one-to-one")
        return px, py

    def _project(self, cam, p):
        """Pixel coordinates (u, v) of world points ``p`` in ``cam`` (through its lens), NaN behind it,
        and the camera-frame points (``Camera.project``)."""
        R, t = cam.R, cam.t
        loc = tuple(p[0] * self._c(R[i, 0]) + p[1] * self._c(R[i, 1]) + p[2] * self._c(R[i, 2]) + self._c(t[i])
                    for i in range(3))
        z = loc[2]
        K = cam.K
        if cam.distortion is None:
            u = (loc[0] * self._c(K[0, 0]) + loc[1] * self._c(K[0, 1]) + z * self._c(K[0, 2])) / z
            v = (loc[0] * self._c(K[1, 0]) + loc[1] * self._c(K[1, 1]) + z * self._c(K[1, 2])) / z
        else:
            xd, yd = self._distort(cam, loc[0] / z, loc[1] / z)[:2]
            u = xd * self._c(K[0, 0]) + yd * self._c(K[0, 1]) + self._c(K[0, 2])
            v = xd * self._c(K[1, 0]) + yd * self._c(K[1, 1]) + self._c(K[1, 2])
        behind = z <= 0
        nan = self.dr.nan
        return self.dr.select(behind, nan, u), self.dr.select(behind, nan, v), loc

    # -- the maps ----------------------------------------------------------------------------
    def camera(self, camera_name: str, occlusion_slack_m: float):
        """(depth64 (H, W) float64, points (H, W, 3) float32, normals (H, W, 3) float32, mask (H, W)
        bool, proj_uv (H, W, 2) float32, feature (H, W) int32) of one camera (module doc), cast in bands
        of whole window rows, at most ``BAND_PIXELS`` pixels each (at least one row)."""
        cam = self.r.spec.rig.cameras[camera_name]
        W, H = cam.width, cam.height
        u0, v0, w, h = plate_window(cam, self.r.plate.mesh.vertices)
        rows = max(1, BAND_PIXELS // w)
        bands = [self._band(camera_name, cam, u0, v0 + top, w, min(rows, h - top), occlusion_slack_m)
                 for top in range(0, h, rows)]
        bands = [b for b in bands if b is not None]
        if not bands:  # the plate is in no pixel of this camera
            return _empty_frames(W, H)
        values = bands[0] if len(bands) == 1 else tuple(np.concatenate(v) for v in zip(*bands))
        return self._frames(W, H, values)

    def _band(self, camera_name: str, cam, u0: int, v0: int, w: int, h: int, occlusion_slack_m: float):
        """The per-hit host arrays (``_frames``' ``values``) of the w x h pixels at (u0, v0), or None
        when none of them sees the plate."""
        dr, mi, F, r = self.dr, self.mi, self.F, self.r
        spec, plate = r.spec, r.plate
        W, H = cam.width, cam.height
        local = dr.arange(mi.UInt32, w * h)
        wo = dr.opaque(mi.UInt32, w)
        px, py = local % wo + dr.opaque(mi.UInt32, u0), local // wo + dr.opaque(mi.UInt32, v0)
        pos = mi.Point2f((mi.Float(px) + 0.5) / W, (mi.Float(py) + 0.5) / H)
        ray, _ = r.sensors[camera_name].sample_ray(0.0, 0.0, pos, mi.Point2f(0.5, 0.5))
        si = r.gt_scene.ray_intersect(ray)
        valid, prim_all, pix = si.is_valid(), si.prim_index, py * W + px
        dr.eval(valid, prim_all, pix)
        on = dr.compress(valid)
        if dr.width(on) == 0:
            return None
        hit = dr.gather(mi.UInt32, pix, on)  # pixel index (row-major) of each pixel that sees the plate
        prim = dr.gather(mi.UInt32, prim_all, on)
        # the float64 ray of the OpenCV model through each hit pixel's centre
        x, y = self._normalised(cam, F(hit % W), F(hit // W))
        Rw = cam.R
        d = tuple(x * self._c(Rw[0, k]) + y * self._c(Rw[1, k]) + self._c(Rw[2, k]) for k in range(3))
        norm = dr.sqrt(self._dot(d, d))
        d = tuple(c / norm for c in d)
        o = tuple(self._c(c) for c in cam.center)
        # its intersection with the triangle Mitsuba named
        f = tuple(dr.gather(mi.UInt32, self.buf["faces"], prim * 3 + k) for k in range(3))
        a, b, c = (self._gather3(self.buf["vertices"], fk) for fk in f)
        e1 = tuple(bi - ai for ai, bi in zip(a, b))
        e2 = tuple(ci - ai for ai, ci in zip(a, c))
        n = self._cross(e1, e2)
        t = self._dot(tuple(ai - oi for ai, oi in zip(a, o)), n) / self._dot(d, n)
        p = tuple(oi + di * t for oi, di in zip(o, d))
        v2 = tuple(pi - ai for pi, ai in zip(p, a))
        d00, d01, d11 = self._dot(e1, e1), self._dot(e1, e2), self._dot(e2, e2)
        d20, d21 = self._dot(v2, e1), self._dot(v2, e2)
        den = d00 * d11 - d01 * d01
        w1 = (d11 * d20 - d01 * d21) / den
        w2 = (d00 * d21 - d01 * d20) / den
        bary = (1.0 - w1 - w2, w1, w2)
        depth = t * (d[0] * self._c(Rw[2, 0]) + d[1] * self._c(Rw[2, 1]) + d[2] * self._c(Rw[2, 2]))
        # the analytic top normal at the hit's material coordinates (the face normal off the top)
        uv = [bary[0] * dr.gather(F, self.buf["uv"], f[0] * 2 + k) + bary[1] * dr.gather(F, self.buf["uv"], f[1] * 2 + k)
              + bary[2] * dr.gather(F, self.buf["uv"], f[2] * 2 + k) for k in range(2)]
        _, r_u, r_v = surface_frame(plate.spec, uv[0], uv[1], self.ops)
        nn = self._cross(r_u, r_v)
        nlen = dr.sqrt(self._dot(nn, nn))
        top = dr.gather(mi.UInt32, self.buf["top"], prim) != 0
        fn = self._gather3(self.buf["face_normals"], prim)
        normal = tuple(dr.select(top, ni / nlen, fi) for ni, fi in zip(nn, fn))
        puv, feature = self._projector(spec.projector, p, occlusion_slack_m)
        values = (hit, depth, *(mi.Float(c) for c in p), *(mi.Float(c) for c in normal), *puv, feature)
        dr.eval(*values)
        return tuple(np.asarray(v) for v in values)

    def _projector(self, proj, p, slack: float):
        """Projector (u, v) (float32, NaN where its light cannot reach) and the feature lighting each point."""
        dr, mi, F = self.dr, self.mi, self.F
        pc = proj.camera
        u, v, loc = self._project(pc, p)
        reach = (dr.isfinite(u) & (u >= self._c(-0.5)) & (u <= self._c(pc.width - 0.5))
                 & (v >= self._c(-0.5)) & (v <= self._c(pc.height - 0.5)))
        if proj.kind == "spot":
            cos_axis = loc[2] / dr.sqrt(self._dot(loc, loc))
            reach &= dr.acos(dr.clip(cos_axis, -1.0, 1.0)) < self._c(proj.cutoff_rad)
        # a shadow ray from the projector's centre: blocked by plate more than ``slack`` before the point
        c = tuple(self._c(x) for x in pc.center)
        seg = tuple(pi - ci for pi, ci in zip(p, c))
        dist = dr.sqrt(self._dot(seg, seg))
        dirn = tuple(s / dist for s in seg)
        origin = tuple(ci + di * slack * 0.1 for ci, di in zip(c, dirn))
        ray = mi.Ray3f(mi.Point3f(*(mi.Float(x) for x in origin)), mi.Vector3f(*(mi.Float(x) for x in dirn)))
        ray.maxt = mi.Float(dist - slack)
        reach &= ~self.r.gt_scene.ray_test(ray, reach)
        u32 = dr.select(reach, mi.Float(u), dr.nan)
        v32 = dr.select(reach, mi.Float(v), dr.nan)
        # ``Pattern.feature_at`` of the float32 coordinates: the pixel whose square holds them
        col = mi.Int32(dr.floor(F(u32) + 0.5))
        row = mi.Int32(dr.floor(F(v32) + 0.5))
        pw, ph = proj.pattern.width, proj.pattern.height
        inside = reach & (col >= 0) & (col < pw) & (row >= 0) & (row < ph)
        fmap = self._feature_map(proj.pattern)
        feature = dr.gather(mi.Int32, fmap, mi.UInt32(dr.select(inside, row * pw + col, 0)), inside)
        return (u32, v32), dr.select(inside, feature, -1)

    def _feature_map(self, pattern):
        """The pattern's feature-id image as a device buffer (cached per pattern)."""
        key = id(pattern)
        cache = self.__dict__.setdefault("_fmaps", {})
        if key not in cache:
            cache.clear()
            cache[key] = (pattern, to_device(self.mi.Int32, pattern.feature_map, np.int32))
        return cache[key][1]

    @staticmethod
    def _frames(W, H, values):
        """Full frames from the per-hit host arrays ``values`` (pixel index, depth, point x y z, normal
        x y z, projector u v, feature; each band's values evaluated in one launch and copied to the host
        once each), one pass over each frame."""
        hit, depth, *rest = values
        n = W * H
        depth64 = np.full(n, np.inf)
        depth64[hit] = depth
        mask = np.zeros(n, bool)
        mask[hit] = True

        def frame(k, first, dtype, fill):
            out = np.full((n, k), fill, dtype)
            out[hit] = np.stack(rest[first:first + k], axis=1)
            return out

        points, normals = frame(3, 0, np.float32, np.nan), frame(3, 3, np.float32, np.nan)
        proj_uv = frame(2, 6, np.float32, np.nan)
        feat = np.full(n, -1, np.int32)
        feat[hit] = rest[8]
        return (depth64.reshape(H, W), points.reshape(H, W, 3), normals.reshape(H, W, 3), mask.reshape(H, W),
                proj_uv.reshape(H, W, 2), feat.reshape(H, W))
