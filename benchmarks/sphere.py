"""Spherical CVTs: hcvt's Newton, L-BFGS and Lloyd against scipy's SphericalVoronoi + Lloyd.

Issue 35's sizes (the MPAS meshes 2,562 / 10,242 / 40,962 / 163,842 sites) from two
starts: the icosahedral sites themselves (``hcvt.initialise(..., method="icosahedral")``,
near a CVT: the converged mesh has exactly 12 pentagons) and uniform random sites (whose
CVT keeps defects: pentagon–heptagon pairs, counted). Per size, start and method it
prints the iterations, the diagrams computed, the seconds and the cells that are not
hexagons, each run to hcvt's default rule (RMS gap < 1e-7).

The recipe Python users run (issue 35): ``scipy.spatial.SphericalVoronoi`` for the cells,
each cell's centroid from its region (a fan of spherical triangles from the site,
``½ Σ θ_k n_k`` vectorised per triangle), the site moved to ``∫x / |∫x|``, repeated until
the same RMS gap ``|x_i − c_i| / √A_i`` or ``--recipe-seconds``; it runs in the same
process from each start at ``--recipe-sizes`` (from random sites both keep defects: the
cells that are not hexagons are counted for both), and the ratio of its seconds to each
hcvt method's is printed. The machine is shared: label the figures "under load".

A variable-resolution mesh (``--refined``, issue 35): cell width 30 km within 10° of the
Greenwich meridian and 240 km far from it on the Earth (R = 6371 km), with a tanh ramp over
the next 10° (:func:`hcvt.seeding.sphere.meridian_band_width`), as ``ρ = (h_fine/h)⁴``
(:class:`hcvt.density.SizingField`); ``n`` cells from ``∫ dA / ((√3/2) h²)`` (80,595),
the hierarchy with the density (``--refined-route hierarchical``, the default: coarse
CVTs subdivided along the spherical Delaunay edges, each level rebalanced to its coarse
cells' share of ``ρ^(1/2)``) or a start graded by ``ρ^(1/2)``
(``--refined-route random``), L-BFGS (``--refined-method``) to ``--tol``; it prints the
time, iterations, diagrams, RMS gap, cells that are not hexagons, and the grid spacing
(mean dcEdge per cell) over the requested width, median and 5-95% per band (within 8° of
the meridian; beyond 22°).

    OPENBLAS_NUM_THREADS=1 python benchmarks/sphere.py [--sizes 2562 40962]
        [--starts icosahedral random] [--methods newton lbfgs] [--recipe-sizes 2562]
        [--refined] [--refined-fine 30 --refined-coarse 240] [--refined-route hierarchical]
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np
from scipy.spatial import SphericalVoronoi

import hcvt
from hcvt.density import SizingField
from hcvt.seeding.hierarchy import Level
from hcvt.seeding.sphere import (
    cells_for_width,
    distance_to_meridian,
    icosahedral,
    meridian_band_width,
    random_sphere,
)

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")


def start_sites(n: int, start: str) -> np.ndarray:
    """The icosahedral sites of size ``n``, or ``n`` uniform random ones (seed 0)."""
    if start == "icosahedral":
        return icosahedral(n)
    return random_sphere(n, np.random.default_rng(0))


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


def run_hcvt(sites: np.ndarray, method: str, tol: float) -> dict[str, float]:
    domain = hcvt.Domain.sphere()
    t0 = time.perf_counter()
    res = hcvt.cvt(domain, sites, method=method, tol=tol, max_iter=20_000)
    seconds = time.perf_counter() - t0
    return {
        "seconds": seconds,
        "iterations": res.iterations,
        "diagrams": res.evaluations,
        "rms_gap": float(res.history["rms_gap"][-1]),
        "not_hexagons": int(np.sum(np.diff(res.diagram.neighbor_offsets) != 6)),
        "converged": res.converged,
    }


def row(name: str, r: dict[str, float]) -> str:
    diagrams = r.get("diagrams", r["iterations"] + 1)
    return (
        f"  {name:14s} {r['iterations']:6d} it {diagrams:6d} diagrams {r['seconds']:8.2f} s"
        f"  RMS gap {r['rms_gap']:.1e}  not hexagons {r['not_hexagons']}"
    )


class Progress:
    """Prints a long run's progress: every finished level, and an iterate every ``every`` s."""

    def __init__(self, start: float, every: float = 30.0) -> None:
        self.start, self.every, self.last = start, every, start

    def level(self, level: Level) -> None:
        """A finished level: sites, iterations, diagrams, RMS gap (``hierarchical_cvt``)."""
        h = level.history
        print(
            f"  {time.perf_counter() - self.start:8.1f} s  level of {level.n} sites: "
            f"{level.iterations} it, {int(h['evaluations'][-1])} diagrams, "
            f"RMS gap {float(h['rms_gap'][-1]):.2e}",
            flush=True,
        )

    def iterate(self, info: dict[str, object]) -> None:
        """An iterate (``hcvt.cvt``'s callback info), printed at most every ``every`` s."""
        now = time.perf_counter()
        if now - self.last < self.every:
            return
        self.last = now
        print(
            f"  {now - self.start:8.1f} s  {len(info['sites'])} sites: {info['step']} step, "  # type: ignore[arg-type]
            f"{info['evaluations']} diagrams, RMS gap {info['rms_gap']:.2e}, "
            f"max gap {info['max_gap']:.2e}",
            flush=True,
        )


