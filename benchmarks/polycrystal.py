"""A periodic Laguerre polycrystal: N grains of log-normal volumes in the unit cube (torus).

The capacity-constrained CVT of ``hcvt.cvt(box, sites, volumes=v, normalise=True)``
(Bourne, Kok, Roper and Spanjer 2020's alternation: optimal-transport weights warm-started
from the previous ones, then sites to their power cells' centroids) from uniform random
sites, with grain volumes drawn log-normal (σ = 0.3 by default) and normalised to the box:
every grain's volume to 1e-8 relative, sites at centroids to the default rule (RMS gap
``|x_i - c_i| / V_i^(1/3)`` below 1e-7). Prints the time, the outer iterations, the
Newton steps of all transports, the largest relative volume error (as the result reports
it and as a power diagram of the returned weights computes it again), the RMS gap and the
spread of the grain volumes.

The grains are then written as an OpenFOAM case with cyclic patch pairs (``--case``;
``Diagram.mesh()`` of the periodic power diagram), and ``checkMesh`` and ``laplacianFoam``
(``hcvt.export.laplace_check``: a Fourier mode decaying on the torus) run on it when they are
on PATH. 100,000 grains (2026-12-04, ``--n 100000 --methods newton``, resumed once with
``--resume``): 403 outer iterations in all, largest volume error 7.9e-11, RMS gap 9.5e-9,
checkMesh "Mesh OK", laplacianFoam last residual 9.9e-16, RMS error 8.3e-4.

The machine is shared with other jobs: timings are "under load" unless it is idle.
Measured 2026-12-03 under heavy load (load average 15-20 on 2 cores, 2 threads): 300
grains, L-BFGS 77.5 s (430 outer iterations, 883 Newton steps, 1,453 diagrams) against
Lloyd's alternation 599 s (5,821 iterations; 7.7x); 2,000 grains, L-BFGS 590 s (713
iterations, 1,544 Newton steps, 2,325 diagrams), largest volume error 9.4e-11, RMS gap
9.6e-8. A 10,000-grain run did not finish in 20 minutes under that load (stopped).

Levers tried for issue 34 (1,000 grains, seed 0, under load; main's run: 331 outer
iterations, 700 Newton steps, 1,038 diagrams), none kept. The outer L-BFGS iterations are
the cost, and they are sensitive to anything that perturbs the trajectory, most of them
(152 of 331) spent with the RMS gap between 1e-4 and 1e-3:

- inexact transports (volume tolerance ``volume_tol · gap / tol`` within [1e-8, 1e-3],
  exact in the last iteration): 471 iterations, 632 Newton steps, 1,134 diagrams; the
  tolerance ten times tighter 506 / 1,424 diagrams, a hundred times 462 / 1,381; only the
  first transport loose 360 / 1,163. (Smaller cases gained: 150 grains in the periodic cube
  477 -> 337 diagrams in the same 152 iterations, 200 in the periodic square 621 -> 477.)
- a better start, sites at a CVT of the box first: to a gap of 1e-2, 429 iterations and
  1,348 diagrams (+10 Voronoi diagrams); to 1e-3, 638 and 2,007 (+77).
- L-BFGS memory 3 or 15 instead of the default 7: 356 and 493 iterations, 1,132 and
  1,580 diagrams.

Measured since (3 seeds, other starts with ``--start``, a Laplacian preconditioner, where
the iterations go: saddle passages): docs/guide/volumes.md, "Large polycrystals".

``--methods newton`` is Newton on the sites with the weights eliminated (the transport
cost's exact Hessian ``H_zz + B L^-1 B^T`` in a trust region): docs/guide/volumes.md,
"Newton on the sites", for its counts against L-BFGS in the same runs.

    OPENBLAS_NUM_THREADS=1 python benchmarks/polycrystal.py [--n 100000] [--sigma 0.3]
        [--seed 0] [--threads 0] [--case DIR] [--progress K] [--save RUN.npz] [--resume RUN.npz]
        [--start random|lloyd:K|coarse:F] [--methods lbfgs|lloyd|newton ...]

Long runs (100,000 grains take hours): ``--progress K`` prints every K-th outer iteration
(elapsed time, RMS gap, diagrams so far), ``--save RUN.npz`` keeps the latest sites there
at each progress line and the converged sites, weights and volumes at the end, and
``--resume RUN.npz`` starts from the sites saved there (same ``--n``, ``--sigma``,
``--seed``: the volumes are drawn again; the L-BFGS memory starts empty).
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

import hcvt
from hcvt.export import laplace_check, write_openfoam
from hcvt.optimise import CAPACITY_METHOD


def grains(n: int, sigma: float, seed: int) -> tuple[np.ndarray, np.ndarray, np.random.Generator]:
    """Random sites and log-normal relative volumes drawn from ``seed``, and the generator.

    Sites uniform in the unit cube, shape (n, 3); volumes summing to 1, shape (n,).
    """
    rng = np.random.default_rng(seed)
    sites = rng.random((n, 3))
    volumes = rng.lognormal(0.0, sigma, n)
    return sites, volumes / volumes.sum(), rng


def resumed(path: Path, n: int) -> np.ndarray:
    """The sites saved by ``--save`` in ``path``, shape (n, 3)."""
    with np.load(path) as saved:
        sites = np.asarray(saved["sites"], dtype=np.float64)
    if sites.shape != (n, 3):
        raise ValueError(f"--resume {path}: sites of shape {sites.shape}, expected ({n}, 3)")
    return sites


class Progress:
    """A callback for ``hcvt.cvt`` that prints every ``every``-th outer iteration.

    It keeps the latest sites in ``save`` (an .npz) at each print; ``every == 0`` prints
    nothing.
    """

    def __init__(self, every: int, save: Path | None) -> None:
        self.every, self.save = every, save
        self.iteration = 0
        self.start = time.perf_counter()

    def __call__(self, info: dict[str, Any]) -> None:
        """Count the iterate ``info`` (the core's history fields and ``sites``)."""
        k, self.iteration = self.iteration, self.iteration + 1
        if not self.every or k % self.every:
            return
        print(
            f"  iteration {k}: {time.perf_counter() - self.start:.0f} s, RMS gap "
            f"{float(info['rms_gap']):.3e}, max gap {float(info['max_gap']):.3e}, "
            f"{int(info['evaluations'])} diagrams",
            flush=True,
        )
        if self.save is not None:
            np.savez(self.save, sites=info["sites"])


def started(
    start: str, sites: np.ndarray, volumes: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Sites to start the run from (``--start``).

    ``random`` (``sites`` as drawn), ``lloyd:K`` (K iterations of Bourne et al.'s
    alternation first) or ``coarse:F`` (F = k³ grains merged at random into each of n / F
    coarse grains, those to an RMS gap of 1e-3, each then split into a k × k × k pattern
    about its centroid).
    """
    box = hcvt.Domain.box([0, 0, 0], [1, 1, 1], periodic=True)
    kind, _, count = start.partition(":")
    if kind == "random":
        return sites
    if kind == "lloyd":
        out = hcvt.cvt(box, sites, "lloyd", volumes=volumes, normalise=True, max_iter=int(count))
        print(f"  start: {out.iterations} Lloyd iterations, {out.evaluations} diagrams")
        return out.sites
    side = round(int(count) ** (1 / 3))
    if kind != "coarse" or side**3 != int(count) or len(sites) % int(count):
        raise ValueError(f"--start {start}: random, lloyd:K or coarse:F (F a cube dividing n)")
    groups = rng.permutation(len(sites)).reshape(-1, int(count))
    coarse = hcvt.cvt(
        box, sites[: len(groups)], volumes=volumes[groups].sum(1), normalise=True, tol=1e-3
    )
    print(f"  start: {coarse.iterations} coarse iterations, {coarse.evaluations} diagrams")
    corners = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), -1).reshape(-1, 3)
    offsets = (corners + 0.5) / side - 0.5
    size = coarse.diagram.volume ** (1 / 3)
    split = np.empty_like(sites)
    for k, offset in enumerate(offsets):
        split[groups[:, k]] = coarse.diagram.centroid + 0.9 * size[:, None] * offset
    split = np.mod(split, 1.0)
    split[split >= 1.0] = 0.0
    return split


def polycrystal(
    sites: np.ndarray, volumes: np.ndarray, method: str, progress: Progress
) -> tuple[hcvt.CVTResult, float]:
    """The run from ``sites`` (n, 3) to relative ``volumes`` (n,) and its wall time, s."""
    box = hcvt.Domain.box([0, 0, 0], [1, 1, 1], periodic=True)
    start = time.perf_counter()
    out = hcvt.cvt(box, sites, method, volumes=volumes, normalise=True, callback=progress)
    return out, time.perf_counter() - start


def write_case(out: hcvt.CVTResult, case: Path) -> None:
    """The grains as an OpenFOAM case, checked by checkMesh, if the mesh can be made."""
    try:
        mesh = out.diagram.mesh()
    except NotImplementedError as err:
        print(f"OpenFOAM case: not written ({err})")
        return
    write_openfoam(mesh, case, domain=out.diagram.domain, binary=True)
    print(f"OpenFOAM case: {case}")
    if shutil.which("checkMesh") is None:
        print("checkMesh: not on PATH")
        return
    env = {**os.environ}
    env.setdefault("WM_PROJECT_DIR", "/usr/share/openfoam")
    log = subprocess.run(
        ["checkMesh", "-case", str(case)], capture_output=True, text=True, env=env, check=False
    ).stdout
    verdict = "Mesh OK" if "Mesh OK." in log else "FAILED"
    failures = [line.strip() for line in log.splitlines() if "***" in line]
    print(f"checkMesh: {verdict}" + "".join(f"\n  {f}" for f in failures))
    solved = laplace_check(case)  # a box periodic along every axis: a decaying mode
    print(
        f"laplacianFoam ({solved.field}): converged {solved.converged}, last residual "
        f"{solved.residual:.2e}, RMS error {solved.rms_error:.2e}, max {solved.max_error:.2e}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--n", type=int, default=100_000, help="grains")
    parser.add_argument("--sigma", type=float, default=0.3, help="log-normal sigma")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--threads", type=int, default=0, help="0: hcvt's default")
    parser.add_argument("--case", type=Path, default=None, help="OpenFOAM case directory")
    parser.add_argument(
        "--progress", type=int, default=0, help="print every K-th outer iteration (0: none)"
    )
    parser.add_argument(
        "--save", type=Path, default=None, help="keep the latest sites, then the result (.npz)"
    )
    parser.add_argument(
        "--resume", type=Path, default=None, help="start from the sites saved by --save"
    )
    parser.add_argument(
        "--start", default="random", help="random, lloyd:K or coarse:F (levers measured)"
    )
    parser.add_argument(
        "--methods",
        nargs="+",
        default=[CAPACITY_METHOD],
        choices=["lloyd", "lbfgs", "newton"],
        help="run each (the last one's grains are meshed); times printed as ratios to the first",
    )
    args = parser.parse_args()
    if args.threads:
        hcvt.set_num_threads(args.threads)
    print(
        f"periodic unit cube, {args.n} grains, log-normal sigma {args.sigma}, seed {args.seed}, "
        f"{hcvt.get_num_threads()} threads (timings under load unless the machine is idle)"
    )
    sites, volumes, rng = grains(args.n, args.sigma, args.seed)
    if args.resume is not None:
        sites = resumed(args.resume, args.n)
        print(f"resumed from the sites in {args.resume}")
    sites = started(args.start, sites, volumes, rng)
    first = None
    for method in args.methods:
        out, seconds = polycrystal(sites, volumes, method, Progress(args.progress, args.save))
        first = first or seconds
        print(f"method {method}: {seconds / first:.2f}x the first method's time")
        report(out, volumes, seconds)
    if args.save is not None:
        np.savez(args.save, sites=out.sites, weights=out.weights, volumes=volumes)
        print(f"saved: {args.save} ({out.stop_reason})")
    if args.case is not None:
        write_case(out, args.case)
    else:
        with tempfile.TemporaryDirectory() as tmp:
            write_case(out, Path(tmp) / "polycrystal")


def report(out: hcvt.CVTResult, volumes: np.ndarray, seconds: float) -> None:
    """Time, iterations, Newton steps, volume errors and gaps of one run."""
    history = out.history
    again = hcvt.voronoi(out.diagram.domain, out.sites, weights=out.weights)
    recomputed = float(np.max(np.abs(again.volume - volumes) / volumes))
    print(
        f"  {out.stop_reason}: {seconds:.1f} s, {out.iterations} outer iterations, "
        f"{int(history['newton_steps'].sum())} Newton steps "
        f"({int(history['newton_steps'][0])} in the first transport), "
        f"{out.evaluations} diagrams"
    )
    print(
        f"  max relative volume error {history['max_volume_error'][-1]:.2e} "
        f"(recomputed from the weights: {recomputed:.2e}); RMS gap "
        f"{history['rms_gap'][-1]:.2e}, max gap {history['max_gap'][-1]:.2e}"
    )
    print(
        f"  grain volumes: max/min {volumes.max() / volumes.min():.2f}, "
        f"coefficient of variation {volumes.std() / volumes.mean():.3f}; "
        f"mean G {out.mean_G:.6f}"
    )


if __name__ == "__main__":
    main()
