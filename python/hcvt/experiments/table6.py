"""Table 6 and Figure 10: four ways to a CVT of the ball, n = 1000 and 5000."""

from __future__ import annotations

from dataclasses import replace

from hcvt.experiments.base import Config, Experiment
from hcvt.experiments.paper import PAPER

# The paper's "maximum possible" subdivisions for each n.
SUBDIVISIONS = {1000: 2, 5000: 3}


def experiments(quick: bool) -> list[Experiment]:
    """Table 6 and its figure; ``quick`` leaves out n = 5000."""
    configs = []
    for n, paper in PAPER["table6"].items():
        if quick and n > 1000:
            continue
        s = SUBDIVISIONS[n]
        methods = [
            ("random + L-BFGS", "lbfgs", "random", None),
            ("Hammersley + L-BFGS", "lbfgs", "hammersley", None),
            (f"hierarchical, random, s={s}", "hierarchical", "random", s),
            ("hierarchical, lattice, s=1", "hierarchical", "lattice", 1),
        ]
        for (label, method, init, sub), (g, e) in zip(methods, paper, strict=True):
            label = f"n={n}: {label}"
            configs.append(
                Config("table6", label, "ball", n, method, init, sub, 0, g, e, keep_sites=True)
            )
    title = "Ball of volume 1.42 (paper Table 6, Figure 10)"
    table6 = Experiment("table6", title, tuple(configs), 3, ("cuts",))
    return [table6, replace(table6, name="fig10")]
