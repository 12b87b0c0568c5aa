"""Table 7: seconds of one clipped Voronoi diagram of random sites in meshes."""

from __future__ import annotations

from hcvt.experiments.base import Config, Experiment, timing_table
from hcvt.experiments.paper import PAPER


def experiments(quick: bool) -> list[Experiment]:
    """Table 7; ``quick`` times the ball and Homer at 5,000 sites (no paper value)."""
    cases = [(shape, n, t) for (shape, n), t in PAPER["table7"].items()]
    if quick:
        cases = [("ball", 1000, PAPER["table7"][("ball", 1000)]), ("homer.obj", 5000, None)]
    configs = tuple(
        Config("table7", f"{shape} {n // 1000}k", shape, n, "voronoi", paper_seconds=t)
        for shape, n, t in cases
    )
    title = "Clipped Voronoi diagrams of meshes, random sites (paper Table 7)"
    return [Experiment("table7", title, configs, 3, table=timing_table, timing=True)]
