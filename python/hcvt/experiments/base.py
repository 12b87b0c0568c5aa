"""What every experiment is made of: configurations, runs, summaries, tables, figures.

An :class:`Experiment` is a grid of :class:`Config` rows (shape, n, method, initialisation,
subdivisions, seed) with its own dimension and its own table (:func:`comparison_table`,
:func:`levels_table`, :func:`timing_table`). :func:`run_grid` runs a grid on
dask.distributed; :func:`summarise` takes the median over the seeds of each row, as the
paper does for random initialisations.
"""

from __future__ import annotations

import csv
import os
import time
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

import hcvt
from hcvt import plot
from hcvt.experiments.paper import PAPER
from hcvt.geometry.shapes import BUILTIN, builtin_domain
from hcvt.io import load_domain
from hcvt.lazy import load
from hcvt.seeding.hierarchy import schedule

Row = dict[str, Any]


@dataclass(frozen=True)
class Config:
    """One configuration of an experiment; ``seed`` varies across its runs."""

    experiment: str
    label: str
    shape: str
    n: int
    method: str  # "lbfgs", "newton", "hierarchical", "monte-carlo", "voronoi", "regular"
    init: str = "random"
    subdivisions: int | None = None
    seed: int = 0
    paper_g: float | None = None
    paper_energy: float | None = None
    paper_seconds: float | None = None
    paper_n: int | None = None  # the paper's site count, when a quick run uses fewer
    keep_sites: bool = False
    keep_history: bool = False
    updates: int = 200  # Monte-Carlo only
    optimiser: str = "lbfgs"  # hierarchical and regular: the optimiser of every CVT
    moves: int = 60  # regular only: defect-relaxation moves (hcvt.regular_cvt)
    start: str = "lattice"  # regular only: what the relaxation starts from
    max_runs: int | None = None  # seeds at most, whatever --runs says (long cases)
    # The stopping rule of every CVT (hcvt.cvt): the paper's, ‖g‖/‖X‖ < 1e-10 in the input
    # coordinates, as the paper ran; "gap" (our scale-free default) where the paper's rule
    # means nothing in the mesh's units (homer.obj: it holds at an RMS gap near 1e-2).
    rule: str = "paper"


@dataclass
class Summary:
    """Median over runs of one configuration."""

    config: Config
    rows: list[Row] = field(default_factory=list)

    def median(self, key: str) -> float:
        """Median of a scalar result over the runs."""
        return float(np.median([row[key] for row in self.rows]))


def summarise(experiment: Experiment, rows: list[Row]) -> list[Summary]:
    """Group runs by configuration label, in the experiment's order."""
    by_label = {c.label: Summary(c) for c in experiment.configs}
    for row in rows:
        by_label[row["label"]].rows.append(row)
    return [s for s in by_label.values() if s.rows]


def paper_energy_at(config: Config, dim: int) -> float | None:
    """The paper's energy brought to our site count: E scales as n^(-2/d) at fixed volume."""
    if config.paper_energy is None:
        return None
    paper_n = config.paper_n or config.n
    return config.paper_energy * (paper_n / config.n) ** (2.0 / dim)


def _ratio(ours: float, paper: float | None) -> str:
    return "" if paper is None else f"{ours / paper:.4f}"


Table = Callable[["Experiment", list[Summary]], str]


