"""Newton's method on triangle surfaces (issue 33): the restricted CVT's exact Hessian.

The Hessian's arcs are weighted by the slope of each bisector against each triangle
(``diagram/surface/measure.rs``, ``HessianArcs``); the core checks it against central differences
of the gradient on the bunny, closed and cut open (``optimise/hessian.rs``, where the flat
weight ``2/|q|`` fails the same check). Here: Newton through :func:`hcvt.cvt`.
"""

from __future__ import annotations

import numpy as np
import pytest

import hcvt
from hcvt.geometry.surface_points import closest_points
from hcvt.optimise import fastest_method
from helpers import DATA

DATA_3D = DATA / "3d"
needs_data = pytest.mark.skipif(not DATA_3D.is_dir(), reason="../shared/data/3d not found")


@needs_data
def test_newton_reaches_the_default_rule_in_fewer_diagrams_than_lbfgs() -> None:
    domain = hcvt.load_domain(DATA_3D / "bunny.off", surface=True)
    start = hcvt.initialise(domain, 100, seed=3)
    newton = hcvt.cvt(domain, start, "newton", max_iter=1000)
    lbfgs = hcvt.cvt(domain, start, "lbfgs", max_iter=1000)
    diagrams = {
        m: int(r.history["evaluations"][-1]) for m, r in [("newton", newton), ("lbfgs", lbfgs)]
    }
    print(f"bunny, 100 sites, to RMS gap 1e-7: diagrams {diagrams}")
    assert newton.converged and lbfgs.converged
    assert newton.history["rms_gap"][-1] < 1e-7
    assert set(newton.history["step"][1:]) == {"newton"}
    assert 2 * diagrams["newton"] < diagrams["lbfgs"], diagrams
    nearest, _ = closest_points(domain.vertices, domain.faces, newton.sites)
    assert np.abs(nearest - newton.sites).max() <= 1e-12
    assert fastest_method(domain) == "newton"


@needs_data
def test_newton_converges_on_an_open_surface() -> None:
    # The scan: five holes in its base, whose border does not move with the sites.
    domain = hcvt.load_domain(DATA_3D / "bad/stanford-bunny.obj", surface=True)
    res = hcvt.cvt(domain, hcvt.initialise(domain, 100, seed=4), "newton", max_iter=300)
    assert res.converged, res.stop_reason
    assert res.history["energy"][-1] < 0.7 * res.history["energy"][0]
