"""The sphere as a domain (DESIGN §13, issue 35): exact spherical cells and CVTs.

Oracles: scipy's ``SphericalVoronoi`` (areas, vertices, hence arc lengths), a fine
subdivision quadrature of each cell's first moment, the icosahedron's symmetry, Euler's
count of pentagons.
"""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
from scipy.spatial import SphericalVoronoi

import hcvt
from hcvt.errors import InvalidDensityError, InvalidSitesError
from hcvt.seeding.sphere import fibonacci, icosahedral, random_sphere


def random_sites(n: int, seed: int, radius: float = 1.0) -> np.ndarray:
    return random_sphere(n, np.random.default_rng(seed)) * radius


def sides(diagram: hcvt.Diagram) -> dict[int, int]:
    counts = np.bincount(np.diff(diagram.neighbor_offsets))
    return {k: int(c) for k, c in enumerate(counts) if c}


@pytest.mark.parametrize(("n", "radius"), [(50, 1.0), (1000, 1.0), (1000, 6371.0)])
def test_areas_equal_scipys_and_tile_the_sphere(n: int, radius: float) -> None:
    sites = random_sites(n, n, radius)
    diagram = hcvt.voronoi(hcvt.Domain.sphere(radius), sites)
    reference = SphericalVoronoi(sites, radius).calculate_areas()
    scale = 4 * math.pi * radius**2 / n
    assert np.max(np.abs(diagram.volume - reference)) < 1e-12 * scale
    total = 4 * math.pi * radius**2
    assert abs(diagram.volume.sum() - total) < 1e-13 * total


def test_arcs_are_scipys_edges() -> None:
    """Each neighbour pair's arc length is the great-circle arc between the two Voronoi
    vertices that scipy's regions of the pair share; both cells list it alike."""
    sites = random_sites(300, 7)
    diagram = hcvt.voronoi(hcvt.Domain.sphere(), sites)
    sv = SphericalVoronoi(sites)
    regions = [set(r) for r in sv.regions]
    for (i, j), arc in zip(diagram.neighbors, diagram.face_measures, strict=True):
        a, b = sorted(regions[i] & regions[j])
        u, v = sv.vertices[a], sv.vertices[b]
        want = math.atan2(np.linalg.norm(np.cross(u, v)), float(u @ v))
        assert abs(arc - want) < 1e-12, (i, j)
    # Every scipy edge is a neighbour pair: 3n − 6 of them (trivalent vertices).
    assert len(diagram.neighbors) == 3 * 300 - 6


def subdivided_first_moment(a: np.ndarray, b: np.ndarray, c: np.ndarray, level: int) -> tuple:
    """Area and ``∫x dA`` of the spherical triangle ``abc`` by ``4^level`` sub-triangles,
    each weighted by its exact solid angle at its normalised centroid (error ~4^-level)."""
    tris = [(a, b, c)]
    for _ in range(level):
        nxt = []
        for p, q, r in tris:
            pq, qr, rp = ((x + y) / np.linalg.norm(x + y) for x, y in ((p, q), (q, r), (r, p)))
            nxt += [(p, pq, rp), (pq, q, qr), (rp, qr, r), (pq, qr, rp)]
        tris = nxt
    p, q, r = (np.array(t) for t in zip(*tris, strict=True))
    det = np.einsum("ij,ij->i", p, np.cross(q, r))
    den = 1 + np.einsum("ij,ij->i", p, q) + np.einsum("ij,ij->i", q, r)
    den += np.einsum("ij,ij->i", r, p)
    omega = 2 * np.arctan2(det, den)
    mid = p + q + r
    mid /= np.linalg.norm(mid, axis=1)[:, None]
    return omega.sum(), (omega[:, None] * mid).sum(axis=0)


