"""The exact 2D clipped Voronoi diagram: analytic cells, invariants on real data, a
shapely reference per cell, neighbours, determinism and bad sites."""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from scipy.spatial import Voronoi

import hcvt
from helpers import POLYGON_FILES, random_inside

G_SQUARE = 1.0 / 12.0
G_HEXAGON = 5.0 / (36.0 * np.sqrt(3.0))


def test_square_grid_in_a_rectangle_gives_squares():
    rect = hcvt.Domain.from_polygon([(0, 0), (3, 0), (3, 2), (0, 2)])
    x, y = np.meshgrid(np.arange(30) * 0.1 + 0.05, np.arange(20) * 0.1 + 0.05)
    diagram = hcvt.voronoi(rect, np.column_stack([x.ravel(), y.ravel()]))
    np.testing.assert_allclose(diagram.G, G_SQUARE, rtol=0, atol=1e-12)
    np.testing.assert_allclose(diagram.volume, 0.01, rtol=1e-12)
    # Square cells: 4 neighbours inside, fewer on the border; diagonals touch at a point only.
    degree = np.bincount(diagram.neighbors.ravel(), minlength=diagram.n)
    assert degree.max() == 4 and degree.min() == 2


def test_hexagonal_lattice_interior_cells_are_regular_hexagons():
    rect = hcvt.Domain.from_polygon([(-0.3, -0.2), (10.8, -0.2), (10.8, 9.1), (-0.3, 9.1)])
    i, j = np.meshgrid(np.arange(11), np.arange(11))
    sites = np.column_stack([(i + 0.5 * (j % 2)).ravel(), (j * np.sqrt(3) / 2).ravel()])
    diagram = hcvt.voronoi(rect, sites)
    interior = diagram.boundary_measure == 0
    assert interior.sum() >= 70
    np.testing.assert_allclose(diagram.G[interior], G_HEXAGON, rtol=0, atol=1e-12)
    np.testing.assert_allclose(diagram.volume[interior], np.sqrt(3) / 2, rtol=1e-12)
    assert np.all(diagram.G[~interior] > G_HEXAGON)


@pytest.mark.parametrize("path", [pytest.param(p, id=p.stem) for p in POLYGON_FILES])
def test_cells_tile_every_real_polygon(path):
    domain = hcvt.load_domain(path)
    sites = random_inside(domain, 10_000, seed=1)
    diagram = hcvt.voronoi(domain, sites)
    reference = domain.geometry
    area = reference.area
    first = np.array([reference.centroid.x, reference.centroid.y]) * area
    assert abs(diagram.volume.sum() - area) <= 1e-12 * area
    got = (diagram.volume[:, None] * diagram.centroid).sum(axis=0)
    scale = np.abs(first).max() + area * np.abs(np.asarray(reference.bounds)).max()
    assert np.abs(got - first).max() <= 1e-12 * scale, (got, first)
    assert np.all(diagram.volume > 0) and np.all(np.isfinite(diagram.G))


def test_cells_tile_a_square_with_holes(square_with_holes):
    sites = random_inside(square_with_holes, 10_000, seed=2)
    diagram = hcvt.voronoi(square_with_holes, sites)
    geometry = square_with_holes.geometry
    assert abs(diagram.volume.sum() - geometry.area) <= 1e-12 * geometry.area
    first = (diagram.volume[:, None] * diagram.centroid).sum(axis=0)
    expected = np.array(geometry.centroid.coords[0]) * geometry.area
    np.testing.assert_allclose(first, expected, rtol=1e-12)


def _reference_cells(domain_geometry, sites):
    """Independent reference: scipy Voronoi (qhull) cells, closed by far-away guard points,
    intersected with the domain by GEOS, moments by the shoelace formulas."""
    lo, hi = sites.min(axis=0), sites.max(axis=0)
    centre, radius = (lo + hi) / 2, 100 * np.abs(hi - lo).max()
    angles = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    guards = centre + radius * np.column_stack([np.cos(angles), np.sin(angles)])
    vor = Voronoi(np.vstack([sites, guards]))
    cells = []
    for i in range(len(sites)):
        region = vor.regions[vor.point_region[i]]
        assert -1 not in region
        convex = shapely.MultiPoint(vor.vertices[region]).convex_hull
        cells.append(shapely.intersection(convex, domain_geometry))
    return cells


def _shoelace(geometry, site):
    """Area, centroid and second moment about the centroid of a polygonal geometry."""
    area, first, second = 0.0, np.zeros(2), 0.0
    for part in shapely.get_parts(geometry):
        rings = [shapely.geometry.polygon.orient(part, 1.0).exterior] + list(
            shapely.geometry.polygon.orient(part, 1.0).interiors
        )
        for ring in rings:
            p = np.asarray(ring.coords) - site
            a, b = p[:-1], p[1:]
            c = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
            area += c.sum() / 2
            first += (c[:, None] * (a + b)).sum(axis=0) / 6
            second += (c * ((a * a).sum(1) + (a * b).sum(1) + (b * b).sum(1))).sum() / 12
    centroid = first / area
    return area, site + centroid, second - area * centroid @ centroid


