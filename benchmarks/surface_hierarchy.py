"""Hierarchical against standard restricted CVTs on triangle surfaces, and remesh's start.

For each model and n, in turn in one process (one thread, under load: CPU seconds and
diagram counts are the figures to compare, ratios of runs taken side by side):

- ``standard``: ``hcvt.cvt(surface, hcvt.initialise(surface, n, seed=s), "lbfgs", tol=...)``;
- ``hierarchical``: ``hcvt.hierarchical_cvt(surface, n, seed=s, tol=..., method="lbfgs")``
  (its default on a surface: the levels before the last to an RMS gap of 1e-2, they only
  place the next level's sites);
- ``hier-paper``: the same with ``level_tol=tol`` (every level to the same tol, the
  paper's way), run only when the tol is tighter than 1e-2.

Each row: diagrams (evaluations of the energy, summed over levels), CPU seconds
(``time.process_time``), mean G and energy of the final diagram.

``--remesh`` then runs ``hcvt.remesh(surface, n, seed=s)`` with its random start and with
the start replaced by ``hierarchical_cvt(surface, n, seed=s, tol=REMESH_TOL)``'s sites (the
module's ``initialise`` patched for the call; remesh's own CVT then goes on from there):
seconds (remesh's, which include the start) and θmin, Q min, Hausdorff of the result.

    OPENBLAS_NUM_THREADS=1 python benchmarks/surface_hierarchy.py \
        [--models bunny.off kitten.obj] [--n 5000 20000] [--tols 1e-2 default] [--remesh]
"""

from __future__ import annotations

import argparse
import importlib
import os
import time
from pathlib import Path
from typing import Any

import numpy as np

import hcvt
from hcvt.optimise import GAP_TOL
from hcvt.surface.remesh import REMESH_TOL

# The module (``hcvt.surface.remesh`` the attribute is the function).
remesh_module = importlib.import_module("hcvt.surface.remesh")

DATA = Path(os.environ.get("HCVT_DATA", Path(__file__).parents[2] / "shared" / "data")) / "3d"


def cvt_rows(
    surface: hcvt.Domain, n: int, tol: float | None, seed: int, paper: bool = True
) -> list[dict[str, Any]]:
    """The standard and hierarchical CVTs of ``surface`` at ``n`` and ``tol``."""
    rows = []
    t = time.process_time()
    std = hcvt.cvt(surface, hcvt.initialise(surface, n, seed=seed), "lbfgs", tol=tol)
    rows.append(row("standard", std.evaluations, time.process_time() - t, std.diagram))
    variants: dict[str, dict[str, Any]] = {"hierarchical": {}}
    if paper and (tol is None or tol < 1e-2):
        variants["hier-paper"] = {"level_tol": GAP_TOL if tol is None else tol}
    for label, extra in variants.items():
        t = time.process_time()
        hier = hcvt.hierarchical_cvt(surface, n, seed=seed, tol=tol, method="lbfgs", **extra)
        seconds = time.process_time() - t
        levels = " ".join(f"{lv.n}:{lv.history['evaluations'][-1]}" for lv in hier.levels)
        evaluations = int(hier.history["evaluations"][-1])
        rows.append(row(label, evaluations, seconds, hier.diagram, levels))
    return rows


def row(
    label: str, evaluations: int, seconds: float, diagram: Any, levels: str = ""
) -> dict[str, Any]:
    return {
        "method": label,
        "diagrams": int(evaluations),
        "cpu": seconds,
        "mean_G": diagram.mean_G,
        "energy": diagram.energy,
        "levels": levels,
    }


def remesh_rows(surface: hcvt.Domain, n: int, seed: int) -> list[dict[str, Any]]:
    """``hcvt.remesh`` from its random start and from a hierarchical one."""
    rows = []
    for label in ("random start", "hierarchical start"):
        original = remesh_module.initialise
        if label == "hierarchical start":

            def start(domain: hcvt.Domain, m: int, **_: Any) -> np.ndarray:
                return hcvt.hierarchical_cvt(
                    domain, m, seed=seed, tol=REMESH_TOL, method="lbfgs"
                ).sites

            remesh_module.initialise = start  # type: ignore[assignment]
        try:
            t = time.process_time()
            out = hcvt.remesh(surface, n, seed=seed)
            cpu = time.process_time() - t
        finally:
            remesh_module.initialise = original
        q = out.quality
        rows.append(
            {
                "start": label,
                "seconds": out.seconds,
                "cpu": cpu,
                "iterations": out.iterations,
                "theta_min": q.angle_min,
                "q_min": q.q_min,
                "hausdorff": q.hausdorff,
                "defects": len(out.defects),
            }
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--models", nargs="+", default=["bunny.off", "kitten.obj"])
    parser.add_argument("--n", nargs="+", type=int, default=[5000, 20000])
    parser.add_argument("--tols", nargs="+", default=["1e-2", "default"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--remesh", action="store_true")
    parser.add_argument("--no-cvt", action="store_true", help="only the --remesh rows")
    parser.add_argument("--no-paper", action="store_true", help="no hier-paper rows")
    args = parser.parse_args()
    hcvt.set_num_threads(1)
    print(f"load: {os.getloadavg()[0]:.2f}", flush=True)
    for name in args.models:
        surface = hcvt.load_domain(DATA / name, surface=True)
        for n in args.n:
            for tol_text in [] if args.no_cvt else args.tols:
                tol = None if tol_text == "default" else float(tol_text)
                for r in cvt_rows(surface, n, tol, args.seed, not args.no_paper):
                    print(
                        f"{name:11s} n={n:6d} tol={tol_text:8s} {r['method']:13s} "
                        f"diagrams {r['diagrams']:5d}  cpu {r['cpu']:7.1f} s  "
                        f"mean G {r['mean_G']:.6f}  energy {r['energy']:.6e}  {r['levels']}",
                        flush=True,
                    )
            if args.remesh:
                for r in remesh_rows(surface, n, args.seed):
                    print(
                        f"{name:11s} n={n:6d} remesh {r['start']:18s} {r['seconds']:6.1f} s "
                        f"(cpu {r['cpu']:6.1f}) it {r['iterations']:4d}  "
                        f"θmin {r['theta_min']:5.2f}°  Q min {r['q_min']:.3f}  "
                        f"Hausdorff {r['hausdorff']:.3f}%  defects {r['defects']}",
                        flush=True,
                    )
            print(f"load: {os.getloadavg()[0]:.2f}", flush=True)


if __name__ == "__main__":
    main()
