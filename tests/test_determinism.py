"""The diagram is bitwise identical for 1, 2 and 4 threads, and from one call to the next.

Work is per cell and every sum runs in index order (crate docs), so the thread count must
not change a single bit; this checks it on real polygons and meshes, with random sites and
with the degenerate ones (lattice on the boundary, sites on vertices) where ties are most
likely to depend on the order of work.
"""

from __future__ import annotations

import numpy as np
import pytest

import hcvt
from helpers import DATA, random_inside

ARRAYS = (
    "volume",
    "centroid",
    "second_moment",
    "G",
    "energy_terms",
    "gradient",
    "boundary_measure",
    "neighbor_offsets",
    "neighbor_sites",
    "neighbor_measures",
)


def _bits(d: hcvt.Diagram) -> list[bytes]:
    return [np.ascontiguousarray(getattr(d, name)).tobytes() for name in ARRAYS] + [
        np.float64(d.energy).tobytes()
    ]


def _with_threads(n: int, domain: hcvt.Domain, sites: np.ndarray) -> list[bytes]:
    before = hcvt.get_num_threads()
    try:
        hcvt.set_num_threads(n)
        return _bits(hcvt.voronoi(domain, sites, allow_outside=True))
    finally:
        hcvt.set_num_threads(before)


def _degenerate(domain: hcvt.Domain, n: int) -> np.ndarray:
    """Random sites, a lattice over the bounding box (its rows and columns on the box's
    sides) and the boundary vertices themselves."""
    lo, hi = domain.bounds
    m = 12 if domain.dim == 2 else 5
    axes = [np.linspace(lo[k], hi[k], m) for k in range(domain.dim)]
    lattice = np.stack(np.meshgrid(*axes), axis=-1).reshape(-1, domain.dim)
    vertices = np.unique(domain.vertices, axis=0)[:: max(1, len(domain.vertices) // 200)]
    sites = np.concatenate([random_inside(domain, n, seed=3), lattice, vertices])
    return np.unique(sites, axis=0)


CASES_2D = ["star5", "dejavu_sans_B", "nybb_staten_island_main", "triangle_double_hex"]
CASES_3D = ["sphere.ply", "fandisk.off", "bunny.off"]


def _domain(name: str) -> hcvt.Domain:
    path = DATA / "2d" / f"{name}.geojson" if "." not in name else DATA / "3d" / name
    if not path.exists():
        pytest.skip(f"{path} not found")
    return hcvt.load_domain(path)


@pytest.mark.parametrize("name", CASES_2D + CASES_3D)
def test_identical_bits_for_1_2_and_4_threads(name: str) -> None:
    domain = _domain(name)
    n = 20_000 if domain.dim == 2 else 4000
    for sites in (random_inside(domain, n, seed=11), _degenerate(domain, n // 5)):
        one = _with_threads(1, domain, sites)
        assert _with_threads(2, domain, sites) == one
        assert _with_threads(4, domain, sites) == one
        assert _with_threads(4, domain, sites) == one  # and again: no scheduling effect


def _in_threads(n: int, run):
    before = hcvt.get_num_threads()
    try:
        hcvt.set_num_threads(n)
        return run()
    finally:
        hcvt.set_num_threads(before)


@pytest.mark.parametrize("shape", ["star", "ball"])
def test_cvt_hierarchy_and_initialisations_do_not_depend_on_threads(shape):
    from hcvt.geometry.shapes import builtin_domain

    domain = builtin_domain(shape)
    n = 600 if domain.dim == 2 else 200

    def run() -> list[bytes]:
        out = [
            hcvt.initialise(domain, n, method=m, seed=5).tobytes()
            for m in ("random", "halton", "hammersley", "lattice")
        ]
        start = hcvt.initialise(domain, n, method="random", seed=5)
        out.append(hcvt.cvt(domain, start, method="lbfgs", max_iter=60).sites.tobytes())
        out.append(hcvt.cvt(domain, start, method="lloyd", max_iter=30).sites.tobytes())
        out.append(hcvt.hierarchical_cvt(domain, n, 2, seed=5, max_iter=60).sites.tobytes())
        return out

    one, two, four = (_in_threads(k, run) for k in (1, 2, 4))
    assert one == two == four
