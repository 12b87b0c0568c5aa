"""Power (Laguerre) diagrams, ``hcvt.voronoi(..., weights=w)``, against independent references.

2D: each power cell built by shapely as the domain polygon cut by the half-planes
``|x - z_i|² - w_i <= |x - z_j|² - w_j`` of every other site (and, in a periodic box, of
every image). 3D: scipy's ``HalfspaceIntersection`` of the same half-spaces in a box. Random
weights of a few squared spacings, so that some cells are empty.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, HalfspaceIntersection

import hcvt
from hcvt.geometry import shapes
from hcvt.io.readers import read_polygon
from helpers import DATA, random_inside

STAR = DATA / "2d" / "star5.geojson"
HOLED = DATA / "2d" / "triangle_square_circle_hole.geojson"
BUNNY = DATA / "3d" / "bunny.off"


def half_plane(normal: np.ndarray, offset: float, size: float) -> shapely.Polygon:
    """``{x : normal·x <= offset}`` cut to a square of half-width ``size`` about it."""
    unit = normal / np.linalg.norm(normal)
    foot = unit * offset / np.linalg.norm(normal)
    along = np.array([-unit[1], unit[0]])
    return shapely.Polygon(
        [
            foot + size * along,
            foot + size * along - size * unit,
            foot - size * along - size * unit,
            foot - size * along,
        ]
    )


def reference_cells_2d(region, points, weights, owners, size=100.0):
    """The power cells of ``owners`` among ``points`` (each of weight ``weights``) in ``region``."""
    cells = []
    for i, (z, w) in enumerate(zip(points[: len(owners)], weights, strict=False)):
        cell = region
        for j, (y, v) in enumerate(zip(points, np.resize(weights, len(points)), strict=True)):
            if j == i:
                continue
            q = y - z
            cell = cell.intersection(half_plane(q, (q @ q + w - v) / 2 + q @ z, size))
            if cell.is_empty:
                break
        cells.append(cell)
    return cells


def power_weights(n: int, volume: float, scale: float, seed: int, dim: int = 2) -> np.ndarray:
    """Uniform random weights in ``[0, scale · h²)``, ``h = (volume / n)^(1/dim)``."""
    return np.random.default_rng(seed).random(n) * scale * (volume / n) ** (2 / dim)


@pytest.mark.parametrize(
    ("geometry", "n"),
    [(shapely.box(0, 0, 1, 1), 150), (read_polygon(STAR), 120), (read_polygon(HOLED), 120)],
    ids=["square", "star5", "holed"],
)
def test_2d_power_cells_are_shapelys_half_plane_intersections(geometry, n):
    domain = hcvt.Domain.from_polygon(geometry)
    sites = random_inside(domain, n, seed=3)
    weights = power_weights(n, geometry.area, 4.0, seed=4)
    diagram = hcvt.voronoi(domain, sites, weights=weights)
    size = 10 * max(np.ptp(np.asarray(geometry.bounds).reshape(2, 2), axis=0))
    reference = reference_cells_2d(geometry, sites, weights, sites, size)
    areas = np.array([c.area for c in reference])
    assert (areas == 0).sum() >= 3, "the weights should empty some cells"
    np.testing.assert_allclose(diagram.volume, areas, rtol=0, atol=1e-10 * geometry.area)
    assert abs(diagram.volume.sum() - geometry.area) <= 1e-12 * geometry.area
    full = areas > 1e-6 * geometry.area / n
    centroids = np.array([[c.centroid.x, c.centroid.y] for c in np.asarray(reference)[full]])
    np.testing.assert_allclose(diagram.centroid[full], centroids, rtol=0, atol=1e-9)
    # Each cell's faces (neighbours and boundary) make up its perimeter.
    counts = np.diff(diagram.neighbor_offsets)
    faces = np.add.reduceat(
        np.append(diagram.neighbor_measures, 0.0), diagram.neighbor_offsets[:-1]
    ) * (counts > 0)
    perimeter = np.array([c.length for c in reference])
    np.testing.assert_allclose(
        faces + diagram.boundary_measure, perimeter, rtol=0, atol=1e-9 * size
    )
    empty = areas == 0
    assert np.all(diagram.volume[empty] == 0)
    assert np.all(counts[empty] == 0)
    assert np.all(np.isnan(diagram.G[empty]))
    # A neighbour of a cell never names an empty one.
    assert not np.any(empty[diagram.neighbor_sites])


def reference_volume_3d(lo, hi, points, weights, i, facets=None) -> float:
    """Volume of the power cell of site ``i`` in the box ``[lo, hi]`` (scipy), and within
    the half-spaces ``facets`` (rows ``a, b``: ``a·x + b <= 0``) when given."""
    z, w = points[i], weights[i]
    q = np.delete(points, i, axis=0) - z
    v = np.delete(weights, i)
    # a·x + b <= 0 with a = q, b = -(|q|² + w - v)/2 - q·z
    halfspaces = [np.append(q, (-(np.einsum("ij,ij->i", q, q) + w - v) / 2 - q @ z)[:, None], 1)]
    if facets is not None:
        halfspaces.append(facets)
    for k in range(3):
        e = np.eye(3)[k]
        halfspaces.append(np.array([np.append(e, -hi[k]), np.append(-e, lo[k])]))
    h = np.vstack(halfspaces)
    norms = np.linalg.norm(h[:, :3], axis=1)
    # The Chebyshev centre: the largest ball inside; none (radius ~0) for an empty cell.
    a_ub = np.column_stack([h[:, :3], norms])
    found = linprog(np.array([0, 0, 0, -1.0]), A_ub=a_ub, b_ub=-h[:, 3], bounds=[(None, None)] * 4)
    if not found.success or found.x[3] <= 1e-9:
        return 0.0
    cell = HalfspaceIntersection(h, found.x[:3])
    return float(ConvexHull(cell.intersections).volume)


def test_3d_power_cells_are_scipys_halfspace_intersections():
    lo, hi = np.zeros(3), np.array([1.0, 1.2, 0.9])
    box = hcvt.Domain.box(lo, hi)
    n = 100
    sites = np.random.default_rng(5).uniform(lo, hi, size=(n, 3))
    weights = power_weights(n, float(np.prod(hi)), 3.0, seed=6, dim=3)
    diagram = hcvt.voronoi(box, sites, weights=weights)
    reference = np.array([reference_volume_3d(lo, hi, sites, weights, i) for i in range(n)])
    assert (reference == 0).sum() >= 3, "the weights should empty some cells"
    np.testing.assert_allclose(diagram.volume, reference, rtol=0, atol=1e-10)
    assert abs(diagram.volume.sum() - np.prod(hi)) <= 1e-12
    # The same box as a closed triangle solid: the cones' clip against the box's.
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)]) * hi
    solid = hcvt.Domain.from_mesh(corners, ConvexHull(corners).simplices, repair=True)
    np.testing.assert_allclose(
        hcvt.voronoi(solid, sites, weights=weights).volume, reference, rtol=0, atol=1e-10
    )


def test_power_cells_at_a_balls_boundary_are_scipys_halfspace_intersections():
    """A convex solid's boundary cells, which reach from their sites out to the corners of
    their box, are bounded by their part in the ball (``InDomain`` in the core): the cells
    of optimal transport's trials (certified from the last step's neighbours) and of a cold
    power diagram of the same weights, both against scipy where their centroids lie
    farthest from their sites."""
    ball = shapes.ball()
    n = 2000
    sites = hcvt.initialise(ball, n, method="random", seed=3)
    masses = np.full(n, ball.volume / n)
    run = hcvt.optimal_transport(ball, sites, masses, tol=1e-10)
    assert run.converged
    np.testing.assert_allclose(run.diagram.volume, masses, rtol=1e-10, atol=0)
    cold = hcvt.voronoi(ball, sites, weights=run.weights)
    np.testing.assert_allclose(cold.volume, run.diagram.volume, rtol=1e-12, atol=0)
    # Outward facets of the icosphere, a·x + b <= 0 inside.
    corners = ball.vertices[ball.faces]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    facets = np.column_stack([normals, -np.einsum("ij,ij->i", normals, corners[:, 0])])
    offset = np.linalg.norm(cold.centroid - sites, axis=1)
    far = np.argsort(-offset)[:25]
    assert offset[far].min() > 0.5 * (ball.volume / n) ** (1 / 3), "cells off their sites"
    lo, hi = ball.bounds
    reference = [reference_volume_3d(lo, hi, sites, run.weights, i, facets) for i in far]
    np.testing.assert_allclose(cold.volume[far], reference, rtol=1e-9, atol=0)
    np.testing.assert_allclose(run.diagram.volume[far], reference, rtol=1e-9, atol=0)


def test_bunny_power_cells_fill_the_solid():
    bunny = hcvt.load_domain(BUNNY)
    n = 400
    sites = random_inside(bunny, n, seed=7)
    weights = power_weights(n, bunny.volume, 3.0, seed=8, dim=3)
    diagram = hcvt.voronoi(bunny, sites, weights=weights)
    assert (diagram.volume == 0).sum() >= 1
    assert abs(diagram.volume.sum() - bunny.volume) <= 1e-12 * bunny.volume
    plain = hcvt.voronoi(bunny, sites)
    zero = hcvt.voronoi(bunny, sites, weights=np.zeros(n))
    for name in ("volume", "centroid", "second_moment", "neighbor_measures", "boundary_measure"):
        assert np.array_equal(getattr(zero, name), getattr(plain, name)), name
    assert np.array_equal(zero.neighbor_sites, plain.neighbor_sites)


@pytest.mark.parametrize("geometry", [shapely.box(0, 0, 1, 1), read_polygon(STAR)])
def test_zero_weights_are_the_voronoi_diagram_bit_for_bit(geometry):
    domain = hcvt.Domain.from_polygon(geometry)
    sites = random_inside(domain, 500, seed=9)
    plain = hcvt.voronoi(domain, sites)
    zero = hcvt.voronoi(domain, sites, weights=np.zeros(len(sites)))
    for name in ("volume", "centroid", "G", "neighbor_measures", "boundary_measure"):
        assert np.array_equal(getattr(zero, name), getattr(plain, name)), name
    assert np.array_equal(zero.neighbor_offsets, plain.neighbor_offsets)
    assert np.array_equal(zero.neighbor_sites, plain.neighbor_sites)


def test_periodic_power_cells_are_the_images_half_plane_intersections():
    box = hcvt.Domain.box([0, 0], [1, 1], periodic=True)
    n = 60
    sites = np.random.default_rng(10).random((n, 2))
    weights = power_weights(n, 1.0, 3.0, seed=11)
    diagram = hcvt.voronoi(box, sites, weights=weights)
    shifts = np.array([[a, b] for a in (-1, 0, 1) for b in (-1, 0, 1)])
    images = np.concatenate([sites + s for s in shifts])  # shift (0, 0) is block 4
    image_weights = np.tile(weights, len(shifts))
    areas = []
    for i in range(n):
        z = sites[i]
        cell = shapely.box(z[0] - 0.5, z[1] - 0.5, z[0] + 0.5, z[1] + 0.5)
        for j in range(len(images)):
            if j == 4 * n + i:
                continue
            q = images[j] - z
            cell = cell.intersection(
                half_plane(q, (q @ q + weights[i] - image_weights[j]) / 2 + q @ z, 10.0)
            )
        areas.append(cell.area)
    areas = np.array(areas)
    assert (areas == 0).sum() >= 2
    np.testing.assert_allclose(diagram.volume, areas, rtol=0, atol=1e-10)
    assert abs(diagram.volume.sum() - 1.0) <= 1e-12
    plain = hcvt.voronoi(box, sites)
    zero = hcvt.voronoi(box, sites, weights=np.zeros(n))
    assert np.array_equal(zero.volume, plain.volume)
    assert np.array_equal(zero.neighbor_measures, plain.neighbor_measures)


def test_weights_scale_with_the_frame():
    """A domain 1e6 wide computes in its own frame: weights map by scale² there."""
    size = 1e6
    small = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    large = hcvt.Domain.from_polygon([(0, 0), (size, 0), (size, size), (0, size)])
    assert not large.frame.is_identity
    sites = random_inside(small, 80, seed=12)
    weights = power_weights(80, 1.0, 3.0, seed=13)
    a = hcvt.voronoi(small, sites, weights=weights).volume
    b = hcvt.voronoi(large, sites * size, weights=weights * size**2).volume
    np.testing.assert_allclose(b / size**2, a, rtol=0, atol=1e-12)


def test_bad_weights_are_refused_by_name():
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    sites = random_inside(square, 10, seed=1)
    with pytest.raises(ValueError, match="shape"):
        hcvt.voronoi(square, sites, weights=np.zeros(9))
    with pytest.raises(ValueError, match="weight 3 is not finite"):
        hcvt.voronoi(square, sites, weights=np.where(np.arange(10) == 3, np.nan, 0.0))
    sphere = hcvt.Domain.sphere()
    points = np.random.default_rng(0).normal(size=(10, 3))
    points /= np.linalg.norm(points, axis=1)[:, None]
    with pytest.raises(ValueError, match="sphere"):
        hcvt.voronoi(sphere, points, weights=np.arange(10.0) * 1e-3)
    diagram = hcvt.voronoi(square, sites, weights=np.arange(10.0) * 1e-3)
    # Power cells are meshed (tests/test_mesh_power_periodic.py).
    volume = diagram.mesh().cell_geometry.volume
    np.testing.assert_allclose(volume, diagram.volume, rtol=0, atol=1e-15)
