"""The global Monte-Carlo baseline of Lu et al. (2012), as reconstructed in hcvt.baselines."""

from __future__ import annotations

import numpy as np
import pytest

import hcvt
from hcvt.shapes import square


@pytest.fixture(scope="module")
def square_run():
    domain = square()
    start = hcvt.initialise(domain, 1033, method="random", seed=3)
    plain = hcvt.cvt(domain, start, method="lbfgs", tol=1e-10)
    mc = hcvt.global_monte_carlo(domain, start, updates=40, seed=3, tol=1e-10)
    return domain, plain, mc


def test_energy_never_goes_up_over_accepted_updates(square_run):
    _, _, mc = square_run
    kept = mc.history.best_energy
    assert len(kept) == 41
    assert np.all(np.diff(kept) <= 0)
    # An accepted update is one whose local minimum is lower than what was kept before.
    accepted = np.flatnonzero(mc.history.accepted[1:]) + 1
    np.testing.assert_array_equal(kept[accepted], mc.history.energy[accepted])
    assert np.all(mc.history.energy[accepted] < kept[accepted - 1])
    assert mc.accepted > 0
    assert mc.diagram.energy == kept[-1]


def test_more_regular_than_plain_lbfgs_from_the_same_start(square_run):
    # Paper Table 4: global Monte-Carlo 0.08075 against random + L-BFGS 0.08101.
    _, plain, mc = square_run
    assert mc.diagram.energy < plain.diagram.energy
    assert mc.diagram.mean_G < plain.diagram.mean_G
    assert mc.sites.shape == (1033, 2)


def test_perturbed_sites_stay_inside_a_non_convex_domain():
    from hcvt.baselines import perturb
    from hcvt.shapes import star

    domain = star()
    sites = hcvt.initialise(domain, 500, method="random", seed=0)
    rng = np.random.default_rng(0)
    for _ in range(50):
        sites = perturb(domain, sites, rng, radius=3.0, step=1.0)
        assert domain.contains(sites).all()


def test_bad_update_count_is_refused():
    domain = square()
    sites = hcvt.initialise(domain, 20, method="random", seed=0)
    with pytest.raises(ValueError, match="updates"):
        hcvt.global_monte_carlo(domain, sites, updates=-1)
