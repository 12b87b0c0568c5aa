"""Table 8: CVT seconds, standard (random + L-BFGS) against hierarchical, and both with Newton."""

from __future__ import annotations

from hcvt.experiments.base import Config, Experiment, timing_table
from hcvt.experiments.paper import PAPER

# Each case with our two optimisers: (optimiser, suffix of the row label).
OPTIMISERS = (("lbfgs", ""), ("newton", ", Newton"))


def configs(shape: str, n: int, optimiser: str, suffix: str) -> tuple[Config, Config]:
    """The standard and the hierarchical run of one case with one optimiser."""
    standard, hierarchical, s = PAPER["table8"][(shape, n)]
    return (
        Config(
            "table8", f"{shape} {n} standard{suffix}", shape, n, optimiser, paper_seconds=standard
        ),
        Config(
            "table8",
            f"{shape} {n} hierarchical{suffix}",
            shape,
            n,
            "hierarchical",
            subdivisions=s,
            paper_seconds=hierarchical,
            optimiser=optimiser,
        ),
    )


def experiments(quick: bool) -> list[Experiment]:
    """Table 8; ``quick`` keeps the cases of at most 2,000 sites."""
    cases = [(shape, n) for shape, n in PAPER["table8"] if not quick or n <= 2000]
    rows = tuple(
        config
        for shape, n in cases
        for optimiser, suffix in OPTIMISERS
        for config in configs(shape, n, optimiser, suffix)
    )
    title = (
        "CVT seconds, standard (random + L-BFGS) vs hierarchical (paper Table 8), "
        "and both with our Newton optimiser"
    )
    return [Experiment("table8", title, rows, None, table=timing_table, timing=True)]
