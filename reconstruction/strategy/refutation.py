"""Refutation: a confirmed outline point that other poses see as the inside of the plate is no edge.

``multiview.confirm`` accepts an outline point when a second pose, turned enough about the edge,
puts its own outline within ``CONFIRM_TOL_M`` of it. Where the occluding contours of two poses
*cross* on the surface, they agree over a few millimetres and pass that test, off the true
boundary; such pieces either leave loose ends (a loop that cannot be verified) or glue a
short-cut loop.

A third pose tells them apart. A true edge point that a pose sees lies on that pose's outline
(or, on a concave plate, in front of the plate's far side, off its surface). A point on the
surface, which a contour crossing is, lies *inside* the outline of any pose that sees that part
of the surface, and on the surface that pose measured. So a confirmed point is *refuted* by a
pose ``m`` when

* it projects into m's left image at least ``REFUTE_MARGIN_PX`` inside m's outline,
* it is farther than ``REFUTE_OFF_OUTLINE_M`` from every point of m's outline, and
* m's own measured surface crosses m's viewing ray within ``REFUTE_DEPTH_M`` of the point.

The measured surface is the pose's chord-free one (``surface_model.view_membrane`` of its
row-matched outline points and checked square centres, no triangle longer than 1.5 grid rows;
the loop's ``Measurements.surfaces``). ``REFUTE_POSES`` poses must agree. A refuted point counts
as unconfirmed (``BoundaryVerdict.refuted`` lists them). Refuting only removes evidence: it can
break a loop, and it removes a loose end only where the end's piece lies on the inside of the plate.

World frame, metres; pixels of each pose's left image. The measurements behind the thresholds:
docs/findings/design-record.md.
"""
from __future__ import annotations

import numpy as np

from platebench.reconstruction.paper.surface_interpolation import points_in_polygon
from platebench.reconstruction.strategy.multiview import ViewOutline
from platebench.reconstruction.strategy.surface_model import Membrane

REFUTE_MARGIN_PX = 4.0  # the point projects at least this far inside the other pose's outline ...
REFUTE_OFF_OUTLINE_M = 3e-3  # ... lies farther than this from every point of that outline ...
REFUTE_DEPTH_M = 8e-3  # ... and that pose's measured surface crosses its ray within this of the point
REFUTE_POSES = 2  # poses that must refute a point


def membrane_mesh(membrane: Membrane):
    """A trimesh of one pose's membrane (None when it has no triangle)."""
    import trimesh  # noqa: PLC0415 (heavy)

    if len(membrane.faces) == 0:
        return None
    return trimesh.Trimesh(membrane.vertices, membrane.faces, process=False)


def seen_inside(points: np.ndarray, view: ViewOutline, mesh) -> np.ndarray:
    """(N,) True where pose ``view`` sees ``points`` ((N,3), world) as the inside of the plate
    (module doc: inside its outline by the margin, off its outline, on its measured surface
    ``mesh``, a trimesh of its membrane). False where the pose has no camera or no membrane."""
    P = np.atleast_2d(np.asarray(points, float))
    out = np.zeros(len(P), bool)
    cam = view.left
    if cam is None or mesh is None or len(P) == 0 or len(view.points) < 3:
        return out
    uv = cam.project(P)
    ok = np.all(np.isfinite(uv), axis=1)
    if not ok.any():
        return out
    idx = np.nonzero(ok)[0]
    inside = points_in_polygon(uv[idx], view.image_points)
    far_px = view.image_tree.query(uv[idx])[0] >= REFUTE_MARGIN_PX
    off = view.tree.query(P[idx])[0] > REFUTE_OFF_OUTLINE_M
    idx = idx[inside & far_px & off]
    if not len(idx):
        return out
    c = cam.center
    d = P[idx] - c
    t = np.linalg.norm(d, axis=1)
    d /= t[:, None]
    locs, ray, _ = mesh.ray.intersects_location(np.repeat(c[None], len(idx), 0), d, multiple_hits=True)
    if len(ray):
        th = np.einsum("ij,ij->i", locs - c, d[ray])
        hit = np.abs(th - t[ray]) <= REFUTE_DEPTH_M
        out[idx[ray[hit]]] = True
    return out


