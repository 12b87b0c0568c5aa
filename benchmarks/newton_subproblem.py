"""Does Newton lose diagrams to its inexact step? The exact trust-region step against Steihaug's.

A prototype trust-region Newton in NumPy on a dense Hessian from central differences of
``hcvt.voronoi``'s gradient (2·(2n) diagrams per iterate, so small cases only), counting
the diagrams (the trial evaluations) to the paper's rule ‖g‖/‖X‖ < 1e-10 from random
sites, with one of two step solvers in the same region and with the same updates as the
core's (``hcvt-core/src/optimise/newton.rs``: accept at ratio 0.1, grow by 1.5 above 0.9
at the edge, shrink to a quarter of the step below 0.25; the region's norm that of the
mass preconditioner ``2 m_i``):

- ``steihaug``: truncated CG preconditioned by ``1/(2 m_i)``, stopped at relative residual
  ``η = min(1/2, √(RMS gap))`` or at the region's edge (along negative curvature too);
- ``exact``: the region's subproblem solved exactly (Moré–Sorensen on the generalised
  eigendecomposition ``H v = λ M v``: ``p = −(H + μM)⁻¹ g`` with ``‖p‖_M`` on the edge).

Neither has the core's per-site stiffness, pinned sites or round-off rule: they compare
the step solvers with everything else equal, not with ``hcvt.cvt``. This is a measuring
prototype, not a second optimiser: the core's Steihaug step cannot be driven with a dense
NumPy Hessian, so both solvers are written here in a few lines each, beside each other.

``--spectrum SEED`` prints instead, along ``hcvt.cvt``'s own Newton run from random sites, the
generalised eigenvalues ``H v = λ M v`` (``M = diag(2 m_i)``: Lloyd's step has ``λ = 1``) at
every ``--every``-th iterate: the least three, how many are negative, the least positive,
and the gradient's share on the negative ones; and each step's moves per site relative to
the spacing ``√(area / n)`` (median, largest).

    OPENBLAS_NUM_THREADS=1 python benchmarks/newton_subproblem.py --n 500 --seeds 0 1 2
    OPENBLAS_NUM_THREADS=1 python benchmarks/newton_subproblem.py --n 1000 --spectrum 4
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse

import numpy as np
import scipy.linalg

import hcvt
from hcvt.geometry import shapes

FD_STEP = 1e-7  # central differences of the gradient, input units (the square is 20 wide)


def evaluate(domain, sites):
    """The diagram of ``sites`` (n, 2), or None when a site left the domain."""
    try:
        return hcvt.voronoi(domain, sites)
    except hcvt.InvalidSitesError:
        return None


def hessian(domain, sites) -> np.ndarray:
    """The CVT energy's Hessian (2n, 2n) by central differences, symmetrised."""
    n = len(sites)
    columns = np.empty((2 * n, 2 * n))
    for j in range(2 * n):
        e = np.zeros(2 * n)
        e[j] = FD_STEP
        up = hcvt.voronoi(domain, sites + e.reshape(n, 2)).gradient.ravel()
        down = hcvt.voronoi(domain, sites - e.reshape(n, 2)).gradient.ravel()
        columns[:, j] = (up - down) / (2 * FD_STEP)
    return 0.5 * (columns + columns.T)


def exact_step(h, g, m, radius) -> tuple[np.ndarray, bool]:
    """The minimiser of ``g·p + ½ pᵀHp`` over ``‖p‖_M ≤ radius`` (M = diag m); at the edge."""
    lam, v = scipy.linalg.eigh(h, np.diag(m))
    gc = v.T @ g
    if lam[0] > 0:
        inside = -gc / lam
        if np.linalg.norm(inside) <= radius:
            return v @ inside, False
    lo = max(0.0, -lam[0]) + 1e-14
    hi = lo + np.linalg.norm(gc) / radius + 1.0
    for _ in range(200):  # bisection on the shift μ: ‖p(μ)‖ falls as μ grows
        mid = 0.5 * (lo + hi)
        if np.linalg.norm(gc / (lam + mid)) > radius:
            lo = mid
        else:
            hi = mid
    return v @ (-gc / (lam + hi)), True


def steihaug_step(h, g, m, radius, eta) -> tuple[np.ndarray, bool]:
    """Steihaug's truncated CG preconditioned by ``1/m`` in ``‖p‖_M ≤ radius``."""
    z, r = np.zeros_like(g), g.copy()
    d = -r / m
    ry = r @ (r / m)
    stop = eta * eta * ry
    for _ in range(200):
        hd = h @ d
        curvature = d @ hd
        alpha = ry / curvature
        step = z + alpha * d
        if curvature <= 0 or step @ (m * step) >= radius**2:
            a, b, c = d @ (m * d), 2 * z @ (m * d), z @ (m * z) - radius**2
            return z + (-b + np.sqrt(b * b - 4 * a * c)) / (2 * a) * d, True
        z, r = step, r + alpha * hd
        ry_next = r @ (r / m)
        if ry_next <= stop:
            return z, False
        d = -r / m + (ry_next / ry) * d
        ry = ry_next
    return z, False


