"""Spherical CVTs from icosahedral sites: hcvt against scipy's SphericalVoronoi + Lloyd.

The recipe Python users run (issue 35): ``scipy.spatial.SphericalVoronoi`` for the cells,
each cell's centroid from its region (a fan of spherical triangles from the site,
``½ Σ θ_k n_k`` vectorised per triangle), the site moved to ``∫x / |∫x|``, repeated.
Both start from the same jittered icosahedral sites (a tenth of a spacing, fixed seed)
and run in this process, alternating, ``--repeat`` times; medians and the ratio are
printed with what each reached: the RMS gap ``|x_i − c_i| / √A_i`` (hcvt's default rule,
1e-7) and the number of cells that are not hexagons (a converged icosahedral CVT has
exactly 12 pentagons). The recipe stops at the same RMS gap or at ``--recipe-seconds``.

    OPENBLAS_NUM_THREADS=1 python benchmarks/sphere.py [--sizes 2562 40962] [--repeat 3]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time

import numpy as np
from scipy.spatial import SphericalVoronoi

import hcvt
from hcvt.seeding.sphere import icosahedral, random_sphere

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def start_sites(n: int) -> np.ndarray:
    """Icosahedral sites jittered in the tangent plane by a tenth of a spacing."""
    x = icosahedral(n)
    r = random_sphere(n, np.random.default_rng(0))
    r -= np.einsum("ij,ij->i", r, x)[:, None] * x
    x = x + 0.1 * math.sqrt(4 * math.pi / n) * r
    return np.ascontiguousarray(x / np.linalg.norm(x, axis=1)[:, None])


def recipe_step(sites: np.ndarray) -> tuple[np.ndarray, float, int]:
    """One Lloyd step by SphericalVoronoi: new sites, RMS gap, cells that are not hexagons."""
    sv = SphericalVoronoi(sites)
    sv.sort_vertices_of_regions()
    lengths = np.array([len(r) for r in sv.regions])
    owner = np.repeat(np.arange(len(sites)), lengths)
    flat = np.concatenate(sv.regions)
    starts = np.cumsum(lengths) - lengths
    nxt = np.arange(len(flat)) + 1
    nxt[starts + lengths - 1] = starts
    z, a, b = sites[owner], sv.vertices[flat], sv.vertices[flat[nxt]]
    det = np.einsum("ij,ij->i", z, np.cross(a, b))
    den = 1 + np.einsum("ij,ij->i", z, a) + np.einsum("ij,ij->i", a, b)
    den += np.einsum("ij,ij->i", b, z)
    area = np.bincount(owner, 2 * np.arctan2(det, den), minlength=len(sites))
    first = np.zeros_like(sites)
    for p, q in ((z, a), (a, b), (b, z)):  # ½ Σ θ n over each fan triangle's edges
        w = np.cross(p, q)
        s = np.linalg.norm(w, axis=1)
        theta = np.arctan2(s, np.einsum("ij,ij->i", p, q))
        term = 0.5 * (theta / np.where(s > 0, s, 1))[:, None] * w
        for k in range(3):
            first[:, k] += np.bincount(owner, term[:, k], minlength=len(sites))
    # scipy's sorted rings turn either way: area and first moment flip sign together.
    sign = np.sign(area)
    area, first = area * sign, first * sign[:, None]
    centroid = first / np.linalg.norm(first, axis=1)[:, None]
    gap = np.linalg.norm(centroid - sites, axis=1) / np.sqrt(area)
    return centroid, float(np.sqrt(np.mean(gap**2))), int(np.sum(lengths != 6))


def run_recipe(sites: np.ndarray, tol: float, seconds: float) -> dict[str, float]:
    t0 = time.perf_counter()
    iterations, gap, defects = 0, math.inf, -1
    while True:
        new, gap, defects = recipe_step(sites)
        if gap < tol or time.perf_counter() - t0 > seconds:
            break
        sites, iterations = new, iterations + 1
    return {
        "seconds": time.perf_counter() - t0,
        "iterations": iterations,
        "rms_gap": gap,
        "not_hexagons": defects,
    }


def run_hcvt(sites: np.ndarray, method: str) -> dict[str, float]:
    domain = hcvt.Domain.sphere()
    t0 = time.perf_counter()
    res = hcvt.cvt(domain, sites, method=method, max_iter=20_000)
    seconds = time.perf_counter() - t0
    return {
        "seconds": seconds,
        "iterations": res.iterations,
        "rms_gap": float(res.history["rms_gap"][-1]),
        "not_hexagons": int(np.sum(np.diff(res.diagram.neighbor_offsets) != 6)),
        "converged": res.converged,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[2562, 40962])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--recipe-seconds", type=float, default=120.0)
    parser.add_argument("--tol", type=float, default=1e-7)
    parser.add_argument("--methods", nargs="+", default=["lbfgs", "lloyd"])
    args = parser.parse_args()
    print(
        f"hcvt threads: {hcvt.get_num_threads()}  OPENBLAS_NUM_THREADS: "
        f"{os.environ.get('OPENBLAS_NUM_THREADS')}"
    )
    for n in args.sizes:
        sites = start_sites(n)
        rows: dict[str, list[dict[str, float]]] = {f"hcvt {m}": [] for m in args.methods}
        rows["recipe"] = []
        for _ in range(args.repeat):
            for m in args.methods:
                rows[f"hcvt {m}"].append(run_hcvt(sites, m))
            rows["recipe"].append(run_recipe(sites, args.tol, args.recipe_seconds))
        medians = {k: statistics.median(r["seconds"] for r in v) for k, v in rows.items()}
        print(f"\nn = {n}")
        for name, runs in rows.items():
            last = runs[-1]
            print(
                f"  {name:11s} median {medians[name]:8.3f} s  iterations {last['iterations']:6d}"
                f"  RMS gap {last['rms_gap']:.2e}  not hexagons {last['not_hexagons']}"
            )
        for m in args.methods:
            print(f"  recipe / hcvt {m}: {medians['recipe'] / medians[f'hcvt {m}']:.2f}x")


if __name__ == "__main__":
    main()
