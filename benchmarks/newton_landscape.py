"""Where a Newton CVT's diagrams go, and whether the one trust region couples the sites.

Two load-independent measures (diagram counts; the same on any number of threads) behind
``docs/results/newton_variants.txt`` round 7:

``phases``: from random sites to the paper's rule ``‖g‖/‖X‖ < 1e-10`` (input
coordinates), the diagrams spent until the RMS gap first falls below 1e-2, 1e-3, 1e-4 and
1e-5, per case and seed. Most of a run is the stretch where cells rearrange.

``decoupled``: ``--squares`` 20 x 20 squares 20 apart (a MultiPolygon: no cell reaches
across a gap), each with the random sites of its own single run (seeds ``first + k``),
Newton to RMS gap ``--tol`` (scale-free, so that the far-apart copies do not change the
rule). If one radius and one acceptance for all sites coupled independent
rearrangements, the joint run would need more diagrams than its slowest part.

    OPENBLAS_NUM_THREADS=1 python benchmarks/newton_landscape.py phases [--cases star10k]
        [--seeds 0 3]
    OPENBLAS_NUM_THREADS=1 python benchmarks/newton_landscape.py decoupled [--squares 5]
        [--first 0 5] [--n 1000]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse

import numpy as np
from shapely.geometry import MultiPolygon, Polygon, box

import hcvt
from hcvt.geometry import shapes
from newton_variants import CASES

LEVELS = (1e-2, 1e-3, 1e-4, 1e-5)
SIDE = 20.0  # the paper's square
GAP = 20.0  # between two squares: many spacings, so no cell reaches across


def diagrams_by_level(run: hcvt.CVTResult) -> list[int | None]:
    """Diagrams ``run`` spent until its RMS gap first fell below each of ``LEVELS``."""
    gaps = np.asarray(run.history["rms_gap"])
    spent = np.asarray(run.history["evaluations"])
    out: list[int | None] = []
    for level in LEVELS:
        below = np.flatnonzero(gaps < level)
        out.append(int(spent[below[0]]) if below.size else None)
    return out


def phases(cases: list[str], seeds: list[int]) -> None:
    print("case        seed  " + "  ".join(f"<{lv:.0e}" for lv in LEVELS) + "  total")
    for name in cases:
        make, n, _ = CASES[name]
        domain = make()
        for seed in seeds:
            sites = hcvt.initialise(domain, n, method="random", seed=seed)
            run = hcvt.cvt(domain, sites, method="newton", rule="paper", tol=1e-10)
            levels = diagrams_by_level(run)
            cells = "  ".join(f"{'-' if v is None else v:>5}" for v in levels)
            print(f"{name:<10} {seed:>5}  {cells}  {run.history['evaluations'][-1]:>5}")


def square_at(k: int) -> Polygon:
    """The ``k``-th square, ``k (SIDE + GAP)`` along x."""
    x = k * (SIDE + GAP)
    return box(x, 0.0, x + SIDE, SIDE)


def newton_diagrams(domain: hcvt.Domain, sites: np.ndarray, tol: float) -> int:
    run = hcvt.cvt(domain, sites, method="newton", rule="gap", tol=tol)
    return int(run.history["evaluations"][-1])


def decoupled(squares: int, firsts: list[int], n: int, tol: float) -> None:
    square = shapes.square()
    for first in firsts:
        singles, parts, all_sites = [], [], []
        for k in range(squares):
            sites = hcvt.initialise(square, n, method="random", seed=first + k)
            sites = sites + np.array([k * (SIDE + GAP), 0.0])
            part = square_at(k)
            singles.append(newton_diagrams(hcvt.Domain.from_polygon(part), sites, tol))
            parts.append(part)
            all_sites.append(sites)
        joint = newton_diagrams(
            hcvt.Domain.from_polygon(MultiPolygon(parts)), np.concatenate(all_sites), tol
        )
        print(
            f"{squares} squares of {n} sites, seeds {first}-{first + squares - 1}: "
            f"single runs {singles} (max {max(singles)}), together {joint}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="what", required=True)
    p = sub.add_parser("phases")
    p.add_argument("--cases", nargs="+", default=["square5k", "star10k", "ball5k"])
    p.add_argument("--seeds", nargs="+", type=int, default=[0])
    d = sub.add_parser("decoupled")
    d.add_argument("--squares", type=int, default=5)
    d.add_argument("--first", nargs="+", type=int, default=[0, 5])
    d.add_argument("--n", type=int, default=1000)
    d.add_argument("--tol", type=float, default=1e-8)
    args = parser.parse_args()
    if args.what == "phases":
        phases(args.cases, args.seeds)
    else:
        decoupled(args.squares, args.first, args.n, args.tol)


if __name__ == "__main__":
    main()
