"""Seconds to place exactly n sites with each method of ``hcvt.initialise``.

Domains: a glyph with two holes (dejavu_sans_B), a square with a round hole
(triangle_square_circle_hole) and two closed meshes (bunny, 3.5k vertices; armadillo, 43k).
n = 10k and 1M; in 3D at 1M only random, halton and lattice, to keep the run short:
Hammersley tests whole box sets of ~n V_box / V points per box count tried (one run for the
bunny at 1M: 7.0 s, exact on the search's first pass).

Peer, timed in the same run: the exact lattice as one would first write it, the same
pose and spacing search but counting with an inside test of every lattice point of the
bounding box (ours counts by rows, touching only the rows that meet the boundary). The
peer keeps no clearance from the boundary, so its lattice differs; only its time compares.

    OPENBLAS_NUM_THREADS=1 python benchmarks/initialise.py [--quick]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import importlib
from pathlib import Path

import numpy as np

import hcvt
from timing import median_seconds

init = importlib.import_module("hcvt.seeding.initialisation")

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
DOMAINS = {
    "glyph B (2 holes)": DATA / "2d" / "dejavu_sans_B.geojson",
    "square with round hole": DATA / "2d" / "triangle_square_circle_hole.geojson",
    "bunny (mesh)": DATA / "3d" / "bunny.off",
    "armadillo (mesh)": DATA / "3d" / "armadillo.obj",
}


def naive_lattice(domain: hcvt.Domain, n: int, seed: int = 0) -> int:
    """The peer: same pose and spacing search, every box lattice point tested; its count."""
    rng = np.random.default_rng(seed)
    cell_volume = {2: np.sqrt(3.0) / 2.0, 3: 0.5}[domain.dim]
    scale0 = float((domain.volume / n / cell_volume) ** (1.0 / domain.dim))
    offset, rotation = init._random_pose(domain, scale0, rng)
    lo, hi = domain.bounds
    corners = np.array(np.meshgrid(*zip(lo, hi, strict=True))).reshape(domain.dim, -1).T

    def count(scale: float) -> int:
        unit = (corners - offset) @ rotation / scale
        first, last = _span(unit)
        first, last = np.floor(first) - 1, np.ceil(last) + 2
        ranges = [np.arange(a, b) for a, b in zip(first, last, strict=True)]
        grid = np.stack(np.meshgrid(*ranges, indexing="ij"), axis=-1).reshape(-1, domain.dim)
        if domain.dim == 2:  # hexagonal: rows j √3/2, points i + j/2
            points = np.column_stack([grid[:, 0] + grid[:, 1] / 2, grid[:, 1] * np.sqrt(0.75)])
        else:  # BCC: cube corners and centres
            points = np.concatenate([grid, grid + 0.5])
        return int(domain.contains(offset + scale * points @ rotation.T).sum())

    return init._search_scale(count, n, scale0)[1]


def _span(unit: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index ranges covering the box in lattice coordinates (hexagonal rows are sheared)."""
    lo, hi = unit.min(axis=0), unit.max(axis=0)
    if unit.shape[1] == 2:
        rows = (lo[1] / np.sqrt(0.75), hi[1] / np.sqrt(0.75))
        return np.array([lo[0] - rows[1] / 2, rows[0]]), np.array([hi[0] - rows[0] / 2, rows[1]])
    return lo, hi


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10k sites only")
    args = parser.parse_args()
    sizes = [10_000] if args.quick else [10_000, 1_000_000]
    print(f"hcvt threads: {hcvt.get_num_threads()}; medians of 3 runs (1 at 1M in 3D)")
    print(f"{'domain':24} {'n':>9} " + " ".join(f"{m:>11}" for m in (*init.METHODS, "naive lat.")))
    for name, path in DOMAINS.items():
        domain = hcvt.load_domain(path)
        for n in sizes:
            repeats = 1 if (n > 100_000 and domain.dim == 3) else 3
            cells = []
            for method in init.METHODS:
                if n > 100_000 and domain.dim == 3 and method == "hammersley":
                    cells.append("-")
                    continue
                seconds = median_seconds(hcvt.initialise, repeats, domain, n, method)
                cells.append(f"{seconds:.3f}")
            if n > 100_000 and domain.dim == 3:
                cells.append("-")
            else:
                cells.append(f"{median_seconds(naive_lattice, 1, domain, n):.3f}")
            print(f"{name:24} {n:>9} " + " ".join(f"{c:>11}" for c in cells), flush=True)


if __name__ == "__main__":
    main()
