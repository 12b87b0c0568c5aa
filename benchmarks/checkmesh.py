"""OpenFOAM's checkMesh and laplacianFoam on converged CVTs of real meshes, beside OpenFOAM's route.

Run ``OPENBLAS_NUM_THREADS=1 python benchmarks/checkmesh.py`` (needs OpenFOAM's
``checkMesh``, ``gmshToFoam`` and ``polyDualMesh``, and ``pip install gmsh``;
``WM_PROJECT_DIR`` defaults to Debian's ``/usr/share/openfoam``). For each case (bunny 50k,
cheese 10k by default; ``--cases bunny fandisk cheese -n 1000`` for the 1k table) it

1. converges a CVT to the default rule (Newton from scrambled Halton sites, seed 0) and
   keeps its sites in ``--cache`` (``<name>_<n>_newton.npy`` and ``.json``): a later run
   reads them and reprints the seconds the converging run took;
2. writes the conforming mesh as an OpenFOAM case twice, ``boundary_faces="exact"`` and
   ``"merged"`` (:mod:`hcvt.mesh.merge`, the default), timing the merge and the writing
   (the split mode, whose parts made laplacianFoam diverge, was removed: issue 30);
3. runs ``checkMesh`` on each and prints its verdict, its failed checks, its max
   non-orthogonality and skewness, and its total volume against the input mesh's volume,
   beside hcvt's own figures for the same mesh (:func:`hcvt.export.mesh_quality`) and,
   for the merged mesh, how much the volumes OpenFOAM computes moved from the exact
   cells' (total, sum of absolute per-cell changes, largest per-cell change); then
   laplacianFoam on a linear field (:func:`hcvt.io.solver.laplace_check`, issue 30):
   converged, last initial residual, RMS and largest error of T (spanning 2) at the
   cell centres;
4. for comparison, the same volume figures when every connected region of a cell's
   pieces is merged into one face (where it is one disc), not only the failing pieces;
5. for each cell whose faces still fail after merging, a search for any other grouping:
   random partitions of all its pieces into 2 to 4 connected groups (seed 0), counting
   those whose groups are all simple loops and those whose faces all pass (against the
   exact cell's centroid);
6. OpenFOAM's own route on the same shape (``--no-gmsh`` leaves it out): gmsh
   tetrahedra (the surface remeshed by gmsh's ``classifySurfaces``/``createGeometry``,
   element size set so that the tetrahedra have about ``n`` vertices, each of which
   becomes one dual cell; where gmsh cannot reparametrise the surface (the bunny: "wrong
   topology") or gives no mesh within ``GMSH_SECONDS`` (fandisk, cheese), the input
   triangles are kept as the boundary mesh, so the dual has more cells than ``n``),
   written as a version 2.2 ``.msh``, ``gmshToFoam``, then
   ``polyDualMesh -overwrite <feature angle>`` (60 degrees by default); checkMesh and
   laplacianFoam on it as on hcvt's meshes.

At the end a table: per shape and mesh, the cells, checkMesh's verdict, the total volume
checkMesh computes against the input mesh's, and laplacianFoam's last residual and RMS
error.

``docs/results/checkmesh.txt`` holds the output of one run.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

import hcvt
from hcvt.export import (
    laplace_check,
    merged_boundary,
    mesh_quality,
    write_openfoam,
)
from hcvt.io.openfoam import write_system
from hcvt.io.solver import LaplaceCheck
from hcvt.mesh.polymesh import PolyMesh
from hcvt.seeding.initialisation import initialise

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d"
NUM = r"([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)"
CASES = {
    "bunny": ("bunny.off", 50_000),
    "fandisk": ("fandisk.off", 10_000),
    "cheese": ("cheese.off", 10_000),
}
#: One line of the final table: shape, mesh, cells, checkMesh, volume error, residual, RMS.
Row = tuple[str, str, int, str, float, float, float]
ROWS: list[Row] = []


def converged_sites(name: str, n: int, cache: Path) -> tuple[np.ndarray, dict]:
    """Sites of a CVT converged to the default rule, from ``cache`` or computed now."""
    stem = cache / f"{Path(name).stem}_{n}_newton"
    if stem.with_suffix(".npy").exists() and stem.with_suffix(".json").exists():
        info = json.loads(stem.with_suffix(".json").read_text())
        info["from_cache"] = str(stem.with_suffix(".npy"))
        return np.load(stem.with_suffix(".npy")), info
    domain = hcvt.load_domain(DATA / name)
    start = time.perf_counter()
    run = hcvt.cvt(domain, initialise(domain, n, "halton", seed=0), method="newton")
    info = {
        "seconds": time.perf_counter() - start,
        "iterations": run.iterations,
        "evaluations": run.evaluations,
        "converged": run.converged,
        "final": {"rms_gap": float(run.history["rms_gap"][-1])},
    }
    cache.mkdir(parents=True, exist_ok=True)
    np.save(stem.with_suffix(".npy"), run.sites)
    stem.with_suffix(".json").write_text(json.dumps(info, indent=1))
    return run.sites, info


def merge_every_region(mesh: PolyMesh, domain: hcvt.Domain) -> tuple[PolyMesh, int, int]:
    """The comparison: each connected region of a cell's pieces (one patch) as one face.

    Regions that are no single disc stay as their pieces. Returns the mesh, the number of
    such regions, and the faces that still fail checkMesh's skewness or pyramid checks.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    from hcvt.mesh.merge import (
        boundary_adjacency,
        failing_boundary_faces,
        merge_boundary_faces,
        outlines,
    )
    from hcvt.mesh.patches import boundary_patches

    patch, _ = boundary_patches(mesh, domain)
    a, b = boundary_adjacency(mesh, patch)
    f = mesh.n_faces
    _, label = connected_components(coo_matrix((np.ones(len(a)), (a, b)), shape=(f, f)))
    first = np.full(label.max() + 1, f)
    np.minimum.at(first, label, np.arange(f))
    group = first[label]
    joined = np.flatnonzero(np.bincount(group, minlength=f)[group] > 1)
    ids, _, _, simple = outlines(mesh, joined, group[joined])
    apart = np.isin(group, ids[~simple])
    group[apart] = np.flatnonzero(apart)
    merged, _ = merge_boundary_faces(mesh, group)
    return merged, int((~simple).sum()), len(failing_boundary_faces(merged))