def test_centroids_match_a_subdivision_quadrature() -> None:
    """The constrained centroid ``∫x / |∫x|`` of a few cells, with ``∫x`` from fanning
    scipy's region into triangles from the site and subdividing each 4^6 times."""
    radius = 2.0
    sites = random_sites(60, 3, radius)
    diagram = hcvt.voronoi(hcvt.Domain.sphere(radius), sites)
    sv = SphericalVoronoi(sites / radius)
    sv.sort_vertices_of_regions()
    for i in (0, 17, 42):
        z = sites[i] / radius
        ring = sv.vertices[sv.regions[i]]
        area, first = 0.0, np.zeros(3)
        for k in range(len(ring)):
            da, df = subdivided_first_moment(z, ring[k], ring[(k + 1) % len(ring)], 6)
            area, first = area + da, first + df
        if area < 0:  # scipy's rings may turn either way: both signs flip together
            area, first = -area, -first
        assert abs(diagram.volume[i] - radius**2 * area) < 1e-12 * radius**2
        want = radius * first / np.linalg.norm(first)
        assert np.linalg.norm(diagram.centroid[i] - want) < 1e-6 * radius * math.sqrt(area)
        assert abs(np.linalg.norm(diagram.centroid[i]) - radius) < 1e-12 * radius


def test_icosahedron_gives_twelve_regular_pentagons() -> None:
    radius = 3.0
    sites = hcvt.initialise(hcvt.Domain.sphere(radius), 12, method="icosahedral")
    diagram = hcvt.voronoi(hcvt.Domain.sphere(radius), sites)
    assert np.allclose(diagram.volume, 4 * math.pi * radius**2 / 12, rtol=1e-14, atol=0)
    assert sides(diagram) == {5: 12}
    # The dodecahedron's edge seen from the centre: cos θ = √5/3.
    assert np.allclose(diagram.face_measures, radius * math.acos(math.sqrt(5) / 3), rtol=1e-14)
    # Every cell is centred on its site; G of the regular pentagon on the sphere.
    assert np.max(np.linalg.norm(diagram.centroid - sites, axis=1)) < 1e-14 * radius
    assert np.max(np.abs(diagram.gradient)) < 1e-13 * radius**3
    assert np.ptp(diagram.G) < 1e-14
    # With the site at the centroid, the second moment about it is the energy term, and
    # G = ∫|x − c|² / (2 A²) with d = 2.
    np.testing.assert_allclose(diagram.second_moment, diagram.energy_terms, rtol=1e-13)
    np.testing.assert_allclose(
        diagram.G, diagram.second_moment / (2 * diagram.volume**2), rtol=1e-14
    )


@pytest.mark.parametrize("n", [42, 162, 642])
def test_icosahedral_sites_converge_to_twelve_pentagons(n: int) -> None:
    domain = hcvt.Domain.sphere(6371.0)
    sites = hcvt.initialise(domain, n, method="icosahedral")
    assert sites.shape == (n, 3)
    jitter = random_sites(n, 5) * 0.05 * math.sqrt(4 * math.pi / n) * 6371.0
    start = sites + jitter
    start *= 6371.0 / np.linalg.norm(start, axis=1)[:, None]
    diagrams = {}
    for method in ("newton", "lbfgs", "lloyd"):
        res = hcvt.cvt(domain, start, method=method, max_iter=3000)
        diagrams[method] = res.evaluations
        assert res.converged, (n, method, res.history["rms_gap"][-1])
        assert sides(res.diagram) == {5: 12, 6: n - 12}
        assert np.allclose(np.linalg.norm(res.sites, axis=1), 6371.0, rtol=1e-15, atol=0)
        assert res.history["energy"][-1] < res.history["energy"][0]
    # Newton's Riemannian Hessian: near the CVT it converges in a few diagrams.
    assert diagrams["newton"] < diagrams["lbfgs"] < diagrams["lloyd"], diagrams


