"""CVT optimisation: exact gradient, Lloyd's monotonicity, fixed points, convergence to the
paper's stopping rule and mean G, non-convex domains, thread independence."""

from __future__ import annotations

import os
import re
import signal
import threading
import time

import numpy as np
import pytest
import shapely

import hcvt
from hcvt import shapes
from helpers import DATA, random_inside

BALL = DATA / "3d" / "sphere.ply"
BUNNY = DATA / "3d" / "bunny.off"
GLYPH_B = DATA / "2d" / "dejavu_sans_B.geojson"


def central_difference(domain, sites, coords, step):
    """Central differences of the energy along the given (row, axis) coordinates."""
    out = []
    for i, k in coords:
        plus, minus = sites.copy(), sites.copy()
        plus[i, k] += step
        minus[i, k] -= step
        e_plus = hcvt.voronoi(domain, plus).energy
        e_minus = hcvt.voronoi(domain, minus).energy
        out.append((e_plus - e_minus) / (2 * step))
    return np.array(out)


def spacing(domain, n):
    return (domain.volume / n) ** (1 / domain.dim)


@pytest.mark.parametrize(
    ("path", "n"), [(GLYPH_B, 150), (DATA / "2d" / "star5.geojson", 150), (BUNNY, 60)]
)
def test_gradient_matches_central_differences(path, n):
    domain = hcvt.load_domain(path)
    sites = random_inside(domain, n, seed=3)
    diagram = hcvt.voronoi(domain, sites)
    rng = np.random.default_rng(0)
    rows = rng.choice(n, size=8, replace=False)
    coords = [(i, k) for i in rows for k in range(domain.dim)]
    fd = central_difference(domain, sites, coords, 1e-6 * spacing(domain, n))
    exact = np.array([diagram.gradient[i, k] for i, k in coords])
    rel = np.linalg.norm(fd - exact) / np.linalg.norm(exact)
    assert rel < 1e-6, f"{path.name}: relative error {rel:.2e}"
    # and the gradient is 2 m_i (x_i - c_i)
    assert np.allclose(
        diagram.gradient, 2 * diagram.volume[:, None] * (sites - diagram.centroid), atol=1e-14
    )


@pytest.mark.parametrize("path", [GLYPH_B, BUNNY])
def test_lloyd_never_increases_the_energy(path):
    domain = hcvt.load_domain(path)
    n = 200 if domain.dim == 2 else 60
    res = hcvt.cvt(domain, random_inside(domain, n, seed=1), "lloyd", max_iter=25, tol=0)
    energy = res.history["energy"]
    assert len(energy) == 26 and res.stop_reason == "max_iter"
    assert np.all(np.diff(energy) <= 1e-13 * energy[:-1]), np.diff(energy).max()
    assert set(res.history["step"][1:]) == {"lloyd"}


def hexagonal_patch(rows, cols, spacing=1.0):
    """Hexagonal lattice sites and the polygon that is the union of their cells."""
    sites = np.array(
        [
            [spacing * (c + 0.5 * (r % 2)), spacing * r * np.sqrt(3) / 2]
            for r in range(rows)
            for c in range(cols)
        ]
    )
    radius = spacing / np.sqrt(3)  # circumradius of the Voronoi hexagon
    angles = np.pi / 6 + np.arange(6) * np.pi / 3
    hexagon = np.column_stack([np.cos(angles), np.sin(angles)]) * radius
    cells = [shapely.Polygon(hexagon + s) for s in sites]
    polygon = shapely.set_precision(shapely.unary_union(cells), 1e-12)
    return sites, polygon


