"""Reproduction of the paper's experiments (tables 2–8, figures 5, 8, 9, 10, 12).

Each experiment is a grid of :class:`Config` rows (shape, n, method, initialisation,
subdivisions, seed). :func:`reproduce` runs the grid on dask.distributed (a LocalCluster
by default, or an existing scheduler address), takes the median over the seeds of each
row as the paper does for random initialisations, and writes ``DIR/EXPERIMENT.md`` (our
value beside the paper's, with the ratio), ``DIR/EXPERIMENT.csv`` (every run) and the
figures.

Shapes are the paper's, at the paper's size (:mod:`hcvt.shapes`): the 20 x 20 square
(area 400), the five-branch star of area 117.5 and the ball of volume 1.42, so that
energies compare without scaling. Meshes of Table 7 come from ``../shared/data/3d``.
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

Row = dict[str, Any]

# The paper's mean G (Tables 2–6) and energies; ``None`` where it gives none.
TABLE2 = [0.08458, 0.08246, 0.08154, 0.08099, 0.08066]
TABLE3 = [0.08079, 0.08063, 0.08060, 0.08056, 0.08054]
# Table 8: (shape, n, paper seconds standard, paper seconds hierarchical, subdivisions).
TABLE8 = [
    ("square", 1000, 2.84, 2.16, 4),
    ("square", 5000, 10.85, 9.50, 4),
    ("star", 2000, 3.56, 4.91, 4),
    ("star", 10000, 26.94, 26.97, 4),
    ("ball", 1000, 521.86, 205.82, 2),
    ("ball", 5000, 1484.69, 665.01, 3),
]


@dataclass(frozen=True)
class Config:
    """One configuration of an experiment; ``seed`` varies across its runs."""

    experiment: str
    label: str
    shape: str
    n: int
    method: str  # "lbfgs", "newton", "hierarchical", "monte-carlo", "voronoi"
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
    optimiser: str = "lbfgs"  # hierarchical only: the optimiser of every level


@dataclass(frozen=True)
class Experiment:
    """A named grid of configurations and the figures drawn from its results."""

    name: str
    title: str
    configs: tuple[Config, ...]
    figures: tuple[str, ...] = ()
    random_only_runs: bool = True  # several seeds only for random initialisations
    timing: bool = False  # run one at a time with every thread


# ------------------------------------------------------------------------- experiments
def _comparison(
    name: str,
    shape: str,
    n: int,
    rows: Iterable[tuple[str, str, str, int | None, float, float]],
    figures: tuple[str, ...] = (),
    title: str = "",
    paper_n: int | None = None,
) -> Experiment:
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
    return Experiment(name, title, configs, figures)


def _experiments(quick: bool) -> dict[str, Experiment]:
    """Every experiment; ``quick`` shrinks sizes and updates to run in a few minutes."""
    star_n = 2000 if quick else 10025
    square10k = 2000 if quick else 10000
    mc_updates = 10 if quick else 200
    table4 = _comparison(
        "table4",
        "square",
        1033,
        [
            ("(a) random + L-BFGS", "lbfgs", "random", None, 0.08101, 25.140),
            ("(b) Hammersley + L-BFGS", "lbfgs", "hammersley", None, 0.08107, 25.160),
            ("(c) global Monte-Carlo", "monte-carlo", "random", None, 0.08075, 25.041),
            ("(d) hierarchical, random, s=4", "hierarchical", "random", 4, 0.08086, 25.082),
            ("(e) hierarchical, lattice, s=1", "hierarchical", "lattice", 1, 0.08077, 25.045),
            ("(f) hexagonal lattice", "lbfgs", "lattice", None, 0.08066, 25.002),
        ],
        figures=("cells",),
        title="Square 20 x 20, n = 1033 (paper Table 4, Figure 8)",
    )
    table4 = replace(
        table4,
        configs=tuple(replace(c, updates=mc_updates) for c in table4.configs),
    )
    star_rows = [
        ("(a) random + L-BFGS", "lbfgs", "random", None, 0.08089, 0.2234),
        ("(c) Hammersley + L-BFGS", "lbfgs", "hammersley", None, 0.08074, 0.2229),
        ("(e) hierarchical, random, s=5", "hierarchical", "random", 5, 0.08068, 0.2227),
        ("(g) hierarchical, lattice, s=1", "hierarchical", "lattice", 1, 0.08054, 0.2222),
        ("(i) hexagonal lattice", "lbfgs", "lattice", None, 0.08049, 0.2220),
    ]
    if quick:
        star_rows[2] = (
            "(e) hierarchical, random, s=4",
            "hierarchical",
            "random",
            4,
            *star_rows[2][4:],
        )
    table5 = _comparison(
        "table5",
        "star",
        star_n,
        star_rows,
        figures=("cells", "histograms"),
        title=f"Star of area 117.5, n = {star_n} (paper Table 5, Figure 9: n = 10025)",
        paper_n=10025,
    )
    ball = []
    for n, s, rows in (
        (
            1000,
            2,
            [(0.08025, 4.324e-3), (0.08025, 4.325e-3), (0.08022, 4.324e-3), (0.08022, 4.325e-3)],
        ),
        (
            5000,
            3,
            [(0.07980, 1.471e-3), (0.07976, 1.470e-3), (0.07975, 1.470e-3), (0.07965, 1.468e-3)],
        ),
    ):
        if quick and n > 1000:
            continue
        methods = [
            ("random + L-BFGS", "lbfgs", "random", None),
            ("Hammersley + L-BFGS", "lbfgs", "hammersley", None),
            (f"hierarchical, random, s={s}", "hierarchical", "random", s),
            ("hierarchical, lattice, s=1", "hierarchical", "lattice", 1),
        ]
        for (label, method, init, sub), (g, e) in zip(methods, rows, strict=True):
            ball.append(
                Config(
                    "table6",
                    f"n={n}: {label}",
                    "ball",
                    n,
                    method,
                    init,
                    sub,
                    0,
                    g,
                    e,
                    keep_sites=True,
                )
            )
    table6 = Experiment(
        "table6",
        "Ball of volume 1.42 (paper Table 6, Figure 10)",
        tuple(ball),
        ("cuts",),
    )
    table2 = Experiment(
        "table2",
        "Square, n = 2560, s = 4, random: mean G per level (paper Table 2, Figure 5)",
        (Config("table2", "levels", "square", 2560, "hierarchical", "random", 4, keep_sites=True),),
        ("levels",),
    )
    table3 = Experiment(
        "table3",
        f"Square, n = {square10k}, random init, s = 0…4 (paper Table 3: n = 10000)",
        tuple(
            Config(
                "table3",
                f"s={s}",
                "square",
                square10k,
                "hierarchical",
                "random",
                s,
                paper_g=TABLE3[s],
            )
            for s in range(5)
        ),
    )
    table7_cases: list[tuple[str, int, float | None]] = [
        ("ball", 1000, 0.55),
        ("homer.obj", 35000, 28.66),
        ("bunny.off", 50000, 30.06),
        ("kitten.obj", 80000, 54.57),
        ("armadillo.obj", 100000, 103.06),
    ]
    if quick:
        table7_cases = [("ball", 1000, 0.55), ("homer.obj", 5000, None)]
    table7 = Experiment(
        "table7",
        "Clipped Voronoi diagrams of meshes, random sites (paper Table 7)",
        tuple(
            Config("table7", f"{shape} {n // 1000}k", shape, n, "voronoi", paper_seconds=t)
            for shape, n, t in table7_cases
        ),
        timing=True,
    )
    table8_cases = TABLE8
    if quick:
        table8_cases = [c for c in table8_cases if c[1] <= 2000]
    table8 = Experiment(
        "table8",
        "CVT seconds, standard (random + L-BFGS) vs hierarchical (paper Table 8), "
        "and both with our Newton optimiser",
        tuple(
            cfg
            for shape, n, standard, hierarchical, s in table8_cases
            for optimiser, suffix in (("lbfgs", ""), ("newton", ", Newton"))
            for cfg in (
                Config(
                    "table8",
                    f"{shape} {n} standard{suffix}",
                    shape,
                    n,
                    optimiser,
                    paper_seconds=standard,
                ),
                Config(
                    "table8",
                    f"{shape} {n} hierarchical{suffix}",
                    shape,
                    n,
                    "hierarchical",
                    subdivisions=s,
                    paper_seconds=hierarchical,
                    optimiser=optimiser,
                ),
            )
        ),
        timing=True,
    )
    fig12 = Experiment(
        "fig12",
        f"Star, n = {star_n}: convergence of the last L-BFGS update (paper Figure 12)",
        tuple(
            replace(c, experiment="fig12", keep_history=True, keep_sites=False)
            for c in table5.configs
        ),
        ("convergence",),
        random_only_runs=False,
    )
    experiments = {
        e.name: e for e in (table2, table3, table4, table5, table6, table7, table8, fig12)
    }
    experiments["fig5"] = replace(table2, name="fig5")
    experiments["fig8"] = replace(table4, name="fig8")
    experiments["fig9"] = replace(table5, name="fig9")
    experiments["fig10"] = replace(table6, name="fig10")
    return experiments


EXPERIMENTS = tuple(_experiments(False))


# ------------------------------------------------------------------------------ runs
def load_shape(shape: str):
    """A built-in shape by name, or a mesh file of ``../shared/data/3d`` by file name."""
    from hcvt.io import load_domain
    from hcvt.shapes import BUILTIN, builtin_domain

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
        Path(__file__).resolve().parents[3] / "shared" / "data",
        Path.cwd().parent / "shared" / "data",
        Path.cwd() / "shared" / "data",
    ]
    found = next((c for c in candidates if c.is_dir()), None)
    if found is None:
        raise FileNotFoundError("no ../shared/data for the meshes of Table 7; set HCVT_DATA")
    return found


def run_config(config: Config) -> Row:
    """Run one configuration; returns its numbers (and sites/G/history when asked)."""
    import hcvt

    domain = load_shape(config.shape)
    start = time.perf_counter()
    levels: list[float] = []
    levels_sites: list[np.ndarray] = []
    history = None
    iterations = 0
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
            method=config.optimiser,
        )
        diagram = result.diagram
        levels = [level.mean_G for level in result.levels]
        if config.keep_sites:
            levels_sites = [level.sites for level in result.levels]
        iterations = sum(level.iterations for level in result.levels)
        history = result.levels[-1].history if config.keep_history else None
    else:
        sites = hcvt.initialise(domain, config.n, method=config.init, seed=config.seed)
        run: hcvt.MonteCarloResult | hcvt.CVTResult
        if config.method == "monte-carlo":
            run = hcvt.global_monte_carlo(domain, sites, updates=config.updates, seed=config.seed)
        else:
            run = hcvt.cvt(domain, sites, method=config.method)
        diagram, iterations = run.diagram, run.iterations
        history = run.history if config.keep_history else None
    seconds = time.perf_counter() - start
    row: Row = {
        **{k: v for k, v in asdict(config).items() if not k.startswith("keep")},
        "mean_G": float(diagram.mean_G),
        "energy": float(diagram.energy),
        "iterations": int(iterations),
        "seconds": seconds,
        "levels_G": levels,
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

    Lattice and Hammersley initialisations are deterministic: one run each.
    """
    out: list[Config] = []
    for config in experiment.configs:
        random = config.init == "random" or config.method == "voronoi"
        count = runs if (random or not experiment.random_only_runs) else 1
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
    from dask.distributed import Client, LocalCluster, as_completed

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


