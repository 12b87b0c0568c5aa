"""A density ρ (issue 17, DESIGN §8): exact ρ-weighted moments for polynomials of degree
≤ 2, sampled callables, gradient, grading of CVTs, initialisation, errors.

The references here are independent of the core: cells cut by GEOS (2D) or by scipy's
half-space intersection (3D), integrated by collapsed Gauss–Legendre product rules (not
the core's symmetric rules), the domain's integral by the divergence theorem over its
boundary, and Monte-Carlo.
"""

from __future__ import annotations

import numpy as np
import pytest
import shapely
from numpy.polynomial.legendre import leggauss
from scipy.spatial import ConvexHull, HalfspaceIntersection, cKDTree

import hcvt
from hcvt.density import Polynomial, SizingField
from hcvt.errors import InvalidDensityError
from helpers import DATA

# ρ of degree 2 with every kind of term, positive on the data used below.
RHO_2D = Polynomial(2.0, [0.7, -0.4], [[1.5, 0.3], [0.3, 0.8]])
RHO_3D = Polynomial(3.0, [0.5, -0.3, 0.2], [[1.0, 0.2, -0.1], [0.2, 0.6, 0.1], [-0.1, 0.1, 0.9]])


# ------------------------------------------------------------------ reference integrators
def _collapsed_rule(dim: int, points: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """A product Gauss–Legendre rule on the unit simplex through the collapsed (Duffy)
    map: barycentric coordinates of the vertices 1..dim, and weights summing to 1. With
    5 points per axis it is exact for polynomials of degree ≤ 7 in 2D and ≤ 6 in 3D."""
    t, w = leggauss(points)
    t, w = 0.5 * (t + 1.0), 0.5 * w
    grids = np.meshgrid(*([t] * dim), indexing="ij")
    weights = np.prod(np.meshgrid(*([w] * dim), indexing="ij"), axis=0).ravel()
    u = [g.ravel() for g in grids]
    if dim == 2:
        lam = np.column_stack([u[0] * (1 - u[1]), u[1]])
        jac = 1 - u[1]
    else:
        lam = np.column_stack([u[0] * (1 - u[1]) * (1 - u[2]), u[1] * (1 - u[2]), u[2]])
        jac = (1 - u[1]) * (1 - u[2]) ** 2
    weights = weights * jac
    return lam, weights / weights.sum()


def _simplex_moments(simplices: np.ndarray, rho, site: np.ndarray) -> np.ndarray:
    """Σ over signed simplices (s, d+1, d) of ``[∫ρ, ∫ρx (d), ∫ρ|x - site|²]``."""
    dim = simplices.shape[2]
    lam, w = _collapsed_rule(dim)
    v0 = simplices[:, 0]
    edges = simplices[:, 1:] - v0[:, None, :]  # (s, d, d)
    volume = np.linalg.det(edges) / (2.0 if dim == 2 else 6.0)
    x = v0[:, None, :] + np.einsum("qk,skj->sqj", lam, edges)  # (s, q, d)
    r = rho(x.reshape(-1, dim)).reshape(x.shape[:2]) * w * volume[:, None]
    return np.concatenate(
        [[r.sum()], np.einsum("sq,sqj->j", r, x), [np.sum(r * np.sum((x - site) ** 2, axis=2))]]
    )


def _polygon_moments(geometry, rho, site: np.ndarray) -> np.ndarray:
    """ρ-moments of a shapely (multi)polygon with holes: each ring fanned from its first
    vertex, signed by orientation (Green's theorem in triangle form)."""
    out = np.zeros(4)
    polygons = getattr(geometry, "geoms", [geometry])
    for polygon in polygons:
        polygon = shapely.geometry.polygon.orient(polygon, 1.0)
        for ring in [polygon.exterior, *polygon.interiors]:
            v = np.asarray(ring.coords)[:-1]
            tri = np.stack([np.repeat(v[:1], len(v) - 2, 0), v[1:-1], v[2:]], axis=1)
            out += _simplex_moments(tri, rho, site)
    return out


# ------------------------------------------------------------------ exactness, quadratic ρ
def _check_cells(diagram: hcvt.Diagram, reference: np.ndarray) -> None:
    mass, first, energy = reference[:, 0], reference[:, 1:-1], reference[:, -1]
    np.testing.assert_allclose(diagram.mass, mass, rtol=1e-12, atol=0)
    h = diagram.volume ** (1.0 / diagram.domain.dim)
    gap = np.linalg.norm(diagram.centroid - first / mass[:, None], axis=1)
    assert np.all(gap <= 1e-12 * h), f"centroid off by {np.max(gap / h):.2e} h"
    np.testing.assert_allclose(diagram.energy_terms, energy, rtol=1e-12, atol=0)


def test_quadratic_density_is_exact_on_a_polygon_with_holes() -> None:
    domain = hcvt.load_domain(DATA / "2d" / "triangle_double_hex.geojson")
    sites = hcvt.initialise(domain, 150, seed=3)
    diagram = hcvt.voronoi(domain, sites, density=RHO_2D)
    cells = diagram.cells()
    reference = np.array(
        [_polygon_moments(c, RHO_2D, s) for c, s in zip(cells, sites, strict=True)]
    )
    assert np.any(diagram.boundary_measure > 0)  # cells cut by the holes are among them
    _check_cells(diagram, reference)
    # The weighted quantities carry ρ, the geometric ones do not.
    uniform = hcvt.voronoi(domain, sites)
    assert np.array_equal(diagram.volume, uniform.volume)
    assert np.array_equal(diagram.G, uniform.G)
    assert np.max(np.abs(diagram.mass / diagram.volume - 1)) > 0.5


def _convex_cells_3d(domain: hcvt.Domain, sites: np.ndarray) -> list[np.ndarray]:
    """Each cell of a convex domain as the intersection of the domain's face planes and
    every bisector (scipy's Qhull), as the signed tetrahedra of its hull fanned from its
    vertex mean."""
    v, f = domain.vertices, domain.faces
    normals = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    planes = np.column_stack([normals, -np.einsum("ij,ij->i", normals, v[f[:, 0]])])
    out = []
    for i, s in enumerate(sites):
        others = np.delete(sites, i, axis=0)
        normal = others - s
        offset = -np.einsum("ij,ij->i", normal, 0.5 * (others + s))
        halfspaces = np.vstack([planes, np.column_stack([normal, offset])])
        corners = HalfspaceIntersection(halfspaces, s).intersections
        hull = ConvexHull(corners)
        centre = corners.mean(axis=0)
        tets = np.stack(
            [
                np.repeat(centre[None], len(hull.simplices), 0),
                *np.moveaxis(corners[hull.simplices], 1, 0),
            ],
            axis=1,
        )
        edges = tets[:, 1:] - tets[:, :1]
        flip = np.linalg.det(edges) < 0
        tets[flip, 1], tets[flip, 2] = tets[flip, 2].copy(), tets[flip, 1].copy()
        out.append(tets)
    return out


def test_quadratic_density_is_exact_on_a_convex_mesh() -> None:
    domain = hcvt.load_domain(DATA / "3d" / "sphere.ply")
    sites = hcvt.initialise(domain, 60, seed=5)
    diagram = hcvt.voronoi(domain, sites, density=RHO_3D)
    cells = _convex_cells_3d(domain, sites)
    reference = np.array(
        [_simplex_moments(t, RHO_3D, s) for t, s in zip(cells, sites, strict=True)]
    )
    assert np.sum(diagram.boundary_measure > 0) > 30
    _check_cells(diagram, reference)


def _divergence_integral(domain: hcvt.Domain, rho: Polynomial) -> float:
    """∫_Ω ρ as ∮ P n_x dS with ∂P/∂x = ρ (the divergence theorem), P a cubic: each
    boundary triangle integrated by the collapsed Gauss rule."""
    c, b, a = rho.coefficients(3)
    b, a = np.asarray(b), np.asarray(a)

    def antiderivative(x: np.ndarray) -> np.ndarray:
        # ∫ρ dx in x: c x + b0 x²/2 + (b1 y + b2 z) x + A00 x³/3 + (A01 y + A02 z) x²
        #             + (A11 y² + 2 A12 y z + A22 z²) x
        X, Y, Z = x[:, 0], x[:, 1], x[:, 2]
        return (
            c * X
            + b[0] * X**2 / 2
            + (b[1] * Y + b[2] * Z) * X
            + a[0, 0] * X**3 / 3
            + (a[0, 1] * Y + a[0, 2] * Z) * X**2
            + (a[1, 1] * Y**2 + 2 * a[1, 2] * Y * Z + a[2, 2] * Z**2) * X
        )

    v, f = domain.vertices, domain.faces
    tri = v[f]
    normal_x = 0.5 * np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])[:, 0]
    lam, w = _collapsed_rule(2)
    x = tri[:, :1] + np.einsum("qk,tkj->tqj", lam, tri[:, 1:] - tri[:, :1])
    values = antiderivative(x.reshape(-1, 3)).reshape(x.shape[:2])
    return float(np.sum(values * w * normal_x[:, None]))