def box_mesh(lo, hi):
    """The box [lo, hi] as 12 outward triangles."""
    v = np.array([[(lo, hi)[(i >> k) & 1][k] for k in range(3)] for i in range(8)], dtype=float)
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    faces = [[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads]
    return v, np.array(faces)


def grid(counts, lo, hi):
    axes = [lo[k] + (np.arange(c) + 0.5) * (hi[k] - lo[k]) / c for k, c in enumerate(counts)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(counts))


def fixed_point_cases():
    rectangle = hcvt.Domain.from_polygon([(-1, 2), (5, 2), (5, 6), (-1, 6)])
    yield "square grid in a rectangle", rectangle, grid((6, 4), (-1, 2), (5, 6))
    sites, polygon = hexagonal_patch(5, 6)
    yield "hexagonal lattice", hcvt.Domain.from_polygon(polygon), sites
    lo, hi = (0.5, -1.0, 2.0), (2.5, 1.0, 3.5)
    yield "cubic grid in a box", hcvt.Domain.from_mesh(*box_mesh(lo, hi)), grid((4, 4, 3), lo, hi)


@pytest.mark.parametrize("method", ["lbfgs", "lloyd", "newton"])
def test_known_cvts_are_fixed_points(method):
    for name, domain, sites in fixed_point_cases():
        diagram = hcvt.voronoi(domain, sites)
        assert np.allclose(diagram.centroid, sites, atol=1e-12), name
        # tol = 0 forces every iteration to run on gradients that are pure round-off.
        res = hcvt.cvt(domain, sites, method, tol=0, max_iter=5)
        moved = np.abs(res.sites - sites).max()
        assert moved < 1e-12, f"{name}: a site moved by {moved:.2e}"
        assert np.all(np.isfinite(res.history["grad_norm"])), name


@pytest.fixture(scope="module")
def square_run():
    domain = shapes.square()
    sites = random_inside(domain, 1033, seed=0)
    return domain, sites, hcvt.cvt(domain, sites, "lbfgs", tol=1e-10)


def test_lbfgs_reaches_the_paper_rule_in_the_square(square_run):
    _, _, res = square_run
    assert res.converged and res.stop_reason == "converged"
    assert res.history["grad_norm"][-1] < 1e-10
    assert res.history["gap"][-1] < 1e-4
    # Paper Table 4 (a), random sampling + L-BFGS: mean G 0.08101, energy 25.140.
    assert 0.0805 <= res.mean_G <= 0.0815, res.mean_G
    assert abs(res.energy - 25.14) < 0.1, res.energy
    assert res.diagram.n == 1033 and np.array_equal(res.diagram.sites, res.sites)
    h = res.history
    assert all(len(h[key]) == res.iterations + 1 for key in h)
    assert h["evaluations"][-1] == res.evaluations >= res.iterations
    assert np.all(np.diff(h["seconds"]) >= 0) and np.all(np.diff(h["evaluations"]) >= 1)


def test_lbfgs_needs_fewer_diagrams_than_lloyd(square_run):
    domain, sites, _ = square_run
    lbfgs = hcvt.cvt(domain, sites, "lbfgs", tol=1e-6)
    lloyd = hcvt.cvt(domain, sites, "lloyd", tol=1e-6)
    assert lbfgs.converged and lloyd.converged
    assert lbfgs.evaluations < lloyd.evaluations, (lbfgs.evaluations, lloyd.evaluations)


def test_newton_reaches_the_rule_with_fewer_diagrams_than_lbfgs(square_run):
    domain, sites, lbfgs = square_run
    res = hcvt.cvt(domain, sites, "newton", tol=1e-10)
    assert res.converged and res.history["grad_norm"][-1] < 1e-10
    assert set(res.history["step"][1:]) == {"newton"}
    assert 0.0805 <= res.mean_G <= 0.0815, res.mean_G
    # Measured: 101 diagrams against 407 for L-BFGS.
    assert res.evaluations < lbfgs.evaluations / 2, (res.evaluations, lbfgs.evaluations)


def test_stopping_rule_ignores_unit_and_position(square_run):
    domain, sites, _ = square_run
    small = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    moved = hcvt.Domain.from_polygon([(-7, 3), (13, 3), (13, 23), (-7, 23)])
    a = hcvt.cvt(small, sites[:200] / 20, max_iter=3)
    b = hcvt.cvt(moved, sites[:200] + [-7, 3], max_iter=3)
    for key in ("grad_norm", "gap", "mean_G"):
        assert np.allclose(a.history[key], b.history[key], rtol=1e-6), key


@pytest.mark.parametrize("method", ["lbfgs", "newton"])
def test_ball_converges_near_the_paper_mean_g(method):
    domain = hcvt.load_domain(BALL)
    res = hcvt.cvt(domain, random_inside(domain, 1000, seed=0), method, tol=1e-10)
    assert res.converged, (res.stop_reason, res.history["grad_norm"][-1])
    # Paper Table 6 (a): 0.08025 (random sampling + L-BFGS, 1000 sites in a ball).
    assert abs(res.mean_G - 0.08025) < 5e-4, res.mean_G


def test_sites_stay_inside_a_non_convex_domain():
    domain = hcvt.load_domain(GLYPH_B)
    res = hcvt.cvt(domain, random_inside(domain, 300, seed=2), tol=1e-9)
    assert res.converged and np.all(np.isfinite(res.sites))
    winding, on_boundary = domain.winding_numbers(res.sites)
    assert np.all((winding != 0) | on_boundary)
    assert np.all(res.diagram.volume > 0)


@pytest.mark.parametrize("method", ["lbfgs", "newton"])
def test_sites_pinned_at_a_notch_do_not_stall_the_run(method):
    # A cell at a notch has its centroid outside; its site ends on the boundary.
    domain = hcvt.load_domain(DATA / "2d" / "cgal_skeleton_sample_1.geojson")
    res = hcvt.cvt(domain, random_inside(domain, 1000, seed=1), method, max_iter=2000)
    assert res.converged, res.stop_reason
    assert res.history["pinned"][-1] >= 1
    winding, on_boundary = domain.winding_numbers(res.sites)
    assert np.all((winding != 0) | on_boundary)


@pytest.mark.parametrize("method", ["lbfgs", "newton"])
def test_results_do_not_depend_on_the_thread_count(method):
    domain = shapes.star()
    sites = random_inside(domain, 400, seed=5)
    before = hcvt.get_num_threads()
    runs = []
    try:
        for threads in (1, 2):
            hcvt.set_num_threads(threads)
            runs.append(hcvt.cvt(domain, sites, method, max_iter=40))
    finally:
        hcvt.set_num_threads(before)
    one, two = runs
    assert np.array_equal(one.sites, two.sites)
    for key in ("energy", "grad_norm", "evaluations"):
        assert np.array_equal(one.history[key], two.history[key]), key


def test_callback_sees_every_iterate_and_can_stop():
    domain = shapes.unit_square()
    sites = random_inside(domain, 50, seed=0)
    seen = []

    def callback(info):
        seen.append(info)
        return len(seen) == 4

    res = hcvt.cvt(domain, sites, callback=callback)
    assert res.stop_reason == "interrupted" and not res.converged
    assert res.iterations == 3 and len(seen) == 4
    assert seen[0]["step"] == "start" and seen[0]["sites"].shape == (50, 2)
    assert np.array_equal(seen[-1]["sites"], res.sites)


def test_callback_may_call_back_into_hcvt():
    domain = shapes.unit_square()
    means = []

    def callback(info):
        means.append(hcvt.voronoi(domain, info["sites"]).mean_G)

    res = hcvt.cvt(domain, random_inside(domain, 40, seed=1), max_iter=5, callback=callback)
    assert len(means) == res.iterations + 1
    assert np.allclose(means, res.history["mean_G"], rtol=1e-12)


@pytest.mark.parametrize("threads", [None, 2])
def test_ctrl_c_interrupts_a_long_run(threads):
    domain = shapes.square()
    sites = random_inside(domain, 2000, seed=0)
    before = hcvt.get_num_threads()
    timer = threading.Timer(0.2, lambda: os.kill(os.getpid(), signal.SIGINT))
    # Ctrl-C raises KeyboardInterrupt only under Python's default handler, whatever an
    # earlier test (a dask cluster, a CLI run) may have installed.
    handler = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        if threads is not None:
            hcvt.set_num_threads(threads)  # the loop then runs on a pool worker
        start = time.perf_counter()
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            hcvt.cvt(domain, sites, tol=0, max_iter=100_000)
        assert time.perf_counter() - start < 2
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, handler)
        hcvt.set_num_threads(before)