def run_refined(
    fine: float, coarse: float, tol: float, degree: int, route: str, method: str | None
) -> None:
    """The band-refined Earth mesh: time, convergence and spacing per band (module docs)."""
    radius = 6371.0

    def width(points: np.ndarray) -> np.ndarray:
        return meridian_band_width(points, fine, coarse)

    n = cells_for_width(width, radius)
    earth = hcvt.Domain.sphere(radius)
    density = SizingField(width)
    print(
        f"\nrefined band: {fine:g} km within 10 deg of lon 0, {coarse:g} km beyond 20 deg, "
        f"{n} cells"
    )
    t0 = time.perf_counter()
    report = Progress(t0)
    if route == "hierarchical":
        result = hcvt.hierarchical_cvt(
            earth,
            n,
            density=density,
            tol=tol,
            method=method,
            quadrature_degree=degree,
            max_iter=20_000,
            callback=report.level,
            iteration_callback=report.iterate,
        )
        diagram, sites_out = result.diagram, result.sites
        levels = [(lv.n, lv.iterations, int(lv.history["evaluations"][-1])) for lv in result.levels]
        iterations = sum(lv.iterations for lv in result.levels)
        diagrams = sum(d for _, _, d in levels)
        gap = float(result.levels[-1].history["rms_gap"][-1])
        print(f"  levels (sites, iterations, diagrams): {levels}")
    else:
        sites = hcvt.initialise(earth, n, method="random", seed=0, density=density)
        res = hcvt.cvt(
            earth,
            sites,
            density=density,
            tol=tol,
            max_iter=20_000,
            method=method,
            quadrature_degree=degree,
            callback=report.iterate,
        )
        diagram, sites_out = res.diagram, res.sites
        iterations, diagrams = res.iterations, res.evaluations
        gap = float(res.history["rms_gap"][-1])
    seconds = time.perf_counter() - t0
    print(
        f"  {route} start: {seconds:.1f} s (under load), {iterations} it, {diagrams} diagrams, "
        f"RMS gap {gap:.1e}"
    )
    quality = hcvt.sphere_quality(diagram, width=width(sites_out))
    ratio = quality.spacing_ratio
    assert ratio is not None
    delta = np.degrees(distance_to_meridian(sites_out))
    for name, where in (("band (< 8 deg)", delta < 8.0), ("far (> 22 deg)", delta > 22.0)):
        r = ratio[where]
        spacing = np.median(quality.grid_spacing[where])
        print(
            f"  {name}: {where.sum()} cells, grid spacing median {spacing:.1f} km, "
            f"spacing / width median {np.median(r):.4f} (5-95%: {np.percentile(r, 5):.3f}-"
            f"{np.percentile(r, 95):.3f})"
        )
    sides = quality.summary()["sides"]
    print(f"  cells by sides: {sides}, not hexagons {n - sides.get('6', 0)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[2562, 10242, 40962, 163842])
    parser.add_argument("--starts", nargs="+", default=["icosahedral", "random"])
    parser.add_argument("--methods", nargs="+", default=["newton", "lbfgs"])
    parser.add_argument("--recipe-sizes", type=int, nargs="*", default=[2562, 40962])
    parser.add_argument("--recipe-seconds", type=float, default=120.0)
    parser.add_argument("--tol", type=float, default=1e-7)
    parser.add_argument("--refined", action="store_true", help="the band-refined Earth mesh")
    parser.add_argument("--refined-only", action="store_true", help="only that mesh")
    parser.add_argument("--refined-fine", type=float, default=30.0)
    parser.add_argument("--refined-coarse", type=float, default=240.0)
    parser.add_argument("--quadrature-degree", type=int, default=4)
    parser.add_argument(
        "--refined-route",
        choices=["random", "hierarchical"],
        default="hierarchical",
        help="graded random start, or hierarchical_cvt with the density",
    )
    parser.add_argument("--refined-method", default=None, help="optimiser (default: fastest)")
    args = parser.parse_args()
    print(
        f"hcvt threads: {hcvt.get_num_threads()}  OPENBLAS_NUM_THREADS: "
        f"{os.environ.get('OPENBLAS_NUM_THREADS')}  (timings under load: shared machine)"
    )
    if args.refined or args.refined_only:
        run_refined(
            args.refined_fine,
            args.refined_coarse,
            args.tol,
            args.quadrature_degree,
            args.refined_route,
            args.refined_method,
        )
    for n in [] if args.refined_only else args.sizes:
        for start in args.starts:
            sites = start_sites(n, start)
            print(f"\nn = {n}, {start} sites")
            runs = {m: run_hcvt(sites, m, args.tol) for m in args.methods}
            for m, r in runs.items():
                print(row(f"hcvt {m}", r) + ("" if r["converged"] else "  (not converged)"))
            if n in args.recipe_sizes:  # from either start: defects counted for both
                recipe = run_recipe(sites, args.tol, args.recipe_seconds)
                print(row("scipy recipe", recipe))
                for m, r in runs.items():
                    print(f"  recipe / hcvt {m}: {recipe['seconds'] / r['seconds']:.1f}x")


if __name__ == "__main__":
    main()
