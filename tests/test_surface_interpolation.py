"""Tests for reconstruction.paper.surface_interpolation (energy-minimising interpolation)."""

import numpy as np
import pytest
from scipy.interpolate import RBFInterpolator

from platebench.reconstruction.paper.boundary_plane import (
    fit_boundary_plane,
    plane_frame,
)
from platebench.reconstruction.paper.surface_interpolation import (
    SurfaceGrid,
    interpolate_surface,
    points_in_polygon,
    surface_grid_to_mesh,
)

RADIUS = 0.1165 / np.radians(10.0)  # 0.6675 m: the reference plate's 10 degree bend
DOMAIN = np.array([[-0.05, -0.035], [0.05, -0.035], [0.05, 0.035], [-0.05, 0.035]])


def grid_points(xs, ys):
    gx, gy = np.meshgrid(xs, ys)
    return np.c_[gx.ravel(), gy.ravel()]


# 4 x 4 samples inside the plate, like the paper's 16 projected squares
INNER16 = grid_points(np.linspace(-0.0375, 0.0375, 4), np.linspace(-0.0225, 0.0225, 4))


def node_coordinates(grid):
    return np.meshgrid(grid.x, grid.y)


def at_points(grid, points):
    """Bilinear interpolation of the grid at (M, 2) points (the model's data term)."""
    z = np.nan_to_num(grid.z)
    fx, fy = (points[:, 0] - grid.x[0]) / grid.step, (points[:, 1] - grid.y[0]) / grid.step
    j, i = np.floor(fx).astype(int), np.floor(fy).astype(int)
    tx, ty = fx - j, fy - i
    return ((1 - tx) * (1 - ty) * z[i, j] + tx * (1 - ty) * z[i, j + 1]
            + (1 - tx) * ty * z[i + 1, j] + tx * ty * z[i + 1, j + 1])


def test_linear_field_is_reproduced_exactly():
    heights = 0.01 + 0.2 * INNER16[:, 0] - 0.1 * INNER16[:, 1]
    for data_weight in (None, 1e6):
        grid = interpolate_surface(INNER16, heights, DOMAIN, 0.002, data_weight=data_weight)
        gx, gy = node_coordinates(grid)
        truth = 0.01 + 0.2 * gx - 0.1 * gy
        assert np.nanmax(np.abs(grid.z - truth)) < 1e-9
        assert np.all(np.isnan(grid.z[~grid.mask])) and not np.any(np.isnan(grid.z[grid.mask]))


def test_grid_covers_domain_and_mask_is_the_polygon():
    grid = interpolate_surface(INNER16, np.zeros(16), DOMAIN, 0.002)
    assert isinstance(grid, SurfaceGrid) and grid.tau == 1.0 and grid.step == 0.002
    assert grid.z.shape == grid.mask.shape == (grid.y.size, grid.x.size)
    assert grid.x[0] == pytest.approx(-0.054) and grid.x[-1] >= 0.054 - 1e-12
    assert np.diff(grid.x) == pytest.approx(np.full(grid.x.size - 1, 0.002))
    gx, gy = node_coordinates(grid)
    inside = (np.abs(gx) <= 0.05 + 1e-9) & (np.abs(gy) <= 0.035 + 1e-9)
    assert np.array_equal(grid.mask, inside)  # edge nodes count as inside
    assert grid.mask.sum() == 51 * 36


def _errors(grid, heights_fn, hull_half):
    gx, gy = node_coordinates(grid)
    truth = heights_fn(gx, gy)
    hull = grid.mask & (np.abs(gx) <= hull_half[0] + 1e-12) & (np.abs(gy) <= hull_half[1] + 1e-12)
    return truth, hull


