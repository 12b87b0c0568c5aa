"""Figure 1: Homer by the hierarchical method, levels of 546, 4,375 and 35,000 cells.

The paper shows the three levels and a cut of the last (pictures only). One run from random
sites, s = 2, Newton at every level to our default rule: in homer.obj's units (volume 0.021)
the paper's rule holds long before the CVT has converged. ``quick``: 4,375 sites, s = 1.
"""

from __future__ import annotations

from hcvt.experiments.base import Config, Experiment, levels_table
from hcvt.experiments.paper import PAPER


def experiments(quick: bool) -> list[Experiment]:
    """Figure 1; its table is mean G per level."""
    shape, n, s = PAPER["fig1"]
    if quick:
        n, s = n // 8, s - 1
    config = Config(
        "fig1",
        f"hierarchical, random, s={s}",
        shape,
        n,
        "hierarchical",
        "random",
        s,
        keep_sites=True,
        optimiser="newton",
        rule="gap",
    )
    title = "Homer, hierarchical from random sites: mean G per level (paper Figure 1)"
    return [Experiment("fig1", title, (config,), 3, ("levels",), table=levels_table)]
