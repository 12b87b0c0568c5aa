"""Repeated diagrams keep the resident memory flat: nothing leaks per call.

The full figure (1,000 diagrams of 10k sites, and peak memory at 1M sites in 2D and 100k
in 3D) is printed by benchmarks/memory.py; this test runs fewer repetitions to stay fast.
"""

from __future__ import annotations

import gc
import os
import sys
from pathlib import Path

import numpy as np
import pytest

import hcvt
from helpers import DATA

STATM = Path("/proc/self/statm")
# Bounds of the peak of one diagram, bytes per site (test_peak_memory_of_one_diagram_per_site):
# measured 2026-12-04, 2 threads, purging at once, benchmarks/memory.py: 2D 1M 222-224 B/site
# (335-339 before: assembly freeing each batch's values as copied, batch faces fitted,
# voronoi returning moments and u32 neighbour sites), 3D 100k 445 (521-527 before).
# This test's child: 2D 200k 225, 3D 100k 474. A copy of the faces adds 72 (u32 + f64) / 182.
# (3D at 30k moved by 25% between runs: the allocator's 32 MiB segments weigh too much.)
BOUND_2D = 280
BOUND_3D = 540
PAGE = os.sysconf("SC_PAGE_SIZE") if hasattr(os, "sysconf") else 4096


def resident_bytes() -> int:
    """Resident set size of this process, from /proc/self/statm (Linux)."""
    return int(STATM.read_text().split()[1]) * PAGE


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/statm")
@pytest.mark.parametrize("dim", [2, 3])
def test_repeated_diagrams_keep_resident_memory_flat(dim: int) -> None:
    rng = np.random.default_rng(5)
    if dim == 2:
        domain = hcvt.Domain.from_polygon(
            [(0, 0), (1, 0), (1, 1), (0, 1)],
            holes=[[(0.4, 0.4), (0.4, 0.6), (0.6, 0.6), (0.6, 0.4)]],
        )
        n, warm_up, repeats = 10_000, 20, 150
    else:
        v = np.array([(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)], float)
        f = np.array(
            [
                (0, 1, 3),
                (0, 3, 2),
                (4, 6, 7),
                (4, 7, 5),
                (0, 4, 5),
                (0, 5, 1),
                (2, 3, 7),
                (2, 7, 6),
                (0, 2, 6),
                (0, 6, 4),
                (1, 5, 7),
                (1, 7, 3),
            ]
        )
        domain = hcvt.Domain.from_mesh(v, f)
        n, warm_up, repeats = 2_000, 10, 60
    sites = rng.uniform(domain.bounds[0], domain.bounds[1], size=(n, dim))
    sites = sites[domain.contains(sites)]

    def run(k: int) -> None:
        for _ in range(k):
            d = hcvt.voronoi(domain, sites)
            assert d.volume.shape == (len(sites),)
        gc.collect()

    run(warm_up)  # allocator pools, thread stacks and caches reach their steady size
    before = resident_bytes()
    run(repeats)
    after = resident_bytes()
    assert after <= 1.05 * before, f"RSS {before / 2**20:.1f} MiB -> {after / 2**20:.1f} MiB"


PEAK_CHILD = """
import gc, sys, numpy as np, hcvt
def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024
dim, n, path = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
if dim == 2:
    domain = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
else:
    domain = hcvt.load_domain(path)
rng = np.random.default_rng(3)
lo, hi = domain.bounds
sites = rng.uniform(lo, hi, size=(2 * n, dim))
sites = np.ascontiguousarray(sites[domain.contains(sites)][:n])
hcvt.voronoi(domain, sites[:1000])  # thread pool, allocator set up
gc.collect()
with open("/proc/self/clear_refs", "w") as f:  # VmHWM := VmRSS
    f.write("5")
resident = status("VmRSS:")
d = hcvt.voronoi(domain, sites)
print((status("VmHWM:") - resident) / len(sites), len(d.neighbor_sites) / len(sites))
"""

# Per dimension: sites, faces per site, and the bound on the peak in bytes per site.
PEAK_CASES = {2: (200_000, (5.5, 6.5), BOUND_2D), 3: (100_000, (14.0, 16.0), BOUND_3D)}


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status")
@pytest.mark.parametrize("dim", [2, 3])
def test_peak_memory_of_one_diagram_per_site(dim: int) -> None:
    """The peak of one diagram (2D 200k sites in the square, 3D 100k in the ball) above
    the resident memory just before it, per site, in a fresh process whose allocator
    returns freed pages at once (``MIMALLOC_PURGE_DELAY=0``: the figure is then steady
    within a few percent; with the default delay it moves by ~20%).

    The result's arrays alone take 184 B/site in 2D (6 faces a site) and 346 in 3D (15),
    the ``as_sites`` copy 16 / 24. Measured: see BOUND_2D and BOUND_3D. The bounds catch
    a copy of the faces or of the whole diagram, not noise.
    """
    import subprocess

    n, (fewest, most), bound = PEAK_CASES[dim]
    sphere = DATA / "3d" / "sphere.ply"
    if dim == 3 and not sphere.exists():
        pytest.skip(f"{sphere} not found")
    out = subprocess.run(
        [sys.executable, "-c", PEAK_CHILD, str(dim), str(n), str(sphere)],
        check=True,
        capture_output=True,
        text=True,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1", "MIMALLOC_PURGE_DELAY": "0"},
    ).stdout.split()
    per_site, faces = float(out[0]), float(out[1])
    assert fewest < faces < most, faces
    assert per_site < bound, f"peak {per_site:.0f} B/site above the memory before the diagram"