def volume_change(label: str, exact: np.ndarray, volume: np.ndarray, domain: float) -> None:
    change = np.abs(volume - exact)
    print(
        f"  {label}: volumes as OpenFOAM computes them vs exact: total "
        f"{volume.sum() / exact.sum() - 1:+.3e} relative, sum |change| / domain volume "
        f"{change.sum() / domain:.3e}, cells changed {int((change > 0).sum())} of {len(exact)}, "
        f"largest per-cell change {(change / exact).max():.3e} relative, median over "
        f"changed cells {np.median((change / exact)[change > 0]):.3e}"
    )


def search_partitions(mesh: PolyMesh, domain: hcvt.Domain, cell: int, trials: int = 1500) -> str:
    """Random partitions of ``cell``'s pieces into 2-4 connected groups: how many pass."""
    from hcvt.mesh.merge import boundary_adjacency, outlines
    from hcvt.mesh.patches import boundary_patches
    from hcvt.mesh.quality import SKEWNESS_LIMIT, face_quality

    patch, _ = boundary_patches(mesh, domain)
    a, b = boundary_adjacency(mesh, patch)
    pieces = np.flatnonzero((mesh.owner == cell) & ~mesh.interior)
    near: dict[int, list[int]] = {int(p): [] for p in pieces}
    for u, v in zip(a.tolist(), b.tolist(), strict=True):
        if u in near and v in near:
            near[u].append(v)
            near[v].append(u)
    rng = np.random.default_rng(0)
    centroid = mesh.cell_geometry.centroid
    covering = discs = upright = passing = 0
    for _ in range(trials):
        seeds = rng.choice(pieces, size=int(rng.integers(2, 5)), replace=False).tolist()
        label = {s: i for i, s in enumerate(seeds)}
        frontier = list(seeds)
        while frontier:  # grow the groups from their seeds in random order
            u = frontier.pop(int(rng.integers(len(frontier))))
            for v in near[u]:
                if v not in label:
                    label[v] = label[u]
                    frontier.append(v)
        if len(label) < len(pieces):
            continue
        covering += 1
        ids, offsets, loops, simple = outlines(
            mesh, pieces, np.array([label[p] for p in pieces.tolist()])
        )
        if not simple.all():
            continue
        discs += 1
        rings = PolyMesh(
            mesh.points,
            offsets,
            loops,
            owner=np.full(len(ids), cell),
            neighbour=np.full(len(ids), -1),
            boundary_element=np.zeros(len(ids), dtype=np.intp),
            n_cells=mesh.n_cells,
        )
        _, skewness, inverted = face_quality(rings, centroid)
        upright += int(not inverted.any())
        passing += int(not inverted.any() and (skewness <= SKEWNESS_LIMIT).all())
    return (
        f"cell {cell} ({len(pieces)} pieces): {covering} random partitions into 2-4 groups, "
        f"{discs} of them all discs, {upright} without an inverted pyramid, {passing} passing"
    )


