"""Figure 12: convergence of the last L-BFGS update of each configuration of Table 5."""

from __future__ import annotations

from dataclasses import replace

from hcvt.experiments import table5
from hcvt.experiments.base import Experiment


def experiments(quick: bool) -> list[Experiment]:
    """Figure 12 over the runs of Table 5 (each seed, with its history)."""
    star = table5.experiments(quick)[0]
    configs = tuple(
        replace(c, experiment="fig12", keep_history=True, keep_sites=False) for c in star.configs
    )
    n = table5.star_n(quick)
    title = f"Star, n = {n}: convergence of the last L-BFGS update (paper Figure 12)"
    return [Experiment("fig12", title, configs, 2, ("convergence",), random_only_runs=False)]
