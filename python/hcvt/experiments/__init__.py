"""Reproduction of the paper's experiments (tables 2–8, figures 1, 5, 8–12).

One module per table or figure builds its :class:`Experiment`: a grid of :class:`Config`
rows with its own dimension and table, and the paper's values from :data:`PAPER` (one
table of every number we compare with). :func:`reproduce` runs the grid on
dask.distributed (a LocalCluster by default, or an existing scheduler address), takes the
median over the seeds of each row as the paper does for random initialisations, and writes
``DIR/EXPERIMENT.md`` (our value beside the paper's, with the ratio), ``DIR/EXPERIMENT.csv``
(every run) and the figures.

Shapes are the paper's, at the paper's size (:mod:`hcvt.geometry.shapes`): the 20 x 20 square
(area 400), the five-branch star of area 117.5 and the ball of volume 1.42, so that
energies compare without scaling. Meshes of Table 7 come from ``../shared/data/3d``.

To add an experiment: a module with ``experiments(quick) -> list[Experiment]`` (the
experiment first, then any copies under a figure's name), its numbers in :data:`PAPER`,
and its place in ``MODULES``.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path

from hcvt.experiments import (
    fig1,
    fig11,
    fig12,
    regular,
    table2,
    table3,
    table4,
    table5,
    table6,
    table7,
    table8,
)
from hcvt.experiments.base import (
    Config,
    Experiment,
    Row,
    Summary,
    comparison_table,
    data_dir,
    draw_figures,
    expand,
    levels_table,
    load_shape,
    markdown_table,
    paper_energy_at,
    run_config,
    run_grid,
    summarise,
    timing_table,
    write_csv,
)
from hcvt.experiments.paper import PAPER

__all__ = [
    "EXPERIMENTS",
    "PAPER",
    "Config",
    "Experiment",
    "Row",
    "Summary",
    "comparison_table",
    "data_dir",
    "draw_figures",
    "expand",
    "experiments",
    "levels_table",
    "load_shape",
    "markdown_table",
    "paper_energy_at",
    "reproduce",
    "run_config",
    "run_grid",
    "summarise",
    "timing_table",
    "write_csv",
]

# In the order of ``hcvt reproduce all``.
MODULES = (table2, table3, table4, table5, table6, table7, table8, fig12, fig1, fig11, regular)


def experiments(quick: bool) -> dict[str, Experiment]:
    """Every experiment by name; ``quick`` shrinks sizes and updates to run in minutes.

    Each module's experiment in the order of ``MODULES``, then the copies made for figures.
    """
    made = [module.experiments(quick) for module in MODULES]
    ordered = [m[0] for m in made] + [copy for m in made for copy in m[1:]]
    return {e.name: e for e in ordered}


EXPERIMENTS = tuple(experiments(False))


def reproduce(
    name: str,
    *,
    runs: int = 10,
    quick: bool = False,
    scheduler: str | None = None,
    out: str | Path = "results",
    progress: Callable[[str, int, int], None] | None = None,
) -> Path:
    """Run experiment ``name`` (or ``"all"``) and write ``out/NAME.md``, CSV and figures.

    Returns the path of the Markdown report (for ``"all"``, of ``out/all.md`` linking
    every report).
    """
    known = experiments(quick)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if name == "all":
        reports = [
            reproduce(e, runs=runs, quick=quick, scheduler=scheduler, out=out, progress=progress)
            for e in known
            if not e.startswith("fig") or e in ("fig12", "fig1", "fig11")
        ]
        index = out / "all.md"
        index.write_text("\n".join(f"- [{p.stem}]({p.name})" for p in reports) + "\n")
        return index
    if name not in known:
        names = ", ".join([*known, "all"])
        raise ValueError(f"unknown experiment {name!r}; known: {names}")
    experiment = known[name]
    configs = expand(experiment, 1 if quick else runs)
    step = (lambda done, total: progress(name, done, total)) if progress else None
    start = time.perf_counter()
    rows = run_grid(configs, scheduler=scheduler, serial=experiment.timing, progress=step)
    summaries = summarise(experiment, rows)
    write_csv(rows, out / f"{name}.csv")
    figures = draw_figures(experiment, summaries, out)
    report = out / f"{name}.md"
    report.write_text(
        f"# {experiment.title}\n\n"
        f"{'quick run (reduced sizes), ' if quick else ''}{len(rows)} runs in "
        f"{time.perf_counter() - start:.0f} s on {os.cpu_count()} cores; medians over seeds. "
        "Where our n differs from the paper's, its energy is scaled by (n_paper / n)^(2/d).\n\n"
        + markdown_table(experiment, summaries)
        + "".join(f"\n![{p.stem}]({p.name})\n" for p in figures)
    )
    return report
