"""Table 2 and Figure 5: mean G of each level of one hierarchical run in the square."""

from __future__ import annotations

from dataclasses import replace

from hcvt.experiments.base import Config, Experiment, levels_table


def experiments(quick: bool) -> list[Experiment]:
    """Table 2 and its figure (the same runs); ``quick`` changes nothing."""
    table2 = Experiment(
        "table2",
        "Square, n = 2560, s = 4, random: mean G per level (paper Table 2, Figure 5)",
        (Config("table2", "levels", "square", 2560, "hierarchical", "random", 4, keep_sites=True),),
        2,
        ("levels",),
        table=levels_table,
        paper_levels="table2",
    )
    return [table2, replace(table2, name="fig5")]
