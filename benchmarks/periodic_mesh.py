"""Conforming meshes of periodic power diagrams (the polycrystal case of issue 34).

Random sites in the unit cube with random weights (normal, σ = 0.1 squared spacings),
periodic along every axis: times the power diagram, its conforming mesh (cyclic faces
paired) and the binary OpenFOAM case, and, as a peer in the same run, the mesh of the same
power diagram in the non-periodic box. Label the figures "under load" on a shared machine.

    python benchmarks/periodic_mesh.py 10000 100000
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import hcvt


def _timed(f):  # type: ignore[no-untyped-def]
    start = time.perf_counter()
    out = f()
    return out, time.perf_counter() - start


def run(n: int, seed: int = 6) -> dict[str, float]:
    """Times (s) of each step for ``n`` sites, and the mesh's volume error."""
    rng = np.random.default_rng(seed)
    sites = rng.random((n, 3))
    weights = rng.normal(0.0, 0.1, n) * n ** (-2 / 3)
    torus = hcvt.Domain.box([0, 0, 0], [1, 1, 1], periodic=True)
    diagram, t_diagram = _timed(lambda: hcvt.voronoi(torus, sites, weights=weights))
    mesh, t_mesh = _timed(diagram.mesh)
    error = float(np.max(np.abs(mesh.cell_geometry.volume - diagram.volume)))
    with tempfile.TemporaryDirectory() as tmp:
        _, t_write = _timed(lambda: hcvt.write_mesh(diagram, Path(tmp) / "case", binary=True))
    box = hcvt.Domain.box([0, 0, 0], [1, 1, 1])
    plain = hcvt.voronoi(box, sites, weights=weights)
    _, t_box = _timed(plain.mesh)
    return {
        "n": n,
        "empty": int((diagram.volume == 0).sum()),
        "diagram_s": t_diagram,
        "mesh_s": t_mesh,
        "write_s": t_write,
        "box_mesh_s": t_box,
        "volume_error": error,
    }


def main(sizes: list[int]) -> None:
    print("periodic power meshes (under load)")
    for n in sizes:
        r = run(n)
        print(
            f"n={r['n']:>7} empty={r['empty']:>5} diagram {r['diagram_s']:7.2f} s  "
            f"mesh {r['mesh_s']:7.2f} s ({r['mesh_s'] / r['diagram_s']:.2f}x the diagram, "
            f"{r['mesh_s'] / r['box_mesh_s']:.2f}x the non-periodic box's mesh "
            f"{r['box_mesh_s']:.2f} s)  OpenFOAM binary {r['write_s']:6.2f} s  "
            f"volume error {r['volume_error']:.1e}"
        )


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [10000])
