"""Memory of the clipped diagram: no growth over repeated calls, and peak at large n.

1. Flatness: 1,000 diagrams of 10k sites in a square with a hole (2D); resident memory
   (/proc/self/statm) after a warm-up of 20 and after every 100 more.
2. Peak: one diagram of 1M sites in 2D and of 100k sites in the unit ball (sphere.ply) in
   3D, each in a fresh child process; the peak is VmHWM from /proc/self/status (ru_maxrss
   of a child can carry its parent's peak across exec), before and after the diagram.

    OPENBLAS_NUM_THREADS=1 python benchmarks/memory.py [--quick]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import gc
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

import hcvt

PAGE = os.sysconf("SC_PAGE_SIZE")
# Issue 32's targets: peak bytes per site of one diagram, 2D at 1M sites, 3D at 100k.
TARGET_BYTES_PER_SITE = {2: (250, 1_000_000), 3: (600, 100_000)}
SPHERE = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d" / "sphere.ply"

CHILD = """
import sys, time, numpy as np, hcvt
def hwm():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
dim, n, path = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
if dim == 2:
    domain = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
else:
    domain = hcvt.load_domain(path)
rng = np.random.default_rng(0)
lo, hi = domain.bounds
sites = rng.uniform(lo, hi, size=(2 * n, dim))
sites = np.ascontiguousarray(sites[domain.contains(sites)][:n])
before = hwm()
start = time.perf_counter()
d = hcvt.voronoi(domain, sites)
seconds = time.perf_counter() - start
print(f"{len(sites)} {before:.1f} {hwm():.1f} {seconds:.2f} {d.volume.sum():.15g}")
"""


def resident_mib() -> float:
    return int(Path("/proc/self/statm").read_text().split()[1]) * PAGE / 2**20


def flatness(repeats: int, n: int) -> None:
    domain = hcvt.Domain.from_polygon(
        [(0, 0), (1, 0), (1, 1), (0, 1)], holes=[[(0.4, 0.4), (0.4, 0.6), (0.6, 0.6), (0.6, 0.4)]]
    )
    rng = np.random.default_rng(5)
    sites = rng.uniform(0, 1, size=(2 * n, 2))
    sites = sites[domain.contains(sites)][:n]
    for _ in range(20):
        hcvt.voronoi(domain, sites)
    gc.collect()
    base = resident_mib()
    print(
        f"flatness: {repeats} diagrams of {len(sites)} sites (2D), threads = "
        f"{hcvt.get_num_threads()}"
    )
    print(f"  after 20 warm-up calls: RSS {base:.1f} MiB")
    start = time.perf_counter()
    step = max(repeats // 10, 1)
    for k in range(1, repeats + 1):
        hcvt.voronoi(domain, sites)
        if k % step == 0:
            gc.collect()
            rss = resident_mib()
            print(f"  after {k:5d}: RSS {rss:.1f} MiB ({100 * (rss / base - 1):+.2f} %)")
    seconds = time.perf_counter() - start
    print(f"  {seconds:.1f} s in all, {1e3 * seconds / repeats:.1f} ms per diagram")


def peak(dim: int, n: int) -> None:
    if dim == 3 and not SPHERE.exists():
        print(f"peak 3D: skipped, {SPHERE} not found")
        return
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(dim), str(n), str(SPHERE)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.split()
    count, before, after, seconds, total = out
    per_site = (float(after) - float(before)) * 2**20 / int(count)
    target, at = TARGET_BYTES_PER_SITE[dim]
    print(
        f"peak {dim}D, {int(count):,} sites: VmHWM {float(before):.0f} MiB with the sites, "
        f"{float(after):.0f} MiB after the diagram: {per_site:,.0f} B/site (target <= "
        f"{target} B/site at {at:,}) ({seconds} s under load, Σ volume {total})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 repeats, 100k / 10k peak")
    args = parser.parse_args()
    if args.quick:
        flatness(100, 10_000)
        peak(2, 100_000)
        peak(3, 10_000)
    else:
        flatness(1000, 10_000)
        peak(2, 1_000_000)
        peak(3, 100_000)


if __name__ == "__main__":
    main()
