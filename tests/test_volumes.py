"""Capacity-constrained CVTs, ``hcvt.cvt(..., volumes=v)``: cells of prescribed volumes with
their sites at their centroids (Bourne, Kok, Roper, Spanjer 2020).

Each result is checked against an independent computation of its power cells from the
returned sites and weights: shapely's half-plane intersections in 2D (``test_power.py``),
scipy's ``HalfspaceIntersection`` of the 27 images' half-spaces in a periodic 3D box, and
in the bunny the power diagram computed again from the weights. Every cell's volume must be
within 1e-8 of its target, relatively, and the RMS of ``|x_i - c_i| / V_i^(1/d)`` below the
default 1e-7 with those cells' centroids.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.optimize import linprog
from scipy.spatial import ConvexHull, Delaunay, HalfspaceIntersection

import hcvt
from hcvt.cli import main
from hcvt.io.readers import read_polygon
from helpers import DATA, random_inside
from test_power import reference_cells_2d

STAR = DATA / "2d" / "star5.geojson"
HOLED = DATA / "2d" / "triangle_square_circle_hole.geojson"
BUNNY = DATA / "3d" / "bunny.off"
VOLUME_TOL = 1e-8
GAP_TOL = 1e-7


def lognormal(n: int, seed: int, sigma: float = 0.3) -> np.ndarray:
    return np.random.default_rng(seed).lognormal(0.0, sigma, n)


def rms_gap(sites: np.ndarray, centroids: np.ndarray, volumes: np.ndarray) -> np.ndarray:
    """Each site's distance to its centroid over its cell's size ``V^(1/d)``."""
    d = sites.shape[1]
    return np.linalg.norm(sites - centroids, axis=1) / volumes ** (1 / d)


@pytest.mark.parametrize("path", [STAR, HOLED], ids=["star5", "holed"])
def test_2d_cells_have_their_volumes_and_sites_at_centroids(path):
    geometry = read_polygon(path)
    domain = hcvt.Domain.from_polygon(geometry)
    n = 60
    sites = random_inside(domain, n, seed=31)
    relative = lognormal(n, seed=32)
    out = hcvt.cvt(domain, sites, volumes=relative, normalise=True)
    pinned = int(out.history["pinned"][-1])
    print(
        f"{path.stem}: {out.iterations} outer iterations, "
        f"{int(out.history['newton_steps'].sum())} Newton steps, "
        f"volume error {out.history['max_volume_error'][-1]:.1e}, "
        f"RMS gap {out.history['rms_gap'][-1]:.1e}, {pinned} pinned"
    )
    assert out.converged and out.stop_reason == "converged"
    targets = relative * (geometry.area / relative.sum())
    size = 10 * max(np.ptp(np.asarray(geometry.bounds).reshape(2, 2), axis=0))
    cells = reference_cells_2d(geometry, out.sites, out.weights, out.sites, size)
    areas = np.array([c.area for c in cells])
    np.testing.assert_array_less(np.abs(areas - targets) / targets, VOLUME_TOL)
    centroids = np.array([[c.centroid.x, c.centroid.y] for c in cells])
    gaps = rms_gap(out.sites, centroids, areas)
    # Sites pinned at a notch with their centroid outside are left out of the rule; the
    # rest are at their centroids.
    kept = np.sort(gaps)[: n - pinned]
    assert np.sqrt(np.mean(kept**2)) < GAP_TOL
    # Unequal cells: the log-normal sizes are kept, not averaged away.
    assert areas.max() / areas.min() > 2


def periodic_cell_3d(points, weights, i, period):
    """Volume and centroid of site ``i``'s power cell on the torus ``[0, period)^3``.

    Half-spaces against every image ``z_j + k period`` (k in {-1, 0, 1}^3) but site i
    itself; its own images bound the cell within half a period of the site.
    """
    z, w = points[i], weights[i]
    shifts = np.array([[a, b, c] for a in (-1, 0, 1) for b in (-1, 0, 1) for c in (-1, 0, 1)])
    images = (points[None, :, :] + period * shifts[:, None, :]).reshape(-1, 3)
    image_weights = np.tile(weights, len(shifts))
    self_index = 13 * len(points) + i  # shift (0, 0, 0) is block 13
    keep = np.arange(len(images)) != self_index
    q = images[keep] - z
    v = image_weights[keep]
    h = np.column_stack([q, -(np.einsum("ij,ij->i", q, q) + w - v) / 2 - q @ z])
    norms = np.linalg.norm(h[:, :3], axis=1)
    found = linprog(
        np.array([0, 0, 0, -1.0]),
        A_ub=np.column_stack([h[:, :3], norms]),
        b_ub=-h[:, 3],
        bounds=[(None, None)] * 4,
    )
    assert found.success and found.x[3] > 1e-6, f"cell {i} is empty"
    corners = HalfspaceIntersection(h, found.x[:3]).intersections
    hull = ConvexHull(corners)
    tets = Delaunay(corners[hull.vertices]).simplices
    p = corners[hull.vertices][tets]
    vols = (
        np.abs(
            np.einsum("ij,ij->i", p[:, 1] - p[:, 0], np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))
        )
        / 6
    )
    centroid = (vols[:, None] * p.mean(axis=1)).sum(axis=0) / vols.sum()
    return hull.volume, centroid


@pytest.mark.parametrize("method", [None, "newton"])
def test_periodic_3d_box_cells_have_their_volumes_and_sites_at_centroids(method):
    """The default L-BFGS and Newton with the weights eliminated (``"newton"``)."""
    period = 1.0
    box = hcvt.Domain.box([0, 0, 0], [period] * 3, periodic=True)
    n = 80
    sites = np.random.default_rng(33).random((n, 3))
    relative = lognormal(n, seed=34)
    out = hcvt.cvt(box, sites, method, volumes=relative, normalise=True)
    print(
        f"periodic box, {method}: {out.iterations} outer iterations, "
        f"{int(out.history['newton_steps'].sum())} Newton steps, {out.evaluations} diagrams"
    )
    if method == "newton":
        assert set(out.history["step"][1:]) <= {"newton", "lloyd"}
    assert out.converged
    assert np.all((out.sites >= 0) & (out.sites < period))
    targets = relative / relative.sum()
    found = [periodic_cell_3d(out.sites, out.weights, i, period) for i in range(n)]
    volumes = np.array([v for v, _ in found])
    centroids = np.array([c for _, c in found])
    np.testing.assert_array_less(np.abs(volumes - targets) / targets, VOLUME_TOL)
    assert np.sqrt(np.mean(rms_gap(out.sites, centroids, volumes) ** 2)) < GAP_TOL
    assert out.history["pinned"][-1] == 0


def test_bunny_cells_have_their_volumes_and_sites_at_centroids():
    bunny = hcvt.load_domain(BUNNY)
    n = 100
    sites = random_inside(bunny, n, seed=35)
    volumes = lognormal(n, seed=36)
    volumes *= bunny.volume / volumes.sum()  # exact volumes, not normalised
    out = hcvt.cvt(bunny, sites, volumes=volumes)
    assert out.converged
    again = hcvt.voronoi(bunny, out.sites, weights=out.weights)
    np.testing.assert_array_less(np.abs(again.volume - volumes) / volumes, VOLUME_TOL)
    gaps = rms_gap(out.sites, again.centroid, again.volume)
    kept = np.sort(gaps)[: n - int(out.history["pinned"][-1])]
    assert np.sqrt(np.mean(kept**2)) < GAP_TOL
    # The history: one record per outer iteration, each with its transport.
    assert len(out.history["max_volume_error"]) == out.iterations + 1
    assert out.history["max_volume_error"][-1] <= VOLUME_TOL
    assert out.history["newton_steps"][0] >= 3  # from zero weights
    assert np.median(out.history["newton_steps"][1:]) <= 3  # warm-started


def test_bourne_et_al_alternation_reaches_the_same_rule():
    """method="lloyd": transport, then sites to centroids, every step a Lloyd step."""
    box = hcvt.Domain.box([0, 0], [2, 1], periodic=True)
    n = 40
    sites = np.random.default_rng(41).random((n, 2)) * [2, 1]
    volumes = lognormal(n, seed=42)
    volumes *= 2.0 / volumes.sum()
    out = hcvt.cvt(box, sites, "lloyd", volumes=volumes)
    assert out.converged
    assert set(out.history["step"][1:]) == {"lloyd"}
    again = hcvt.voronoi(box, out.sites, weights=out.weights)
    np.testing.assert_array_less(np.abs(again.volume - volumes) / volumes, VOLUME_TOL)
    gaps = rms_gap(out.sites, again.centroid, again.volume)
    assert np.sqrt(np.mean(gaps**2)) < GAP_TOL
    fast = hcvt.cvt(box, sites, volumes=volumes)
    assert set(fast.history["step"][1:]) <= {"lbfgs", "lloyd"}
    assert fast.iterations < out.iterations


def _run(threads: int, domain, sites, volumes, method=None):
    before = hcvt.get_num_threads()
    try:
        hcvt.set_num_threads(threads)
        return hcvt.cvt(domain, sites, method, volumes=volumes, normalise=True)
    finally:
        hcvt.set_num_threads(before)


@pytest.mark.parametrize("method", [None, "newton"])
@pytest.mark.parametrize("dim", [2, 3])
def test_the_same_bits_for_a_seed_on_1_and_3_threads(dim, method):
    box = hcvt.Domain.box(np.zeros(dim), np.ones(dim), periodic=True)
    n = 150 if dim == 2 else 60
    sites = np.random.default_rng(37).random((n, dim))
    volumes = lognormal(n, seed=38)
    one, three, again = (_run(k, box, sites, volumes, method) for k in (1, 3, 1))
    for other in (three, again):
        assert np.array_equal(one.sites, other.sites)
        assert np.array_equal(one.weights, other.weights)
        assert np.array_equal(one.diagram.volume, other.diagram.volume)
        assert np.array_equal(one.history["rms_gap"], other.history["rms_gap"])


def test_volumes_as_masses_of_a_density():
    """A density: masses ∫ρ over each cell are the targets, sites at ρ-centroids."""
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    sites = random_inside(square, 40, seed=39)
    rho = hcvt.Polynomial(1.0, [2.0, 0.0])
    out = hcvt.cvt(square, sites, volumes=np.ones(40), normalise=True, density=rho)
    assert out.converged
    np.testing.assert_array_less(np.abs(out.diagram.mass - 2.0 / 40) / (2.0 / 40), VOLUME_TOL)
    # Equal masses under ρ = 1 + 2x: smaller cells on the right.
    right = out.sites[:, 0] > 0.7
    assert out.diagram.volume[right].mean() < out.diagram.volume[~right].mean()


def test_bad_volumes_are_refused_by_name():
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    sites = random_inside(square, 10, seed=40)
    ok = np.full(10, 0.1)
    with pytest.raises(ValueError, match="shape"):
        hcvt.cvt(square, sites, volumes=np.full(9, 0.1))
    with pytest.raises(ValueError, match="volume 3 is not finite"):
        hcvt.cvt(square, sites, volumes=np.where(np.arange(10) == 3, np.nan, 0.1))
    with pytest.raises(ValueError, match="volume 4 must be positive"):
        hcvt.cvt(square, sites, volumes=np.where(np.arange(10) == 4, 0.0, 0.1))
    with pytest.raises(ValueError, match="sum to"):
        hcvt.cvt(square, sites, volumes=np.full(10, 0.2))
    with pytest.raises(ValueError, match="volumes= takes method None, 'lloyd'"):
        hcvt.cvt(square, sites, "cg", volumes=ok)
    with pytest.raises(NotImplementedError, match="dask"):
        hcvt.cvt(square, sites, volumes=ok, client=object())
    # Volumes that sum right are taken as they are.
    assert hcvt.cvt(square, sites, volumes=ok, max_iter=2).weights.shape == (10,)


def test_cli_periodic_box_with_lognormal_and_file_volumes(tmp_path):
    summary = tmp_path / "run.json"
    args = ["run", "box", "--periodic", "-n", "40", "--volumes", "lognormal:0.3"]
    result = CliRunner().invoke(main, [*args, "--seed", "3", "--summary", str(summary)])
    assert result.exit_code == 0, result.output
    info = json.loads(summary.read_text())
    assert info["max_volume_error"] <= VOLUME_TOL
    assert info["rms_gap"] < GAP_TOL
    assert "max relative error" in result.output
    # The same volumes from a file (one per line), relative: the same run.
    drawn = np.random.default_rng(np.random.SeedSequence(3).spawn(1)[0]).lognormal(0, 0.3, 40)
    listed = tmp_path / "volumes.txt"
    np.savetxt(listed, drawn * 7.0)
    again = tmp_path / "again.json"
    args_file = ["run", "box", "--periodic", "-n", "40", "--volumes", str(listed)]
    result = CliRunner().invoke(main, [*args_file, "--seed", "3", "--summary", str(again)])
    assert result.exit_code == 0, result.output
    info_file = json.loads(again.read_text())
    assert info_file["iterations"] == info["iterations"]
    assert info_file["mean_G"] == pytest.approx(info["mean_G"], rel=1e-12)
    bad = CliRunner().invoke(main, ["run", "box", "-n", "40", "--volumes", "nofile.txt"])
    assert bad.exit_code != 0 and "neither lognormal" in bad.output
    helped = CliRunner().invoke(main, ["run", "--help"])
    assert "--volumes" in helped.output and "lognormal:SIGMA" in helped.output
