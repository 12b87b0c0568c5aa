"""Where the time of ``hcvt.remesh`` goes: its phases one by one, CPU and wall seconds.

The phases of :func:`hcvt.remesh` without features, called as it calls them: the input's
edge topology, the initial sites (random by area), their spread (remesh's sampled Lloyd
steps, ``_spread``), the CVT (L-BFGS at ``REMESH_TOL``, its final restricted Delaunay
triangulation of the projected sites included), the defects, and ``tighten`` (its
set-up, the points checked and their distances, timed apart). One thread, as
``benchmarks/remesh.py --cores 1`` runs hcvt; the quality is measured after, untimed.

    OPENBLAS_NUM_THREADS=1 python benchmarks/remesh_split.py fandisk 5000 [--repeat 3]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import importlib
import time

import numpy as np

import hcvt
from hcvt.seeding.initialisation import initialise
from hcvt.surface.quality import edge_topology, triangle_angles
from remesh import DATA, MODELS  # benchmarks/remesh.py: the same meshes

# The modules, not the functions hcvt.surface exports under the same names.
REMESH = importlib.import_module("hcvt.surface.remesh")
TIGHTEN = importlib.import_module("hcvt.surface.tighten")


class Clock:
    """Wall and CPU seconds per phase, over the repeats."""

    def __init__(self) -> None:
        self.rows: dict[str, list[tuple[float, float]]] = {}
        self.reset()

    def reset(self) -> None:
        """Start the next phase now."""
        self.wall, self.cpu = time.perf_counter(), time.process_time()

    def tick(self, name: str) -> None:
        """End phase ``name`` now (and start the next)."""
        wall, cpu = time.perf_counter(), time.process_time()
        self.rows.setdefault(name, []).append((wall - self.wall, cpu - self.cpu))
        self.wall, self.cpu = wall, cpu


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", choices=sorted(MODELS))
    parser.add_argument("n", type=int)
    parser.add_argument("--repeat", type=int, default=1)
    args = parser.parse_args()
    hcvt.set_num_threads(1)
    surface = hcvt.load_domain(DATA / MODELS[args.model], surface=True)
    n = args.n
    clock, setup = Clock(), Clock()
    mesh_class = TIGHTEN._Mesh
    init = mesh_class.__init__

    def timed_init(self, *a, **k) -> None:  # type: ignore[no-untyped-def]
        setup.reset()
        init(self, *a, **k)
        setup.tick("tighten: set-up (points, distances)")

    mesh_class.__init__ = timed_init
    print(f"{args.model} n={n}, {len(surface.faces)} input triangles, load {os.getloadavg()}")
    for _ in range(args.repeat):
        clock.reset()
        total = (time.perf_counter(), time.process_time())
        topology = edge_topology(surface.faces, len(surface.vertices))
        clock.tick("edge_topology (input)")
        sites = initialise(surface, n, method="random", seed=0)
        clock.tick("initialise")
        sites = REMESH._spread(surface, sites, 0)
        clock.tick("spread (the start's sampled Lloyd steps)")
        run = hcvt.cvt(surface, sites, "lbfgs", tol=REMESH.REMESH_TOL, max_iter=200)
        clock.tick(f"cvt ({run.evaluations} diagrams + the final triangulation)")
        rdt = run._triangulation
        faces = np.asarray(rdt["triangles"], dtype=np.intp)
        defects = REMESH._defects(faces, n, np.asarray(rdt["repeated"]), topology)
        clock.tick("defects")
        floor = min(REMESH.TIGHTEN_MIN_ANGLE, float(triangle_angles(run.sites, faces).min()))
        out = TIGHTEN.tighten(
            run.sites,
            faces,
            surface,
            samples=max(30_000, REMESH.TIGHTEN_SAMPLES_PER_VERTEX * n),
            seed=0,
            min_angle=floor,
        )
        clock.tick("tighten (all)")
        clock.rows.setdefault("total", []).append(
            (time.perf_counter() - total[0], time.process_time() - total[1])
        )
    q = hcvt.surface_quality(out.vertices, faces, (surface.vertices, surface.faces))
    print(
        f"{run.iterations} iterations, defects {defects or 'none'}, {out.moves} moves; "
        f"Q min {q.q_min:.3f}, θmin {q.angle_min:.2f}, Hausdorff {q.hausdorff:.3f}%"
    )
    for name, values in {**clock.rows, **setup.rows}.items():
        wall, cpu = np.median(np.array(values), axis=0)
        print(f"  {name:48s} wall {wall:7.3f} s  CPU {cpu:7.3f} s")
    print(f"load {os.getloadavg()}")


if __name__ == "__main__":
    main()