def test_bunny_masses_sum_to_the_domain_integral_and_match_monte_carlo() -> None:
    domain = hcvt.load_domain(DATA / "3d" / "bunny.off")
    lo, hi = domain.bounds
    size = float(np.max(hi - lo))
    # ρ in units of the bunny's box: from about 1 to 4 across it.
    centre = 0.5 * (lo + hi)
    scale = 1.0 / size**2
    a = scale * np.diag([1.0, 2.0, 0.5]) + scale * 0.3 * (np.ones((3, 3)) - np.eye(3))
    rho = Polynomial(
        1.5 + float(centre @ a @ centre), (-2 * a @ centre + 0.5 / size).tolist(), a.tolist()
    )
    sites = hcvt.initialise(domain, 40, seed=2)
    diagram = hcvt.voronoi(domain, sites, density=rho)
    total = _divergence_integral(domain, rho)
    assert abs(diagram.mass.sum() - total) <= 1e-12 * total
    # Per cell: Monte-Carlo of ∫ρ over the points nearest each site, 5 standard errors.
    rng = np.random.default_rng(0)
    samples = rng.uniform(lo, hi, size=(400_000, 3))
    inside = samples[domain.contains(samples)]
    owner = cKDTree(sites).query(inside)[1]
    box = float(np.prod(hi - lo))
    contribution = np.zeros(len(samples))
    contribution[: len(inside)] = rho(inside) * box
    per_cell = np.zeros((len(sites), len(samples)))
    per_cell[owner, np.arange(len(inside))] = contribution[: len(inside)]
    estimate = per_cell.mean(axis=1)
    error = per_cell.std(axis=1) / np.sqrt(len(samples))
    assert np.all(np.abs(estimate - diagram.mass) <= 5 * error), np.max(
        np.abs(estimate - diagram.mass) / error
    )


