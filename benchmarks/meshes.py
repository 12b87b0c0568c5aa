"""Time the cell geometry and conforming mesh (issue 19) against the diagram itself.

Run ``OPENBLAS_NUM_THREADS=1 python benchmarks/meshes.py`` (``--quick`` for a short run).
For each case it prints the median seconds of, in the same run:

- ``diagram``: ``hcvt.voronoi`` (moments only), the reference;
- ``mesh``: the conforming mesh in the core (``_core.mesh``, what ``Diagram.mesh()``
  computes once), and its ratio to the diagram (the issue asks for at most 3x on 100k
  Armadillo cells);
- ``cells()``: the mesh plus the per-cell triangulations of ``Diagram.cells()``;
- ``old cells()``: the path this replaced, kept here only for comparison: the diagram run
  again with its convex cells, and every cell that meets the boundary intersected with the
  whole mesh by manifold3d in Python (one run, on the smaller cases only: it is slow).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

import numpy as np

import hcvt
from hcvt import _core
from timing import median_seconds

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d"


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


def old_cells(d: hcvt.Diagram) -> list[Any]:
    """The 3D ``Diagram.cells()`` before issue 19: manifold3d boolean per boundary cell."""
    import manifold3d as m3

    arrays = _core.voronoi(d.domain._core, d.sites, keep_cells=True)
    vo, vertices = arrays["cell_vertex_offsets"], arrays["cell_vertices"]
    fo, faces = arrays["cell_face_offsets"], arrays["cell_faces"]
    solid = m3.Manifold(
        m3.Mesh64(
            vert_properties=np.ascontiguousarray(d.domain.vertices, dtype=np.float64),
            tri_verts=np.ascontiguousarray(d.domain.faces, dtype=np.uint32),
        )
    )
    out = []
    for i in range(d.n):
        v, f = vertices[vo[i] : vo[i + 1]], faces[fo[i] : fo[i + 1]]
        if d.boundary_measure[i] == 0:
            out.append((v, f))
        else:
            mesh = (m3.Manifold.hull_points(v) ^ solid).to_mesh64()
            out.append((np.asarray(mesh.vert_properties)[:, :3], mesh.tri_verts))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small cases, one repeat")
    args = parser.parse_args()
    if not DATA.exists():
        sys.exit(f"data not found: {DATA}")
    cases = [("sphere.ply", 2_000, True), ("bunny.off", 10_000, True)]
    cases += [("armadillo.obj", 100_000, False)]
    repeat = 1 if args.quick else 3
    if args.quick:
        cases = [("sphere.ply", 2_000, True), ("armadillo.obj", 10_000, True)]
    print(f"threads: {_core.get_num_threads()}, repeats: {repeat} (medians, seconds)")
    header = f"{'mesh':<16}{'cells':>8}{'diagram':>10}{'mesh':>10}{'ratio':>7}"
    header += f"{'cells()':>10}{'old cells()':>13}{'old/new':>9}"
    print(header)
    for name, n, with_old in cases:
        domain = hcvt.load_domain(DATA / name)
        sites = interior_sites(domain, n, seed=19)
        d = hcvt.voronoi(domain, sites)
        t_diagram = median_seconds(hcvt.voronoi, repeat, domain, sites)
        t_mesh = median_seconds(_core.mesh, repeat, domain._core, d.sites)

        def new_cells(d: hcvt.Diagram = d) -> None:
            d._mesh = None
            d.cells()

        t_cells = median_seconds(new_cells, repeat)
        old = median_seconds(old_cells, 1, d) if with_old else float("nan")
        print(
            f"{name:<16}{n:>8}{t_diagram:>10.3f}{t_mesh:>10.3f}{t_mesh / t_diagram:>7.2f}"
            f"{t_cells:>10.3f}{old:>13.3f}{old / t_cells:>9.1f}"
        )


if __name__ == "__main__":
    main()