def test_cells_match_an_independent_reference():
    domain = hcvt.load_domain([p for p in POLYGON_FILES if p.stem == "triangle_double_hex"][0])
    assert len(domain.geometry.interiors) == 2  # non-convex, two holes
    sites = random_inside(domain, 2000, seed=3)
    diagram = hcvt.voronoi(domain, sites)
    reference = _reference_cells(domain.geometry, sites)
    for i in range(len(sites)):
        area, centroid, second = _shoelace(reference[i], sites[i])
        scale = np.sqrt(area)
        assert abs(diagram.volume[i] - area) <= 1e-9 * area, i
        assert np.abs(diagram.centroid[i] - centroid).max() <= 1e-9 * scale, i
        assert abs(diagram.second_moment[i] - second) <= 1e-9 * second, i


def test_cells_geometry_matches_the_moments(square_with_holes):
    sites = random_inside(square_with_holes, 500, seed=4)
    diagram = hcvt.voronoi(square_with_holes, sites)
    cells = diagram.cells()
    np.testing.assert_allclose(shapely.area(np.array(cells)), diagram.volume, rtol=1e-9)
    union = shapely.unary_union(cells)
    assert abs(union.area - square_with_holes.volume) < 1e-9


def test_neighbours_are_symmetric_with_equal_shared_lengths(square_with_holes):
    sites = random_inside(square_with_holes, 3000, seed=5)
    diagram = hcvt.voronoi(square_with_holes, sites)
    h = np.sqrt(square_with_holes.volume / diagram.n)  # round-off scales with the cell size
    seen = {}
    for i in range(diagram.n):
        for j, length in zip(*diagram.cell_neighbors(i), strict=True):
            seen[(i, int(j))] = length
    for (i, j), length in seen.items():
        assert (j, i) in seen, (i, j)
        assert abs(seen[(j, i)] - length) <= 1e-12 * h, (i, j)
    pairs = {tuple(p) for p in diagram.neighbors.tolist()}
    assert pairs == {(i, j) for (i, j) in seen if i < j and seen[(i, j)] > 1e-9 * 0.04}
    # Every restricted Delaunay edge joins cells whose shared face lies in the domain:
    # its midpoint may leave a non-convex domain, but the shared face never does.
    assert len(diagram.face_measures) == len(diagram.neighbors)
    assert np.all(diagram.face_measures > 0)


def test_results_do_not_depend_on_the_number_of_threads(square_with_holes):
    sites = random_inside(square_with_holes, 20_000, seed=6)
    before = hcvt.get_num_threads()
    try:
        hcvt.set_num_threads(1)
        one = hcvt.voronoi(square_with_holes, sites)
        hcvt.set_num_threads(2)
        two = hcvt.voronoi(square_with_holes, sites)
    finally:
        hcvt.set_num_threads(before)
    for name in ["volume", "centroid", "second_moment", "G", "neighbor_sites", "neighbor_measures"]:
        assert np.array_equal(getattr(one, name), getattr(two, name)), name
    assert one.energy == two.energy


def test_outside_sites_are_refused_by_default_and_clipped_when_allowed(square_with_holes):
    sites = np.vstack([random_inside(square_with_holes, 200, seed=7), [[1.5, 1.5], [9, 9]]])
    with pytest.raises(hcvt.InvalidSitesError, match="site 200 .* outside"):
        hcvt.voronoi(square_with_holes, sites)
    diagram = hcvt.voronoi(square_with_holes, sites, allow_outside=True)
    assert abs(diagram.volume.sum() - square_with_holes.volume) <= 1e-12 * 15
    assert diagram.volume[201] == 0 and np.isnan(diagram.G[201])
    assert np.array_equal(diagram.centroid[201], [9, 9])


def test_sites_on_the_boundary_count_as_inside(square_with_holes):
    sites = np.vstack([random_inside(square_with_holes, 100, seed=8), [[0, 2], [1, 1], [4, 4]]])
    diagram = hcvt.voronoi(square_with_holes, sites)
    assert abs(diagram.volume.sum() - square_with_holes.volume) <= 1e-12 * 15
    assert np.all(diagram.volume > 0)


@pytest.mark.parametrize(
    ("sites", "error", "match"),
    [
        ([[0.5, 0.5], [np.nan, 0.2]], hcvt.InvalidSitesError, "site 1 has a non-finite"),
        ([[0.5, 0.5], [0.2, np.inf]], hcvt.InvalidSitesError, "site 1 has a non-finite"),
        ([[0.5, 0.5], [0.2, 0.3], [0.5, 0.5]], hcvt.InvalidSitesError, "sites 0 and 2 coincide"),
        (np.zeros((0, 2)), hcvt.InvalidSitesError, "no sites"),
        ([[0.5, 0.5, 0.5]], ValueError, r"shape \(n, 2\)"),
        ([0.5, 0.5], ValueError, r"shape \(n, 2\)"),
        ([["a", "b"]], ValueError, "real numbers"),
        ([[0.5 + 1j, 0.5]], ValueError, "real numbers"),
    ],
)
def test_bad_sites_raise_a_clear_value_error(sites, error, match):
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    with pytest.raises(error, match=match):
        hcvt.voronoi(square, sites)
    assert issubclass(error, ValueError)


def test_the_callers_array_is_left_alone():
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    sites = np.asfortranarray([[0.2, 0.2], [0.8, 0.7], [0.3, 0.9]])
    copy = sites.copy()
    diagram = hcvt.voronoi(square, sites)
    assert np.array_equal(sites, copy) and diagram.sites is not sites
    assert abs(diagram.volume.sum() - 1) < 1e-15
