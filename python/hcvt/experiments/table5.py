"""Table 5 and Figure 9: five ways to a CVT of the star, n = 10025."""

from __future__ import annotations

from dataclasses import replace

from hcvt.experiments.base import Experiment, comparison
from hcvt.experiments.paper import PAPER

# (label, method, initialisation, subdivisions) of each row; its key in PAPER["table5"].
ROWS = (
    ("(a) random + L-BFGS", "lbfgs", "random", None),
    ("(c) Hammersley + L-BFGS", "lbfgs", "hammersley", None),
    ("(e) hierarchical, random, s=5", "hierarchical", "random", 5),
    ("(g) hierarchical, lattice, s=1", "hierarchical", "lattice", 1),
    ("(i) hexagonal lattice", "lbfgs", "lattice", None),
)


def star_n(quick: bool) -> int:
    """Sites in the star: the paper's 10025, or 2000 for a quick run."""
    return 2000 if quick else 10025


def experiments(quick: bool) -> list[Experiment]:
    """Table 5 and its figure; ``quick`` takes 2,000 sites, so at most s = 4."""
    rows = []
    for label, method, init, s in ROWS:
        paper = PAPER["table5"][label]
        if quick and s == 5:
            label, s = "(e) hierarchical, random, s=4", 4
        rows.append((label, method, init, s, *paper))
    n = star_n(quick)
    table5 = comparison(
        "table5",
        "star",
        n,
        rows,
        figures=("cells", "histograms"),
        title=f"Star of area 117.5, n = {n} (paper Table 5, Figure 9: n = 10025)",
        paper_n=10025,
    )
    return [table5, replace(table5, name="fig9")]
