"""Time the exact 3D clipped Voronoi diagram against the paper's Table 7 and against peers.

Run ``OPENBLAS_NUM_THREADS=1 python benchmarks/diagram_3d.py`` (``--quick`` for a short
run). For every Table 7 case whose mesh ``../shared/data/3d`` holds, it prints our median
time beside the paper's seconds and, in the same run, the ``geogram`` PyPI wheel end to end
(tetrahedralise the mesh, then its restricted Voronoi diagram) on the same sites. On a box
it times us against pysdot and voro++ (through freud, periodic box, and multivoro). Last,
the memory of a diagram: peak resident-set growth in a fresh process, in bytes per site.

Peers that are not installed are reported as such; install with
``pip install geogram freud-analysis multivoro pysdot==0.2.16``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import numpy as np

import hcvt
from timing import median_seconds

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d"

# Paper Table 7: (object, mesh file here, sites, seconds). Dragon is not in the data folder.
TABLE7 = [
    ("Homer", "homer.obj", 35_000, 28.66),
    ("Ball", "sphere.ply", 1_000, 0.55),
    ("Bunny", "bunny.off", 50_000, 30.06),
    ("Kitten", "kitten.obj", 80_000, 54.57),
    ("Armadillo", "armadillo.obj", 100_000, 103.06),
    ("Dragon", "dragon.obj", 100, 1.89),
    ("Dragon", "dragon.obj", 1_000, 6.14),
    ("Dragon", "dragon.obj", 10_000, 21.26),
    ("Dragon", "dragon.obj", 100_000, 99.09),
]


def interior_sites(domain: hcvt.Domain, n: int, seed: int = 0) -> np.ndarray:
    """``n`` uniform random sites inside ``domain``, by rejection with exact winding numbers."""
    rng = np.random.default_rng(seed)
    lo, hi = domain.bounds
    parts, count = [], 0
    while count < n:
        p = rng.uniform(lo, hi, size=(max(4 * n, 1000), 3))
        p = p[domain.contains(p)]
        parts.append(p)
        count += len(p)
    return np.ascontiguousarray(np.concatenate(parts)[:n])


def geogram_seconds(domain: hcvt.Domain, sites: np.ndarray, repeat: int) -> float | None:
    """Time the geogram wheel end to end: tetrahedralise, then restricted Voronoi."""
    try:
        import geogram
    except ImportError:
        return None
    v = np.ascontiguousarray(domain.vertices)
    f = np.ascontiguousarray(domain.faces, dtype=np.uint32)

    def run() -> None:
        tv, tt = geogram.mesh.tetrahedralize(v, f)
        geogram.Voronoi(
            sites, domain_vertices=tv, domain_simplices=np.ascontiguousarray(tt, dtype=np.uint32)
        )

    return median_seconds(run, repeat)


def box_domain() -> hcvt.Domain:
    """Build the unit cube as 12 outward triangles."""
    v = np.array([[(i >> k) & 1 for k in range(3)] for i in range(8)], dtype=float)
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    f = [[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads]
    return hcvt.Domain.from_mesh(v, f)


def box_peers(sites: np.ndarray, repeat: int) -> dict[str, float | None]:
    """Seconds of the box peers on ``sites`` in the unit cube."""
    out: dict[str, float | None] = {}
    try:
        from pysdot import PowerDiagram
        from pysdot.domain_types import ConvexPolyhedraAssembly

        box = ConvexPolyhedraAssembly()
        box.add_box([0, 0, 0], [1, 1, 1], 1.0, 0)
        weights = np.zeros(len(sites))
        out["pysdot 0.2.16"] = median_seconds(
            lambda: PowerDiagram(sites, weights, box).integrals(), repeat
        )
    except ImportError:
        out["pysdot 0.2.16"] = None
    try:
        import freud

        fbox = freud.box.Box.cube(1.0)
        centred = sites - 0.5
        out["voro++ via freud (periodic)"] = median_seconds(
            lambda: freud.locality.Voronoi().compute((fbox, centred)), repeat
        )
    except ImportError:
        out["voro++ via freud (periodic)"] = None
    try:
        import multivoro  # zero radii: Laguerre = Voronoi

        limits = np.array([[0.0] * 3, [1.0] * 3])
        radii = np.zeros(len(sites))
        out["voro++ via multivoro (2 threads)"] = median_seconds(
            lambda: multivoro.compute_voronoi(sites, limits=limits, radii=radii, n_threads=2),
            repeat,
        )
    except ImportError:
        out["voro++ via multivoro (2 threads)"] = None
    return out


MEMORY_PROBE = """
import sys, numpy as np, hcvt
sys.path.insert(0, {bench!r})
from diagram_3d import box_domain

