"""Sites held fixed in the core's optimiser: ``hcvt.cvt(..., fixed=mask)``.

Checked against what is known another way: the fixed rows are the input's bits; the free
sites' gaps ``|x_i - c_i| / sqrt(V_i)`` are recomputed here from the final diagram's
centroids and areas; the result is not the unconstrained CVT's; on the fandisk surface
the sites held are mesh vertices, the free ones converge around them.
"""

from __future__ import annotations

import numpy as np
import pytest

import hcvt
from helpers import DATA

SQUARE = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]


def square_case() -> tuple[hcvt.Domain, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    sites = rng.uniform(0.02, 0.98, size=(150, 2))
    mask = np.zeros(len(sites), dtype=bool)
    mask[::6] = True
    return hcvt.Domain.from_polygon(SQUARE), sites, mask


def free_rms_gap(res: hcvt.CVTResult, free: np.ndarray) -> float:
    """RMS of ``|x_i - c_i| / sqrt(V_i)`` over the free sites, from the final diagram."""
    offset = np.linalg.norm(res.sites - res.diagram.centroid, axis=1)
    r = offset[free] / np.sqrt(res.diagram.volume[free])
    return float(np.sqrt(np.mean(r**2)))


@pytest.mark.parametrize("method", ["lbfgs", "lloyd"])
def test_fixed_sites_hold_and_the_free_ones_converge(method: str) -> None:
    square, sites, mask = square_case()
    tol = 1e-7 if method == "lbfgs" else 1e-4
    res = hcvt.cvt(square, sites, method, tol=tol, max_iter=3000, fixed=mask)
    assert res.converged
    assert np.array_equal(res.sites[mask], sites[mask])  # bit for bit
    gap = free_rms_gap(res, ~mask)
    assert gap < tol
    # The fixed sites are far from their centroids (they never moved towards them): the
    # gap over all sites is not small, so the rule did count the free sites only.
    assert free_rms_gap(res, np.ones(len(sites), dtype=bool)) > 100 * tol
    plain = hcvt.cvt(square, sites, method, tol=tol, max_iter=3000)
    assert plain.converged
    assert np.abs(plain.sites[mask] - sites[mask]).max() > 1e-3
    assert np.abs(plain.sites - res.sites).max() > 1e-3
    # Holding sites still cannot lower the energy below the free optimum's from here.
    assert res.energy > plain.energy


def test_no_fixed_site_is_the_plain_run_bit_for_bit() -> None:
    square, sites, mask = square_case()
    plain = hcvt.cvt(square, sites, "lbfgs", max_iter=50)
    none_fixed = hcvt.cvt(square, sites, "lbfgs", max_iter=50, fixed=np.zeros_like(mask))
    assert np.array_equal(plain.sites, none_fixed.sites)
    assert np.array_equal(plain.history["energy"], none_fixed.history["energy"])


def test_fixed_sites_in_a_non_convex_polygon() -> None:
    star = hcvt.load_domain(DATA / "2d" / "star5.geojson")
    sites = hcvt.initialise(star, 300, method="random", seed=3)
    mask = np.zeros(len(sites), dtype=bool)
    mask[:40] = True
    res = hcvt.cvt(star, sites, "lbfgs", tol=1e-6, max_iter=2000, fixed=mask)
    assert res.converged
    assert np.array_equal(res.sites[mask], sites[mask])
    assert res.history["rms_gap"][-1] < 1e-6


@pytest.mark.skipif(not (DATA / "3d").is_dir(), reason="../shared/data/3d not found")
def test_fixed_sites_on_a_surface() -> None:
    fandisk = hcvt.load_domain(DATA / "3d" / "fandisk.off", surface=True)
    rng = np.random.default_rng(5)
    held = fandisk.vertices[rng.choice(len(fandisk.vertices), 40, replace=False)]
    free = hcvt.initialise(fandisk, 400, method="random", seed=5)
    sites = np.vstack([free, held])
    mask = np.arange(len(sites)) >= len(free)
    res = hcvt.cvt(fandisk, sites, "lbfgs", tol=1e-4, max_iter=400, fixed=mask)
    assert res.converged and res.history["rms_gap"][-1] < 1e-4
    assert np.array_equal(res.sites[mask], held)
    assert np.abs(res.sites[~mask] - free).max() > 1e-3  # the free ones did move
    assert res.history["energy"][-1] < res.history["energy"][0]


def test_newton_runs_when_no_site_is_fixed() -> None:
    # A mask with a site held is refused (tests/test_hostile_inputs.py); an all-False one is not.
    square, sites, mask = square_case()
    assert hcvt.cvt(square, sites, "newton", fixed=np.zeros_like(mask)).converged
