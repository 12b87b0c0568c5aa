"""Memory of the clipped diagram: no growth over repeated calls, and peak at large n.

1. Flatness: 1,000 diagrams of 10k sites in a square with a hole (2D); resident memory
   (/proc/self/statm) after a warm-up of 20 and after every 100 more.
2. Peak: one diagram of 1M sites in 2D and of 100k sites in the unit ball (sphere.ply) in
   3D, each in a fresh child process: VmHWM from /proc/self/status (ru_maxrss of a child
   can carry its parent's peak across exec) after the diagram, above VmRSS just before it
   (VmHWM reset there through /proc/self/clear_refs); see peak().
3. Held: the bytes per site a CVT result's diagram keeps (200k sites, 2D); see held().

    OPENBLAS_NUM_THREADS=1 python benchmarks/memory.py [--quick]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import gc
import time
from pathlib import Path

import numpy as np

import hcvt
from timing import run_child

PAGE = os.sysconf("SC_PAGE_SIZE")
# Issue 32's targets: peak bytes per site of one diagram, 2D at 1M sites, 3D at 100k.
TARGET_BYTES_PER_SITE = {2: (250, 1_000_000), 3: (600, 100_000)}
SPHERE = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d" / "sphere.ply"

# Run by run_child, which defines status(key).
CHILD = """
import gc, sys, time, numpy as np, hcvt
dim, n, path = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
if dim == 2:
    domain = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
else:
    domain = hcvt.load_domain(path)
rng = np.random.default_rng(0)
lo, hi = domain.bounds
sites = rng.uniform(lo, hi, size=(2 * n, dim))
sites = np.ascontiguousarray(sites[domain.contains(sites)][:n])
hcvt.voronoi(domain, sites[:1000])  # warm-up: thread pool, allocator, the domain's index
gc.collect()
hwm_before = status("VmHWM:")
try:
    with open("/proc/self/clear_refs", "w") as f:  # VmHWM := VmRSS (Linux >= 4.0)
        f.write("5")
    resident = status("VmRSS:")
except OSError:
    resident = float("nan")
start = time.perf_counter()
d = hcvt.voronoi(domain, sites)
seconds = time.perf_counter() - start
total = repr(float(d.volume.sum()))
print(len(sites), hwm_before, resident, status("VmHWM:"), f"{seconds:.2f}", total)
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


def child_peak(dim: int, n: int, purge_at_once: bool) -> tuple[int, float, float, str, str]:
    """One diagram of ``n`` sites in a fresh child process.

    Returns (sites, peak above the resident memory just before the diagram, peak above
    the earlier peak, seconds, sum of volumes), memory in MiB.
    """
    env = dict(os.environ)
    if purge_at_once:
        env["MIMALLOC_PURGE_DELAY"] = "0"
    count, hwm_before, resident, after, seconds, total = run_child(CHILD, dim, n, SPHERE, env=env)
    own = float(after) - float(resident)
    return int(count), own, float(after) - float(hwm_before), seconds, total


def peak(dim: int, n: int) -> None:
    """Print the peak memory of one diagram of ``n`` sites, per site.

    ``dim`` = 2: the unit square, 3: the unit ball; each figure from a fresh child.

    The figure is the diagram's own peak: the highest resident memory during
    ``hcvt.voronoi`` above the resident memory just before it (the sites drawn, a warm-up
    diagram of 1,000 sites made, the peak counter reset through ``/proc/self/clear_refs``).
    With the allocator's default settings it moves by ~20% from run to run: mimalloc
    returns freed pages to the system ("purges") 10 ms after the free, if the thread
    that owns them allocates again. The steady figure is the second, with the allocator
    told to purge at once (``MIMALLOC_PURGE_DELAY=0`` in the child only): the memory the
    diagram needs, without what the allocator keeps. The older figure (the peak above
    the highest resident memory before, which holds the transient of drawing 2n sites)
    follows for comparison with earlier results.
    """
    if dim == 3 and not SPHERE.exists():
        print(f"peak 3D: skipped, {SPHERE} not found")
        return
    count, own, older, seconds, total = child_peak(dim, n, purge_at_once=False)
    _, steady, _, _, _ = child_peak(dim, n, purge_at_once=True)
    target, at = TARGET_BYTES_PER_SITE[dim]

    def per_site(mib: float) -> str:
        return f"{mib * 2**20 / count:,.0f} B/site"

    print(
        f"peak {dim}D, {count:,} sites: {per_site(steady)} purging at once (steady), "
        f"{per_site(own)} with the allocator's defaults (target <= {target} B/site at "
        f"{at:,}); older measure {per_site(older)}; {seconds} s under load, "
        f"sum of volumes {total}"
    )


def held(n: int) -> None:
    """Print the bytes per site a CVT result's diagram holds (its arrays, summed).

    Two L-BFGS iterations from ``n`` random sites in the unit square: what
    ``CVTResult.diagram`` keeps until a quantity is read (the cells' moments and faces
    since every producer returns them; seven quantities before).
    """
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    sites = np.random.default_rng(0).uniform(0, 1, size=(n, 2))
    result = hcvt.cvt(square, sites, max_iter=2)
    arrays = result.diagram._arrays
    total = sum(v.nbytes for v in arrays.values() if isinstance(v, np.ndarray))
    print(f"CVT result 2D, {n:,} sites: its diagram holds {total / n:.1f} B/site", sorted(arrays))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="100 repeats, 100k / 10k peak")
    args = parser.parse_args()
    if args.quick:
        flatness(100, 10_000)
        peak(2, 100_000)
        peak(3, 10_000)
        held(100_000)
    else:
        flatness(1000, 10_000)
        peak(2, 1_000_000)
        peak(3, 100_000)
        held(200_000)


if __name__ == "__main__":
    main()