def check_mesh(case: Path) -> str:
    env = {**os.environ}
    env.setdefault("WM_PROJECT_DIR", "/usr/share/openfoam")
    done = subprocess.run(
        ["checkMesh", "-case", str(case)], capture_output=True, text=True, env=env, check=True
    )
    return done.stdout


def figure(log: str, pattern: str) -> float:
    found = re.search(pattern, log)
    return float(found.group(1)) if found else float("nan")


def report(label: str, log: str, mesh: PolyMesh, domain_volume: float) -> None:
    verdict = "Mesh OK" if "Mesh OK." in log else re.search(r"Failed \d+ mesh checks", log)[0]
    failures = [f.strip() for f in re.findall(r"\*\*\*(.*)", log)]
    total = figure(log, rf"Total volume = {NUM}")
    ours = mesh_quality(mesh).summary()
    print(f"  {label}: checkMesh: {verdict}")
    for f in failures:
        print(f"    *** {f}")
    print(
        f"    checkMesh: max non-orthogonality {figure(log, rf'non-orthogonality Max: {NUM}'):.6g}"
        f" deg, average {figure(log, rf'average: {NUM}'):.6g}, max skewness "
        f"{figure(log, rf'Max skewness = {NUM}'):.6g}, total volume {total:.15g} "
        f"(input mesh {domain_volume:.15g}, relative {total / domain_volume - 1:+.3e})"
    )
    print(
        f"    hcvt:      max non-orthogonality {ours['non_orthogonality_max']:.6g} deg, max "
        f"skewness {ours['skewness_max']:.6g}, {ours['skew_faces']} faces skewness > 4, "
        f"{ours['inverted_pyramids']} inverted pyramids, faces {ours['faces']}, "
        f"{ours['non_orthogonal_faces']} faces non-orthogonality > 70 deg, cells {ours['cells']}"
    )


def verdict(log: str) -> str:
    """``Mesh OK``, or how many checks failed and how each failure begins."""
    if "Mesh OK." in log:
        return "Mesh OK"
    failures = [" ".join(f.split()[:6]) for f in re.findall(r"\*\*\*(.*)", log)]
    return f"failed {len(failures)}: " + "; ".join(failures)


def solve(case: Path) -> LaplaceCheck:
    """Run laplacianFoam on ``case`` (:func:`laplace_check`) and print its figures."""
    start = time.perf_counter()
    solved = laplace_check(case)
    print(
        f"    laplacianFoam: converged {solved.converged}, residual "
        f"{solved.residual:.2e} after {len(solved.residuals)} solves, error RMS "
        f"{solved.rms_error:.3e} max {solved.max_error:.3e} "
        f"({time.perf_counter() - start:.1f} s)"
    )
    return solved


def row(shape: str, mesh: str, log: str, domain_volume: float, solved: LaplaceCheck) -> Row:
    total = figure(log, rf"Total volume = {NUM}")
    cells = int(figure(log, r"cells:\s+(\d+)"))
    return (
        shape,
        mesh,
        cells,
        verdict(log),
        total / domain_volume - 1,
        solved.residual,
        solved.rms_error,
    )


def gmsh_dual(name: str, n: int, case: Path, feature_angle: float) -> str:
    """OpenFOAM's route: gmsh tetrahedra with about ``n`` vertices, their dual mesh.

    Returns checkMesh's log of the case left in ``case`` (module docs, step 6).
    """
    domain = hcvt.load_domain(DATA / name)
    shutil.rmtree(case, ignore_errors=True)
    case.mkdir(parents=True)
    write_system(case)
    stl = case / "surface.stl"
    vertices, faces = np.asarray(domain.vertices), np.asarray(domain.faces)
    with stl.open("w") as out:
        out.write("solid surface\n")
        for tri in vertices[faces]:
            normal = np.cross(tri[1] - tri[0], tri[2] - tri[0])
            out.write(f"facet normal {normal[0]:.17g} {normal[1]:.17g} {normal[2]:.17g}\n")
            out.write(" outer loop\n")
            for v in tri:
                out.write(f"  vertex {v[0]:.17g} {v[1]:.17g} {v[2]:.17g}\n")
            out.write(" endloop\nendfacet\n")
        out.write("endsolid surface\n")
    size = (domain.volume / n) ** (1 / 3)
    start = time.perf_counter()
    surface = "remeshed"
    try:
        nodes, size = _in_time(_gmsh_tetrahedra, (stl, case / "mesh.msh", n, size, True))
    except Exception as err:
        # "Wrong topology of boundary mesh for parametrization" (bunny, cheese), or no
        # remeshed surface within GMSH_SECONDS (fandisk: still running after 10 minutes)
        surface = f"input triangles kept (remeshing: {err})"
        nodes, size = _gmsh_tetrahedra(stl, case / "mesh.msh", n, size, remesh=False)
    env = {**os.environ}
    env.setdefault("WM_PROJECT_DIR", "/usr/share/openfoam")
    for command in (
        ["gmshToFoam", "-case", str(case), str(case / "mesh.msh")],
        ["polyDualMesh", "-case", str(case), "-overwrite", f"{feature_angle:g}"],
    ):
        subprocess.run(command, capture_output=True, text=True, env=env, check=True)
    print(
        f"  gmsh + polyDualMesh: surface {surface}, {nodes} tetrahedron vertices (element "
        f"size {size:.3g}), "
        f"{time.perf_counter() - start:.1f} s"
    )
    return check_mesh(case)