def comparison_table(experiment: Experiment, summaries: list[Summary]) -> str:
    """Our median mean G and energy beside the paper's, with ratios (ours / paper)."""
    header = (
        "| configuration | runs | ours mean G | paper mean G | ratio | ours energy | "
        "paper energy | ratio | interior defects | seconds |\n"
        "|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for s in summaries:
        g, e = s.median("mean_G"), s.median("energy")
        c = s.config
        if experiment.dim is not None:
            pe = paper_energy_at(c, experiment.dim)
        else:  # mixed dimensions: the paper's energy only where n is the paper's
            pe = c.paper_energy if (c.paper_n or c.n) == c.n else None
        paper_e = "" if pe is None else f"{pe:.6g}"
        lines.append(
            f"| {c.label} | {len(s.rows)} | {g:.5f} | {c.paper_g or ''} | {_ratio(g, c.paper_g)} "
            f"| {e:.6g} | {paper_e} | {_ratio(e, pe)} | {_defects(s)} "
            f"| {s.median('seconds'):.2f} |"
        )
    return header + "\n".join(lines) + "\n"


def _defects(summary: Summary) -> str:
    """Median interior defects, their share of the interior cells, and the deep ones."""
    if "defects" not in summary.rows[0]:
        return ""
    count, interior = summary.median("defects"), summary.median("interior_cells")
    share = f" ({100 * count / interior:.1f}%)" if interior else ""
    deep = (
        f", deep {summary.median('deep_defects'):.0f}" if "deep_defects" in summary.rows[0] else ""
    )
    return f"{count:.0f}{share}{deep}"


def levels_table(experiment: Experiment, summaries: list[Summary]) -> str:
    """Median mean G of each level of one hierarchical configuration beside the paper's.

    The paper's values per level come from ``PAPER[experiment.paper_levels]`` when it has
    them (Table 2); Figure 1 gives pictures only.
    """
    config = summaries[0].config
    if experiment.dim is None:
        raise ValueError(f"{experiment.name}: a levels table needs one dimension")
    plan = schedule(config.n, config.subdivisions or 0, experiment.dim)
    sizes = [plan.k0, *plan.targets]
    paper = PAPER[experiment.paper_levels] if experiment.paper_levels else [None] * len(sizes)
    levels = np.median([row["levels_G"] for row in summaries[0].rows], axis=0)
    header = "| level | sites | ours mean G | paper mean G | ratio |\n|---|---|---|---|---|\n"
    lines = [
        f"| {i} | {sizes[i]} | {g:.5f} | {'' if paper[i] is None else f'{paper[i]:.5f}'} "
        f"| {_ratio(g, paper[i])} |"
        for i, g in enumerate(levels)
    ]
    return header + "\n".join(lines) + "\n"


def timing_table(experiment: Experiment, summaries: list[Summary]) -> str:
    """Our median seconds beside the paper's, with the speed-up, and the stopping rule.

    A speed-up is printed only for runs under the paper's rule (``‖g‖/‖X‖ < 1e-10`` in input
    coordinates) or with no rule (diagrams alone); runs to our default rule say so instead.
    """
    header = (
        "| case | runs | rule | ours (s) | paper (s) | paper / ours |\n|---|---|---|---|---|---|\n"
    )
    lines = []
    for s in summaries:
        c = s.config
        ours, paper = s.median("seconds"), c.paper_seconds
        rule = "—" if c.method == "voronoi" else ("paper's" if c.rule == "paper" else "ours (gap)")
        if paper is None:
            speedup = ""
        elif c.rule == "paper" or c.method == "voronoi":
            speedup = f"{paper / ours:.0f}×"
        else:
            speedup = "none: not the paper's rule"
        lines.append(
            f"| {c.label} | {len(s.rows)} | {rule} | {ours:.3f} | {paper or ''} | {speedup} |"
        )
    return header + "\n".join(lines) + "\n"


@dataclass(frozen=True)
class Experiment:
    """A named grid of configurations, its dimension, its table and its figures."""

    name: str
    title: str
    configs: tuple[Config, ...]
    dim: int | None  # None: cases of both dimensions (timings only)
    figures: tuple[str, ...] = ()
    table: Table = comparison_table
    random_only_runs: bool = True  # several seeds only for random initialisations
    timing: bool = False  # run one at a time with every thread
    paper_levels: str | None = None  # levels_table: the PAPER entry of mean G per level


def comparison(
    name: str,
    shape: str,
    n: int,
    rows: Iterable[tuple[str, str, str, int | None, float, float]],
    figures: tuple[str, ...] = (),
    title: str = "",
    paper_n: int | None = None,
) -> Experiment:
    """A 2D experiment of one shape and size: ``rows`` of (label, method, init, s, G, E)."""
    configs = tuple(
        Config(
            name,
            label,
            shape,
            n,
            method,
            init,
            s,
            paper_g=g,
            paper_energy=e,
            keep_sites=True,
            paper_n=paper_n or n,
        )
        for label, method, init, s, g, e in rows
    )
    return Experiment(name, title, configs, 2, figures)


# ------------------------------------------------------------------------------ runs
def load_shape(shape: str):
    """A built-in shape by name, or a mesh file of ``../shared/data/3d`` by file name."""
    if shape in BUILTIN:
        return builtin_domain(shape)
    return load_domain(data_dir() / "3d" / shape, repair=True)


def data_dir() -> Path:
    """The shared data folder: ``$HCVT_DATA``, else ``../shared/data`` nearby.

    Looked for beside the repository (editable install), then beside the working directory.
    """
    env = os.environ.get("HCVT_DATA")
    if env:
        return Path(env)
    candidates = [
        Path(__file__).resolve().parents[4] / "shared" / "data",
        Path.cwd().parent / "shared" / "data",
        Path.cwd() / "shared" / "data",
    ]
    found = next((c for c in candidates if c.is_dir()), None)
    if found is None:
        raise FileNotFoundError("no ../shared/data for the meshes of Table 7; set HCVT_DATA")
    return found


def run_config(config: Config) -> Row:
    """Run one configuration; returns its numbers (and sites/G/history when asked)."""
    domain = load_shape(config.shape)
    start = time.perf_counter()
    levels: list[float] = []
    levels_sites: list[np.ndarray] = []
    history = None
    iterations = 0
    extra: Row = {}
    if config.method == "voronoi":
        sites = hcvt.initialise(domain, config.n, method=config.init, seed=config.seed)
        start = time.perf_counter()  # Table 7 times the diagram alone
        diagram = hcvt.voronoi(domain, sites)
    elif config.method == "hierarchical":
        result = hcvt.hierarchical_cvt(
            domain,
            config.n,
            config.subdivisions,
            init=config.init,
            seed=config.seed,
            rule=config.rule,
            method=config.optimiser,
        )
        diagram = result.diagram
        levels = [level.mean_G for level in result.levels]
        if config.keep_sites:
            levels_sites = [level.sites for level in result.levels]
        iterations = sum(level.iterations for level in result.levels)
        history = result.levels[-1].history if config.keep_history else None
    elif config.method == "regular":
        regular = hcvt.regular_cvt(
            domain,
            config.n,
            seed=config.seed,
            start=config.start,
            moves=config.moves,
            method=config.optimiser,
            rule=config.rule,
        )
        diagram = regular.diagram
        iterations = regular.relaxation.moves
        extra = {
            "start_energy": regular.start_energy,
            "start_mean_G": regular.start_mean_G,
            "start_defects": regular.start_defects,
            "accepted": regular.relaxation.accepted,
        }
    else:
        sites = hcvt.initialise(domain, config.n, method=config.init, seed=config.seed)
        run: hcvt.MonteCarloResult | hcvt.CVTResult
        if config.method == "monte-carlo":
            run = hcvt.global_monte_carlo(
                domain, sites, updates=config.updates, seed=config.seed, rule=config.rule
            )
        else:
            run = hcvt.cvt(domain, sites, method=config.method, rule=config.rule)
        diagram, iterations = run.diagram, run.iterations
        history = run.history if isinstance(run, hcvt.CVTResult) and config.keep_history else None
    seconds = time.perf_counter() - start
    row: Row = {
        **{k: v for k, v in asdict(config).items() if not k.startswith("keep")},
        "mean_G": float(diagram.mean_G),
        "energy": float(diagram.energy),
        "iterations": int(iterations),
        "seconds": seconds,
        "levels_G": levels,
        **hcvt.defects(diagram).summary(),
        **extra,
    }
    if config.keep_sites:
        row["sites"] = diagram.sites
        row["G"] = diagram.G
        row["levels_sites"] = levels_sites
    if history is not None:
        row["history_energy"] = np.asarray(history["energy"])
        row["history_G"] = np.asarray(history["mean_G"])
    return row


def expand(experiment: Experiment, runs: int) -> list[Config]:
    """The experiment's configurations, each with ``runs`` seeds where the paper took a median.

    Lattice and Hammersley initialisations are deterministic: one run each; the regular
    method's seed chooses its poses and moves, so it runs every seed.
    """
    out: list[Config] = []
    for config in experiment.configs:
        random = config.init == "random" or config.method in ("voronoi", "regular")
        count = runs if (random or not experiment.random_only_runs) else 1
        count = count if config.max_runs is None else min(count, config.max_runs)
        out.extend(replace(config, seed=seed) for seed in range(count))
    return out


def run_grid(
    configs: list[Config],
    *,
    scheduler: str | None = None,
    serial: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> list[Row]:
    """Run every configuration on dask.distributed; rows in the order of ``configs``.

    ``scheduler``: an existing scheduler address; by default a LocalCluster of one
    single-threaded worker process per core. ``serial``: one task at a time (timings).
    """
    dask_distributed = load("dask.distributed")
    Client, LocalCluster, as_completed = (  # noqa: N806 (dask's class names)
        dask_distributed.Client,
        dask_distributed.LocalCluster,
        dask_distributed.as_completed,
    )
    cluster = None
    if scheduler is None:
        workers = 1 if serial else (os.cpu_count() or 1)
        cluster = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        )
    client = Client(scheduler or cluster)
    try:
        rows: list[Row | None] = [None] * len(configs)
        if serial:
            for i, config in enumerate(configs):
                rows[i] = client.submit(run_config, config, pure=False).result()
                if progress:
                    progress(i + 1, len(configs))
        else:
            futures = {client.submit(run_config, c, pure=False): i for i, c in enumerate(configs)}
            for done, future in enumerate(as_completed(futures), 1):
                rows[futures[future]] = future.result()
                if progress:
                    progress(done, len(configs))
        return [row for row in rows if row is not None]
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def markdown_table(experiment: Experiment, summaries: list[Summary]) -> str:
    """The experiment's own table of our medians beside the paper's values."""
    return experiment.table(experiment, summaries)


def write_csv(rows: list[Row], path: Path) -> None:
    """Every run's scalar results, one line per run."""
    # The union of every row's scalar keys, first seen first: methods add their own.
    scalar = list(
        dict.fromkeys(k for row in rows for k, v in row.items() if np.isscalar(v) or v is None)
    )
    with path.open("w", newline="") as out:
        writer = csv.DictWriter(out, fieldnames=scalar, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)


# --------------------------------------------------------------------------- figures
def _median_run(summary: Summary, key: str = "mean_G") -> Row:
    """The run whose value is the median (the lower median for an even count)."""
    ordered = sorted(summary.rows, key=lambda row: row[key])
    return ordered[(len(ordered) - 1) // 2]


def draw_figures(experiment: Experiment, summaries: list[Summary], out: Path) -> list[Path]:
    """The experiment's figures as PNG files in ``out``; returns their paths."""
    written = []
    for kind in experiment.figures:
        path = out / f"{experiment.name}_{kind}.png"
        if kind == "convergence":
            plot.convergence_figure({s.config.label: _median_run(s) for s in summaries}, path)
        elif kind == "levels":  # every level of the median run, 2D cells or 3D cut views
            plot.levels_figure(
                load_shape(summaries[0].config.shape), _median_run(summaries[0]), path
            )
        else:
            if kind == "defects":  # the rows that kept their sites (one shape, 2D)
                summaries = [s for s in summaries if "sites" in s.rows[0]]
            runs = {s.config.label: _median_run(s) for s in summaries}
            domains = {s.config.label: load_shape(s.config.shape) for s in summaries}
            plot.comparison_figure(domains, runs, path, kind=kind)
        written.append(path)
    return written