def test_random_sites_converge_by_both_rules() -> None:
    domain = hcvt.Domain.sphere()
    sites = hcvt.initialise(domain, 400, method="random", seed=2)
    for rule in ("gap", "paper"):
        res = hcvt.cvt(domain, sites, rule=rule)
        assert res.converged and res.stop_reason == "converged"
        value = res.history["rms_gap" if rule == "gap" else "grad_norm"][-1]
        assert value < res.tol
        # Euler: Σ (6 − sides) = 12 for any trivalent tiling of the sphere.
        assert sum((6 - k) * c for k, c in sides(res.diagram).items()) == 12
        assert 0.0801 < res.mean_G < 0.0812
        # At the CVT every site is its constrained centroid.
        gap = np.linalg.norm(res.diagram.centroid - res.sites, axis=1)
        assert np.max(gap / np.sqrt(res.diagram.volume)) < 1e-4


def test_the_gap_means_the_same_at_every_radius() -> None:
    sites = random_sites(200, 9)
    runs = [hcvt.cvt(hcvt.Domain.sphere(r), sites * r, max_iter=5) for r in (1.0, 1e4)]
    a, b = (run.history for run in runs)
    np.testing.assert_allclose(a["rms_gap"], b["rms_gap"], rtol=1e-9)
    np.testing.assert_allclose(b["energy"], a["energy"] * 1e16, rtol=1e-9)


def test_initialise_on_the_sphere() -> None:
    domain = hcvt.Domain.sphere(2.0)
    for method, n in (("random", 100), ("fibonacci", 101), ("icosahedral", 2562)):
        sites = hcvt.initialise(domain, n, method=method, seed=1)
        assert sites.shape == (n, 3)
        np.testing.assert_allclose(np.linalg.norm(sites, axis=1), 2.0, rtol=1e-15)
        assert len(np.unique(sites, axis=0)) == n
    with pytest.raises(ValueError, match="10·4\\^k \\+ 2"):
        hcvt.initialise(domain, 100, method="icosahedral")
    with pytest.raises(ValueError, match="unknown method"):
        hcvt.initialise(domain, 100, method="halton")
    # Fibonacci points are nearly uniform: the CVT of them has few defects to remove.
    cells = hcvt.voronoi(hcvt.Domain.sphere(), fibonacci(1000)).volume
    assert np.ptp(cells) / np.mean(cells) < 0.5
    assert len(icosahedral(10242)) == 10242


def test_bad_input_is_refused_by_row() -> None:
    domain = hcvt.Domain.sphere(10.0)
    sites = random_sites(20, 1, 10.0)
    sites[7] *= 1.001
    with pytest.raises(InvalidSitesError, match="site 7 .* not on the sphere of radius 10"):
        hcvt.voronoi(domain, sites)
    sites[7] /= 1.001
    sites[12] = sites[3]
    with pytest.raises(InvalidSitesError, match="sites 3 and 12 coincide"):
        hcvt.voronoi(domain, sites)
    sites[12] = -sites[3]
    with pytest.raises(InvalidDensityError, match="density is -1"):
        hcvt.voronoi(domain, sites, density=lambda p: -np.ones(len(p)))
    with pytest.raises(NotImplementedError):
        hcvt.voronoi(domain, sites).mesh()
    for radius in (0.0, -1.0, math.inf, "1"):
        with pytest.raises(ValueError, match="radius"):
            hcvt.Domain.sphere(radius)  # type: ignore[arg-type]


def test_the_domain_knows_it_is_a_sphere() -> None:
    domain = hcvt.Domain.sphere(6371.0)
    assert domain.is_sphere and domain.cell_dim == 2 and domain.radius == 6371.0
    assert math.isclose(domain.volume, 4 * math.pi * 6371.0**2, rel_tol=1e-15)
    lo, hi = domain.bounds
    assert lo.tolist() == [-6371.0] * 3 and hi.tolist() == [6371.0] * 3
    inside = domain.contains([[6371.0, 0, 0], [0, 0, 6000.0]])
    assert inside.tolist() == [True, False]
    again = pickle.loads(pickle.dumps(domain))
    assert again.is_sphere and again.radius == 6371.0
    assert "sphere" in repr(domain)
    assert not hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)]).is_sphere
