"""Regular CVTs beyond the paper (issue 20): best-posed lattices and defect relaxation.

Beside the paper's Tables 3-6, for the cases where the paper gave its most regular values:
a plain Newton CVT from random sites (the time reference), the paper's hierarchical method
(Newton at every level), our best-posed lattice (:func:`hcvt.seeding.regular.posed_lattice` and a
Newton CVT, no moves) and :func:`hcvt.regular_cvt` (the same, then defect-relaxation
moves). Every row also gives the interior defects (:func:`hcvt.defects`). The paper's values
set beside a row are its most regular of that case: the hand-posed lattice (square 1,033:
Table 4 f; star: Table 5 i), its best (ball 5,000: Table 6, hierarchical from a lattice;
square 10,000: Table 3, s = 4); beside the hierarchical rows, its hierarchical values.
"""

from __future__ import annotations

from hcvt.experiments.base import Config, Experiment
from hcvt.experiments.paper import PAPER

# (case, shape, n, subdivisions of the hierarchy, moves of the relaxation, seeds at most,
# paper's most regular (G, E), paper's hierarchical-from-random (G, E)); E None where the
# paper gives none. Seeds are capped for the long cases (minutes per run on 2 cores).
CASES = (
    ("square 1033", "square", 1033, 4, 60, None, PAPER["table4"]["(f) hexagonal lattice"],
     PAPER["table4"]["(d) hierarchical, random, s=4"]),
    ("star 10025", "star", 10025, 5, 20, 5, PAPER["table5"]["(i) hexagonal lattice"],
     PAPER["table5"]["(e) hierarchical, random, s=5"]),
    ("square 10000", "square", 10000, 4, 20, 5, (PAPER["table3"][4], None),
     (PAPER["table3"][4], None)),
    ("ball 5000", "ball", 5000, 3, 20, 3, PAPER["table6"][5000][3], PAPER["table6"][5000][2]),
)  # fmt: skip


def experiments(quick: bool) -> list[Experiment]:
    """The regular table; ``quick``: the square of 1,033 sites only, 20 moves."""
    configs = []
    for case, shape, n, s, moves, max_runs, best, hierarchical in CASES:
        if quick and n != 1033:
            continue
        moves = 20 if quick else moves
        rows = [
            ("random + Newton", "newton", "random", None, "lbfgs", 0, "lattice", (None, None)),
            (f"hierarchical, random, s={s}", "hierarchical", "random", s, "newton", 0, "lattice",
             hierarchical),
            ("posed lattice, no moves", "regular", "lattice", None, "newton", 0, "lattice", best),
            (f"regular: posed lattice + {moves} moves", "regular", "lattice", None, "newton",
             moves, "lattice", best),
        ]  # fmt: skip
        if shape == "star":
            rows.append(
                (f"regular: hierarchical, lattice, s=1 + {moves} moves", "regular", "lattice",
                 None, "newton", moves, "hierarchical-lattice", best)
            )  # fmt: skip
        for label, method, init, sub, optimiser, m, start, (g, e) in rows:
            configs.append(
                Config(
                    "regular",
                    f"{case}: {label}",
                    shape,
                    n,
                    method,
                    init,
                    sub,
                    paper_g=g,
                    paper_energy=e,
                    optimiser=optimiser,
                    moves=m,
                    start=start,
                    max_runs=max_runs,
                    keep_sites=n == 1033,  # the figure: cells and defects of the square
                )
            )
    title = "Regular CVTs beyond the paper: best-posed lattices and defect relaxation (issue 20)"
    # Mixed dimensions (timings-like) unless quick leaves the square alone.
    dim = 2 if quick else None
    return [Experiment("regular", title, tuple(configs), dim, ("defects",))]
