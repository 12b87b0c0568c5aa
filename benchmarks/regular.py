"""Time hcvt.regular_cvt against a plain Newton CVT from random sites of the same n.

Issue 20 asks the regular method to stay within 10x of a Newton CVT from random sites. For
each case the same seeds run (one at a time, every thread):

- ``newton``: ``hcvt.initialise(random)`` + ``hcvt.cvt(method="newton")``,
- ``posed``: ``hcvt.regular_cvt(moves=0)``: the pose search and the Newton CVT of the best
  poses (``pose`` and ``cvt`` columns: seconds of each part),
- ``regular``: ``hcvt.regular_cvt(moves=M)``: the same, then M relaxation moves,

all to the default rule (RMS gap < 1e-7). Printed: median seconds over the seeds, the ratio
of each to ``newton``, and mean G / energy / interior defects of seed 0's runs.

    OPENBLAS_NUM_THREADS=1 python benchmarks/regular.py [--quick] [--seeds 3]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import statistics
import time

import hcvt
from hcvt.geometry import shapes

# (name, domain, n, moves)
CASES = [
    ("square", shapes.square, 1033, 60),
    ("star", shapes.star, 10025, 20),
    ("square", shapes.square, 10000, 20),
    ("ball", shapes.ball, 5000, 20),
]


def timed(run, *args, **kwargs):
    start = time.perf_counter()
    out = run(*args, **kwargs)
    return time.perf_counter() - start, out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="square 1033 only")
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    cases = CASES[:1] if args.quick else CASES
    print(f"threads {hcvt.get_num_threads()}, seeds 0..{args.seeds - 1}, default rule\n")
    print(
        "| case | newton (s) | posed (s) | pose | cvt | ratio | regular (s) | moves | ratio "
        "| G newton | G posed | G regular | E posed | E regular | defects newton/posed/regular |"
    )
    print("|---" * 15 + "|")
    for name, make, n, moves in cases:
        domain = make()
        rows: dict[str, list[float]] = {key: [] for key in ("newton", "posed", "regular", "pose")}
        for seed in range(args.seeds):
            sites = hcvt.initialise(domain, n, seed=seed)
            t_newton, newton = timed(hcvt.cvt, domain, sites, "newton")
            t_regular, regular = timed(hcvt.regular_cvt, domain, n, seed=seed, moves=moves)
            stage, seconds = regular.history["stage"], regular.history["seconds"]
            rows["newton"].append(t_newton)
            rows["regular"].append(t_regular)
            rows["pose"].append(float(seconds[stage == "pose"].max()))
            rows["posed"].append(float(seconds[stage == "cvt"].max()))
            if seed == 0:
                first = (newton, regular)
        med = {key: statistics.median(values) for key, values in rows.items()}
        newton, regular = first
        defects = (
            f"{hcvt.defects(newton.diagram).number}/{regular.start_defects}/"
            f"{regular.defects.number}"
        )
        print(
            f"| {name} {n} | {med['newton']:.2f} | {med['posed']:.2f} | {med['pose']:.2f} "
            f"| {med['posed'] - med['pose']:.2f} | {med['posed'] / med['newton']:.1f}x "
            f"| {med['regular']:.2f} | {moves} | {med['regular'] / med['newton']:.1f}x "
            f"| {newton.mean_G:.6f} | {regular.start_mean_G:.6f} | {regular.mean_G:.6f} "
            f"| {regular.start_energy:.7g} | {regular.energy:.7g} | {defects} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
