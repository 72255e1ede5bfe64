"""A reconstructed surface model from every pose's measurements, for normals, coverage and occlusion.

Each pose sees its part of the plate as a graph over its left image (a visible-surface
representation, as in the paper's reference [12]): the measured outline's pixels, plus any
measured interior points (the active stage's square centres), are triangulated in the image
(Delaunay, triangles inside the outline) and lifted to their 3D points. Between outline points
on opposite sides the triangles run straight across: exact for a ruled plate (cylinders, folds,
flat, twisted), a chord for a doubly curved one. The model is the union of every pose's membrane.
The sensing loop builds it from the membranes without chords (``SURFACE_EDGE_ROWS``,
``SURFACE_MAX_STRETCH``): a chord across a curl's opening lies where no plate is, and blocked, in
the model, rays to gap ends the poses had measured (``bench.run.sensing.loop.Measurements``).

It never sees ground truth. It answers: the surface normal near a point (``normals_near``), whether
a straight segment is blocked by the measured plate (``blocked``), and points on the measured
surface (``sample``). World frame, metres.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import Delaunay, cKDTree

from platebench.reconstruction.paper.surface_interpolation import points_in_polygon
from platebench.reconstruction.strategy.multiview import ViewOutline
from platebench.tolerances import tol

MEMBRANE_SPACING_M = 1.5e-3  # outline points kept for the triangulation (one per this arc length)
SAMPLE_SPACING_M = 1.0e-3  # surface samples for normals and coverage
NORMAL_RADIUS_M = 6e-3  # neighbourhood of a local plane fit
MIN_TRIANGLE_QUALITY = 0.05  # 1 for an equilateral triangle; below this a triangle gives no normal
BLOCK_SLACK_M = 3e-3  # a segment is blocked only by surface farther than this from its ends
# A pose's measured surface for the merged reconstruction (``view_membrane``): row-matched outline
# points and checked square centres; no triangle with a 3D edge over SURFACE_EDGE_ROWS times the
# projected grid's row spacing at the pose (``active_views.row_spacing``; SURFACE_MAX_EDGE_M where
# the pose measured no square): such a triangle spans more than the rows of squares next to it,
# surface nobody measured (a grid with rows 15 mm apart at 0.4 m gives 22 mm: a 22 mm chord of a
# 28 mm radius curl lies up to 2.2 mm off it); and none stretched over SURFACE_MAX_STRETCH times its
# image length (a depth step between two layers of a curl). The merged surface also drops faces other
# poses see as background (``refutation.free_space_faces``). Figures: docs/findings/design-record.md.
SURFACE_EDGE_ROWS = 1.5
SURFACE_MAX_EDGE_M = 22e-3
SURFACE_MAX_STRETCH = 3.0


@dataclass(frozen=True)
class Membrane:
    """One pose's visible surface: (V,3) vertices, (F,3) faces, the pose's mid-baseline point."""

    view: str
    vertices: np.ndarray
    faces: np.ndarray
    camera_center: np.ndarray


def view_membrane(view: ViewOutline, extra_uv=None, extra_points=None,
                  spacing_m: float = MEMBRANE_SPACING_M, matched_only: bool = False,
                  max_edge_m: float | None = None, max_stretch: float | None = None) -> Membrane:
    """Triangulate a pose's outline (and extra interior points with their left-image pixels) in its
    image; keep the triangles inside the outline; lift them to 3D.

    ``matched_only``: of the outline, only the points whose disparity was measured on the row
    (``ViewOutline.matched``) become vertices: an interpolated stretch of outline can lie centimetres
    off a curled plate, a row-matched point close to it.
    ``max_edge_m``: triangles with a longer 3D edge are dropped (a chord over unmeasured surface).
    ``max_stretch``: triangles with an edge longer in 3D than this many times its image length
    times the metres per pixel at its range (``view.left``) are dropped (a depth step: the edge
    joins two layers of a curl that overlap in the image). See ``SURFACE_MAX_EDGE_M``."""
    P, uv = view.points, view.image_points
    arc = np.concatenate([[0.0], np.cumsum(view.arc_m[:-1])])
    keep = np.unique(np.searchsorted(arc, np.arange(0.0, arc[-1] if len(arc) else 0.0, spacing_m)))
    keep = keep[keep < len(P)]
    if matched_only:
        keep = keep[np.asarray(view.matched, bool)[keep]]
    V, U = P[keep], uv[keep]
    if extra_uv is not None and len(extra_uv):
        inside = points_in_polygon(np.asarray(extra_uv, float), uv)
        V = np.vstack([V, np.asarray(extra_points, float)[inside]])
        U = np.vstack([U, np.asarray(extra_uv, float)[inside]])
    if len(V) < 3:
        return Membrane(view.name, V, np.zeros((0, 3), int), view.camera_center)
    tri = Delaunay(U)
    F = tri.simplices
    cent = U[F].mean(axis=1)
    F = F[points_in_polygon(cent, uv)]
    if len(F) and (max_edge_m is not None or max_stretch is not None):
        e3 = np.stack([np.linalg.norm(V[F[:, i]] - V[F[:, (i + 1) % 3]], axis=1) for i in range(3)], axis=1)
        keep_f = np.ones(len(F), bool)
        if max_edge_m is not None:
            keep_f &= e3.max(axis=1) <= max_edge_m
        if max_stretch is not None and view.left is not None:
            m_per_px = np.linalg.norm(V - view.left.center, axis=1) / view.left.K[0, 0]
            for i in range(3):
                a_, b_ = F[:, i], F[:, (i + 1) % 3]
                px = np.linalg.norm(U[a_] - U[b_], axis=1)
                keep_f &= e3[:, i] <= max_stretch * px * 0.5 * (m_per_px[a_] + m_per_px[b_])
        F = F[keep_f]
    return Membrane(view.name, V, F, view.camera_center)


def sample_triangles(V: np.ndarray, F: np.ndarray, spacing_m: float, with_faces: bool = False):
    """About one point per ``spacing_m``^2 on each triangle (deterministic barycentric grids); with
    ``with_faces`` also the (S,) index of each sample's triangle."""
    if len(F) == 0:
        return (np.zeros((0, 3)), np.zeros(0, int)) if with_faces else np.zeros((0, 3))
    T = V[F]
    area = 0.5 * np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1)
    levels = np.maximum(1, np.ceil(np.sqrt(2.0 * area) / spacing_m)).astype(int)
    out, faces = [], []
    for n in np.unique(levels):
        sel = np.nonzero(levels == n)[0]
        tri = T[sel]
        i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
        m = i + j <= n
        w1, w2 = i[m] / n, j[m] / n  # (K,)
        a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
        P = a[:, None] + w1[None, :, None] * (b - a)[:, None] + w2[None, :, None] * (c - a)[:, None]
        out.append(P.reshape(-1, 3))
        faces.append(np.repeat(sel, len(w1)))
    return (np.vstack(out), np.concatenate(faces)) if with_faces else np.vstack(out)


