"""How many power cells a stored-margin certificate could pass in optimal transport's later steps.

Analysis only (no timing), for issue 34's proposal of a cheaper certificate for the cells of
a trial power diagram (docs/results/transport.txt §11). Equal masses in the unit square
(seed 0, as ``benchmarks/transport.py``), the Newton iterates ``w_k`` read back by rerunning
``hcvt.optimal_transport`` with ``max_iter=k``. For the cell ``K_i`` at the weights ``w_a``
(the diagram whose margin is stored) and a later iterate ``w_b``, the certificate passes if

    min_j [ s_j − 2 |q_j| e_i ] > 2 max_k |w_b,k − w_a,k|,

``j`` over the 40 sites nearest ``z_i`` that are not neighbours of ``K_i`` (the farther ones
are left to a reach bound), ``q_j = z_j − z_i``, ``s_j`` the least of
``|v − z_j|² − w_j − |v − z_i|² + w_i`` over the vertices ``v`` of ``K_i`` at ``w_a``, and
``e_i`` the largest distance from a vertex of the cell at ``w_b`` to the nearest vertex of
``K_i`` (a bound on its distance to ``K_i``). Printed per pair ``(a, b)``: the share of cells
that pass, and the share with the stored pair (least ``s_j``, largest ``|q_j|``) in place of
the minimum over ``j``, and that share with the local bound ``max_j |dw_j − dw_i|``
over the 40 nearest sites in place of ``2 max |dw|`` (what per-block maxima of ``|dw|``
would give). 2D cells clipped by the square: the square is the start box, so they
are the cells the certificate sees. Also per ``a``: the median least slack over the
vertices, and over the ball about the vertices' mean that holds them (the per-site test (a)
of ``Power::hinted_cell``), with the share of cells where the latter is positive.

    python benchmarks/transport_margins.py [--n 10000]
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.spatial import cKDTree

import hcvt

NEAREST = 40


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=10000)
    n = parser.parse_args().n
    z = np.random.default_rng(0).random((n, 2))
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    masses = np.full(n, 1.0 / n)
    steps = hcvt.optimal_transport(square, z, masses).iterations
    weights = [np.zeros(n)] + [
        hcvt.optimal_transport(square, z, masses, max_iter=k).weights for k in range(1, steps + 1)
    ]
    near = cKDTree(z).query(z, NEAREST)[1]
    vertices, neighbours = {}, {}
    for k in range(2, steps + 1):
        diagram = hcvt.voronoi(square, z, weights=weights[k])
        vertices[k] = [np.asarray(p.exterior.coords)[:-1] for p in diagram.cells()]
        off, nb = diagram.neighbor_offsets, diagram.neighbor_sites
        neighbours[k] = [set(nb[off[i] : off[i + 1]].tolist()) for i in range(n)]
    print(f"square, n={n}, {steps} Newton steps")
    for a in range(2, steps):
        w = weights[a]
        slacks, balls = [], []
        for i in range(n):
            js = np.array([j for j in near[i] if j != i and j not in neighbours[a][i]])
            v = vertices[a][i]
            f = ((v[None] - z[js][:, None]) ** 2).sum(-1) - w[js][:, None]
            f -= (((v - z[i]) ** 2).sum(-1) - w[i])[None]
            q = z[js] - z[i]
            slacks.append((f.min(1), np.sqrt((q**2).sum(-1))))
            # The same least over the ball about the vertices' mean holding them.
            c = v.mean(0) - z[i]
            rho = np.sqrt(((v - z[i] - c) ** 2).sum(-1).max())
            ball = (q**2).sum(-1) - 2 * q @ c - (w[js] - w[i]) - 2 * rho * slacks[-1][1]
            balls.append(ball.min())
        least = np.array([s.min() for s, _ in slacks])
        print(
            f"margin at w{a}: median least slack over the vertices {np.median(least) * n:.3f} "
            f"mean areas, over the ball {np.median(balls) * n:.3f} (positive for "
            f"{np.mean(np.array(balls) > 0):.3f} of the cells)"
        )
        for b in range(a + 1, steps + 1):
            budget = 2 * np.abs(weights[b] - w).max()
            dw = weights[b] - w
            each = stored = local = 0
            for i in range(n):
                gaps = vertices[b][i][:, None] - vertices[a][i][None]
                e = np.sqrt((gaps**2).sum(-1).min(1).max())
                s, q = slacks[i]
                each += (s - 2 * q * e).min() > budget
                stored += s.min() - 2 * q.max() * e > budget
                local += s.min() - 2 * q.max() * e > np.abs(dw[near[i]] - dw[i]).max()
            print(
                f"margin at w{a}, trial w{b}: 2 max|dw| = {budget * n:.2e} mean areas; "
                f"certified {each / n:.3f} (stored pair {stored / n:.3f}, "
                f"with the local bound {local / n:.3f})",
                flush=True,
            )


if __name__ == "__main__":
    main()
