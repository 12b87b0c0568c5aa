"""Time the Voronoi cells of random sites in a periodic box against freud and multivoro.

hcvt, freud and multivoro (both voro++) are timed in the same run on the same sites, one
thread each. Every call runs in a child process (freud's 2D Voronoi is about O(n²), and
voro++ calls ``exit(1)`` on some inputs, which would end this process), the codes taking
turns round after round so that a change of the machine's load falls on all alike. Prints
the median of ``--repeats`` rounds per code (each a call after a warm-up call), the ratio
peer / hcvt, and what each returns: Σ volumes against the box, neighbour entries per
cell, and the largest difference of a cell's volume from hcvt's (freud rounds positions
to float32 in 3D; multivoro's volumes are those of the convex hulls of its cells'
vertices, on a sample of cells).

    OPENBLAS_NUM_THREADS=1 python benchmarks/periodic.py [--quick] [--million]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import json
import subprocess
import sys

import numpy as np

import hcvt
from timing import median_seconds

#: Cells whose volume multivoro's output is checked on (a convex hull each, in Python).
SAMPLE = 2000


def sites(dim: int, n: int, seed: int = 0) -> np.ndarray:
    """``n`` uniform random sites in the unit square or cube."""
    return np.random.default_rng(seed).random((n, dim))


def run_hcvt(dim: int, n: int, repeats: int) -> dict:
    """Median seconds of ``hcvt.voronoi`` on the unit torus, and what it returns."""
    hcvt.set_num_threads(1)
    torus = hcvt.Domain.box([0.0] * dim, [1.0] * dim, periodic=True)
    points = sites(dim, n)
    d = hcvt.voronoi(torus, points)  # also warms up: threads, pages
    seconds = median_seconds(hcvt.voronoi, repeats, torus, points)
    return {
        "seconds": seconds,
        "volume_error": abs(float(d.volume.sum()) - 1.0),
        "entries": len(d.neighbor_sites) / n,
        "volumes": d.volume.tolist(),
    }


def run_freud(dim: int, n: int, repeats: int) -> dict:
    """freud.locality.Voronoi on the same sites (shifted: freud's box is centred)."""
    import freud

    freud.parallel.set_num_threads(1)
    box = freud.box.Box.cube(1.0) if dim == 3 else freud.box.Box.square(1.0)
    points = sites(dim, n) - 0.5
    if dim == 2:
        points = np.column_stack([points, np.zeros(n)])
    voronoi = freud.locality.Voronoi()
    if dim == 3:  # warm-up (in 2D a call takes a minute)
        voronoi.compute((box, points))
    seconds = median_seconds(lambda: voronoi.compute((box, points)), repeats)
    return {
        "seconds": seconds,
        "volume_error": abs(float(voronoi.volumes.sum()) - 1.0),
        "entries": len(voronoi.nlist) / n,
        "volumes": voronoi.volumes.tolist(),
    }


def run_multivoro(dim: int, n: int, repeats: int) -> dict:
    """multivoro.compute_voronoi (3D only; zero radii: Laguerre = Voronoi)."""
    import multivoro
    from scipy.spatial import ConvexHull

    points = sites(dim, n)
    limits = np.array([[0.0] * 3, [1.0] * 3])
    radii = np.zeros(n)

    def run():
        return multivoro.compute_voronoi(
            points, limits=limits, radii=radii, periodic_boundaries=(True,) * 3, n_threads=1
        )

    cells = run()  # also warms up
    seconds = median_seconds(run, repeats)
    entries = sum(len(c.get_neighbors()) for c in cells) / n
    volumes = [ConvexHull(np.asarray(c.get_vertices())).volume for c in cells[:SAMPLE]]
    return {"seconds": seconds, "volume_error": None, "entries": entries, "volumes": volumes}


CODES = {"hcvt": run_hcvt, "freud": run_freud, "multivoro": run_multivoro}


def child(peer: str, dim: int, n: int, repeats: int, timeout: float) -> dict | str:
    """Run ``peer`` in a child process; its result, or why there is none."""
    command = [sys.executable, __file__, "--child", peer, str(dim), str(n), str(repeats)]
    try:
        done = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return f"no result in {timeout:.0f} s"
    if done.returncode != 0:
        tail = (done.stderr.strip().splitlines() or ["(no message)"])[-1]
        return f"exit status {done.returncode}: {tail}"
    return json.loads(done.stdout.strip().splitlines()[-1])


def report(dim: int, n: int, peers: list[str], rounds: int, timeout: float) -> None:
    """One line per code: median seconds over ``rounds``, the codes taking turns."""
    results: dict[str, list[dict | str]] = {code: [] for code in ["hcvt", *peers]}
    for round_ in range(rounds):
        for code, runs in results.items():
            # freud's 2D cells take a minute at 10k sites: one round only.
            if round_ == 0 or not (code == "freud" and dim == 2):
                runs.append(child(code, dim, n, 1, timeout))
    ours = results["hcvt"][0]
    assert isinstance(ours, dict), ours
    seconds = float(np.median([r["seconds"] for r in results["hcvt"]]))
    print(
        f"{dim}D, {n:,} sites: hcvt {seconds:.3f} s "
        f"(Σ volumes − 1 = {ours['volume_error']:.1e}, {ours['entries']:.2f} faces per cell, "
        "symmetric, float64)"
    )
    for peer in peers:
        failed = [r for r in results[peer] if isinstance(r, str)]
        if failed:
            print(f"  {peer}: {failed[0]}")
            continue
        runs = [r for r in results[peer] if isinstance(r, dict)]
        theirs = np.asarray(runs[0]["volumes"])
        worst = np.abs(theirs - np.asarray(ours["volumes"][: len(theirs)])).max() * n
        error = runs[0]["volume_error"]
        total = "" if error is None else f"Σ volumes − 1 = {error:.1e}, "
        median = float(np.median([r["seconds"] for r in runs]))
        print(
            f"  {peer}: {median:.3f} s = {median / seconds:.2f} × hcvt over {len(runs)} "
            f"round(s) ({total}{runs[0]['entries']:.2f} neighbour entries per cell, largest "
            f"volume difference from hcvt {worst:.1e} of the mean cell over {len(theirs)} "
            "cells)"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10k sites, one call each")
    parser.add_argument("--million", action="store_true", help="also hcvt alone at 1M sites")
    parser.add_argument("--repeats", type=int, default=3, help="rounds")
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds per peer run")
    parser.add_argument("--child", nargs=4, metavar=("PEER", "DIM", "N", "REPEATS"))
    args = parser.parse_args()
    if args.child:
        peer, dim, n, repeats = args.child
        out = CODES[peer](int(dim), int(n), int(repeats))
        print(json.dumps(out))
        return
    n = 10_000 if args.quick else 100_000
    repeats = 1 if args.quick else args.repeats
    # freud's 2D cells cost about O(n²) (a minute at 10k sites measured here): 10k only.
    report(2, 10_000, ["freud"], repeats, args.timeout)
    if n > 10_000:
        report(2, n, [], repeats, args.timeout)
    report(3, n, ["freud", "multivoro"], repeats, args.timeout)
    if args.million:
        for dim in (2, 3):
            report(dim, 1_000_000, [], 1, args.timeout)


if __name__ == "__main__":
    main()
