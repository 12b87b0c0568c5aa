"""Isotropic remeshing with n vertices: hcvt against pyacvd and MeshLab, side by side.

For each model and n, three remeshers on the same input surface:

- ``hcvt.remesh``: n sites random by area, a restricted CVT by L-BFGS (gap rule, tol
  1e-4, at most ``--max-iter`` iterations), the restricted Delaunay triangulation;
- pyacvd 0.4.0 (approximated CVT by clustering the input's vertices, Valette et al.
  2008): ``Clustering(mesh)``, the input subdivided until it has at least 3n vertices
  (pyacvd's own advice: clusters of several vertices), ``cluster(n)``, ``create_mesh()``;
- MeshLab's isotropic explicit remeshing (pymeshlab, 10 iterations): the target edge
  length ``L`` tuned (``L ← L · sqrt(count / n)`` from the equilateral estimate
  ``sqrt(2A / (√3 n))``) until the vertex count is within 1% of n; the time of the
  final run is reported, the tuning runs are counted apart.

Every output is measured by :func:`hcvt.surface_quality` against the input: Q min/mean
(Frey–Borouchaki ``6/√3 · A/(p·h)``), least angle θmin, % of angles < 30°, Hausdorff
distance both ways (% of the bounding-box diagonal, sampled), manifold/closed and genus
by edge counts, and the seconds of the remeshing itself. One thread each (hcvt and
pyacvd; MeshLab is single-threaded). Timings are under load (other jobs share the
machine): ratios are of runs taken in turn in the same process.

    OPENBLAS_NUM_THREADS=1 python benchmarks/remesh.py [--quick] [--models bunny ...] [--n ...]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

import hcvt

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d"
MODELS = {
    "bunny": "bunny.off",
    "kitten": "kitten.obj",
    "fandisk": "fandisk.off",
    "armadillo": "armadillo.obj",
}
#: MeshLab: how close the vertex count must come to n, and the most tuning runs.
COUNT_RTOL = 0.01
MAX_TUNING = 12


def quality(vertices: np.ndarray, faces: np.ndarray, reference: tuple, samples: int) -> dict:
    """The columns of the table for one output mesh."""
    q = hcvt.surface_quality(vertices, faces, reference, samples=samples)
    return {
        "vertices": q.vertices,
        "q_min": q.q_min,
        "q_mean": q.q_mean,
        "angle_min": q.angle_min,
        "below_30": q.below_30,
        "hausdorff": q.hausdorff,
        "manifold": q.manifold,
        "closed": q.closed,
        "genus": q.genus,
    }


def run_hcvt(domain: hcvt.Domain, n: int, max_iter: int) -> tuple[dict, np.ndarray, np.ndarray]:
    out = hcvt.remesh(domain, n, seed=0, max_iter=max_iter, samples=1000)
    info = {
        "seconds": out.seconds,  # the CVT and the triangulation, not the quality
        "iterations": out.cvt.iterations,
        "stop": out.cvt.stop_reason,
        "defects": out.defects,
    }
    return info, out.vertices, out.faces


def run_pyacvd(
    vertices: np.ndarray, faces: np.ndarray, n: int
) -> tuple[dict, np.ndarray, np.ndarray]:
    import pyacvd
    import pyvista as pv

    mesh = pv.PolyData(vertices, np.hstack([np.full((len(faces), 1), 3), faces]).ravel())
    start = time.perf_counter()
    clus = pyacvd.Clustering(mesh)
    # Each subdivision about quadruples the vertices.
    subdivisions = math.ceil(math.log(3 * n / len(vertices), 4)) if 3 * n > len(vertices) else 0
    if subdivisions:
        clus.subdivide(subdivisions)
    clus.cluster(n)
    out = clus.create_mesh()
    seconds = time.perf_counter() - start
    f = out.faces.reshape(-1, 4)[:, 1:] if out.n_cells else np.zeros((0, 3), dtype=int)
    return {"seconds": seconds, "subdivisions": subdivisions}, np.asarray(out.points), f


def meshlab_once(
    vertices: np.ndarray, faces: np.ndarray, length: float
) -> tuple[float, np.ndarray, np.ndarray]:
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertices, faces))
    start = time.perf_counter()
    ms.meshing_isotropic_explicit_remeshing(iterations=10, targetlen=pymeshlab.PureValue(length))
    seconds = time.perf_counter() - start
    m = ms.current_mesh()
    return seconds, m.vertex_matrix(), m.face_matrix()


def run_meshlab(
    vertices: np.ndarray, faces: np.ndarray, area: float, n: int
) -> tuple[dict, np.ndarray, np.ndarray]:
    length = math.sqrt(2.0 * area / (math.sqrt(3.0) * n))
    tuning, tries = 0.0, 0
    while True:
        seconds, v, f = meshlab_once(vertices, faces, length)
        tries += 1
        count = len(v)
        if abs(count - n) <= COUNT_RTOL * n or tries == MAX_TUNING:
            break
        tuning += seconds
        length *= math.sqrt(count / n)
    return {"seconds": seconds, "tries": tries, "tuning_seconds": tuning, "length": length}, v, f


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=list(MODELS), choices=list(MODELS))
    parser.add_argument("--n", nargs="+", type=int, default=[5000, 20000])
    parser.add_argument("--max-iter", type=int, default=100)
    parser.add_argument("--samples", type=int, default=200_000)
    parser.add_argument("--quick", action="store_true", help="bunny and fandisk at n = 5000")
    parser.add_argument("--json", type=Path, help="write the rows here")
    args = parser.parse_args()
    if args.quick:
        args.models, args.n = ["bunny", "fandisk"], [5000]
    hcvt.set_num_threads(1)
    rows = []
    header = (
        f"{'model':10} {'n':>6} {'code':8} {'verts':>6} {'Qmin':>6} {'Qmean':>6} {'θmin':>6} "
        f"{'%<30':>6} {'H %':>6} {'manif':>5} {'genus':>5} {'s':>8} {'s/hcvt':>7}"
    )
    print("under load: other jobs share this 2-core machine; ratios are in-run")
    print(header)
    for model in args.models:
        domain = hcvt.load_domain(DATA / MODELS[model], surface=True)
        v, f = domain.vertices, domain.faces
        reference = (v, f)
        for n in args.n:
            results = {}
            info, rv, rf = run_hcvt(domain, n, args.max_iter)
            results["hcvt"] = (info, rv, rf)
            results["pyacvd"] = run_pyacvd(v, f, n)
            results["meshlab"] = run_meshlab(v, f, domain.volume, n)
            base = results["hcvt"][0]["seconds"]
            for code, (info, ov, of) in results.items():
                q = quality(ov, of, reference, args.samples)
                row = {"model": model, "n": n, "code": code, **info, **q}
                rows.append(row)
                print(
                    f"{model:10} {n:6d} {code:8} {q['vertices']:6d} {q['q_min']:6.3f} "
                    f"{q['q_mean']:6.3f} {q['angle_min']:6.2f} {q['below_30']:6.2f} "
                    f"{q['hausdorff']:6.3f} {str(q['manifold']):>5} {q['genus']:5d} "
                    f"{info['seconds']:8.2f} {info['seconds'] / base:7.2f}",
                    flush=True,
                )
            extra = results["hcvt"][0]
            print(
                f"{'':10} hcvt: {extra['iterations']} iterations ({extra['stop']}), "
                f"defects {extra['defects'] or 'none'}; meshlab: {results['meshlab'][0]['tries']} "
                f"runs to reach n ± 1%; pyacvd: {results['pyacvd'][0]['subdivisions']} "
                "subdivisions",
                flush=True,
            )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1, default=str))


if __name__ == "__main__":
    main()
