"""OpenFOAM's checkMesh and laplacianFoam on converged CVTs of real meshes: exact, merged.

Run ``OPENBLAS_NUM_THREADS=1 python benchmarks/checkmesh.py`` (needs OpenFOAM's
``checkMesh``; ``WM_PROJECT_DIR`` defaults to Debian's ``/usr/share/openfoam``). For each
case (bunny 50k, cheese 10k by default) it

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
   exact cell's centroid).

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
from hcvt.mesh.polymesh import PolyMesh
from hcvt.seeding.initialisation import initialise

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d"
NUM = r"([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)"
CASES = {"bunny": ("bunny.off", 50_000), "cheese": ("cheese.off", 10_000)}


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
            start = time.perf_counter()
            solved = laplace_check(case)
            print(
                f"    laplacianFoam: converged {solved.converged}, residual "
                f"{solved.residual:.2e} after {len(solved.residuals)} solves, error RMS "
                f"{solved.rms_error:.3e} max {solved.max_error:.3e} "
                f"({time.perf_counter() - start:.1f} s)"
            )
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
    args = parser.parse_args()
    for key in args.cases:
        run_case(key, args.n, args.cache, args.keep)


if __name__ == "__main__":
    main()
