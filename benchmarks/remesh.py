"""Isotropic remeshing with n vertices: hcvt against pyacvd and MeshLab, side by side.

For each model and n, three remeshers on the same input surface:

- ``hcvt.remesh``: n sites random by area, a restricted CVT by L-BFGS (gap rule at
  remesh's default tol 1e-2, tighter while the triangulation has defects, at most
  ``--max-iter`` iterations in all), the restricted Delaunay triangulation;
- pyacvd 0.4.0 (approximated CVT by clustering the input's vertices, Valette et al.
  2008): ``Clustering(mesh)``, the input subdivided until it has at least 3n vertices
  (pyacvd's own advice: clusters of several vertices), ``cluster(n)``, ``create_mesh()``;
- MeshLab's isotropic explicit remeshing (pymeshlab, 10 iterations): the target edge
  length ``L`` tuned (``L ← L · sqrt(count / n)`` from the equilateral estimate
  ``sqrt(2A / (√3 n))``) until the vertex count is within 1% of n; the time of the
  final run is reported, the tuning runs are counted apart.

Every output is measured by :func:`hcvt.surface_quality` against the input: Q min/mean
(Frey–Borouchaki ``6/√3 · A/(p·h)``), least angle θmin, % of angles < 30°, Hausdorff
distance both ways (% of the bounding-box diagonal, to 0.1%: a branch and bound over
each mesh's triangles, not sampled; ``>`` before it where the search ran out of nearest
points and the figure is a lower bound only: until 2026-12-04 such figures were printed
unmarked, e.g. hcvt's bunny 20k 0.181 for a certified 0.205), manifold/closed and genus
by edge counts, and the seconds of the remeshing itself, wall and CPU (their ratio is the
cores it used). ``hcvt.remesh``'s quality is computed when first read (since 2026-12-04;
before, every call paid its exact Hausdorff distance, ~0.9 CPU s on armadillo 5k, which
the wall seconds left out and the CPU counted): the table measures every code's output
apart, outside both columns. Every code gets the same cores: by default all of the machine's (hcvt's
default threads; pyacvd's kd-tree runs OpenMP threads: it is not single-threaded, it used
~1.8 cores on armadillo 5k; MeshLab's remeshing is single-threaded), with ``--cores 1``
every thread pinned to one CPU, hcvt on one thread and ``OMP_NUM_THREADS=1``
(``timing.use_cores``). Until 2026-12-04 this script pinned hcvt alone to one thread and
left pyacvd its OpenMP threads. The header prints the load average at the start (the machine
may be shared): ratios are of runs taken in turn in the same process.

    OPENBLAS_NUM_THREADS=1 python benchmarks/remesh.py [--quick] [--models bunny ...] [--n ...]
        [--cores 1]

(Where pymeshlab's plugins fail to load, "libgomp.so.1: cannot allocate memory in static
TLS block", and ``meshing_isotropic_explicit_remeshing`` is then missing: run with
``LD_PRELOAD=<site-packages>/pymeshlab/lib/libgomp.so.1``.)

The ``hcvt`` row is ``hcvt.remesh``'s defaults, ``tighten=True`` among them (vertices moved
along the input where the mesh is farthest from it, :mod:`hcvt.surface.tighten`);
``--plain`` adds a row ``hcvt-t`` with ``tighten=False``, and ``--min-angle A`` a row
``hcvt>A`` with ``min_angle=A``.

``--features ANGLE`` keeps the sharp edges above ANGLE degrees in both hcvt
(``hcvt.remesh(features=ANGLE)``) and MeshLab (its ``featuredeg``, 30 by default otherwise);
pyacvd has no such option.

``--large`` then times one restricted diagram of 1M sites on a 1.38M-triangle surface
(:mod:`surface_large`).

``--pictures DIR`` also draws each case's three meshes side by side, triangles coloured by
Q and shaded by a light, as ``DIR/remesh_<model>_<n>.png`` (matplotlib, off-screen; the
pictures of docs/guide/surfaces.md: ``--models bunny fandisk --n 5000 --pictures
docs/results``).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import json
import math
import time
import warnings
from pathlib import Path

import numpy as np

import hcvt
from hcvt.surface.quality import HausdorffWarning
from timing import cpu_seconds, use_cores

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d"
MODELS = {
    "bunny": "bunny.off",
    "kitten": "kitten.obj",
    "fandisk": "fandisk.off",
    "armadillo": "armadillo.obj",
}
#: Pictures: the axis pointing up on screen, the camera's azimuth and elevation (degrees),
#: the zoom (matplotlib's, of the box in its panel: above 1 a tilted box is cropped).
VIEWS = {
    "bunny": (1, 20.0, 15.0, 1.25),
    "kitten": (2, 30.0, 15.0, 1.1),
    "fandisk": (2, 35.0, 30.0, 0.9),
    "armadillo": (1, 200.0, 10.0, 1.1),
}
#: The peers' names in the pictures' titles.
TITLES = {"hcvt": "hcvt.remesh", "pyacvd": "pyacvd", "meshlab": "MeshLab isotropic"}
#: MeshLab: how close the vertex count must come to n, and the most tuning runs.
COUNT_RTOL = 0.01
MAX_TUNING = 12


def quality(vertices: np.ndarray, faces: np.ndarray, reference: tuple) -> dict:
    """The columns of the table for one output mesh."""
    with warnings.catch_warnings():
        # Not certified: the table marks it (hausdorff_cell).
        warnings.simplefilter("ignore", HausdorffWarning)
        q = hcvt.surface_quality(vertices, faces, reference)
    return {
        "vertices": q.vertices,
        "q_min": q.q_min,
        "q_mean": q.q_mean,
        "angle_min": q.angle_min,
        "below_30": q.below_30,
        "hausdorff": q.hausdorff,
        "hausdorff_to_reference": q.hausdorff_to_reference,
        "hausdorff_from_reference": q.hausdorff_from_reference,
        "hausdorff_bound": q.hausdorff_bound,
        "hausdorff_certified": q.hausdorff_certified,
        "manifold": q.manifold,
        "closed": q.closed,
        "genus": q.genus,
    }


def hausdorff_cell(row: dict) -> str:
    """The H % column: the distance, ``>`` before it where it is a lower bound only.

    The search ran out of nearest points there; the bound is in the JSON rows
    (``hausdorff_bound``).
    """
    mark = "" if row["hausdorff_certified"] else ">"
    return f"{mark}{row['hausdorff']:.3f}".rjust(6)


def run_hcvt(
    domain: hcvt.Domain,
    n: int,
    max_iter: int,
    features: float | None = None,
    tighten: bool = True,
    min_angle: float | None = None,
) -> tuple[dict, np.ndarray, np.ndarray]:
    cpu = cpu_seconds()
    out = hcvt.remesh(
        domain,
        n,
        seed=0,
        max_iter=max_iter,
        features=features,
        tighten=tighten,
        min_angle=min_angle,
    )
    info = {
        "moves": out.moves,
        "freed": out.freed,
        "seconds": out.seconds,  # the CVT and the triangulation
        # The whole call (its quality is computed when first read, not here).
        "cpu": cpu_seconds() - cpu,
        "iterations": out.iterations,
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
    start, cpu = time.perf_counter(), cpu_seconds()
    clus = pyacvd.Clustering(mesh)
    # Each subdivision about quadruples the vertices.
    subdivisions = math.ceil(math.log(3 * n / len(vertices), 4)) if 3 * n > len(vertices) else 0
    if subdivisions:
        clus.subdivide(subdivisions)
    clus.cluster(n)
    out = clus.create_mesh()
    seconds, cpu = time.perf_counter() - start, cpu_seconds() - cpu
    f = out.faces.reshape(-1, 4)[:, 1:] if out.n_cells else np.zeros((0, 3), dtype=int)
    info = {"seconds": seconds, "cpu": cpu, "subdivisions": subdivisions}
    return info, np.asarray(out.points), f


def meshlab_once(
    vertices: np.ndarray, faces: np.ndarray, length: float, features: float | None = None
) -> tuple[float, float, np.ndarray, np.ndarray]:
    """Wall and CPU seconds, vertices and faces of one MeshLab remeshing at ``length``."""
    import pymeshlab

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(vertices, faces))
    start, cpu = time.perf_counter(), cpu_seconds()
    crease = {} if features is None else {"featuredeg": features}
    ms.meshing_isotropic_explicit_remeshing(
        iterations=10, targetlen=pymeshlab.PureValue(length), **crease
    )
    seconds, cpu = time.perf_counter() - start, cpu_seconds() - cpu
    m = ms.current_mesh()
    return seconds, cpu, m.vertex_matrix(), m.face_matrix()


def run_meshlab(
    vertices: np.ndarray, faces: np.ndarray, area: float, n: int, features: float | None = None
) -> tuple[dict, np.ndarray, np.ndarray]:
    length = math.sqrt(2.0 * area / (math.sqrt(3.0) * n))
    tuning, tries = 0.0, 0
    while True:
        seconds, cpu, v, f = meshlab_once(vertices, faces, length, features)
        tries += 1
        count = len(v)
        if abs(count - n) <= COUNT_RTOL * n or tries == MAX_TUNING:
            break
        tuning += seconds
        length *= math.sqrt(count / n)
    info = {"seconds": seconds, "cpu": cpu, "tries": tries, "tuning_seconds": tuning}
    return {**info, "length": length}, v, f


def picture(model: str, n: int, meshes: dict, path: Path) -> None:
    """The meshes of one case side by side, triangles coloured by Q, shaded by a light.

    ``meshes`` maps a code to ``(vertices (V, 3), faces (F, 3), quality row)``. Drawn by
    matplotlib (off-screen, no OpenGL): the painter's order of Poly3DCollection, fine
    for these convex-ish views.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib import colormaps
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    from hcvt.surface.quality import triangle_quality

    up, azimuth, elevation, zoom = VIEWS[model]
    # Screen axes: the model's `up` axis becomes z (matplotlib's vertical).
    order = [k for k in range(3) if k != up] + [up]
    cmap, norm = colormaps["viridis"], plt.Normalize(0.3, 1.0)
    fig = plt.figure(figsize=(5.0 * len(meshes), 5.4), dpi=130)
    for column, (code, (vertices, faces, row)) in enumerate(meshes.items()):
        v = np.asarray(vertices)[:, order]
        f = np.asarray(faces)
        corners = v[f]
        normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
        normals /= np.maximum(np.linalg.norm(normals, axis=1), 1e-300)[:, None]
        view = np.radians(azimuth)
        light = np.array([np.cos(view), np.sin(view), 0.8])
        light /= np.linalg.norm(light)
        shade = 0.45 + 0.55 * np.abs(normals @ light)
        colours = cmap(norm(triangle_quality(np.asarray(vertices), f)))
        colours[:, :3] *= shade[:, None]
        ax = fig.add_subplot(1, len(meshes), column + 1, projection="3d")
        ax.add_collection3d(
            Poly3DCollection(
                corners, facecolors=colours, edgecolors=(0, 0, 0, 0.25), linewidths=0.1
            )
        )
        lo, hi = v.min(axis=0), v.max(axis=0)
        for set_lim, a, b in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), lo, hi, strict=True):
            set_lim(a, b)
        ax.set_box_aspect(hi - lo, zoom=zoom)  # true proportions, filling the panel
        ax.view_init(elev=elevation, azim=azimuth)
        ax.set_axis_off()
        ax.set_title(
            f"{TITLES.get(code, code)}: {row['vertices']} vertices\nQ min {row['q_min']:.3f}, mean "
            f"{row['q_mean']:.3f}, θmin {row['angle_min']:.1f}°\nHausdorff "
            f"{hausdorff_cell(row).strip()}% of the diagonal",
            fontsize=10,
        )
    bar = fig.colorbar(
        plt.cm.ScalarMappable(norm=norm, cmap=cmap), ax=fig.axes, shrink=0.6, pad=0.02
    )
    bar.set_label("triangle quality Q (1 equilateral; below 0.3 in the darkest colour)")
    fig.suptitle(f"{model}, n = {n}: triangles coloured by Q (benchmarks/remesh.py)")
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--models", nargs="+", default=list(MODELS), choices=list(MODELS))
    parser.add_argument("--n", nargs="+", type=int, default=[5000, 20000])
    parser.add_argument("--max-iter", type=int, default=100)
    parser.add_argument("--quick", action="store_true", help="bunny and fandisk at n = 5000")
    parser.add_argument("--json", type=Path, help="write the rows here")
    parser.add_argument("--pictures", type=Path, help="draw each case's meshes into this folder")
    parser.add_argument("--features", type=float, help="keep sharp edges above this angle (°)")
    parser.add_argument(
        "--large",
        action="store_true",
        help="then one restricted diagram of 1M sites on armadillo subdivided to 1.38M "
        "triangles (benchmarks/surface_large.py): seconds, cells/s, peak memory",
    )
    parser.add_argument(
        "--plain",
        action="store_true",
        help="also a row 'hcvt-t': remesh(tighten=False), without the vertices moved to "
        "lower the Hausdorff distance",
    )
    parser.add_argument(
        "--min-angle",
        type=float,
        help="also a row 'hcvt>A': remesh(min_angle=A), the tightening moves allowed "
        "down to this least angle (°)",
    )
    parser.add_argument(
        "--cores", type=int, default=None, help="pin every code to this many CPUs (default: all)"
    )
    parser.add_argument(
        "--hcvt-only",
        action="store_true",
        help="only hcvt's rows (the peers' quality does not change from run to run; their "
        "seconds do, so ratios need a full run)",
    )
    args = parser.parse_args()
    if args.quick:
        args.models, args.n = ["bunny", "fandisk"], [5000]
    cores = use_cores(args.cores)
    if args.cores is not None:
        hcvt.set_num_threads(args.cores)
    rows = []
    header = (
        f"{'model':10} {'n':>6} {'code':8} {'verts':>6} {'Qmin':>6} {'Qmean':>6} {'θmin':>6} "
        f"{'%<30':>6} {'H %':>6} {'manif':>5} {'genus':>5} {'s':>8} {'cpu s':>8} {'s/hcvt':>7}"
    )
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"load average {load} at the start; ratios are in-run; {cores}")
    if args.features is not None:
        print(f"sharp features above {args.features}° kept by hcvt and MeshLab")
    print(header)
    for model in args.models:
        domain = hcvt.load_domain(DATA / MODELS[model], surface=True)
        v, f = domain.vertices, domain.faces
        reference = (v, f)
        for n in args.n:
            results = {}
            info, rv, rf = run_hcvt(domain, n, args.max_iter, args.features)
            results["hcvt"] = (info, rv, rf)
            if args.plain:
                results["hcvt-t"] = run_hcvt(domain, n, args.max_iter, args.features, False)
            if args.min_angle is not None:
                results[f"hcvt>{args.min_angle:g}"] = run_hcvt(
                    domain, n, args.max_iter, args.features, True, args.min_angle
                )
            if not args.hcvt_only:
                results["pyacvd"] = run_pyacvd(v, f, n)
                results["meshlab"] = run_meshlab(v, f, domain.volume, n, args.features)
            base = results["hcvt"][0]["seconds"]
            drawn = {}
            for code, (info, ov, of) in results.items():
                q = quality(ov, of, reference)
                row = {"model": model, "n": n, "code": code, **info, **q}
                rows.append(row)
                drawn[code] = (ov, of, row)
                print(
                    f"{model:10} {n:6d} {code:8} {q['vertices']:6d} {q['q_min']:6.3f} "
                    f"{q['q_mean']:6.3f} {q['angle_min']:6.2f} {q['below_30']:6.2f} "
                    f"{hausdorff_cell(q)} {str(q['manifold']):>5} {q['genus']:5d} "
                    f"{info['seconds']:8.2f} {info['cpu']:8.2f} {info['seconds'] / base:7.2f}",
                    flush=True,
                )
            extra = results["hcvt"][0]
            peers = (
                ""
                if args.hcvt_only
                else f"; meshlab: {results['meshlab'][0]['tries']} runs to reach n ± 1% (the "
                f"final one timed; {results['meshlab'][0]['tuning_seconds']:.2f} s before it); "
                f"pyacvd: {results['pyacvd'][0]['subdivisions']} subdivisions"
            )
            print(
                f"{'':10} hcvt: {extra['iterations']} iterations ({extra['stop']}), "
                f"{extra['moves']} vertices moved by tighten, "
                + (f"{extra['freed']} feature sites freed, " if extra["freed"] else "")
                + f"defects {extra['defects'] or 'none'}{peers}",
                flush=True,
            )
            if args.pictures:
                picture(model, n, drawn, args.pictures / f"remesh_{model}_{n}.png")
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1, default=str))
    if args.large:
        from surface_large import large_row

        large_row()


if __name__ == "__main__":
    main()