def seen_outside(points: np.ndarray, view: ViewOutline) -> np.ndarray:
    """(N,) True where pose ``view`` saw background where ``points`` ((N,3), world) project: at
    least ``REFUTE_MARGIN_PX`` outside its outline and inside its image frame, in front of its
    camera. Every point of the plate in a pose's view projects inside the plate's outline there,
    so such a point is not on the plate (the visual hull). False where the pose has no camera."""
    P = np.atleast_2d(np.asarray(points, float))
    out = np.zeros(len(P), bool)
    cam = view.left
    if cam is None or len(P) == 0 or len(view.points) < 3:
        return out
    uv = cam.project(P)
    framed = np.all(np.isfinite(uv), axis=1) & (cam.depth(P) > 0) & cam.in_image(uv, margin=REFUTE_MARGIN_PX)
    j = np.nonzero(framed)[0]
    if len(j):
        outside = ~points_in_polygon(uv[j], view.image_points)
        outside &= view.image_tree.query(uv[j])[0] >= REFUTE_MARGIN_PX
        out[j[outside]] = True
    return out


def free_space_faces(membranes: list, views: list[ViewOutline], poses_needed: int = REFUTE_POSES) -> list[np.ndarray]:
    """Per pose, (F,) bool: the faces of its membrane (``surface_model.Membrane``) to keep in the
    merged surface: those none of whose vertices at least ``poses_needed`` other poses saw as
    background (``seen_outside``). A row-matched stretch of outline that stereo put off the plate
    (a spike of a concave trough's outline matched centimetres off it) lies outside the other
    poses' outlines. Same order for both lists; figures in docs/findings/design-record.md."""
    keep = []
    for k, mb in enumerate(membranes):
        count = np.zeros(len(mb.vertices), int)
        for m, vm in enumerate(views):
            if m != k and len(mb.vertices):
                count += seen_outside(mb.vertices, vm)
        faces = np.asarray(mb.faces, int).reshape(-1, 3)
        keep.append(~np.any(count[faces] >= poses_needed, axis=1))
    return keep


def refute(views: list[ViewOutline], confirmed: list[np.ndarray], meshes: list,
           poses_needed: int = REFUTE_POSES, shifts: np.ndarray | None = None) -> list[np.ndarray]:
    """Per pose, (N,) bool: the confirmed points that at least ``poses_needed`` other poses see as
    the inside of the plate (module doc). ``meshes``: each view's membrane as ``membrane_mesh``
    made it, in the same order (built once per pose by the caller: trimesh keeps its ray-casting
    structure with the mesh). ``shifts``: (V,3) metres, the poses' registration
    (``registration.register_translations``) when ``confirmed`` was found on the registered
    outlines: pose k's point moved by its shift is looked at from pose m's own frame (less m's
    shift), where m's outline, camera and mesh stay."""
    if len(meshes) != len(views):
        raise ValueError(f"refute: {len(meshes)} membrane meshes for {len(views)} views; one per view is needed")
    S = np.zeros((len(views), 3)) if shifts is None else np.asarray(shifts, float)
    idx = [np.nonzero(c)[0] for c in confirmed]
    count = [np.zeros(len(i), int) for i in idx]
    for m, (vm, mesh) in enumerate(zip(views, meshes)):  # every other pose's points at once: one ray cast
        ks = [k for k in range(len(views)) if k != m and len(idx[k])]
        if not ks:
            continue
        inside = seen_inside(np.vstack([views[k].points[idx[k]] + (S[k] - S[m]) for k in ks]), vm, mesh)
        at = np.cumsum([0] + [len(idx[k]) for k in ks])
        for j, k in enumerate(ks):
            count[k] += inside[at[j]:at[j + 1]]
    out = []
    for c, i, n in zip(confirmed, idx, count):
        r = np.zeros(len(c), bool)
        r[i[n >= poses_needed]] = True
        out.append(r)
    return out


__all__ = ["refute", "seen_inside", "seen_outside", "free_space_faces", "membrane_mesh", "REFUTE_MARGIN_PX",
           "REFUTE_OFF_OUTLINE_M", "REFUTE_DEPTH_M", "REFUTE_POSES"]