# ------------------------------------------------------------------------- summaries
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


def markdown_table(experiment: Experiment, summaries: list[Summary]) -> str:
    """Our medians beside the paper's values, with ratios (ours / paper)."""
    if experiment.timing:
        header = "| case | runs | ours (s) | paper (s) | paper / ours |\n|---|---|---|---|---|\n"
        lines = []
        for s in summaries:
            ours, paper = s.median("seconds"), s.config.paper_seconds
            speedup = "" if paper is None else f"{paper / ours:.0f}×"
            lines.append(
                f"| {s.config.label} | {len(s.rows)} | {ours:.3f} | {paper or ''} | {speedup} |"
            )
        return header + "\n".join(lines) + "\n"
    if experiment.name in ("table2", "fig5"):
        levels = np.median([row["levels_G"] for row in summaries[0].rows], axis=0)
        header = "| level | sites | ours mean G | paper mean G | ratio |\n|---|---|---|---|---|\n"
        sizes = [10, 40, 160, 640, 2560]
        lines = [
            f"| {i} | {sizes[i]} | {g:.5f} | {TABLE2[i]:.5f} | {_ratio(g, TABLE2[i])} |"
            for i, g in enumerate(levels)
        ]
        return header + "\n".join(lines) + "\n"
    header = (
        "| configuration | runs | ours mean G | paper mean G | ratio | ours energy | "
        "paper energy | ratio | seconds |\n|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = []
    dim = 3 if summaries and summaries[0].config.shape not in ("square", "star") else 2
    for s in summaries:
        g, e = s.median("mean_G"), s.median("energy")
        c = s.config
        pe = paper_energy_at(c, dim)
        paper_e = "" if pe is None else f"{pe:.6g}"
        lines.append(
            f"| {c.label} | {len(s.rows)} | {g:.5f} | {c.paper_g or ''} | {_ratio(g, c.paper_g)} "
            f"| {e:.6g} | {paper_e} | {_ratio(e, pe)} "
            f"| {s.median('seconds'):.2f} |"
        )
    return header + "\n".join(lines) + "\n"


def write_csv(rows: list[Row], path: Path) -> None:
    """Every run's scalar results, one line per run."""
    scalar = [k for k, v in rows[0].items() if np.isscalar(v) or v is None]
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
    from hcvt import plot

    written = []
    for kind in experiment.figures:
        path = out / f"{experiment.name}_{kind}.png"
        if kind == "convergence":
            plot.convergence_figure({s.config.label: _median_run(s) for s in summaries}, path)
        elif kind == "levels":
            plot.levels_figure(
                load_shape(summaries[0].config.shape), _median_run(summaries[0]), path
            )
        else:
            runs = {s.config.label: _median_run(s) for s in summaries}
            domains = {s.config.label: load_shape(s.config.shape) for s in summaries}
            plot.comparison_figure(domains, runs, path, kind=kind)
        written.append(path)
    return written


# ------------------------------------------------------------------------------- all
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
    experiments = _experiments(quick)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if name == "all":
        reports = [
            reproduce(e, runs=runs, quick=quick, scheduler=scheduler, out=out, progress=progress)
            for e in experiments
            if not e.startswith("fig") or e == "fig12"
        ]
        index = out / "all.md"
        index.write_text("\n".join(f"- [{p.stem}]({p.name})" for p in reports) + "\n")
        return index
    if name not in experiments:
        known = ", ".join([*experiments, "all"])
        raise ValueError(f"unknown experiment {name!r}; known: {known}")
    experiment = experiments[name]
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
