"""Would a multiscale start (Mérigot 2011) save Newton steps in hcvt's transport? Analysis.

Mérigot's multiscale approach clusters the sites (Lloyd), solves the coarse transport and
starts the fine one from the coarse weights; his fine solver (Aurenhammer, Hoffmann and
Aronov's, a quasi-Newton ascent) accepts empty cells. The damped Newton of Kitagawa,
Mérigot and Thibert, hcvt's, does not: its Hessian is that of the non-empty cells and its
guard keeps every cell above half of the least start mass. So a start helps only if it
keeps every cell non-empty and lowers the mass error. For the benchmark's problem
(``benchmarks/transport.py``: uniform random sites in the square or the L-shape, equal
masses, seed 0) this prints, for a start ``s · w0`` with ``s = 1, 1/2, 1/4, ...``, the
empty cells of its power diagram and its largest relative mass error (the zero start,
the Voronoi diagram: none empty):

- ``coarse const`` / ``coarse linear``: the sites in Morton order cut into clusters of
  ``--cluster`` (16) consecutive ones, each cluster's site the member nearest its
  centroid, its mass the members' sum; the coarse transport solved by
  ``hcvt.optimal_transport`` (to 1e-6); ``w0`` the cluster's coarse weight, or that plus
  the coarse weights' gradient (least squares over the 8 nearest coarse sites) times
  ``z_i - y_c``.
- ``ideal k``: the converged fine weights ``w*`` averaged over each site's ``k`` nearest
  sites, the smooth part of the answer, better than any coarse solve can give.

    OPENBLAS_NUM_THREADS=1 python benchmarks/transport_multiscale.py [--domain square]
        [--n 10000] [--cluster 16]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse

import numpy as np
from scipy.spatial import cKDTree

import hcvt
from transport import DOMAINS, random_sites


def morton_order(z: np.ndarray, bits: int = 16) -> np.ndarray:
    """The sites' indices along the Morton curve of their bounding box."""
    lo = z.min(axis=0)
    q = ((z - lo) / (z.max(axis=0) - lo).max() * (2**bits - 1)).astype(np.uint64)
    code = np.zeros(len(z), np.uint64)
    for b in range(bits):
        for d in range(2):
            code |= ((q[:, d] >> np.uint64(b)) & np.uint64(1)) << np.uint64(2 * b + d)
    return np.argsort(code, kind="stable")


def coarse_starts(
    domain: hcvt.Domain, z: np.ndarray, m: np.ndarray, cluster: int
) -> dict[str, np.ndarray]:
    """The fine starts from the coarse transport: constant and linear per cluster."""
    groups = np.array_split(morton_order(z), len(z) // cluster)
    label = np.empty(len(z), int)
    y = np.empty((len(groups), 2))
    mc = np.empty(len(groups))
    for c, g in enumerate(groups):
        centroid = (z[g] * m[g, None]).sum(axis=0) / m[g].sum()
        y[c] = z[g[np.argmin(((z[g] - centroid) ** 2).sum(axis=1))]]
        mc[c] = m[g].sum()
        label[g] = c
    coarse = hcvt.optimal_transport(domain, y, mc, tol=1e-6)
    psi = coarse.weights - coarse.weights.mean()
    print(f"coarse: {len(y)} sites, {coarse.iterations} Newton steps")
    _, near = cKDTree(y).query(y, 9)
    gradient = np.array(
        [
            np.linalg.lstsq(y[near[c, 1:]] - y[c], psi[near[c, 1:]] - psi[c], rcond=None)[0]
            for c in range(len(y))
        ]
    )
    linear = psi[label] + ((z - y[label]) * gradient[label]).sum(axis=1)
    return {"coarse const": psi[label], "coarse linear": linear}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--domain", choices=list(DOMAINS), default="square")
    parser.add_argument("--n", type=int, default=10_000)
    parser.add_argument("--cluster", type=int, default=16)
    args = parser.parse_args()
    polygon, _, area = DOMAINS[args.domain]
    domain = hcvt.Domain.from_polygon(polygon)
    z = random_sites(args.domain, args.n)
    m = np.full(args.n, area / args.n)
    fine = hcvt.optimal_transport(domain, z, m)
    w = fine.weights - fine.weights.mean()
    print(
        f"{args.domain} n={args.n}: zero start {fine.iterations} Newton steps, errors "
        + " ".join(f"{e:.2g}" for e in fine.history["max_error"])
        + f"; w* std {w.std():.2e} (mean cell area {area / args.n:.1e})"
    )
    starts = coarse_starts(domain, z, m, args.cluster)
    _, near = cKDTree(z).query(z, 1024)
    for k in (16, 256, 1024):
        rough = w - w[near[:, :k]].mean(axis=1)
        starts[f"ideal {k}"] = w - rough
        print(f"ideal {k}: the rough part w* - smooth has std {rough.std():.2e}")
    for name, start in starts.items():
        for scale in (1.0, 0.5, 0.25, 1 / 16, 1 / 256):
            volume = hcvt.voronoi(domain, z, weights=scale * start).volume
            print(
                f"{name:14s} scale {scale:<8.4g} empty cells {int((volume <= 0).sum()):5d}  "
                f"max rel. error {np.max(np.abs(volume / m - 1)):.2f}"
            )


if __name__ == "__main__":
    main()
