"""A CVT of a region of the sphere: the Mediterranean Sea at the Earth's radius.

The rough outline of ``tests/test_sphere_region.py`` (48 vertices typed from well-known
coasts; Italy's boot makes it non-convex), ``n`` random sites, L-BFGS to the default rule
(RMS gap 1e-7). Prints the time, the iterations and the final gap; with ``--figure`` draws
the sites and the cells' Delaunay edges (``diagram.neighbors``) in lon/lat, sites coloured
by their cell's area: no edge crosses Italy, whose two seas' cells are not neighbours.

    python benchmarks/sphere_region.py -n 2000 --figure docs/results/sphere_region_med.png
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

import hcvt
from hcvt.geometry.sphere_region import unit_to_lonlat

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_sphere_region import MEDITERRANEAN  # noqa: E402

EARTH_KM = 6371.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("-n", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-iter", type=int, default=5000)
    parser.add_argument("--figure", type=Path, default=None)
    args = parser.parse_args()

    domain = hcvt.Domain.sphere(EARTH_KM, region=MEDITERRANEAN)
    sites = hcvt.initialise(domain, args.n, seed=args.seed)
    start = time.perf_counter()
    result = hcvt.cvt(domain, sites, max_iter=args.max_iter)
    seconds = time.perf_counter() - start
    gap = result.history["rms_gap"][-1]
    areas = result.diagram.volume
    print(
        f"Mediterranean, R = {EARTH_KM} km, area {domain.volume:.6g} km², n = {args.n}: "
        f"L-BFGS, {result.stop_reason} after {len(result.history['rms_gap']) - 1} "
        f"iterations, {seconds:.1f} s (under load), RMS gap {gap:.2e}, Σ areas / area - 1 = "
        f"{areas.sum() / domain.volume - 1:.1e}, cell area min/median/max "
        f"{areas.min():.4g}/{np.median(areas):.4g}/{areas.max():.4g} km²"
    )
    if args.figure is None:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    lonlat = unit_to_lonlat(result.sites)
    fig, ax = plt.subplots(figsize=(12, 5.5))
    outline = np.vstack((MEDITERRANEAN, MEDITERRANEAN[:1]))
    ax.plot(outline[:, 0], outline[:, 1], "k-", lw=1.2)
    pairs = result.diagram.neighbors
    segments = np.stack((lonlat[pairs[:, 0]], lonlat[pairs[:, 1]]), axis=1)
    from matplotlib.collections import LineCollection

    ax.add_collection(LineCollection(segments, colors="0.6", linewidths=0.3))
    points = ax.scatter(lonlat[:, 0], lonlat[:, 1], c=areas, s=3, cmap="viridis")
    fig.colorbar(points, ax=ax, label="cell area, km²")
    ax.set_aspect(1 / np.cos(np.radians(37)))
    ax.set_xlabel("longitude, °")
    ax.set_ylabel("latitude, °")
    ax.set_title(
        f"CVT of the Mediterranean (rough outline), {args.n} cells, L-BFGS, "
        f"RMS gap {gap:.1e}: sites and Delaunay edges"
    )
    fig.tight_layout()
    fig.savefig(args.figure, dpi=130)
    print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()