def status_kib(key):
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith(key))

n = int(sys.argv[1])
dom = box_domain()
sites = np.random.default_rng(0).uniform(0, 1, size=(n, 3))
hcvt.voronoi(dom, sites[:10])
with open("/proc/self/clear_refs", "w") as f:
    f.write("5")  # reset the peak (VmHWM) to the current resident set
before = status_kib("VmRSS")
diagram = hcvt.voronoi(dom, sites)
print((status_kib("VmHWM") - before) * 1024 / n)
"""


def bytes_per_site(n: int) -> float:
    """Peak resident-set growth of one box diagram, bytes per site, in a fresh process.

    The peak resident set during the diagram (VmHWM, reset just before it) minus the
    resident set before it: kd-tree, per-cell results, output arrays, allocator slack.
    """
    code = MEMORY_PROBE.format(bench=str(Path(__file__).resolve().parent))
    out = subprocess.run(
        [sys.executable, "-c", code, str(n)], capture_output=True, text=True, check=True
    )
    return float(out.stdout.strip())


def fmt(seconds: float | None) -> str:
    return "n/a" if seconds is None else f"{seconds:8.3f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs per timing (median)")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--quick", action="store_true", help="sites / 10, one geogram run")
    parser.add_argument("--no-geogram", action="store_true")
    parser.add_argument("--geogram-repeat", type=int, default=1, help="runs per geogram timing")
    args = parser.parse_args()
    hcvt.set_num_threads(args.threads)
    scale = 10 if args.quick else 1
    print(f"hcvt {hcvt.__version__}, {args.threads} threads, median of {args.repeat}")
    head = ["case".ljust(22), "sites".rjust(8), "ours s".rjust(10), "paper s".rjust(10)]
    head += ["paper/ours".rjust(12), "geogram s".rjust(11), "geogram/ours".rjust(14)]
    print("".join(head))
    for label, name, n, paper in TABLE7:
        path = DATA / name
        if not path.exists():
            print(f"{label:<22}{n:>8}   (mesh not in ../shared/data/3d)")
            continue
        domain = hcvt.load_domain(path)
        sites = interior_sites(domain, n // scale)
        ours = median_seconds(lambda d=domain, s=sites: hcvt.voronoi(d, s), args.repeat)
        geo = None if args.no_geogram else geogram_seconds(domain, sites, args.geogram_repeat)
        ratio = f"{geo / ours:14.1f}" if geo else f"{'n/a':>14}"
        row = f"{label:<22}{len(sites):>8}{ours:10.3f}{paper:10.2f}{paper / ours:12.1f}"
        print(f"{row}{fmt(geo):>11}{ratio}")
    n_box = 100_000 // scale
    sites = np.random.default_rng(1).uniform(0, 1, size=(n_box, 3))
    ours = median_seconds(lambda: hcvt.voronoi(box_domain(), sites), args.repeat)
    print(f"\nbox, {n_box} uniform sites: ours {ours:.3f} s")
    for peer, seconds in box_peers(sites, args.repeat).items():
        ratio = "" if seconds is None else f"  (peer/ours {seconds / ours:.2f})"
        print(f"  {peer:<34}{fmt(seconds)} s{ratio}")
    for n in (10_000, 100_000 // scale):
        print(f"memory, box, {n} sites: {bytes_per_site(n):.0f} bytes/site (peak RSS growth)")


if __name__ == "__main__":
    main()
