"""Time one clipped 2D Voronoi diagram (cells + clip + moments) against today's peers.

hcvt and the peers a Python user has today are timed in the same run on the same sites.

Peers: the usual recipe (scipy.spatial.Voronoi + shapely intersection + shapely area and
centroid), GEOS (shapely.voronoi_polygons + intersection), and pysdot 0.2.16 (exact power
diagrams; the polygon given as a union of triangles). Prints medians and ratios; peak
memory of hcvt at 1M sites is measured in a child process.

    OPENBLAS_NUM_THREADS=1 python benchmarks/diagram_2d.py [--quick]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
import shapely
from scipy.spatial import Voronoi

import hcvt
from timing import median_seconds

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "2d"
DOMAINS = {
    "unit square": None,
    "double hex (2 holes)": DATA / "triangle_double_hex.geojson",
    "South Africa (1 hole)": DATA / "naturalearth_south_africa.geojson",
}


def load(path: Path | None) -> hcvt.Domain:
    if path is None:
        return hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    return hcvt.load_domain(path)


def sample(domain: hcvt.Domain, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo, hi = domain.bounds
    out, count = [], 0
    while count < n:
        p = rng.uniform(lo, hi, size=(2 * n + 100, 2))
        p = p[domain.contains(p)]
        out.append(p)
        count += len(p)
    return np.concatenate(out)[:n]


def run_hcvt(domain, sites):
    d = hcvt.voronoi(domain, sites)
    return d.volume, d.centroid


def run_recipe(domain, sites):
    """Scipy Voronoi closed by far guard points, cells intersected with the polygon."""
    lo, hi = domain.bounds
    centre, radius = (lo + hi) / 2, 10 * np.abs(hi - lo).max()
    angles = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    guards = centre + radius * np.column_stack([np.cos(angles), np.sin(angles)])
    vor = Voronoi(np.vstack([sites, guards]))
    regions = [vor.regions[r] for r in vor.point_region[: len(sites)]]
    counts = [len(r) for r in regions]
    rings = shapely.linearrings(
        vor.vertices[np.concatenate(regions)], indices=np.repeat(np.arange(len(sites)), counts)
    )
    cells = shapely.polygons(rings)
    clipped = shapely.intersection(cells, domain.geometry)
    return shapely.area(clipped), shapely.get_coordinates(shapely.centroid(clipped))


def run_geos(domain, sites):
    cells = shapely.voronoi_polygons(
        shapely.multipoints(sites), extend_to=domain.geometry, ordered=True
    )
    clipped = shapely.intersection(shapely.get_parts(cells), domain.geometry)
    return shapely.area(clipped), shapely.get_coordinates(shapely.centroid(clipped))


def pysdot_domain(domain):
    from pysdot.domain_types import ConvexPolyhedraAssembly

    assembly = ConvexPolyhedraAssembly()
    for tri in shapely.get_parts(shapely.constrained_delaunay_triangles(domain.geometry)):
        p = np.asarray(tri.exterior.coords)[:3]
        if shapely.geometry.Polygon(p).exterior.is_ccw is False:
            p = p[::-1]
        rows = []
        for k in range(3):
            a, b = p[k], p[(k + 1) % 3]
            rows.append([a[0], a[1], b[1] - a[1], a[0] - b[0]])  # point, outward normal
        assembly.add_convex_polyhedron(rows, cut_id=0)  # pysdot 0.2.16: -1 overflows
    return assembly


def run_pysdot(assembly, sites):
    from pysdot import PowerDiagram

    pd = PowerDiagram(sites, np.zeros(len(sites)), assembly)
    return pd.integrals(), pd.centroids()


def peak_memory_1m() -> tuple[float, float]:
    """Peak resident memory (GB) of a fresh process computing one 1M-site diagram, and its growth.

    Read from VmHWM in /proc (the high-water mark of this address space): ru_maxrss would
    carry the parent's peak across exec.
    """
    code = (
        "import numpy as np, hcvt\n"
        "def hwm():\n"
        "    for line in open('/proc/self/status'):\n"
        "        if line.startswith('VmHWM'):\n"
        "            return int(line.split()[1])\n"
        "sq = hcvt.Domain.from_polygon([(0,0),(1,0),(1,1),(0,1)])\n"
        "s = np.random.default_rng(0).uniform(0, 1, (1_000_000, 2))\n"
        "base = hwm()\n"
        "d = hcvt.voronoi(sq, s)\n"
        "print(base, hwm())\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    base_kb, peak_kb = map(int, out.stdout.split())
    return peak_kb / 1e6, (peak_kb - base_kb) / 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="1k and 10k only")
    args = parser.parse_args()
    sizes = [1_000, 10_000] if args.quick else [1_000, 10_000, 100_000]
    try:
        import pysdot  # noqa: F401

        have_pysdot = True
    except ImportError:
        have_pysdot = False
        print("pysdot not installed (pip install pysdot==0.2.16): its column is skipped")
    print(f"threads: {hcvt.get_num_threads()}, cores: {os.cpu_count()}")
    header = (
        f"{'domain':24} {'n':>8} {'hcvt s':>9} {'pysdot s':>9} {'recipe s':>9} "
        f"{'GEOS s':>9} {'x pysdot':>9} {'x recipe':>9} {'x GEOS':>8}"
    )
    print(header)
    for name, path in DOMAINS.items():
        domain = load(path)
        assembly = pysdot_domain(domain) if have_pysdot else None
        for n in sizes:
            sites = sample(domain, n)
            ours = median_seconds(run_hcvt, 5, domain, sites)
            slow_repeats = 1 if n >= 100_000 else 3
            recipe = median_seconds(run_recipe, slow_repeats, domain, sites)
            geos = median_seconds(run_geos, slow_repeats, domain, sites)
            sdot = median_seconds(run_pysdot, 3, assembly, sites) if have_pysdot else np.nan
            print(
                f"{name:24} {n:>8} {ours:9.4f} {sdot:9.4f} {recipe:9.4f} {geos:9.4f} "
                f"{sdot / ours:9.1f} {recipe / ours:9.1f} {geos / ours:8.1f}",
                flush=True,
            )
    if not args.quick:
        domain = load(None)
        sites = sample(domain, 1_000_000)
        ours = median_seconds(run_hcvt, 3, domain, sites)
        peak, grown = peak_memory_1m()
        print(f"unit square, 1M sites: hcvt {ours:.3f} s (median of 3)")
        print(f"peak resident memory at 1M: {peak:.2f} GB (diagram adds {grown:.2f} GB)")
    print(
        f"this process peak RSS: {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6:.2f} GB"
    )


if __name__ == "__main__":
    main()