def run(domain, sites, solver: str, tol: float = 1e-10) -> int:
    """Diagrams to ‖g‖/‖X‖ < tol from ``sites`` with the step ``solver``."""
    diagram, diagrams, radius = evaluate(domain, sites), 1, None
    while True:
        g, m = diagram.gradient.ravel(), np.repeat(2 * diagram.mass, 2)
        if np.linalg.norm(g) / np.linalg.norm(sites) < tol:
            return diagrams
        h = hessian(domain, sites)
        radius = np.sqrt(g @ (g / m)) if radius is None else radius
        gaps = diagram.gradient / (2 * diagram.mass[:, None] * np.sqrt(diagram.volume)[:, None])
        eta = min(0.5, np.sqrt(np.sqrt(np.mean(np.sum(gaps**2, axis=1)))))
        while True:
            if solver == "exact":
                p, at_edge = exact_step(h, g, m, radius)
            else:
                p, at_edge = steihaug_step(h, g, m, radius, eta)
            predicted = -(g @ p + 0.5 * p @ (h @ p))
            length = np.sqrt(p @ (m * p))
            trial = evaluate(domain, sites + p.reshape(-1, 2))
            diagrams += 1
            if trial is None:
                radius = 0.25 * length
                continue
            ratio = (diagram.energy - trial.energy) / predicted if predicted > 0 else -1.0
            if ratio < 0.25:
                radius = 0.25 * length
            elif ratio > 0.9 and at_edge:
                radius *= 1.5
            if ratio >= 0.1:
                sites, diagram = sites + p.reshape(-1, 2), trial
                break


def spectrum(domain, n: int, seed: int, every: int) -> None:
    """The Hessian's spectrum and the steps' moves along ``hcvt.cvt``'s Newton run."""
    iterates: list[np.ndarray] = []
    sites = hcvt.initialise(domain, n, method="random", seed=seed)
    run = hcvt.cvt(
        domain,
        sites,
        "newton",
        rule="paper",
        tol=1e-10,
        callback=lambda info: iterates.append(np.array(info["sites"])),
    )
    spacing = np.sqrt(domain.volume / n)
    print(f"square {n} seed {seed}: {run.evaluations} diagrams, {len(iterates)} iterates")
    for k in sorted(set(range(0, len(iterates), every)) | {len(iterates) - 1}):
        x = iterates[k]
        diagram = hcvt.voronoi(domain, x)
        g = diagram.gradient.ravel()
        lam, v = scipy.linalg.eigh(hessian(domain, x), np.diag(np.repeat(2 * diagram.mass, 2)))
        negative = lam < -1e-6
        share = np.linalg.norm((v.T @ g)[negative]) / np.linalg.norm(v.T @ g)
        moves = np.linalg.norm(x - iterates[k - 1], axis=1) / spacing if k else np.zeros(1)
        print(
            f"iterate {k:4d}  RMS gap {run.history['rms_gap'][k]:.1e}  least {lam[0]:+.4f} "
            f"{lam[1]:+.4f} {lam[2]:+.4f}  negative {negative.sum():4d}  least positive "
            f"{lam[lam > 1e-6].min():.1e}  gradient on negative {share:.2f}  moves/spacing "
            f"median {np.median(moves):.1e} largest {moves.max():.1e}",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=500)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--spectrum", type=int, metavar="SEED")
    parser.add_argument("--every", type=int, default=8)
    args = parser.parse_args()
    hcvt.set_num_threads(1)
    domain = shapes.square()
    if args.spectrum is not None:
        spectrum(domain, args.n, args.spectrum, args.every)
        return
    print(f"square {args.n}: diagrams to the paper's rule per seed")
    print("seed  steihaug  exact  hcvt.cvt(newton)")
    for seed in args.seeds:
        sites = hcvt.initialise(domain, args.n, method="random", seed=seed)
        core = hcvt.cvt(domain, sites, "newton", rule="paper", tol=1e-10).evaluations
        counts = [run(domain, sites, solver) for solver in ("steihaug", "exact")]
        print(f"{seed:4d}  {counts[0]:8d}  {counts[1]:5d}  {core:16d}", flush=True)


if __name__ == "__main__":
    main()
