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

STATM = Path("/proc/self/statm")
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
import sys, numpy as np, hcvt
def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024
n = int(sys.argv[1])
domain = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
rng = np.random.default_rng(3)
hcvt.voronoi(domain, rng.uniform(0, 1, size=(1000, 2)))  # thread pool, allocator set up
sites = rng.uniform(0, 1, size=(n, 2))
resident = status("VmRSS:")
d = hcvt.voronoi(domain, sites)
print((status("VmHWM:") - resident) / n, len(d.neighbor_sites) / n)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/status")
def test_peak_memory_of_one_diagram_per_site() -> None:
    """The peak of one 2D diagram of 200k sites above the resident memory before it, per
    site, in a fresh process: the result's arrays alone take 184 B/site (6 faces a site) and
    the as_sites copy 16. Measured 2026-12-03 (2 threads): 537-553 B/site before issue 32's
    assembly changes, 492 after (the 1M figure is benchmarks/memory.py's: 368 -> 241). The
    bound catches a copy of the faces or of the whole diagram, not noise."""
    import subprocess

    n = 200_000
    out = subprocess.run(
        [sys.executable, "-c", PEAK_CHILD, str(n)],
        check=True,
        capture_output=True,
        text=True,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    ).stdout.split()
    per_site, faces = float(out[0]), float(out[1])
    assert 5.5 < faces < 6.5, faces
    assert per_site < 600, f"peak {per_site:.0f} B/site above the memory before the diagram"