def test_cylinder_from_16_points_matches_truth_and_thin_plate_spline():
    """z = x^2 / (2R), R = 0.6675 m (sag 1.87 mm at the domain's ends), 16 samples.

    Measured at 1 mm grid step (max |error| over the 0.1 m x 0.07 m domain; inside
    the samples' hull; RMS over the domain):
      energy thin plate   280 um;  50 um;  78 um
      scipy TPS (RBF)     486 um;  83 um; 133 um
      |energy - TPS|      206 um;  33 um
    Sixteen samples cannot pin the curvature near the ends: both interpolants relax
    to zero curvature outside the samples (natural boundary conditions); the grid
    energy on the finite rectangle does better than the infinite-plane spline.
    """
    heights = INNER16[:, 0] ** 2 / (2 * RADIUS)
    grid = interpolate_surface(INNER16, heights, DOMAIN, 0.001)
    truth, hull = _errors(grid, lambda x, y: x**2 / (2 * RADIUS), (0.0375, 0.0225))
    err = np.abs(grid.z - truth)
    rbf = RBFInterpolator(INNER16, heights, kernel="thin_plate_spline")
    gx, gy = node_coordinates(grid)
    z_rbf = np.full_like(grid.z, np.nan)
    z_rbf[grid.mask] = rbf(np.c_[gx[grid.mask], gy[grid.mask]])
    err_rbf, gap = np.abs(z_rbf - truth), np.abs(z_rbf - grid.z)
    assert np.nanmax(err) < 300e-6 and err[hull].max() < 55e-6 and np.sqrt(np.nanmean(err**2)) < 85e-6
    assert np.nanmax(err_rbf) < 500e-6 and err_rbf[hull].max() < 90e-6
    assert np.nanmax(gap) < 220e-6 and gap[hull].max() < 40e-6
    assert np.max(np.abs(at_points(grid, INNER16) - heights)) < 1e-12  # samples honoured exactly


def test_cylinder_with_samples_on_the_plate_edges():
    points = grid_points(np.linspace(-0.05, 0.05, 4), np.linspace(-0.035, 0.035, 4))
    heights = points[:, 0] ** 2 / (2 * RADIUS)
    grid = interpolate_surface(points, heights, DOMAIN, 0.001, margin=0.004)
    gx, _ = node_coordinates(grid)
    err = np.abs(grid.z - gx**2 / (2 * RADIUS))
    assert np.nanmax(err) < 95e-6  # measured 88 um: spacing 33 mm, sag 1.87 mm
    # halving the step changes the answer by < 1 um (measured 0.84 um 2 -> 1 mm,
    # 0.24 um 1 -> 0.5 mm): the discretisation has converged
    coarse = interpolate_surface(points, heights, DOMAIN, 0.002, margin=0.004)
    assert np.nanmax(np.abs(grid.z[::2, ::2] - coarse.z)) < 1.5e-6


def test_off_node_samples_are_interpolated_bilinearly_and_penalty_approaches_them():
    rng = np.random.default_rng(2)
    points = rng.uniform([-0.045, -0.03], [0.045, 0.03], (16, 2))
    heights = 0.002 * np.sin(40 * points[:, 0]) + 0.001 * points[:, 1] / 0.035
    exact = interpolate_surface(points, heights, DOMAIN, 0.0015)

    assert np.max(np.abs(at_points(exact, points) - heights)) < 1e-12
    loose = interpolate_surface(points, heights, DOMAIN, 0.0015, data_weight=1e-3)
    tight = interpolate_surface(points, heights, DOMAIN, 0.0015, data_weight=1e3)
    miss_loose = np.max(np.abs(at_points(loose, points) - heights))
    miss_tight = np.max(np.abs(at_points(tight, points) - heights))
    assert miss_tight < 1e-3 * miss_loose and miss_tight < 1e-7


@pytest.mark.parametrize("smoothness", ["membrane", 0.3, "thin_plate"])
def test_constant_field_is_reproduced_for_every_smoothness(smoothness):
    grid = interpolate_surface(INNER16, np.full(16, 0.004), DOMAIN, 0.002, smoothness=smoothness)
    assert np.nanmax(np.abs(grid.z - 0.004)) < 1e-12


def test_membrane_stays_within_the_data_range():
    # samples on grid nodes (2.5 mm step): the discrete maximum principle holds
    heights = INNER16[:, 0] ** 2 / (2 * RADIUS)
    grid = interpolate_surface(INNER16, heights, DOMAIN, 0.0025, smoothness="membrane")
    assert np.nanmin(grid.z) >= heights.min() - 1e-12 and np.nanmax(grid.z) <= heights.max() + 1e-12


