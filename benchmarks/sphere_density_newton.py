"""Newton against L-BFGS on the sphere with a callable density (issue 35).

The 4:1 meridian band of ``tests/test_sphere_density.py`` (MPAS style, ``ρ = (h_fine/h)⁴``
through :class:`hcvt.density.SizingField`) on the Earth (R = 6371 km): 200/800 km cells
(~2,600 sites) and 100/400 km (~10,300). From the same graded random start
(``hcvt.initialise(..., "random", density=)``, seeds 0-2) each method runs until both the
default rule (RMS gap < 1e-7) and the paper's (``‖g‖/‖X‖ < 1e-10`` in km) have held, up
to ``--max-iter`` iterations; the rule does not steer the steps, so the first record where
a rule holds is where a run with that rule would have stopped. The table has the medians
over the seeds of the diagrams and seconds to each rule, and their ratios L-BFGS / Newton
(above 1: Newton is faster). A run that stopped short of a rule is counted with its whole
cost and flagged (``*``): its figures are then lower bounds.

Usage: ``python benchmarks/sphere_density_newton.py [--seeds 3] [--sizes 200,100]``.
Timings on a shared machine: label them "under load" when other jobs run.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

import hcvt
from hcvt.density import SizingField
from hcvt.seeding.sphere import cells_for_width, meridian_band_width

EARTH = 6371.0  # km
GAP_TOL, PAPER_TOL = 1e-7, 1e-10


def band(fine: float) -> SizingField:
    """The 4:1 band: ``fine`` km within 10° of the Greenwich meridian, ``4 · fine`` far."""
    return SizingField(lambda p: meridian_band_width(p, fine, 4.0 * fine))


def run(sites: np.ndarray, density: SizingField, method: str, max_iter: int) -> dict:
    """Per rule, the diagrams and seconds until it first held (or the run's, flagged)."""
    earth = hcvt.Domain.sphere(EARTH)
    state = {"gap": None, "paper": None}
    start = time.perf_counter()

    def watch(info: dict) -> bool:
        now = (int(info["evaluations"]), time.perf_counter() - start, True)
        if state["gap"] is None and info["rms_gap"] < GAP_TOL:
            state["gap"] = now
        if state["paper"] is None and info["grad_norm"] < PAPER_TOL:
            state["paper"] = now
        return state["gap"] is not None and state["paper"] is not None

    out = hcvt.cvt(
        earth, sites, method=method, density=density, tol=1e-30, max_iter=max_iter, callback=watch
    )
    whole = (int(out.history["evaluations"][-1]), time.perf_counter() - start, False)
    return {rule: state[rule] or whole for rule in state}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--sizes", default="200,100", help="fine cell widths, km")
    parser.add_argument("--max-iter", type=int, default=3000)
    args = parser.parse_args()
    print(f"{'n':>7} {'rule':>6} {'method':>7} {'diagrams':>9} {'seconds':>9}  per seed")
    for fine in (float(f) for f in args.sizes.split(",")):
        density = band(fine)
        n = cells_for_width(lambda p, f=fine: meridian_band_width(p, f, 4.0 * f), EARTH)
        earth = hcvt.Domain.sphere(EARTH)
        starts = [
            hcvt.initialise(earth, n, method="random", seed=s, density=density)
            for s in range(args.seeds)
        ]
        runs = {m: [run(s, density, m, args.max_iter) for s in starts] for m in ("newton", "lbfgs")}
        for rule in ("gap", "paper"):
            medians = {}
            for method, rows in runs.items():
                per_rule = [r[rule] for r in rows]
                diagrams = statistics.median(r[0] for r in per_rule)
                seconds = statistics.median(r[1] for r in per_rule)
                medians[method] = (diagrams, seconds)
                each = " ".join(f"{d}/{s:.1f}s{'' if ok else '*'}" for d, s, ok in per_rule)
                print(f"{n:>7} {rule:>6} {method:>7} {diagrams:>9.0f} {seconds:>9.2f}  {each}")
            (nd, ns), (ld, ls) = medians["newton"], medians["lbfgs"]
            print(f"{n:>7} {rule:>6} {'ratio':>7} {ld / nd:>9.2f} {ls / ns:>9.2f}  L-BFGS / Newton")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