# ------------------------------------------------------------------ callables
@pytest.mark.parametrize("dim", [2, 3])
def test_a_callable_quadratic_equals_the_polynomial_path(dim: int) -> None:
    domain = (
        hcvt.load_domain(DATA / "2d" / "triangle_double_hex.geojson")
        if dim == 2
        else hcvt.load_domain(DATA / "3d" / "bunny.off")
    )
    rho = RHO_2D if dim == 2 else None
    if dim == 3:
        lo, hi = domain.bounds
        rho = Polynomial(1.0, [0.0, 0.0, 0.0], (np.eye(3) / np.max(hi - lo) ** 2).tolist())
    sites = hcvt.initialise(domain, 200, seed=1)
    exact = hcvt.voronoi(domain, sites, density=rho)
    calls = []

    def function(points: np.ndarray) -> np.ndarray:
        calls.append(points.shape)
        return rho(points)

    sampled = hcvt.voronoi(domain, sites, density=function)  # default degree 4
    assert len(calls) == 1 and calls[0][1] == dim  # one call for the whole diagram
    np.testing.assert_allclose(sampled.mass, exact.mass, rtol=1e-12, atol=0)
    np.testing.assert_allclose(sampled.energy_terms, exact.energy_terms, rtol=1e-12, atol=0)
    h = exact.volume ** (1 / dim)
    assert np.all(np.linalg.norm(sampled.centroid - exact.centroid, axis=1) <= 1e-12 * h)


