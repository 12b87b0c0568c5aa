"""The paper's Table 8: CVT seconds, standard (random + L-BFGS) against hierarchical.

Each row runs one optimiser (``--methods``, default L-BFGS, the paper's, then Newton) for
both the standard and the hierarchical method.

Both methods run to the paper's stopping rule, ‖g‖/‖X‖ < 1e-10 in the input coordinates
(``rule="paper"``, at every level of the hierarchy), on the paper's shapes (the 20 x 20
square, the star of area 117.5, the ball of volume 1.42) in the same run; the
hierarchical method starts from random sites with the paper's subdivisions (4 in 2D; 2
and 3 for the ball, its "maximum possible"). Prints our medians beside the paper's
seconds (Intel Xeon E5-2643, 3.3 GHz) and the speed-ups.

    OPENBLAS_NUM_THREADS=1 python benchmarks/hierarchy.py [--repeat 3] [--quick] [--methods ...]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import statistics
import time

import hcvt
from hcvt.experiments import PAPER
from hcvt.experiments.table8 import DEFAULT_RULE
from hcvt.geometry.shapes import builtin_domain


def seconds(run, repeat: int) -> tuple[float, object]:
    """Median wall-clock seconds of ``run()`` over ``repeat`` seeds, and the last result."""
    times, result = [], None
    for seed in range(repeat):
        start = time.perf_counter()
        result = run(seed)
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=3, help="seeds per case (median)")
    parser.add_argument("--quick", action="store_true", help="cases up to 2,000 sites")
    parser.add_argument("--methods", nargs="+", default=["lbfgs", "newton"], help="optimisers")
    args = parser.parse_args()
    print(
        f"hcvt {hcvt.__version__}, {hcvt.get_num_threads()} threads, median of {args.repeat}; "
        "every time to the paper's rule ‖g‖/‖X‖ < 1e-10 in input coordinates"
    )
    print(
        f"{'case':<14}{'method':>8}{'std s':>9}{'hier s':>9}{'std/hier':>9}"
        f"{'paper std':>11}{'paper hier':>11}{'x paper std':>12}{'x paper hier':>13}"
        f"{'G std':>9}{'G hier':>9}"
    )
    for (shape, n), (paper_std, paper_hier, s) in PAPER["table8"].items():
        if (args.quick and n > 2000) or (shape, n) in DEFAULT_RULE:
            continue  # Homer 50k: no paper-rule time means anything there (benchmarks/cvt.py)
        domain = builtin_domain(shape)
        for method in args.methods:
            run_case(domain, shape, n, s, method, paper_std, paper_hier, args.repeat)


def run_case(domain, shape, n, s, method, paper_std, paper_hier, repeat) -> None:
    """One row: standard and hierarchical with ``method``, against the paper."""

    def standard(seed: int):
        sites = hcvt.initialise(domain, n, method="random", seed=seed)
        return hcvt.cvt(domain, sites, method=method, rule="paper")

    def hierarchical(seed: int):
        return hcvt.hierarchical_cvt(
            domain, n, s, init="random", seed=seed, rule="paper", method=method
        )

    t_std, r_std = seconds(standard, repeat)
    t_hier, r_hier = seconds(hierarchical, repeat)
    print(
        f"{shape + ' ' + str(n):<14}{method:>8}{t_std:>9.2f}{t_hier:>9.2f}{t_std / t_hier:>9.2f}"
        f"{paper_std:>11.2f}{paper_hier:>11.2f}{paper_std / t_std:>12.0f}"
        f"{paper_hier / t_hier:>13.0f}"
        f"{r_std.diagram.mean_G:>9.5f}{r_hier.diagram.mean_G:>9.5f}",
        flush=True,
    )


if __name__ == "__main__":
    main()
