"""Prescribed masses, ``hcvt.optimal_transport``: every cell's mass within 1e-10 of its target.

In 2D the power cells of the weights found are rebuilt by shapely (the domain polygon cut by
the half-planes of every other site, as in ``test_power.py``) and their areas compared with
the targets: an independent check of both the weights and the diagram. In 3D (the bunny)
the masses are those of the power diagram computed again from the weights.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely

import hcvt
from hcvt.io.readers import read_polygon
from helpers import DATA, random_inside
from test_power import reference_cells_2d

SOUTH_AFRICA = DATA / "2d" / "naturalearth_south_africa.geojson"
BUNNY = DATA / "3d" / "bunny.off"


def random_masses(n: int, total: float, seed: int) -> np.ndarray:
    """Masses between 0.5 and 1.5 times the mean, summing to ``total``."""
    raw = 0.5 + np.random.default_rng(seed).random(n)
    return raw * (total / raw.sum())


@pytest.mark.parametrize(
    "geometry",
    [shapely.box(0, 0, 1, 1), read_polygon(SOUTH_AFRICA)],
    ids=["unit_square", "south_africa"],
)
def test_2d_masses_are_met_to_1e_10(geometry):
    domain = hcvt.Domain.from_polygon(geometry)
    n = 150
    sites = random_inside(domain, n, seed=21)
    masses = random_masses(n, geometry.area, seed=22)
    out = hcvt.optimal_transport(domain, sites, masses)
    print(f"{n} sites: {out.iterations} Newton steps, max relative error {out.max_error:.2e}")
    assert out.converged
    assert out.max_error <= 1e-10
    size = 10 * max(np.ptp(np.asarray(geometry.bounds).reshape(2, 2), axis=0))
    areas = np.array(
        [c.area for c in reference_cells_2d(geometry, sites, out.weights, sites, size)]
    )
    np.testing.assert_array_less(np.abs(areas - masses) / masses, 1e-10)
    np.testing.assert_array_less(np.abs(out.diagram.mass - masses) / masses, 1e-10)
    # Damped Newton: the last steps are full ones (locally quadratic convergence).
    assert out.history["step"][-1] == 1.0
    assert np.all(out.history["min_mass"] > 0)


def test_bunny_masses_are_met_to_1e_10():
    bunny = hcvt.load_domain(BUNNY)
    n = 1000
    sites = random_inside(bunny, n, seed=23)
    masses = random_masses(n, bunny.volume, seed=24)
    out = hcvt.optimal_transport(bunny, sites, masses)
    print(f"bunny, {n} sites: {out.iterations} Newton steps, max error {out.max_error:.2e}")
    assert out.converged
    again = hcvt.voronoi(bunny, sites, weights=out.weights)
    np.testing.assert_array_less(np.abs(again.volume - masses) / masses, 1e-10)
    assert abs(again.volume.sum() - bunny.volume) <= 1e-12 * bunny.volume


def test_relative_masses_and_a_density():
    """Relative masses normalised; with ρ = 1 + x the masses are ∫ρ over each cell."""
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    sites = random_inside(square, 200, seed=25)
    out = hcvt.optimal_transport(
        square, sites, np.ones(200), density=hcvt.Polynomial(1.0, [1.0, 0.0]), normalise=True
    )
    assert out.converged
    np.testing.assert_allclose(out.targets, np.full(200, 1.5 / 200), rtol=1e-15)
    np.testing.assert_array_less(np.abs(out.diagram.mass - 1.5 / 200) / (1.5 / 200), 1e-10)
    # Equal masses under a density growing with x: cells narrower where ρ is larger.
    left = sites[:, 0] < 0.25
    right = sites[:, 0] > 0.75
    assert out.diagram.volume[left].mean() > 1.3 * out.diagram.volume[right].mean()


def test_transport_in_a_scaled_frame():
    """A domain 1e6 wide: masses map by scale², weights back by scale²."""
    size = 1e6
    unit = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    large = hcvt.Domain.from_polygon([(0, 0), (size, 0), (size, size), (0, size)])
    sites = random_inside(unit, 100, seed=26)
    masses = random_masses(100, 1.0, seed=27)
    a = hcvt.optimal_transport(unit, sites, masses)
    b = hcvt.optimal_transport(large, sites * size, masses * size**2)
    assert b.converged
    np.testing.assert_allclose(b.diagram.volume / size**2, masses, rtol=1e-10)
    np.testing.assert_allclose(
        (b.weights - b.weights.mean()) / size**2, a.weights - a.weights.mean(), atol=1e-9
    )


def test_bad_masses_are_refused_by_name():
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    sites = random_inside(square, 10, seed=28)
    with pytest.raises(ValueError, match="sum to"):
        hcvt.optimal_transport(square, sites, np.full(10, 0.2))
    with pytest.raises(ValueError, match="mass 3 must be finite and positive"):
        hcvt.optimal_transport(square, sites, np.where(np.arange(10) == 3, -0.1, 0.1))
    with pytest.raises(ValueError, match="shape"):
        hcvt.optimal_transport(square, sites, np.full(9, 0.1))
    sphere = hcvt.Domain.sphere()
    points = np.random.default_rng(0).normal(size=(10, 3))
    points /= np.linalg.norm(points, axis=1)[:, None]
    with pytest.raises(ValueError, match="sphere"):
        hcvt.optimal_transport(sphere, points, np.full(10, 4 * np.pi / 10))


def test_newton_systems_are_factorised_and_the_same_on_1_and_3_threads():
    """2D: the first Newton step solved by the sparse Cholesky (no CG iteration), the later
    ones by CG preconditioned by that factor (at most 30 iterations each, else factorised
    afresh; measured 6-16 on 2026-12-04), bitwise alike on 1
    and 3 threads, and the first cells' areas from shapely within 1e-10."""
    l_shape = shapely.Polygon([(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)])
    domain = hcvt.Domain.from_polygon(l_shape)
    n = 1500
    sites = random_inside(domain, n, seed=29)
    masses = random_masses(n, l_shape.area, seed=30)
    before = hcvt.get_num_threads()
    try:
        runs = []
        for threads in (1, 3):
            hcvt.set_num_threads(threads)
            runs.append(hcvt.optimal_transport(domain, sites, masses))
    finally:
        hcvt.set_num_threads(before)
    one, three = runs
    assert one.converged
    iterations = one.history["cg_iterations"]
    assert iterations[0] == 0 and np.all(iterations <= 30)
    assert np.array_equal(one.weights, three.weights)
    assert np.array_equal(one.diagram.mass, three.diagram.mass)
    first = 30
    areas = np.array(
        [c.area for c in reference_cells_2d(l_shape, sites, one.weights, sites[:first], 20.0)]
    )
    np.testing.assert_array_less(np.abs(areas - masses[:first]) / masses[:first], 1e-10)


