"""Table 3: mean G of hierarchical CVTs of the square for s = 0 … 4."""

from __future__ import annotations

from hcvt.experiments.base import Config, Experiment
from hcvt.experiments.paper import PAPER


def experiments(quick: bool) -> list[Experiment]:
    """Table 3; ``quick`` takes 2,000 sites instead of the paper's 10,000."""
    n = 2000 if quick else 10000
    configs = tuple(
        Config("table3", f"s={s}", "square", n, "hierarchical", "random", s, paper_g=g)
        for s, g in enumerate(PAPER["table3"])
    )
    title = f"Square, n = {n}, random init, s = 0…4 (paper Table 3: n = 10000)"
    return [Experiment("table3", title, configs, 2)]
