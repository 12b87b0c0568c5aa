"""Time writing a 100k-cell polyhedral mesh: OpenFOAM case (text, binary) and VTU.

Run ``OPENBLAS_NUM_THREADS=1 python benchmarks/export.py`` (``--cells 20000`` for a short
run). The mesh is the Voronoi diagram of uniform random sites in the unit box, built by
tests/meshes.py (scipy, one half-space intersection per cell; a few minutes for 100k
cells, cached in the temporary directory), or with ``--domain bunny.off`` (a file in
shared/data/3d) ``Diagram.mesh()`` of Halton sites in that mesh: its boundary cells have
the non-convex faces the VTU writer splits into triangles. Printed: median seconds of
each writer, the VTU's size, and ratios against peers in the same run -- meshio 5.3's VTU
writer on the same polyhedra, and OpenFOAM's own ``checkMesh`` reading (and checking) the
case we wrote.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from hcvt.export import mesh_quality, write_openfoam, write_vtu
from hcvt.io.vtu import _split_for_vtk
from hcvt.mesh.polymesh import PolyMesh
from timing import median_seconds

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import meshes  # noqa: E402 (tests/meshes.py: the builders)


def box_mesh(n: int, seed: int = 0) -> PolyMesh:
    """Voronoi mesh of ``n`` random sites in the unit box, cached as .npz."""
    cache = Path(tempfile.gettempdir()) / f"hcvt_bench_box_voronoi_{n}_{seed}.npz"
    if cache.exists():
        z = np.load(cache)
        return PolyMesh(**{k: z[k] for k in z.files if k != "n_cells"}, n_cells=int(z["n_cells"]))
    start = time.perf_counter()
    sites = np.random.default_rng(seed).uniform(0, 1, size=(n, 3))
    mesh = meshes.convex_voronoi(meshes.box_domain(), sites)
    print(f"built the mesh of {n} cells in {time.perf_counter() - start:.0f} s (cached: {cache})")
    np.savez(cache, **{k: getattr(mesh, k) for k in PolyMesh.__dataclass_fields__})
    return mesh


def domain_mesh(name: str, n: int) -> PolyMesh:
    """``Diagram.mesh()`` of ``n`` Halton sites in a mesh of shared/data/3d."""
    import hcvt

    data = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d"
    domain = hcvt.load_domain(data / name)
    return hcvt.voronoi(domain, hcvt.initialise(domain, n, "halton")).mesh()


def vtu_unsplit(mesh: PolyMesh, path: Path) -> None:
    """Our VTU writer with every face written whole: the cost of splitting for VTK."""
    from hcvt.export import vtu

    split, vtu._split_for_vtk = vtu._split_for_vtk, lambda m: m
    try:
        write_vtu(mesh, path)
    finally:
        vtu._split_for_vtk = split


def meshio_vtu(mesh: PolyMesh, path: Path) -> None:
    """Meshio's writer: polyhedra as lists of outward faces, in blocks by point count."""
    import meshio

    cf = mesh.cell_faces
    blocks: dict[int, list] = {}
    for c in range(mesh.n_cells):
        span = slice(cf.offsets[c], cf.offsets[c + 1])
        faces = [
            mesh.face(f) if out else mesh.face(f)[::-1]
            for f, out in zip(cf.faces[span], cf.outward[span], strict=True)
        ]
        count = len(np.unique(np.concatenate(faces)))
        blocks.setdefault(count, []).append(faces)
    cells = [(f"polyhedron{k}", v) for k, v in blocks.items()]
    meshio.Mesh(mesh.points, cells).write(path)


def check_mesh_seconds(case: Path) -> float | None:
    exe = shutil.which("checkMesh")
    if exe is None:
        return None
    env = dict(os.environ)
    env.setdefault("WM_PROJECT_DIR", "/usr/share/openfoam")
    start = time.perf_counter()
    subprocess.run([exe, "-case", str(case)], capture_output=True, check=True, env=env)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--cells", type=int, default=100_000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--domain", help="a mesh in shared/data/3d instead of the unit box")
    args = parser.parse_args()
    mesh = domain_mesh(args.domain, args.cells) if args.domain else box_mesh(args.cells)
    mesh.check()
    print(
        f"mesh: {mesh.n_cells} cells, {mesh.n_faces} faces, {len(mesh.points)} points, "
        f"{len(mesh.face_vertices)} face vertices"
    )
    written = _split_for_vtk(mesh.compacted()[0])
    print(
        f"VTU faces: {written.n_faces} ({written.n_faces / mesh.n_faces:.3f}x the mesh's: "
        "those VTK would triangulate wrongly are written as triangles)"
    )
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)

        def fresh(make):  # each write on a mesh whose cached geometry is recomputed
            return lambda: make(
                PolyMesh(**{k: getattr(mesh, k) for k in PolyMesh.__dataclass_fields__})
            )

        text = median_seconds(fresh(lambda m: write_openfoam(m, out / "text")), args.repeats)
        binary = median_seconds(
            fresh(lambda m: write_openfoam(m, out / "binary", binary=True)), args.repeats
        )
        vtu = median_seconds(fresh(lambda m: write_vtu(m, out / "c.vtu")), args.repeats)
        vtu_mb = (out / "c.vtu").stat().st_size / 1e6
        whole = median_seconds(fresh(lambda m: vtu_unsplit(m, out / "w.vtu")), args.repeats)
        compact = mesh.compacted()[0]
        split = median_seconds(fresh(lambda m: _split_for_vtk(compact)), args.repeats)
        whole_mb = (out / "w.vtu").stat().st_size / 1e6
        quality = median_seconds(fresh(mesh_quality), args.repeats)
        rows += [
            ("OpenFOAM case, text", text),
            ("OpenFOAM case, binary", binary),
            ("VTU (ours)", vtu),
            ("VTU (ours, no face split for VTK)", whole),
            ("  the face split alone (part of VTU)", split),
            ("quality (non-orth., skewness)", quality),
        ]
        try:
            peer = median_seconds(lambda: meshio_vtu(mesh, out / "m.vtu"), 1)
            rows.append(("VTU (meshio 5.3, same polyhedra)", peer))
        except ImportError:
            peer = None
        reading = check_mesh_seconds(out / "binary")
        if reading is not None:
            rows.append(("checkMesh on our binary case (OpenFOAM)", reading))
    print(f"\n{'task':42s} {'median s':>9s}")
    for name, seconds in rows:
        print(f"{name:42s} {seconds:9.2f}")
    print(f"\nVTU (ours): {vtu_mb:.1f} MB; with no face split for VTK {whole_mb:.1f} MB")
    print(f"VTU (ours) / no face split: {vtu / whole:.2f}x time, {vtu_mb / whole_mb:.3f}x size")
    print(f"face split / VTU (ours): {split / vtu:.2f}")
    if peer is not None:
        print(f"meshio VTU / ours: {peer / vtu:.1f}x")
    print(f"OpenFOAM text / binary: {text / binary:.1f}x")
    if reading is not None:
        print(f"checkMesh reading+checking / our binary write: {reading / binary:.1f}x")


if __name__ == "__main__":
    main()
