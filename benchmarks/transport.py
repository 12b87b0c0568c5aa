"""Time semi-discrete optimal transport (equal masses, uniform density) against pysdot.

The same uniform random sites in the unit square (or the L-shape ``[0,2]² ∖ (1,2]²``),
every cell's target the same mass, through ``hcvt.optimal_transport`` and pysdot 0.2.16's
``OptimalTransport`` (its ``ConvexPolyhedraAssembly`` of one box, or two for the L, added
with ``cut_id=2**64-1``: its default ``-1`` raises ``OverflowError`` under numpy 2). Both
are asked for the same accuracy: hcvt's ``tol`` is the largest relative mass error,
pysdot's ``max delta masses`` the largest absolute one, set to ``tol`` times the target
mass. Prints each code's seconds, Newton steps and largest relative mass error measured
afterwards (pysdot's from its own ``integrals()``), and the ratio pysdot / hcvt; for hcvt
also its power diagrams and conjugate-gradient iterations. No density: pysdot takes
piecewise-constant or image densities, hcvt polynomial and sampled ones.

hcvt's linear solver: in 2D a sparse Cholesky factorisation (faer, AMD ordering) of the
graph Laplacian at the first Newton step, in the core, then conjugate gradients
preconditioned by that factor (refactorised when they fall short); conjugate gradients
preconditioned by the diagonal where the factor would be too full (3D) or the face graph
is not connected. The CG iterations printed are those of both. pysdot's: the first of
PETSc, then scipy that imports (printed).

Both run in this process one after the other, after an untimed warm-up of both on 1,000
sites, on the same cores: by default all of the machine's (hcvt's default threads; pysdot
runs its own thread pool: it is not single-threaded, at 10k it used ~1.45 cores), with
``--cores 1`` every thread of the process pinned to one CPU and hcvt on one thread
(``timing.use_cores``). Each code's CPU seconds are printed beside its wall seconds (their
ratio is the cores it used). Until 2026-12-04 this script pinned hcvt alone to one thread
and left pysdot its pool. The machine is shared with other jobs: timings are "under load"
unless the machine is idle; compare the ratios, measured in the same run.

With ``--repeats R`` each code runs R times on the same sites, alternating, and the
medians are printed (a single 10k run swings by +-15% on a quiet machine).

    OPENBLAS_NUM_THREADS=1 python benchmarks/transport.py [--sizes 10000 100000]
        [--domains square lshape] [--tol 1e-10] [--repeats 1] [--cores 1]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import time

import numpy as np

import hcvt
from timing import cpu_seconds, use_cores

# Each domain: hcvt's polygon, pysdot's boxes (lower and upper corners) and its area.
DOMAINS = {
    "square": ([(0, 0), (1, 0), (1, 1), (0, 1)], [([0, 0], [1, 1])], 1.0),
    "lshape": (
        [(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)],
        [([0, 0], [2, 1]), ([0, 1], [1, 2])],
        3.0,
    ),
}


def random_sites(name: str, n: int) -> np.ndarray:
    """``n`` uniform random points in the domain ``name`` (seed 0, rejection in its box)."""
    rng = np.random.default_rng(0)
    if name == "square":
        return rng.random((n, 2))
    found = np.empty((0, 2))
    while len(found) < n:
        p = 2 * rng.random((2 * n, 2))
        found = np.vstack([found, p[(p[:, 0] < 1) | (p[:, 1] < 1)]])
    return found[:n]


def run_hcvt(name: str, sites: np.ndarray, tol: float) -> tuple[float, float, int, float, int, int]:
    """Wall and CPU seconds, Newton steps, max relative mass error, CG iterations, diagrams.

    hcvt's; the diagrams count the first one, at zero weights.
    """
    polygon, _, area = DOMAINS[name]
    domain = hcvt.Domain.from_polygon(polygon)
    n = len(sites)
    start, cpu = time.perf_counter(), cpu_seconds()
    out = hcvt.optimal_transport(domain, sites, np.full(n, area / n), tol=tol)
    seconds, cpu = time.perf_counter() - start, cpu_seconds() - cpu
    error = float(np.max(np.abs(out.diagram.mass * n / area - 1.0)))
    cg = int(out.history["cg_iterations"].sum())
    diagrams = int(out.history["diagrams"].sum()) + 1
    return seconds, cpu, out.iterations, error, cg, diagrams


def run_pysdot(name: str, sites: np.ndarray, tol: float) -> tuple[float, float, int, float, str]:
    """Wall and CPU seconds, Newton steps, max relative mass error, linear solver: pysdot's."""
    from pysdot import OptimalTransport
    from pysdot.domain_types import ConvexPolyhedraAssembly

    _, boxes, area = DOMAINS[name]
    n = len(sites)
    domain = ConvexPolyhedraAssembly()
    for lo, hi in boxes:
        domain.add_box(lo, hi, cut_id=2**64 - 1)
    ot = OptimalTransport(sites, domain=domain, masses=np.full(n, area / n))
    ot.set_stopping_criterion(tol * area / n, "max delta masses")
    start, cpu = time.perf_counter(), cpu_seconds()
    ot.adjust_weights()
    seconds, cpu = time.perf_counter() - start, cpu_seconds() - cpu
    error = float(np.max(np.abs(ot.pd.integrals() * n / area - 1.0)))
    solver = type(ot._get_linear_solver()).__module__
    return seconds, cpu, len(ot.delta_m), error, solver


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--domains", nargs="+", choices=list(DOMAINS), default=["square"])
    parser.add_argument("--tol", type=float, default=1e-10)
    parser.add_argument("--repeats", type=int, default=1, help="runs of each; medians printed")
    parser.add_argument(
        "--cores", type=int, default=None, help="pin both codes to this many CPUs (default: all)"
    )
    args = parser.parse_args()
    cores = use_cores(args.cores)
    if args.cores is not None:
        hcvt.set_num_threads(args.cores)
    print(
        f"equal masses, tol {args.tol:g} (relative), {cores}, under load, "
        f"median of {max(1, args.repeats)} run(s) each"
    )
    # Untimed warm-up of both codes: the process's first transport paid one-time set-up
    # (square 10k read 1.12x pysdot first, 1.60x second in one quiet run).
    warm = random_sites("square", 1_000)
    run_hcvt("square", warm, args.tol)
    run_pysdot("square", warm, args.tol)
    for name in args.domains:
        for n in args.sizes:
            sites = random_sites(name, n)
            h_runs, p_runs = [], []
            for _ in range(max(1, args.repeats)):
                h_time, h_cpu, h_steps, h_error, h_cg, h_diagrams = run_hcvt(name, sites, args.tol)
                p_time, p_cpu, p_steps, p_error, solver = run_pysdot(name, sites, args.tol)
                h_runs.append((h_time, h_cpu))
                p_runs.append((p_time, p_cpu))
            (h_time, h_cpu), (p_time, p_cpu) = np.median(h_runs, axis=0), np.median(p_runs, axis=0)
            print(
                f"{name:>6} n={n:>7}  hcvt {h_time:8.3f} s (CPU {h_cpu:.3f} s; {h_steps} Newton "
                f"steps, {h_diagrams} diagrams, {h_cg} CG iterations, max rel. error "
                f"{h_error:.1e})  pysdot {p_time:8.3f} s (CPU {p_cpu:.3f} s; {p_steps} steps, "
                f"max rel. error {p_error:.1e}, {solver})  pysdot/hcvt {p_time / h_time:.2f}"
            )


if __name__ == "__main__":
    main()
