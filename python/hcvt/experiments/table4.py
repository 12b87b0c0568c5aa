"""Table 4 and Figure 8: six ways to a CVT of the square, n = 1033."""

from __future__ import annotations

from dataclasses import replace

from hcvt.experiments.base import Experiment, comparison
from hcvt.experiments.paper import PAPER

# (label, method, initialisation, subdivisions) of each row.
ROWS = (
    ("(a) random + L-BFGS", "lbfgs", "random", None),
    ("(b) Hammersley + L-BFGS", "lbfgs", "hammersley", None),
    ("(c) global Monte-Carlo", "monte-carlo", "random", None),
    ("(d) hierarchical, random, s=4", "hierarchical", "random", 4),
    ("(e) hierarchical, lattice, s=1", "hierarchical", "lattice", 1),
    ("(f) hexagonal lattice", "lbfgs", "lattice", None),
)


def experiments(quick: bool) -> list[Experiment]:
    """Table 4 and its figure; ``quick`` makes 10 Monte-Carlo updates instead of 200."""
    rows = [(*row, *PAPER["table4"][row[0]]) for row in ROWS]
    table4 = comparison(
        "table4",
        "square",
        1033,
        rows,
        figures=("cells",),
        title="Square 20 x 20, n = 1033 (paper Table 4, Figure 8)",
    )
    updates = 10 if quick else 200
    table4 = replace(table4, configs=tuple(replace(c, updates=updates) for c in table4.configs))
    return [table4, replace(table4, name="fig8")]