def test_l_shape_with_a_quadratic_density_meets_masses_to_1e_10():
    """ρ = 1 + x + 2y² on the L-shape (1 to 11): the power cells of the weights found, cut
    by shapely and integrated by test_density's product Gauss rule, hold their targets
    within 1e-10 (the masses' sum, the L-shape's ∫ρ, by the same rule)."""
    from test_density import _polygon_moments

    l_shape = shapely.Polygon([(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)])
    domain = hcvt.Domain.from_polygon(l_shape)
    rho = hcvt.Polynomial.parse("1 + x + 2*y^2")
    total = _polygon_moments(l_shape, rho, np.zeros(2))[0]
    assert total == pytest.approx(11.5, rel=1e-14)
    n = 150
    sites = random_inside(domain, n, seed=31)
    masses = random_masses(n, total, seed=32)
    out = hcvt.optimal_transport(domain, sites, masses, density=rho)
    print(f"{n} sites: {out.iterations} Newton steps, max relative error {out.max_error:.2e}")
    assert out.converged and out.max_error <= 1e-10
    cells = reference_cells_2d(l_shape, sites, out.weights, sites, 20.0)
    reference = np.array([_polygon_moments(c, rho, np.zeros(2))[0] for c in cells])
    np.testing.assert_array_less(np.abs(reference - masses) / masses, 1e-10)
