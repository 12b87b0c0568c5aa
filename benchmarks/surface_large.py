"""A restricted Voronoi diagram of 1,000,000 sites on a surface of over 1M triangles (issue 33).

The surface is ``armadillo.obj`` (86,482 triangles) subdivided twice at edge midpoints
(trimesh's ``subdivide``: every triangle into four coplanar ones, so the surface itself is
unchanged) to 1,383,712 triangles; the sites are ``hcvt.initialise(surface, n)`` (random
by area, seed 0). One ``hcvt.voronoi`` is timed in a fresh child process, which also
reports its peak memory (VmHWM from /proc/self/status, before and after the diagram: the
difference is the diagram's own peak, per site) and Σ cell areas against the surface's
area (exact cells: equal to round-off).

    OPENBLAS_NUM_THREADS=1 python benchmarks/surface_large.py [--sites 1000000] [--subdivisions 2]

``benchmarks/remesh.py --large`` runs the same row after its remeshing table.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
from pathlib import Path

from timing import run_child

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d"

# Run by run_child, which defines status(key).
CHILD = """
import sys, time, numpy as np, trimesh, hcvt
path, n, subdivisions = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
mesh = trimesh.load(path, process=False)
vertices, faces = mesh.vertices, mesh.faces
for _ in range(subdivisions):
    vertices, faces = trimesh.remesh.subdivide(vertices, faces)
start = time.perf_counter()
surface = hcvt.Domain.from_surface(vertices, faces)
domain_seconds = time.perf_counter() - start
sites = hcvt.initialise(surface, n, method="random", seed=0)
before = status("VmHWM:")
start = time.perf_counter()
diagram = hcvt.voronoi(surface, sites)
seconds = time.perf_counter() - start
error = abs(diagram.volume.sum() / surface.volume - 1)
print(len(faces), len(sites), domain_seconds, seconds, before, status("VmHWM:"), error)
"""


def large_row(model: str = "armadillo.obj", sites: int = 1_000_000, subdivisions: int = 2) -> None:
    """Time one restricted diagram of ``sites`` sites on ``model`` subdivided, and print it."""
    out = run_child(CHILD, DATA / model, sites, subdivisions)
    triangles, count = int(out[0]), int(out[1])
    domain_s, seconds, before, after, error = map(float, out[2:])
    per_site = (after - before) * 2**20 / count
    print(
        f"restricted diagram, {model} subdivided {subdivisions}x ({triangles:,} triangles), "
        f"{count:,} sites, {os.cpu_count()} cores: {seconds:.1f} s ({count / seconds:,.0f} "
        f"cells/s); peak {after:.0f} MiB ({before:.0f} MiB before the diagram: "
        f"{per_site:,.0f} B/site); |sum of areas / area - 1| = {error:.1e}; surface set-up "
        f"{domain_s:.1f} s"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default="armadillo.obj")
    parser.add_argument("--sites", type=int, default=1_000_000)
    parser.add_argument("--subdivisions", type=int, default=2)
    args = parser.parse_args()
    large_row(args.model, args.sites, args.subdivisions)


if __name__ == "__main__":
    main()
