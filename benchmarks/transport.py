"""Time semi-discrete optimal transport (equal masses) against pysdot, uniform or polynomial.

The same random sites in the unit square (or the L-shape ``[0,2]² ∖ (1,2]²``), uniform
(or drawn from the density, below), every cell's target the same mass, through
``hcvt.optimal_transport`` and pysdot 0.2.16's ``OptimalTransport`` (its
``ConvexPolyhedraAssembly`` of one box, or two for the L, added with ``cut_id=2**64-1``:
its default ``-1`` raises ``OverflowError`` under numpy 2). Both are asked for the same
accuracy: hcvt's ``tol`` is the largest relative mass error, pysdot's ``max delta
masses`` the largest absolute one, set to ``tol`` times the target mass. Prints each
code's seconds, Newton steps and largest relative mass error measured afterwards
(pysdot's from its own ``integrals()``), and the ratio pysdot / hcvt; for hcvt also its
power diagrams and conjugate-gradient iterations. Each pysdot row also gives the
mass error of pysdot's final weights measured independently by hcvt (``hcvt.voronoi`` of
the power diagram of those weights, the same convention: cell i the points where
``|x - z_i|² - w_i`` is least; the two codes' masses of one set of weights agree to 1e-14).

``--density poly`` (or ``uniform poly``) adds rows with the density
``ρ = 1 + x + 2y²`` (``POLYNOMIAL``; 1 to 4 on the square, 1 to 11 on the L-shape):
every cell's target the domain's mass ``∫ρ`` (exact, over the boxes) over n, the same
sites and targets for both codes, each exact. hcvt takes ``density=POLYNOMIAL`` (its
masses and Hessian exact). pysdot 0.2.16 has no polynomial in ``ConvexPolyhedraAssembly``
(``add_box`` takes one constant a box), but its ``ScaledImage(min, max, img)`` takes
``img`` of shape (6, rows, columns): one polynomial a pixel, coefficients of
``1, x, y, x², xy, y²`` in absolute coordinates (the order checked against hcvt's masses
with six different coefficients; another count of coefficients, or the coefficients on
the last axis, aborts the process: "ScaledImage.tcc:62: assertion 0 not checked"). So
pysdot is given the exact polynomial too: one pixel for the square, 2 x 2 unit pixels
over ``[0, 2]²`` for the L-shape with the pixel ``(1, 2]²`` zero (pysdot's cells then
reach into the notch with no mass there: the L-shape's transport problem exactly). No
pixelation error on either side: the errors printed are both against the true masses.

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
        [--domains square lshape] [--density uniform poly] [--tol 1e-10] [--repeats 1]
        [--cores 1]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import time

import numpy as np

import hcvt
from timing import cpu_seconds, use_cores

# Each domain: hcvt's polygon, pysdot's boxes (lower and upper corners, integers: unions of
# unit pixels for the polynomial's image) and its area.
DOMAINS = {
    "square": ([(0, 0), (1, 0), (1, 1), (0, 1)], [([0, 0], [1, 1])], 1.0),
    "lshape": (
        [(0, 0), (2, 0), (2, 1), (1, 1), (1, 2), (0, 2)],
        [([0, 0], [2, 1]), ([0, 1], [1, 2])],
        3.0,
    ),
}

#: The density of ``--density poly``: of degree 2, positive on both domains.
POLYNOMIAL = hcvt.Polynomial.parse("1 + x + 2*y^2")
DENSITIES = {"uniform": None, "poly": POLYNOMIAL}


def domain_mass(name: str, density: hcvt.Polynomial | None) -> float:
    """``∫ρ`` over the domain ``name`` (its area without a density), exact, box by box.

    On each box the 2 x 2 Gauss–Legendre rule (nodes ``mid ± half / √3``), exact for
    degree 3 in each coordinate.
    """
    _, boxes, area = DOMAINS[name]
    if density is None:
        return area
    total = 0.0
    for lo, hi in boxes:
        mid, half = (np.add(lo, hi)) / 2, (np.subtract(hi, lo)) / 2
        offsets = np.array([[-1, -1], [-1, 1], [1, -1], [1, 1]]) / np.sqrt(3)
        total += float(np.mean(density(mid + offsets * half))) * np.prod(2 * half)
    return total


def pysdot_domain(name: str, density: hcvt.Polynomial | None) -> object:
    """The pysdot domain ``name``: its boxes, or with a polynomial density an exact image.

    The image is of unit pixels over ``[0, size]²`` (size the boxes' largest corner), each
    pixel inside a box holding the polynomial's coefficients of ``1, x, y, x², xy, y²``,
    the others zero: shape (6, rows, columns), row ``i`` the pixel ``y ∈ [i, i + 1]``.
    """
    from pysdot.domain_types import ConvexPolyhedraAssembly, ScaledImage

    _, boxes, _ = DOMAINS[name]
    if density is None:
        domain = ConvexPolyhedraAssembly()
        for lo, hi in boxes:
            domain.add_box(lo, hi, cut_id=2**64 - 1)
        return domain
    constant, linear, quadratic = density.coefficients(2)
    coefficients = [constant, *linear, quadratic[0][0], 2 * quadratic[0][1], quadratic[1][1]]
    size = int(max(max(hi) for _, hi in boxes))
    image = np.zeros((6, size, size))
    for lo, hi in boxes:
        image[:, lo[1] : hi[1], lo[0] : hi[0]] = np.reshape(coefficients, (6, 1, 1))
    return ScaledImage([0.0, 0.0], [float(size), float(size)], image)


def random_sites(name: str, n: int, density: hcvt.Polynomial | None = None) -> np.ndarray:
    """``n`` random points in the domain ``name`` (seed 0), shape (n, 2).

    Uniform without a density (rejection in the domain's box); with one, drawn from ρ
    (a point of the box kept with probability ρ / max ρ, the largest value at a corner of
    the box as ρ is convex), so that the Voronoi diagram's masses start near the equal
    targets as they do without a density. (Uniform sites with equal masses under
    ``POLYNOMIAL`` leave neither code converged at 10k on the L-shape: the mass has to
    cross the domain; docs/results/transport.txt §18.)
    """
    rng = np.random.default_rng(0)
    if name == "square" and density is None:
        return rng.random((n, 2))
    _, boxes, _ = DOMAINS[name]
    size = max(max(hi) for _, hi in boxes)
    if density is not None:
        if np.any(np.linalg.eigvalsh(density.coefficients(2)[2]) < 0):
            raise ValueError(f"{density!r} is not convex: its largest value may be inside")
        top = float(np.max(density(np.array([[0, 0], [0, size], [size, 0], [size, size]]))))
    found = np.empty((0, 2))
    while len(found) < n:
        p = size * rng.random((2 * n, 2))
        keep = np.zeros(len(p), dtype=bool)
        for lo, hi in boxes:
            keep |= np.all((p >= lo) & (p < hi), axis=1)
        if density is not None:
            keep &= rng.random(len(p)) * top < density(p)
        found = np.vstack([found, p[keep]])
    return found[:n]


def run_hcvt(
    name: str, sites: np.ndarray, tol: float, density: hcvt.Polynomial | None = None
) -> tuple[float, float, int, float, int, int]:
    """Wall and CPU seconds, Newton steps, max relative mass error, CG iterations, diagrams.

    hcvt's; the diagrams count the first one, at zero weights.
    """
    polygon, _, _ = DOMAINS[name]
    domain = hcvt.Domain.from_polygon(polygon)
    n, mass = len(sites), domain_mass(name, density)
    start, cpu = time.perf_counter(), cpu_seconds()
    out = hcvt.optimal_transport(domain, sites, np.full(n, mass / n), density=density, tol=tol)
    seconds, cpu = time.perf_counter() - start, cpu_seconds() - cpu
    error = float(np.max(np.abs(out.diagram.mass * n / mass - 1.0)))
    cg = int(out.history["cg_iterations"].sum())
    diagrams = int(out.history["diagrams"].sum()) + 1
    return seconds, cpu, out.iterations, error, cg, diagrams


def run_pysdot(
    name: str, sites: np.ndarray, tol: float, density: hcvt.Polynomial | None = None
) -> tuple[float, float, int, float, float, str]:
    """Wall and CPU seconds, Newton steps, max relative mass errors, linear solver: pysdot.s.

    Two errors: from pysdot's own ``integrals()``, and from hcvt's power diagram of
    pysdot's final weights (untimed).
    """
    from pysdot import OptimalTransport

    n, mass = len(sites), domain_mass(name, density)
    ot = OptimalTransport(sites, domain=pysdot_domain(name, density), masses=np.full(n, mass / n))
    ot.set_stopping_criterion(tol * mass / n, "max delta masses")
    start, cpu = time.perf_counter(), cpu_seconds()
    ot.adjust_weights()
    seconds, cpu = time.perf_counter() - start, cpu_seconds() - cpu
    error = float(np.max(np.abs(ot.pd.integrals() * n / mass - 1.0)))
    domain = hcvt.Domain.from_polygon(DOMAINS[name][0])
    again = hcvt.voronoi(domain, sites, weights=ot.get_weights(), density=density)
    error_by_hcvt = float(np.max(np.abs(again.mass * n / mass - 1.0)))
    solver = type(ot._get_linear_solver()).__module__
    return seconds, cpu, len(ot.delta_m), error, error_by_hcvt, solver


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000])
    parser.add_argument("--domains", nargs="+", choices=list(DOMAINS), default=["square"])
    parser.add_argument(
        "--density",
        nargs="+",
        choices=list(DENSITIES),
        default=["uniform"],
        help=f"uniform, or poly: rho = {POLYNOMIAL!r}, exact in both codes",
    )
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
        f"median of {max(1, args.repeats)} run(s) each; poly: rho = {POLYNOMIAL!r}"
    )
    # Untimed warm-up of both codes: the process's first transport paid one-time set-up
    # (square 10k read 1.12x pysdot first, 1.60x second in one quiet run).
    for density in (DENSITIES[name] for name in args.density):
        warm = random_sites("square", 1_000, density)
        run_hcvt("square", warm, args.tol, density)
        run_pysdot("square", warm, args.tol, density)
    for name in args.domains:
        for density_name in args.density:
            for n in args.sizes:
                sites = random_sites(name, n, DENSITIES[density_name])
                print(compare(name, density_name, sites, args.tol, args.repeats))


def compare(name: str, density_name: str, sites: np.ndarray, tol: float, repeats: int) -> str:
    """One row: both codes ``repeats`` times on ``sites``, alternating; median seconds."""
    density = DENSITIES[density_name]
    h_runs, p_runs = [], []
    for _ in range(max(1, repeats)):
        h_time, h_cpu, h_steps, h_error, h_cg, h_diagrams = run_hcvt(name, sites, tol, density)
        p_time, p_cpu, p_steps, p_error, p_by_hcvt, solver = run_pysdot(name, sites, tol, density)
        h_runs.append((h_time, h_cpu))
        p_runs.append((p_time, p_cpu))
    (h_time, h_cpu), (p_time, p_cpu) = np.median(h_runs, axis=0), np.median(p_runs, axis=0)
    return (
        f"{name:>6} {density_name:>7} n={len(sites):>7}  hcvt {h_time:8.3f} s (CPU {h_cpu:.3f} s; "
        f"{h_steps} Newton steps, {h_diagrams} diagrams, {h_cg} CG iterations, max rel. error "
        f"{h_error:.1e})  pysdot {p_time:8.3f} s (CPU {p_cpu:.3f} s; {p_steps} steps, max rel. "
        f"error {p_error:.1e}, by hcvt {p_by_hcvt:.1e}, {solver})  pysdot/hcvt "
        f"{p_time / h_time:.2f}"
    )


if __name__ == "__main__":
    main()