@dataclass(frozen=True)
class SurfaceModel:
    """The union of the poses' membranes, with dense samples for normals and coverage."""

    membranes: tuple[Membrane, ...]
    samples: np.ndarray  # (S,3)
    sample_view: np.ndarray  # (S,) index of the membrane each sample came from
    sample_normals: np.ndarray  # (S,3) unit normal of each sample's triangle (sign arbitrary)
    mesh: object = None  # trimesh.Trimesh of all membranes (ray casting), None when empty

    @classmethod
    def build(cls, membranes) -> "SurfaceModel":
        import trimesh  # noqa: PLC0415 (heavy)

        ms = tuple(membranes)
        pts, idx, nrm = [], [], []
        for k, m in enumerate(ms):
            p, f = sample_triangles(m.vertices, m.faces, SAMPLE_SPACING_M, with_faces=True)
            if len(m.faces):
                T = m.vertices[m.faces]
                fn = np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0])
                area2 = np.linalg.norm(fn, axis=1)
                edges2 = sum(np.sum((T[:, i] - T[:, (i + 1) % 3]) ** 2, axis=1) for i in range(3))
                # Near-degenerate triangles (three points along one edge) have no reliable normal.
                quality = 2.0 * np.sqrt(3.0) * area2 / np.maximum(edges2, tol.tiny)
                fn = np.where((quality >= MIN_TRIANGLE_QUALITY)[:, None], fn / np.maximum(area2, tol.tiny)[:, None], 0.0)
                nrm.append(fn[f])
            pts.append(p)
            idx.append(np.full(len(p), k))
        S = np.vstack(pts) if pts else np.zeros((0, 3))
        N = np.vstack(nrm) if nrm else np.zeros((0, 3))
        meshes = [trimesh.Trimesh(m.vertices, m.faces, process=False) for m in ms if len(m.faces)]
        mesh = trimesh.util.concatenate(meshes) if meshes else None
        return cls(ms, S, np.concatenate(idx) if idx else np.zeros(0, int), N, mesh)

    def normals_near(self, points: np.ndarray, toward: np.ndarray, exclude_view: str | None = None,
                     radius_m: float = NORMAL_RADIUS_M, neighbours: int = 24) -> np.ndarray:
        """(N,3) unit normals of the model near each point: the mean of the triangle normals of the
        ``neighbours`` nearest samples within ``radius_m`` (each turned toward ``toward`` first;
        NaN where fewer than 3), oriented toward ``toward`` ((3,) or (N,3)). With ``exclude_view``,
        that pose's own membrane is left out (its own outline tells nothing of what lies beyond it)."""
        pts = np.atleast_2d(np.asarray(points, float))
        out = np.full((len(pts), 3), np.nan)
        use = np.ones(len(self.samples), bool)
        if exclude_view is not None and len(use):
            keep = np.array([m.view != exclude_view for m in self.membranes], bool)
            use = keep[self.sample_view]
        S, Nrm = self.samples[use], self.sample_normals[use]
        if len(S) < 3 or len(pts) == 0:
            return out
        d, idx = cKDTree(S).query(pts, k=min(neighbours, len(S)), distance_upper_bound=radius_m)
        d, idx = d.reshape(len(pts), -1), idx.reshape(len(pts), -1)
        ok = np.isfinite(d)
        enough = ok.sum(axis=1) >= 3
        if not enough.any():
            return out
        tw = np.broadcast_to(np.asarray(toward, float), pts.shape)
        n = Nrm[np.where(ok, idx, 0)]  # (N,k,3)
        sgn = np.sign(np.einsum("nkj,nj->nk", n, tw - pts))
        n = n * (np.where(sgn == 0, 1.0, sgn) * ok)[..., None]
        m = n.sum(axis=1)
        norm = np.linalg.norm(m, axis=1)
        good = enough & (norm > tol.zero_length)
        out[good] = m[good] / norm[good, None]
        return out

    def blocked(self, origins: np.ndarray, targets: np.ndarray, slack_m: float = BLOCK_SLACK_M) -> np.ndarray:
        """(N,) True where the model's surface lies on the segment origin -> target, farther than
        ``slack_m`` from both ends (ray casting with trimesh, each ray from ``slack_m`` past its origin:
        the first surface it meets decides, as any farther one lies farther along the segment)."""
        origins = np.atleast_2d(np.asarray(origins, float))
        targets = np.atleast_2d(np.asarray(targets, float))
        origins = np.broadcast_to(origins, targets.shape)
        if self.mesh is None:
            return np.zeros(len(targets), bool)
        mesh = self.mesh
        d = targets - origins
        dist = np.linalg.norm(d, axis=1)
        d = d / dist[:, None]
        locs, ray_idx, _ = mesh.ray.intersects_location(origins + d * slack_m, d, multiple_hits=False)
        out = np.zeros(len(targets), bool)
        if len(ray_idx):
            t = np.einsum("ij,ij->i", locs - origins[ray_idx], d[ray_idx])
            hit = t < dist[ray_idx] - slack_m
            out[ray_idx[hit]] = True
        return out