#: Seconds gmsh may take to remesh a surface before its input triangles are kept instead.
GMSH_SECONDS = 120.0


def _in_time(function, args):  # noqa: ANN001, ANN202 (a benchmark's helper)
    """``function(*args)`` in a child process, killed after :data:`GMSH_SECONDS`."""
    import multiprocessing

    context = multiprocessing.get_context("fork")
    with context.Pool(1) as pool:
        pending = pool.apply_async(function, args)
        try:
            return pending.get(GMSH_SECONDS)
        except multiprocessing.TimeoutError:
            pool.terminate()
            raise TimeoutError(f"no mesh after {GMSH_SECONDS:g} s") from None


def _gmsh_tetrahedra(stl: Path, msh: Path, n: int, size: float, remesh: bool) -> tuple[int, float]:
    """Tetrahedra inside the surface ``stl`` written to ``msh``: vertices, element size.

    ``remesh``: the surface remeshed at the element size (patches split at 40-degree
    creases, reparametrised); else its triangles kept as the boundary mesh.
    """
    import gmsh

    gmsh.initialize(["gmsh", "-nt", "1"])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.merge(str(stl))
        if remesh:
            gmsh.model.mesh.classifySurfaces(np.radians(40.0), True, True, np.pi)
            gmsh.model.mesh.createGeometry()
        # else the merged triangles are one discrete surface, kept as the boundary mesh
        # (gmsh's own recipe: Surface Loop + Volume on the STL, no parametrisation)
        surfaces = [tag for _, tag in gmsh.model.getEntities(2)]
        loop = gmsh.model.geo.addSurfaceLoop(surfaces)
        volume = gmsh.model.geo.addVolume([loop])
        gmsh.model.geo.synchronize()
        gmsh.model.addPhysicalGroup(2, surfaces, name="wall")
        gmsh.model.addPhysicalGroup(3, [volume], name="solid")
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature", 0)
        nodes = 0
        for attempt in range(3):  # the element size that gives about n vertices
            gmsh.option.setNumber("Mesh.MeshSizeMin", size)
            gmsh.option.setNumber("Mesh.MeshSizeMax", size)
            if remesh:  # clearing would drop the kept input triangles too
                gmsh.model.mesh.clear()
            gmsh.model.mesh.generate(3)
            nodes = len(gmsh.model.mesh.getNodes()[0])
            if abs(nodes / n - 1) < 0.1 or attempt == 2 or not remesh:
                break
            size *= (nodes / n) ** (1 / 3)
        gmsh.option.setNumber("Mesh.MshFileVersion", 2.2)
        gmsh.write(str(msh))
    finally:
        gmsh.finalize()
    return nodes, size


def run_gmsh(key: str, n: int | None, root: Path, feature_angle: float) -> None:
    name, default_n = CASES[key]
    n = n or default_n
    domain = hcvt.load_domain(DATA / name)
    case = root / f"{Path(name).stem}_{n}_gmsh_dual"
    try:
        log = gmsh_dual(name, n, case, feature_angle)
    except Exception as err:  # gmsh raises Exception; OpenFOAM's tools CalledProcessError
        print(f"  gmsh + polyDualMesh: failed ({err})")
        ROWS.append((key, "gmsh + polyDualMesh", 0, f"not made: {err}", *[float("nan")] * 3))
        return
    print(f"  gmsh + polyDualMesh: checkMesh: {verdict(log)}")
    ROWS.append(row(key, "gmsh + polyDualMesh", log, domain.volume, solve(case)))


