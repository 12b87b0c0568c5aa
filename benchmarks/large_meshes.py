"""Per-site cost of the 3D clipped Voronoi diagram on large meshes beside the small ones (issue 32).

Run ``OPENBLAS_NUM_THREADS=1 python benchmarks/large_meshes.py`` (``--quick`` for a fifth of
the sites, ``--threads 2`` for both cores). For Bunny 50k, Homer 35k, Kitten 80k and Armadillo
100k (the paper's Table 7 sizes, sites from ``hcvt.initialise(seed=0)``) it prints the first
call (it builds the winding-number grid) and the median of the later ones, in seconds and in
microseconds of wall time per site, with each mesh's per-site cost as a multiple of Homer's
measured in the same run. The load average is printed before and after: on a shared machine
the ratios are the figure to read, not the seconds.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import hcvt
from timing import median_seconds

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d"

# (name, mesh file, sites): small meshes first, the reference (Homer) among them.
MESHES = [
    ("Bunny", "bunny.off", 50_000),
    ("Homer", "homer.obj", 35_000),
    ("Kitten", "kitten.obj", 80_000),
    ("Armadillo", "armadillo.obj", 100_000),
]
REFERENCE = "Homer"


def load_average() -> str:
    """The 1, 5 and 15 minute load averages, as ``uptime`` prints them."""
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def time_mesh(path: Path, n: int, repeat: int) -> tuple[int, float, float]:
    """Triangles, first-call seconds and median seconds of later calls of ``hcvt.voronoi``."""
    domain = hcvt.load_domain(str(path))
    sites = hcvt.initialise(domain, n, seed=0)
    start = time.perf_counter()
    hcvt.voronoi(domain, sites)
    first = time.perf_counter() - start
    return len(domain.faces), first, median_seconds(hcvt.voronoi, repeat, domain, sites)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="a fifth of the sites, 1 repeat")
    parser.add_argument("--threads", type=int, default=1, help="hcvt threads (default 1)")
    parser.add_argument("--repeat", type=int, default=3, help="timed calls after the first")
    args = parser.parse_args()
    hcvt.set_num_threads(args.threads)
    scale, repeat = (5, 1) if args.quick else (1, args.repeat)
    print(f"{args.threads} thread(s); load average before: {load_average()}")
    print(
        f"{'mesh':<10} {'faces':>7} {'sites':>7} {'first s':>8} {'median s':>9} "
        f"{'us/site':>8} {'x ' + REFERENCE:>8}"
    )
    rows = []
    for name, file, n in MESHES:
        path = DATA / file
        if not path.exists():
            print(f"{name:<10} (no {path})")
            continue
        faces, first, median = time_mesh(path, n // scale, repeat)
        rows.append((name, faces, n // scale, first, median, 1e6 * median / (n // scale)))
    per_site = {row[0]: row[5] for row in rows}
    reference = per_site.get(REFERENCE)
    for name, faces, n, first, median, us in rows:
        ratio = f"{us / reference:.2f}" if reference else "-"
        print(f"{name:<10} {faces:>7} {n:>7} {first:>8.2f} {median:>9.2f} {us:>8.1f} {ratio:>8}")
    print(f"load average after: {load_average()} (above 0: other jobs shared the cores)")


if __name__ == "__main__":
    main()