def test_non_rectangular_domain_mask():
    triangle = np.array([[-0.05, -0.035], [0.05, -0.035], [0.0, 0.035]])
    grid = interpolate_surface(INNER16, np.zeros(16), triangle, 0.002)
    gx, gy = node_coordinates(grid)
    assert np.array_equal(grid.mask, points_in_polygon(np.c_[gx.ravel(), gy.ravel()], triangle,
                                                       margin=1e-9).reshape(gx.shape))
    assert grid.mask[np.argmin(np.abs(grid.y - 0.03)), np.argmin(np.abs(grid.x + 0.04))] == False  # noqa: E712


def test_mesh_cells_and_frame_mapping():
    heights = INNER16[:, 0] ** 2 / (2 * RADIUS)
    grid = interpolate_surface(INNER16, heights, DOMAIN, 0.002)
    vertices, faces = surface_grid_to_mesh(grid)
    assert faces.shape == (2 * 50 * 35, 3) and vertices.shape == (51 * 36, 3)
    assert faces.min() == 0 and faces.max() == len(vertices) - 1
    assert np.all(np.isfinite(vertices))
    e1, e2 = vertices[faces[:, 1]] - vertices[faces[:, 0]], vertices[faces[:, 2]] - vertices[faces[:, 0]]
    assert np.all(np.cross(e1, e2)[:, 2] > 0)  # counter-clockwise seen from +z
    assert np.cross(e1, e2)[:, 2].sum() / 2 == pytest.approx(0.1 * 0.07, rel=1e-9)  # projected area

    # a tilted plane's frame: local (x, y, z) -> world = origin + R.T @ local
    tilt = np.radians(20.0)
    square = np.array([[-0.05, -0.035, 0], [0.05, -0.035, 0], [0.05, 0.035, 0], [-0.05, 0.035, 0]])
    rot_x = np.array([[1, 0, 0], [0, np.cos(tilt), -np.sin(tilt)], [0, np.sin(tilt), np.cos(tilt)]])
    plane = fit_boundary_plane(square @ rot_x.T + [0.1, 0.2, 0.3])
    rotation, origin = plane_frame(plane)
    world, faces_w = surface_grid_to_mesh(grid, frame=(rotation, origin))
    assert np.array_equal(faces_w, faces)
    assert world == pytest.approx(origin + vertices @ rotation, abs=1e-15)
    assert plane.signed_distance(world) == pytest.approx(vertices[:, 2], abs=1e-15)
    n_world = np.cross(world[faces[:, 1]] - world[faces[:, 0]], world[faces[:, 2]] - world[faces[:, 0]])
    assert np.all(n_world @ plane.normal > 0)
    with pytest.raises(ValueError, match="orthonormal"):
        surface_grid_to_mesh(grid, frame=(2 * rotation, origin))


def test_bad_inputs_raise():
    heights = np.zeros(16)
    with pytest.raises(ValueError, match="at least 3"):
        interpolate_surface(INNER16[:2], heights[:2], DOMAIN, 0.001)
    with pytest.raises(ValueError, match="finite"):
        interpolate_surface(INNER16, np.where(np.arange(16) == 3, np.nan, heights), DOMAIN, 0.001)
    with pytest.raises(ValueError, match="grid_step"):
        interpolate_surface(INNER16, heights, DOMAIN, 0.0)
    with pytest.raises(ValueError, match="grid_step"):
        interpolate_surface(INNER16, heights, DOMAIN, -0.001)
    with pytest.raises(ValueError, match="heights"):
        interpolate_surface(INNER16, heights[:5], DOMAIN, 0.001)
    with pytest.raises(ValueError, match="smoothness"):
        interpolate_surface(INNER16, heights, DOMAIN, 0.001, smoothness="plate")
    with pytest.raises(ValueError, match="tau"):
        interpolate_surface(INNER16, heights, DOMAIN, 0.001, smoothness=1.5)
    with pytest.raises(ValueError, match="collinear"):
        interpolate_surface(np.c_[np.linspace(0, 0.04, 5), np.zeros(5)], np.zeros(5), DOMAIN, 0.001)
    with pytest.raises(ValueError, match="data_weight"):
        interpolate_surface(INNER16, heights, DOMAIN, 0.001, data_weight=0.0)
    with pytest.raises(ValueError, match="singular"):  # two different heights at one spot
        pts = np.vstack([INNER16, INNER16[:1]])
        interpolate_surface(pts, np.r_[heights, 1.0], DOMAIN, 0.002)