def print_table() -> None:
    print()
    print(
        f"{'shape':8} {'mesh':20} {'cells':>6} {'volume error':>12} {'residual':>9} "
        f"{'RMS error':>9}  checkMesh"
    )
    for shape, mesh, cells, check, volume, residual, rms in ROWS:
        print(f"{shape:8} {mesh:20} {cells:6d} {volume:+12.2e} {residual:9.1e} {rms:9.2e}  {check}")


def run_case(key: str, n: int | None, cache: Path, keep: Path | None) -> None:
    name, default_n = CASES[key]
    n = n or default_n
    domain = hcvt.load_domain(DATA / name)
    sites, info = converged_sites(name, n, cache)
    where = f" (sites from {info['from_cache']})" if "from_cache" in info else ""
    print(
        f"{name} {n}: CVT Newton from Halton, {info['iterations']} iterations, "
        f"{info['evaluations']} diagrams, {info['seconds']:.1f} s, converged "
        f"{info['converged']}, RMS gap {info['final']['rms_gap']:.2e}{where}"
    )
    start = time.perf_counter()
    diagram = hcvt.voronoi(domain, sites)
    mesh = diagram.mesh()
    print(f"  diagram + mesh: {time.perf_counter() - start:.2f} s")
    start = time.perf_counter()
    merged, merge = merged_boundary(mesh, domain)
    seconds = time.perf_counter() - start
    exact_volume, volume = mesh.cell_geometry.volume, merged.cell_geometry.volume
    print(
        f"  merge: {seconds:.2f} s, {merge.rounds} rounds, {merge.merged_faces} boundary "
        f"faces joined into {merge.groups} merged faces, {len(merge.failing)} still failing"
    )
    volume_change("merged", exact_volume, volume, domain.volume)
    every, not_discs, failing = merge_every_region(mesh, domain)
    print(
        f"  comparison, every region of a cell's pieces merged: {not_discs} regions are no "
        f"disc (left as pieces), {failing} faces fail"
    )
    volume_change("every region", exact_volume, every.cell_geometry.volume, domain.volume)
    with tempfile.TemporaryDirectory() as tmp:
        root = keep or Path(tmp)
        for label, written in (("exact", mesh), ("merged", merged)):
            case = root / f"{Path(name).stem}_{n}_{label}"
            shutil.rmtree(case, ignore_errors=True)
            start = time.perf_counter()
            # Each mesh as made above ("exact": write_openfoam would merge by default).
            write_openfoam(written, case, domain=domain, binary=True, boundary_faces="exact")
            seconds = time.perf_counter() - start
            start = time.perf_counter()
            log = check_mesh(case)
            print(
                f"  {label}: written in {seconds:.2f} s (binary), checkMesh "
                f"{time.perf_counter() - start:.1f} s"
            )
            report(label, log, written, domain.volume)
            solved = solve(case)
            ROWS.append(row(key, f"hcvt {label}", log, domain.volume, solved))
    if len(merge.failing):
        cells = np.unique(merged.owner[merge.failing])
        centroid = merged.cell_geometry.centroid
        centre, area = merged.face_geometry
        behind = np.einsum(
            "ij,ij->i",
            area[merge.failing] / np.linalg.norm(area[merge.failing], axis=1)[:, None],
            centre[merge.failing] - centroid[merged.owner[merge.failing]],
        )
        depth = -behind / volume[merged.owner[merge.failing]] ** (1 / 3)
        print(
            f"  still failing: faces {merge.failing.tolist()} of cells {cells.tolist()}; "
            f"their centre lies {depth.round(3).tolist()} cell sizes V^(1/3) behind the "
            "face's plane"
        )
        for cell in cells.tolist():
            print(f"    {search_partitions(mesh, domain, cell)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    parser.add_argument("-n", type=int, help="sites (default: bunny 50k, cheese 10k)")
    parser.add_argument("--cache", type=Path, default=Path(".cache/checkmesh"))
    parser.add_argument("--keep", type=Path, help="write the cases here and keep them")
    parser.add_argument("--no-gmsh", action="store_true", help="leave out gmsh + polyDualMesh")
    parser.add_argument("--feature-angle", type=float, default=60.0, help="polyDualMesh's")
    args = parser.parse_args()
    for key in args.cases:
        run_case(key, args.n, args.cache, args.keep)
        if not args.no_gmsh:
            with tempfile.TemporaryDirectory() as tmp:
                run_gmsh(key, args.n, args.keep or Path(tmp), args.feature_angle)
    print_table()


if __name__ == "__main__":
    main()