def _square_cell_exp_integral(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """∫ exp(x + y) over axis-aligned boxes (k, 2): a product of 1D integrals."""
    return np.prod(np.exp(hi) - np.exp(lo), axis=1)


@pytest.mark.parametrize("degree", [1, 2, 4])
def test_the_error_on_a_smooth_density_falls_at_the_rules_order(degree: int) -> None:
    # Square cells of side h (a grid of sites): the exact integral is a product. A rule of
    # degree p leaves a relative error O(h^(p+1)) per cell, or O(h^(p+2)) when the
    # cell's symmetry cancels the odd term: the fitted order must be at least p + 1.
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    errors, sides = [], []
    for k in (4, 8, 16):
        h = 1.0 / k
        g = (np.arange(k) + 0.5) * h
        sites = np.array([(x, y) for y in g for x in g])
        d = hcvt.voronoi(
            square, sites, density=lambda p: np.exp(p[:, 0] + p[:, 1]), quadrature_degree=degree
        )
        exact = _square_cell_exp_integral(sites - h / 2, sites + h / 2)
        errors.append(np.max(np.abs(d.mass / exact - 1)))
        sides.append(h)
    order = np.polyfit(np.log(sides), np.log(errors), 1)[0]
    assert order >= degree + 1 - 0.1, (order, errors)
    assert order <= degree + 2 + 0.3, (order, errors)


# ------------------------------------------------------------------ gradient
@pytest.mark.parametrize("dim", [2, 3])
def test_the_weighted_gradient_matches_finite_differences(dim: int) -> None:
    if dim == 2:
        domain, rho = hcvt.load_domain(DATA / "2d" / "triangle_double_hex.geojson"), RHO_2D
    else:
        domain, rho = hcvt.load_domain(DATA / "3d" / "sphere.ply"), RHO_3D
    sites = hcvt.initialise(domain, 40, seed=7)
    diagram = hcvt.voronoi(domain, sites, density=rho)
    h = (domain.volume / len(sites)) ** (1 / dim)
    rng = np.random.default_rng(1)
    for _ in range(3):
        direction = rng.normal(size=sites.shape)
        direction /= np.linalg.norm(direction)
        eps = 1e-4 * h
        plus = hcvt.voronoi(domain, sites + eps * direction, density=rho).energy
        minus = hcvt.voronoi(domain, sites - eps * direction, density=rho).energy
        numeric = (plus - minus) / (2 * eps)
        exact = float(np.sum(diagram.gradient * direction))
        assert abs(numeric - exact) <= 1e-6 * np.linalg.norm(diagram.gradient), (numeric, exact)
    # ∂E/∂x_i = 2 m_i (x_i - c_i), with the ρ-weighted mass and centroid.
    np.testing.assert_allclose(
        diagram.gradient, 2 * diagram.mass[:, None] * (sites - diagram.centroid), atol=1e-13 * h
    )


def test_newton_with_a_polynomial_density_converges_with_fewer_diagrams() -> None:
    # The Hessian's face terms are weighted by ρ (checked against finite differences in
    # crates/hcvt-core/tests/it/density.rs): Newton converges in fewer diagrams, and near a
    # CVT it converges quadratically (measured: RMS gap 1e-7, 3e-11, 6e-16).
    domain = hcvt.load_domain(DATA / "2d" / "triangle_double_hex.geojson")
    sites = hcvt.initialise(domain, 200, seed=2)
    newton = hcvt.cvt(domain, sites, method="newton", density=RHO_2D, tol=1e-9)
    lbfgs = hcvt.cvt(domain, sites, "lbfgs", density=RHO_2D, tol=1e-9)
    assert newton.converged and lbfgs.converged
    assert newton.evaluations < lbfgs.evaluations, (newton.evaluations, lbfgs.evaluations)
    near = hcvt.cvt(domain, sites, "lbfgs", density=RHO_2D, tol=1e-6)
    again = hcvt.cvt(domain, near.sites, method="newton", density=RHO_2D, tol=1e-13)
    gaps = again.history["rms_gap"]
    assert again.converged and again.iterations <= 10, gaps
    assert gaps[-1] < 1e-13 and gaps[-2] < 1e-9, gaps


# ------------------------------------------------------------------ grading
def _slope(result: hcvt.CVTResult, rho) -> float:
    d = result.diagram
    interior = d.boundary_measure == 0
    size = d.volume[interior] ** (1.0 / d.domain.dim)
    return float(np.polyfit(np.log(rho(d.centroid[interior])), np.log(size), 1)[0])


def test_a_2d_cvt_grades_its_cells_as_rho_to_minus_one_quarter() -> None:
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    # A sizing field whose ρ = h^-4 varies 100x across the square: h from 1 to 1/√10.
    sizing = SizingField(lambda p: 1.0 / (1.0 + (np.sqrt(10.0) - 1.0) * p[:, 0]))
    rho = sizing.density(2)
    sites = hcvt.initialise(square, 1500, seed=0, density=sizing)
    res = hcvt.cvt(square, sites, density=sizing, tol=1e-4)
    assert res.converged
    assert abs(_slope(res, rho) / -0.25 - 1) < 0.05, _slope(res, rho)


def test_a_3d_cvt_in_a_ball_grades_its_cells_as_rho_to_minus_one_fifth() -> None:
    ball = hcvt.load_domain(DATA / "3d" / "sphere.ply")
    # (1 + 4.5 (x + 1)/2 ... ): ρ = (1 + 2.25 (x + 1))² runs from 1 to 30.25 along x ...
    # 100x: ρ = (1 + 4.5 (x + 1))² / ... from 1 at x = -1 to 100 at x = 1.
    a = 4.5
    rho = Polynomial((1 + a) ** 2, [2 * a * (1 + a), 0, 0], [[a * a, 0, 0], [0, 0, 0], [0, 0, 0]])
    assert np.isclose(rho(np.array([[1.0, 0, 0]]))[0] / rho(np.array([[-1.0, 0, 0]]))[0], 100)
    sites = hcvt.initialise(ball, 2000, seed=0, density=rho)
    res = hcvt.cvt(ball, sites, density=rho, tol=1e-4)
    assert res.converged
    assert abs(_slope(res, rho) / -0.2 - 1) < 0.05, _slope(res, rho)


# ------------------------------------------------------------------ uniform ρ, errors
def test_rho_one_is_the_uniform_diagram_bit_for_bit() -> None:
    domain = hcvt.load_domain(DATA / "2d" / "triangle_double_hex.geojson")
    sites = hcvt.initialise(domain, 300, seed=4)
    uniform = hcvt.voronoi(domain, sites)
    one = hcvt.voronoi(domain, sites, density=Polynomial(1.0))
    for name in ("mass", "volume", "centroid", "energy_terms", "gradient", "G"):
        assert np.array_equal(getattr(one, name), getattr(uniform, name)), name
    assert np.array_equal(uniform.mass, uniform.volume)
    three = hcvt.voronoi(domain, sites, density=Polynomial(3.0))
    np.testing.assert_allclose(three.centroid, uniform.centroid, rtol=0, atol=1e-15)
    np.testing.assert_allclose(three.energy_terms, 3 * uniform.energy_terms, rtol=1e-15)
    a = hcvt.cvt(domain, sites, max_iter=5)
    b = hcvt.cvt(domain, sites, max_iter=5, density=Polynomial(1.0))
    assert np.array_equal(a.sites, b.sites)


def test_bad_densities_are_named() -> None:
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    g = np.linspace(0.1, 0.9, 5)
    sites = np.array([(x, y) for x in g for y in g])
    # Positive at every site, negative at the corner (1, 1): a boundary vertex.
    with pytest.raises(InvalidDensityError, match=r"is -0\.1\d* at \[1\.0, 1\.0\]"):
        hcvt.voronoi(square, sites, density=Polynomial(1.0, [0, 0], [[-0.55, 0], [0, -0.55]]))

    def nan_right(points: np.ndarray) -> np.ndarray:
        return np.where(points[:, 0] > 0.9, np.nan, 1.0)

    with pytest.raises(InvalidDensityError, match=r"the density is NaN at \[0\.9"):
        hcvt.voronoi(square, sites, density=nan_right)

    def broken(points: np.ndarray) -> np.ndarray:
        raise KeyError("inside the user's function")

    with pytest.raises(KeyError, match="inside the user's function"):
        hcvt.cvt(square, sites, density=broken)
    with pytest.raises(InvalidDensityError, match=r"shape \("):
        hcvt.voronoi(square, sites, density=lambda p: np.ones(3))
    with pytest.raises(InvalidDensityError, match="quadrature_degree"):
        hcvt.voronoi(square, sites, density=lambda p: np.ones(len(p)), quadrature_degree=7)
    with pytest.raises(InvalidDensityError, match="Newton"):
        hcvt.cvt(square, sites, method="newton", density=lambda p: np.ones(len(p)))
    with pytest.raises(InvalidDensityError, match="3 dimensions"):
        hcvt.voronoi(square, sites, density=RHO_3D)
    with pytest.raises(TypeError, match="density must be"):
        hcvt.voronoi(square, sites, density=2.0)  # type: ignore[arg-type]


# ------------------------------------------------------------------ initialise, hierarchy
def test_initialise_with_a_density_follows_gersho() -> None:
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    rho = Polynomial(1.0, [0.0, 0.0], [[99.0, 0.0], [0.0, 0.0]])  # 1 to 100 along x
    n = 20_000
    for method in ("random", "halton"):
        sites = hcvt.initialise(square, n, method=method, seed=3, density=rho)
        assert sites.shape == (n, 2) and square.contains(sites).all()
        # Expected share left of x = 1/2 under g = ρ^(1/2) = sqrt(1 + 99 x²).
        x = (np.arange(100_000) + 0.5) / 100_000
        g = np.sqrt(1 + 99 * x**2)
        share = g[x < 0.5].sum() / g.sum()
        observed = np.mean(sites[:, 0] < 0.5)
        assert abs(observed - share) < 5 * np.sqrt(share * (1 - share) / n), (
            method,
            observed,
            share,
        )
    with pytest.raises(ValueError, match="uniformly"):
        hcvt.initialise(square, 10, method="lattice", density=rho)


def test_hierarchical_cvt_with_a_density_keeps_exact_counts() -> None:
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    rho = Polynomial(1.0, [0.0, 0.0], [[99.0, 0.0], [0.0, 0.0]])
    res = hcvt.hierarchical_cvt(square, 600, subdivisions=2, density=rho, tol=1e-4)
    assert [level.n for level in res.levels] == [res.schedule.k0, *res.schedule.targets]
    assert len(res.sites) == 600 and res.diagram.density is rho
    # The finest level is graded: smaller cells where ρ is larger.
    d = res.diagram
    interior = d.boundary_measure == 0
    slope = np.polyfit(np.log(rho(d.centroid[interior])), np.log(d.volume[interior]) / 2, 1)[0]
    assert -0.3 < slope < -0.2, slope


# ------------------------------------------------------------------ CLI and picture
def test_the_cli_takes_a_polynomial_or_a_function_from_a_file(tmp_path) -> None:
    from click.testing import CliRunner

    from hcvt.cli import main

    def invoke(*args: object):
        return CliRunner().invoke(main, [str(a) for a in args], catch_exceptions=False)

    summary = tmp_path / "s.json"
    result = invoke(
        "run", "unit-square", "-n", 400, "--method", "lbfgs", "--tol", 1e-4,
        "--density", "1 + 99*x^2", "--summary", summary, "--out", tmp_path / "a.npy",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    import json

    assert json.loads(summary.read_text())["density"] == "Polynomial(1 + 99*x**2)"
    graded = np.load(tmp_path / "a.npy")
    # More sites where ρ is large: about ∫ρ^(1/2) over x > 1/2 against x < 1/2.
    assert np.mean(graded[:, 0] > 0.5) > 0.6
    module = tmp_path / "rho.py"
    module.write_text("def rho(p):\n    return 1 + 99 * p[:, 0] ** 2\n")
    result = invoke(
        "run", "unit-square", "-n", 400, "--method", "lbfgs", "--tol", 1e-4,
        "--density", f"{module}:rho", "--out", tmp_path / "b.npy",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    # The same ρ as a function: the same CVT to the sampling's round-off.
    assert np.max(np.abs(np.load(tmp_path / "b.npy") - graded)) < 1e-6
    bad = CliRunner().invoke(main, ["run", "unit-square", "-n", "10", "--density", "__import__"])
    assert bad.exit_code == 2 and "cannot read" in bad.output


def test_the_grading_figure_measures_gershos_slope(tmp_path) -> None:
    from hcvt.plot import grading_figure

    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    rho = Polynomial.parse("1 + 99*x^2")
    res = hcvt.cvt(square, hcvt.initialise(square, 800, density=rho), density=rho, tol=1e-4)
    slope = grading_figure(res.diagram, tmp_path / "g.png")
    assert abs(slope / -0.25 - 1) < 0.05, slope
    assert (tmp_path / "g.png").stat().st_size > 20_000
