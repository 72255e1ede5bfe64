"""Plate: a triangle mesh of a PlateSpec plus its exact analytic surface and outline.

Units: metres and radians. Frames: the mesh, boundary and surface points are in the
world frame (+Z up, undeformed plate in z = 0 centred on the origin); uv are
material coordinates in metres (u along X, v along Y on the flat plate).

Mesh layout. Vertices [0, V_top) are on the top surface, exactly at
surface_point(mesh_uv). With thickness_m > 0 the next V_top vertices are their
bottom twins, exactly at surface_point(uv) - thickness_m * surface_normal(uv), and
side walls join the top and bottom outlines (no extra vertices), so the mesh is
watertight with outward normals. Top faces point along the top normal, bottom
faces along its negative.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from . import deformations
from .meshing import mesh_layout
from .spec import PlateSpec

if TYPE_CHECKING:
    import trimesh  # imported where a mesh is made or written: a plate's spec (a config) needs none

__all__ = ["Plate", "build_plate"]

_SAFETY = 0.8       # aim this fraction of the requested facet error at first
_MAX_REFINES = 6

MAX_FACET_ERROR_M = 1e-6  # default largest distance of a mesh facet from the exact surface (m)


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False)
class Plate:
    """A meshed plate with exact ground truth.

    spec: the PlateSpec. mesh: trimesh.Trimesh, world frame, metres. mesh_uv: (V, 2)
    material coords of every vertex. top_vertices (V,), top_faces (F,): bool masks
    of the top surface (all True for a sheet). boundary: (N, 3) closed outline of the
    top surface, counter-clockwise in uv seen from +Z, first point not repeated;
    boundary_uv: (N, 2) its material coords (on the rectangle's edges).
    """

    spec: PlateSpec
    mesh: trimesh.Trimesh
    mesh_uv: np.ndarray
    top_vertices: np.ndarray
    top_faces: np.ndarray
    boundary: np.ndarray
    boundary_uv: np.ndarray

    def __repr__(self) -> str:
        return (f"Plate({self.spec!r}, vertices={len(self.mesh.vertices)}, "
                f"faces={len(self.mesh.faces)}, boundary_points={len(self.boundary)})")

    def surface_point(self, uv: np.ndarray) -> np.ndarray:
        """Exact top-surface point (world, metres) at material coords uv ((N, 2) or (2,))."""
        return deformations.surface_point(self.spec, uv)

    def surface_normal(self, uv: np.ndarray) -> np.ndarray:
        """Exact unit top-surface normal (world frame) at material coords uv ((N, 2) or (2,))."""
        return deformations.surface_normal(self.spec, uv)

    def vertex_offsets_m(self) -> np.ndarray:
        """(V,) distance of each vertex below the top surface along -normal: 0 or thickness_m."""
        return np.where(self.top_vertices, 0.0, self.spec.thickness_m)

    def facet_error_m(self) -> float:
        """Max distance (metres) between the mesh and the analytic surface.

        Taken over top and bottom faces at triangle centroids and edge midpoints,
        each against the analytic surface (offset for the bottom) at the same uv.
        Side walls are exact across the thickness and share the outline's edges.
        """
        faces = self.mesh.faces
        offsets = self.vertex_offsets_m()
        keep = np.ptp(offsets[faces], axis=1) == 0
        faces = faces[keep]
        weights = np.array([[1 / 3, 1 / 3, 1 / 3], [0.5, 0.5, 0], [0, 0.5, 0.5], [0.5, 0, 0.5]])
        uv = np.einsum("kj,fjc->fkc", weights, self.mesh_uv[faces]).reshape(-1, 2)
        xyz = np.einsum("kj,fjc->fkc", weights, np.asarray(self.mesh.vertices)[faces]).reshape(-1, 3)
        off = np.repeat(offsets[faces[:, 0]], len(weights))
        r, r_u, r_v = deformations.surface_derivatives(self.spec, uv)
        n = np.cross(r_u, r_v)
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        truth = r - off[:, None] * n
        return float(np.max(np.linalg.norm(xyz - truth, axis=1)))

    def export_ply(self, path: str, vertex_normals: bool | None = None) -> None:
        """Write the mesh as binary PLY (metres, world frame) via trimesh.

        vertex_normals: include the analytic vertex normals; default only for a
        sheet (thickness 0), where they give exact smooth shading. With thickness
        the walls share the top/bottom vertices, so per-vertex normals would be wrong there.
        """
        import trimesh  # noqa: PLC0415

        if vertex_normals is None:
            vertex_normals = self.spec.thickness_m == 0
        with open(path, "wb") as f:
            f.write(trimesh.exchange.ply.export_ply(self.mesh, vertex_normal=bool(vertex_normals)))


def _boundary_loop(faces: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Vertex indices of the sheet's outline, in the faces' winding order (CCW in uv)."""
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    n = int(faces.max()) + 1
    keys = edges[:, 0] * n + edges[:, 1]
    open_edges = edges[~np.isin(edges[:, 1] * n + edges[:, 0], keys)]
    nxt = np.full(n, -1)
    nxt[open_edges[:, 0]] = open_edges[:, 1]
    start = open_edges[np.argmin(uv[open_edges[:, 0]].sum(axis=1)), 0]
    loop = [start]
    for _ in range(len(open_edges) - 1):
        loop.append(nxt[loop[-1]])
    if nxt[loop[-1]] != start or len(set(loop)) != len(open_edges):
        raise RuntimeError("plate sheet outline is not a single closed loop")
    return np.array(loop)


def _assemble(spec: PlateSpec, uv: np.ndarray, faces: np.ndarray) -> Plate:
    import trimesh  # noqa: PLC0415

    r, r_u, r_v = deformations.surface_derivatives(spec, uv)
    normals = np.cross(r_u, r_v)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    loop = _boundary_loop(faces, uv)
    n_top = len(uv)
    t = spec.thickness_m
    if t > 0:
        a, b = loop, np.roll(loop, -1)
        walls = np.concatenate([np.stack([a, a + n_top, b], 1), np.stack([b, a + n_top, b + n_top], 1)])
        vertices = np.concatenate([r, r - t * normals])
        all_faces = np.concatenate([faces, faces[:, ::-1] + n_top, walls])
        mesh_uv = np.concatenate([uv, uv])
        vertex_normals = None
    else:
        vertices, all_faces, mesh_uv, vertex_normals = r, faces, uv, normals
    top_vertices = np.arange(len(vertices)) < n_top
    top_faces = np.arange(len(all_faces)) < len(faces)
    mesh = trimesh.Trimesh(vertices=vertices, faces=all_faces, vertex_normals=vertex_normals,
                           process=False, validate=False)
    return Plate(spec=spec, mesh=mesh, mesh_uv=_readonly(mesh_uv),
                 top_vertices=_readonly(top_vertices), top_faces=_readonly(top_faces),
                 boundary=_readonly(r[loop]), boundary_uv=_readonly(uv[loop]))


def build_plate(spec: PlateSpec, max_facet_error_m: float = MAX_FACET_ERROR_M) -> Plate:
    """Mesh spec so that facet_error_m() < max_facet_error_m (metres).

    The grid is sized from the deformation's curvature (fine only across the bend
    for cylinders and folds, only over the support for dents), then refined
    uniformly if the measured error is still too large.
    """
    tol = float(max_facet_error_m)
    if not (math.isfinite(tol) and tol > 0):
        raise ValueError(f"max_facet_error_m = {max_facet_error_m!r} is out of range: allowed > 0 m")
    refine = 1.0
    for _ in range(_MAX_REFINES):
        plate = _assemble(spec, *mesh_layout(spec, _SAFETY * tol, refine))
        error = plate.facet_error_m()
        if error < tol:
            return plate
        refine *= 1.1 * math.sqrt(error / (_SAFETY * tol))
    raise RuntimeError(f"could not reach facet error {tol} m (last {error} m) for {spec}")
