"""Table 8: CVT seconds, standard (random + L-BFGS) against hierarchical, and both with Newton.

Every run stops by the paper's rule, ``‖g‖/‖X‖ < 1e-10`` in the input coordinates, except
Homer 50k (``DEFAULT_RULE``), which is timed to our scale-free rule and says so.
"""

from __future__ import annotations

from hcvt.experiments.base import Config, Experiment, timing_table
from hcvt.experiments.paper import PAPER

# Each case with our two optimisers: (optimiser, suffix of the row label).
OPTIMISERS = (("lbfgs", ""), ("newton", ", Newton"))


# Cases timed to our default rule: in homer.obj's units (volume 0.021) the paper's rule
# holds at an RMS gap near 1e-2, a dozen diagrams from random sites, so its time would mean
# nothing. Newton only: L-BFGS at 50k sites in 3D takes too long for a reproduction run.
DEFAULT_RULE = {("homer.obj", 50000)}


def configs(shape: str, n: int, optimiser: str, suffix: str) -> tuple[Config, Config]:
    """The standard and the hierarchical run of one case with one optimiser."""
    standard, hierarchical, s = PAPER["table8"][(shape, n)]
    rule = "gap" if (shape, n) in DEFAULT_RULE else "paper"
    tag = suffix + (", our rule" if rule == "gap" else "")
    return (
        Config(
            "table8",
            f"{shape} {n} standard{tag}",
            shape,
            n,
            optimiser,
            paper_seconds=standard,
            rule=rule,
        ),
        Config(
            "table8",
            f"{shape} {n} hierarchical{tag}",
            shape,
            n,
            "hierarchical",
            subdivisions=s,
            paper_seconds=hierarchical,
            optimiser=optimiser,
            rule=rule,
        ),
    )


def experiments(quick: bool) -> list[Experiment]:
    """Table 8; ``quick`` keeps the cases of at most 2,000 sites."""
    cases = [(shape, n) for shape, n in PAPER["table8"] if not quick or n <= 2000]
    rows = tuple(
        config
        for shape, n in cases
        for optimiser, suffix in OPTIMISERS
        if (shape, n) not in DEFAULT_RULE or optimiser == "newton"
        for config in configs(shape, n, optimiser, suffix)
    )
    title = (
        "CVT seconds, standard (random + L-BFGS) vs hierarchical (paper Table 8), "
        "and both with our Newton optimiser"
    )
    return [Experiment("table8", title, rows, None, table=timing_table, timing=True)]
