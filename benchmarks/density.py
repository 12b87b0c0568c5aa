"""Time diagrams and CVTs with a density ρ (issue 17, DESIGN §8) against the uniform ones.

One run, the same sites for every variant:

- a diagram with no density, with a quadratic ρ (exact, in the core), and with the same ρ
  as a Python callable sampled by the degree-2 rule (one call per diagram), at 100k sites
  in the unit square and 50k in the ball (``sphere.ply``); medians and ratios to uniform;
- pysdot 0.2 (the peer with a density in 2D: an image, piecewise constant on pixels) on
  the same 2D sites, ρ sampled on a 512 x 512 image of the square;
- a graded CVT (L-BFGS to the default rule, RMS gap < 1e-7) of 100k sites in 2D and 20k
  in 3D with the quadratic ρ, from sites initialised ∝ ρ^(d/(d+2)) (``--cvt``).

    OPENBLAS_NUM_THREADS=1 python benchmarks/density.py [--quick] [--cvt]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import time
from pathlib import Path

import numpy as np

import hcvt
from hcvt.density import Polynomial
from timing import median_seconds

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
# ρ from 1 to 100 across each domain.
RHO = {
    2: Polynomial(1.0, [0.0, 0.0], [[99.0, 0.0], [0.0, 0.0]]),  # square [0, 1]²
    3: Polynomial(30.25, [49.5, 0, 0], [[20.25, 0, 0], [0, 0, 0], [0, 0, 0]]),  # ball, x in ±1
}


def domains() -> dict[int, hcvt.Domain]:
    return {
        2: hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)]),
        3: hcvt.load_domain(DATA / "3d" / "sphere.ply"),
    }


def time_diagrams(dim: int, domain: hcvt.Domain, n: int, repeats: int) -> None:
    sites = hcvt.initialise(domain, n, seed=0)
    rho = RHO[dim]
    uniform = median_seconds(lambda: hcvt.voronoi(domain, sites), repeats)
    poly = median_seconds(lambda: hcvt.voronoi(domain, sites, density=rho), repeats)
    sampled = median_seconds(
        lambda: hcvt.voronoi(domain, sites, density=rho.__call__, quadrature_degree=2), repeats
    )
    print(f"{dim}D, {n} sites: uniform {uniform:.3f} s")
    print(f"  quadratic rho (exact)     {poly:.3f} s  x{poly / uniform:.2f} of uniform")
    print(f"  callable rho, degree 2    {sampled:.3f} s  x{sampled / uniform:.2f} of uniform")
    if dim == 2:
        time_pysdot(sites, rho, poly, repeats)


def time_pysdot(sites: np.ndarray, rho: Polynomial, ours: float, repeats: int) -> None:
    try:
        from pysdot import PowerDiagram
        from pysdot.domain_types import ScaledImage
    except ImportError:  # pragma: no cover - optional peer
        print("  pysdot not installed")
        return
    k = 512
    centres = (np.arange(k) + 0.5) / k
    xx, yy = np.meshgrid(centres, centres)  # image rows run along y
    image = rho(np.column_stack([xx.ravel(), yy.ravel()])).reshape(k, k)
    domain = ScaledImage([0.0, 0.0], [1.0, 1.0], image / image.mean())

    def run() -> None:
        pd = PowerDiagram(sites, np.zeros(len(sites)), domain)
        pd.integrals()
        pd.centroids()

    peer = median_seconds(run, repeats)
    print(
        f"  pysdot, {k}x{k} image rho   {peer:.3f} s  (hcvt quadratic rho x{ours / peer:.2f} "
        "of pysdot's time)"
    )


def time_cvt(dim: int, domain: hcvt.Domain, n: int) -> None:
    rho = RHO[dim]
    sites = hcvt.initialise(domain, n, seed=0, density=rho)
    start = time.perf_counter()
    res = hcvt.cvt(domain, sites, density=rho)
    seconds = time.perf_counter() - start
    print(
        f"{dim}D graded CVT, {n} sites: {seconds:.1f} s, {res.evaluations} diagrams, "
        f"{res.stop_reason}, RMS gap {res.history['rms_gap'][-1]:.1e}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10x fewer sites, 1 repeat")
    parser.add_argument("--cvt", action="store_true", help="also time the graded CVTs")
    args = parser.parse_args()
    scale = 10 if args.quick else 1
    repeats = 1 if args.quick else 5
    print(f"hcvt threads: {hcvt.get_num_threads()}")
    doms = domains()
    time_diagrams(2, doms[2], 100_000 // scale, repeats)
    time_diagrams(3, doms[3], 50_000 // scale, repeats)
    if args.cvt:
        time_cvt(2, doms[2], 100_000 // scale)
        time_cvt(3, doms[3], 20_000 // scale)


if __name__ == "__main__":
    main()