def test_callback_errors_propagate():
    def callback(info):
        raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        hcvt.cvt(shapes.unit_square(), [[0.2, 0.3], [0.6, 0.7]], callback=callback)


def test_progress_bar_shows_the_final_state(capsys):
    # issue 16: the test checked only that nothing crashed. The bar's last render must show
    # the run's end: the paper's rule below tol, the mean G and diagram count of the result.
    res = hcvt.cvt(shapes.unit_square(), random_inside(shapes.unit_square(), 30), progress=True)
    assert res.converged
    out = capsys.readouterr().out
    assert out.lstrip().startswith("CVT")
    rule = re.findall(r"\|g\|/\|X\| (\S+)", out)
    assert rule and float(rule[-1]) < 1e-10
    assert re.findall(r"mean G (\S+)", out)[-1] == f"{res.diagram.mean_G:.6f}"
    assert re.findall(r"diagrams (\d+)", out)[-1] == str(res.evaluations)


def test_bad_input_is_refused():
    square = shapes.unit_square()
    with pytest.raises(ValueError, match="method"):
        hcvt.cvt(square, [[0.5, 0.5]], "bfgs")
    with pytest.raises(hcvt.InvalidSitesError, match="site 1"):
        hcvt.cvt(square, [[0.5, 0.5], [1.5, 0.5]])
    with pytest.raises(ValueError, match="shape"):
        hcvt.cvt(square, [[0.5, 0.5, 0.5]])


def test_single_site_goes_to_the_centroid():
    domain = hcvt.load_domain(DATA / "2d" / "star5.geojson")
    start = random_inside(domain, 1, seed=4)
    res = hcvt.cvt(domain, start, tol=1e-12)
    assert res.converged
    assert np.allclose(res.sites[0], domain.centroid, atol=1e-9 * spacing(domain, 1))
