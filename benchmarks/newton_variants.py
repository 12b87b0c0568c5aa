"""Diagrams per Newton CVT to the paper's rule, per variant of the trust-region step.

A load-independent measure of the optimiser: the number of diagrams (evaluations) each run
needs from random sites to ``‖g‖/‖X‖ < 1e-10`` in input coordinates (the paper's rule), over
``--seeds`` seeds per case (square 1k/5k, star 2k/10k, ball 1k/5k), printed as the median
and the range. Beside it: the CG iterations (Hessian products) per diagram, and the wall
time per diagram, which is measured on a machine shared with other jobs ("under load").

Besides them: the median seconds per run and the paper's Table 8 "Standard" seconds over
it ("x paper", as in ``benchmarks/cvt.py``), the shares of the wall time spent in CG
(Hessian products) and in trial diagrams, and seed by seed against the first variant the
median ratio of diagrams ("paired") and of seconds ("paired s"); the variants of a seed run
one after another, so that a change of the machine's load touches them alike.

A variant is a comma-separated set of flags handed to the core in ``HCVT_NEWTON_VARIANT``
("base": none). Only the experimental builds read the flags and print the CG count and
the time split per trial (``HCVT_NEWTON_DEBUG``); a later build ignores both and measures
its own default (the CG column then reads "-" and the shares 0). Commit "newton variants
(experimental)" (cfb77c0): ``bj`` block-Jacobi CG (inverse 2x2/3x3 diagonal blocks, the
region in their norm), ``nm=M`` non-monotone acceptance against the last M energies,
``lloyd=G`` Lloyd steps while the RMS gap is above G, ``interp=T`` a rejected step's radius
shrunk to the minimiser of the quadratic through E(0), g.s, E(1) (at least T), and the
region's factors ``shrink``, ``poor``, ``good``, ``grow``, ``stiffen``. Commit "newton
variants 2 (experimental)" (1010c2f): ``ew=1``/``ew=2`` Eisenstat-Walker forcing (choices 1
and 2, safeguarded, at most 1/2), ``eta=C`` the forcing times C, ``r0=C`` a first radius
moving every site C spacings, ``open`` the first radius from the unbounded CG step,
``nc2`` on negative curvature the better of the two boundary points, ``accept=T`` the
acceptance threshold, ``warm`` warm-started diagrams. Results and conclusions:
``docs/results/newton_variants.txt``.

    OPENBLAS_NUM_THREADS=1 python benchmarks/newton_variants.py [--seeds 10]
        [--variants base bj] [--cases square1k star10k]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import re
import statistics
import tempfile
import time
from collections.abc import Callable
from typing import NamedTuple

import hcvt
from hcvt.geometry import shapes

TOL = 1e-10  # the paper's rule, input coordinates


# Case: domain, sites, the paper's Table 8 "Standard" seconds (as in benchmarks/cvt.py: the
# paper's shapes at the paper's sizes; rounds 1-5 of docs/results/newton_variants.txt ran the
# ball cases on sphere.ply, volume 4.15, where the paper's rule is 2.9x stricter).
CASES: dict[str, tuple[Callable[[], hcvt.Domain], int, float]] = {
    "square1k": (shapes.square, 1_000, 2.84),
    "square5k": (shapes.square, 5_000, 10.85),
    "star2k": (shapes.star, 2_000, 3.56),
    "star10k": (shapes.star, 10_000, 26.94),
    "ball1k": (shapes.ball, 1_000, 521.86),
    "ball5k": (shapes.ball, 5_000, 1484.69),
}


class Run(NamedTuple):
    """One Newton CVT's counts.

    Diagrams, CG iterations, seconds, converged, seconds in CG and in trial diagrams (CG and
    the two shares from the core's debug lines; 0 without them).
    """

    diagrams: int
    cg: int
    seconds: float
    converged: bool
    cg_seconds: float
    trial_seconds: float


def run(domain: hcvt.Domain, sites, variant: str) -> Run:
    """One Newton CVT from ``sites`` with the flags ``variant``."""
    os.environ["HCVT_NEWTON_VARIANT"] = "" if variant == "base" else variant
    os.environ["HCVT_NEWTON_DEBUG"] = "1"
    with tempfile.TemporaryFile(mode="w+") as log:
        saved = os.dup(2)
        os.dup2(log.fileno(), 2)
        try:
            start = time.perf_counter()
            res = hcvt.cvt(domain, sites, "newton", rule="paper", tol=TOL, max_iter=5_000)
            seconds = time.perf_counter() - start
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        log.seek(0)
        text = log.read()
    cg = sum(int(m) for m in re.findall(r"cg=(\d+)", text))
    t_cg = sum(float(m) for m in re.findall(r"t_cg=([0-9.e+-]+)", text))
    t_eval = sum(float(m) for m in re.findall(r"t_eval=([0-9.e+-]+)", text))
    return Run(res.evaluations, cg, seconds, res.converged, t_cg, t_eval)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="random starts per case")
    parser.add_argument("--variants", nargs="+", default=["base"], help="flag sets")
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    args = parser.parse_args()
    print(
        f"hcvt {hcvt.__version__}, {hcvt.get_num_threads()} threads, load average "
        f"{os.getloadavg()[0]:.1f} at the start; Newton to ‖g‖/‖X‖ < {TOL:g}, random sites, "
        f"seeds 0-{args.seeds - 1}. 'ms/diagram' is under load."
    )
    print(
        f"{'case':<10}{'variant':<22}{'diagrams':>9}{'min':>6}{'max':>6}{'CG/diagram':>11}"
        f"{'ms/diagram':>11}{'ratio':>7}{'seconds':>9}{'x paper':>8}{'CG %':>6}{'diag %':>7}"
        f"{'paired':>7}{'paired s':>9}"
    )
    for case in args.cases:
        make, n, paper = CASES[case]
        domain = make()
        starts = [hcvt.initialise(domain, n, method="random", seed=k) for k in range(args.seeds)]
        base = None
        # Seed by seed, the variants in turn: a change of the machine's load during the
        # case then touches every variant alike.
        by_variant: dict[str, list[Run]] = {v: [] for v in args.variants}
        for start in starts:
            for variant in args.variants:
                by_variant[variant].append(run(domain, start, variant))
        first = by_variant[args.variants[0]]
        for variant, runs in by_variant.items():
            diagrams = [r.diagrams for r in runs]
            # Seed by seed against the first variant: the spread between seeds (2x) is
            # larger than most differences between variants.
            pairs = list(zip(runs, first, strict=True))
            paired = statistics.median(r.diagrams / b.diagrams for r, b in pairs)
            paired_s = statistics.median(r.seconds / b.seconds for r, b in pairs)
            median = statistics.median(diagrams)
            base = base or median
            cg_total = sum(r.cg for r in runs)
            cg = f"{cg_total / sum(diagrams):.1f}" if cg_total else "-"
            ms = 1e3 * statistics.median(r.seconds / r.diagrams for r in runs)
            seconds = statistics.median(r.seconds for r in runs)
            total = sum(r.seconds for r in runs)
            # Shares of the wall time: CG (Hessian products), trial diagrams (with the
            # Hessian's face terms); the rest is the first diagram, bookkeeping and Python.
            cg_share = 100 * sum(r.cg_seconds for r in runs) / total
            trial_share = 100 * sum(r.trial_seconds for r in runs) / total
            failed = sum(not r.converged for r in runs)
            print(
                f"{case:<10}{variant:<22}{median:>9.1f}{min(diagrams):>6}{max(diagrams):>6}"
                f"{cg:>11}{ms:>11.2f}{median / base:>7.2f}{seconds:>9.2f}{paper / seconds:>8.0f}"
                f"{cg_share:>6.1f}{trial_share:>7.1f}{paired:>7.2f}{paired_s:>9.2f}"
                + (f"  [{failed} not converged]" if failed else ""),
                flush=True,
            )


if __name__ == "__main__":
    main()
