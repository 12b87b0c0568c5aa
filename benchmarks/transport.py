"""Time semi-discrete optimal transport (equal masses, uniform density) against pysdot.

The same uniform random sites in the unit square, every cell's target the same mass 1/n,
through ``hcvt.optimal_transport`` and pysdot 0.2.16's ``OptimalTransport`` (its
``ConvexPolyhedraAssembly`` unit box, added with ``cut_id=2**64-1``: its default ``-1``
raises ``OverflowError`` under numpy 2). Both are asked for the same accuracy: hcvt's
``tol`` is the largest relative mass error, pysdot's ``max delta masses`` the largest
absolute one, set to ``tol / n``. Prints each code's seconds, Newton steps and largest
relative mass error measured afterwards (pysdot's from its own ``integrals()``), and the
ratio pysdot / hcvt; for hcvt also its power diagrams and conjugate-gradient iterations.

hcvt's linear solver: conjugate gradients preconditioned by the diagonal on the graph
Laplacian, in the core, solved to a per-cell residual that shrinks with the mass error
(inexact Newton); pysdot's: the first of PETSc, then scipy that imports (printed).

Both run in this process one after the other on one thread (``hcvt.set_num_threads(1)``;
pysdot is single-threaded). The machine is shared with other jobs: timings are "under
load" unless the machine is idle.

    OPENBLAS_NUM_THREADS=1 python benchmarks/transport.py [--sizes 10000 100000] [--tol 1e-10]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import time

import numpy as np

import hcvt


def run_hcvt(sites: np.ndarray, tol: float) -> tuple[float, int, float, int, int]:
    """Seconds, Newton steps, largest relative mass error, CG iterations and diagrams of hcvt.

    The diagrams count the first one, at zero weights.
    """
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    n = len(sites)
    start = time.perf_counter()
    out = hcvt.optimal_transport(square, sites, np.full(n, 1.0 / n), tol=tol)
    seconds = time.perf_counter() - start
    error = float(np.max(np.abs(out.diagram.mass * n - 1.0)))
    cg = int(out.history["cg_iterations"].sum())
    diagrams = int(out.history["diagrams"].sum()) + 1
    return seconds, out.iterations, error, cg, diagrams


def run_pysdot(sites: np.ndarray, tol: float) -> tuple[float, int, float, str]:
    """Seconds, Newton steps, largest relative mass error and linear solver of pysdot."""
    from pysdot import OptimalTransport
    from pysdot.domain_types import ConvexPolyhedraAssembly

    n = len(sites)
    domain = ConvexPolyhedraAssembly()
    domain.add_box([0, 0], [1, 1], cut_id=2**64 - 1)
    ot = OptimalTransport(sites, domain=domain, masses=np.full(n, 1.0 / n))
    ot.set_stopping_criterion(tol / n, "max delta masses")
    start = time.perf_counter()
    ot.adjust_weights()
    seconds = time.perf_counter() - start
    error = float(np.max(np.abs(ot.pd.integrals() * n - 1.0)))
    solver = type(ot._get_linear_solver()).__module__
    return seconds, len(ot.delta_m), error, solver


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--tol", type=float, default=1e-10)
    args = parser.parse_args()
    hcvt.set_num_threads(1)
    print(f"equal masses in the unit square, tol {args.tol:g} (relative), one thread, under load")
    for n in args.sizes:
        sites = np.random.default_rng(0).random((n, 2))
        h_time, h_steps, h_error, h_cg, h_diagrams = run_hcvt(sites, args.tol)
        p_time, p_steps, p_error, solver = run_pysdot(sites, args.tol)
        print(
            f"n={n:>7}  hcvt {h_time:8.3f} s ({h_steps} Newton steps, {h_diagrams} diagrams, "
            f"{h_cg} CG iterations, max rel. error {h_error:.1e})  pysdot {p_time:8.3f} s "
            f"({p_steps} steps, max rel. error "
            f"{p_error:.1e}, {solver})  pysdot/hcvt {p_time / h_time:.2f}"
        )


if __name__ == "__main__":
    main()
