"""The cells of a restricted Voronoi diagram as pieces, against the plain diagram (issue 33).

``Diagram.surface_pieces()`` computes the diagram once more with the core noting each
cell's pieces as it measures them (``_core.surface_pieces``). Per mesh and n (sites
``hcvt.initialise``, random by area, seed 0), one thread, CPU seconds of ``_core.voronoi``
(the plain diagram's arrays) and of ``_core.surface_pieces`` (the diagram and its pieces),
alternating ``--repeats`` times (paired runs under the same load); medians, cells/s and
the ratio pieces / plain. Label the figures "under load" with ``uptime``'s load.

    OPENBLAS_NUM_THREADS=1 python benchmarks/surface_cells.py [--sizes 5000,20000]
        [--meshes bunny.off,armadillo.obj] [--repeats 5]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import statistics
import time
from pathlib import Path

import hcvt
from hcvt import _core

DATA = Path(os.environ.get("HCVT_DATA", Path(__file__).resolve().parents[2] / "shared" / "data"))


def cpu(call, *args) -> float:
    """CPU seconds of ``call(*args)``."""
    start = time.process_time()
    call(*args)
    return time.process_time() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="5000,20000")
    parser.add_argument("--meshes", default="bunny.off,armadillo.obj")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    hcvt.set_num_threads(1)
    print(f"load {os.getloadavg()[0]:.1f}; one thread; CPU seconds, medians of {args.repeats}")
    print(f"{'mesh':<16}{'n':>8}{'plain s':>10}{'pieces s':>10}{'pieces/s':>12}{'ratio':>8}")
    for name in args.meshes.split(","):
        surface = hcvt.load_domain(DATA / "3d" / name, surface=True)
        for n in map(int, args.sizes.split(",")):
            sites = surface.frame.to_core(hcvt.initialise(surface, n, seed=0))
            plain, pieces = [], []
            for _ in range(args.repeats):
                plain.append(cpu(_core.voronoi, surface._core, sites))
                pieces.append(cpu(_core.surface_pieces, surface._core, sites))
            a, b = statistics.median(plain), statistics.median(pieces)
            print(f"{name:<16}{n:>8}{a:>10.3f}{b:>10.3f}{n / b:>12.0f}{b / a:>8.2f}")
    print(f"load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
