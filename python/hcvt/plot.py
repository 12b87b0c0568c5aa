"""Pictures in the paper's conventions: cells coloured by G from blue (regular) to red.

Every function draws into a matplotlib Axes (a new figure when none is given) and returns
it; pass one ``vmin``/``vmax`` to several calls to share a colour scale across a figure.
The backend is the user's: importing this module leaves it alone (inline figures in
Jupyter keep working; without a display matplotlib itself falls back to Agg).
"""

from __future__ import annotations

from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from numpy.typing import ArrayLike

from hcvt.density import grading_slope
from hcvt.diagram import Diagram, voronoi
from hcvt.draw import CMAP, G_OPTIMUM, draw_cells, draw_cut, g_colour_range
from hcvt.seeding.regular import defects

__all__ = [
    "CMAP",
    "G_OPTIMUM",
    "comparison_figure",
    "convergence_figure",
    "g_colour_range",
    "grading_figure",
    "levels_figure",
    "plot_cells",
    "plot_convergence",
    "plot_cut",
    "plot_histogram",
    "save",
    "shared_range",
]


def plot_cells(
    diagram: Diagram,
    ax: Any = None,
    *,
    vmin: float | None = None,
    vmax: float | None = None,
    show_sites: bool = False,
    show_defects: bool = False,
    colorbar: bool = True,
    title: str | None = None,
) -> Any:
    """Draw the clipped cells of a 2D diagram coloured by G (blue regular, red irregular).

    Parameters
    ----------
    diagram : Diagram
        A 2D diagram.
    ax : matplotlib Axes, optional
    vmin, vmax : float, optional
        Colour range of G; default from :func:`g_colour_range`.
    show_sites : bool
        Also draw the sites as dots.
    show_defects : bool
        Mark the sites of interior cells without 6 neighbours (:func:`hcvt.defects`):
        fewer as downward triangles, more as upward ones; the count goes in the title.
    colorbar : bool
        Add a colour bar labelled G.
    title : str, optional
    """
    if diagram.domain.dim != 2:
        raise ValueError("plot_cells draws 2D diagrams; use a cut view for 3D")
    low, high = g_colour_range(diagram.G, 2)
    vmin = low if vmin is None else vmin
    vmax = high if vmax is None else vmax
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 7))
    ax = draw_cells(diagram, diagram.G, ax, (vmin, vmax), CMAP, "G" if colorbar else None)
    if show_sites:
        ax.plot(diagram.sites[:, 0], diagram.sites[:, 1], "k.", markersize=1)
    suffix = _mark_defects(ax, diagram) if show_defects else ""
    ax.set_title(title or f"n = {diagram.n}, mean G = {diagram.mean_G:.5f}{suffix}")
    return ax


def _mark_defects(ax: Any, diagram: Diagram) -> str:
    """Mark defective interior sites on ``ax``; returns ``", D defects"`` for the title."""
    found = defects(diagram)
    for sign, marker, colour in ((-1, "v", "k"), (1, "^", "m")):
        pick = found.defective & (np.sign(found.counts - found.ideal) == sign)
        points = diagram.sites[pick]
        ax.plot(points[:, 0], points[:, 1], marker, color=colour, markersize=2.5, linestyle="")
    return f", {found.number} defects"


def plot_histogram(
    G: ArrayLike,
    ax: Any = None,
    *,
    bins: int | ArrayLike = 40,
    range_: tuple[float, float] | None = None,
    label: str | None = None,
) -> Any:
    """Histogram of G values (paper Fig. 9): how many cells fall in each bin."""
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 4))
    values = np.asarray(G, dtype=float)
    values = values[np.isfinite(values)]
    ax.hist(values, bins=bins, range=range_, color="tab:blue", alpha=0.8, label=label)
    ax.set_xlabel("G")
    ax.set_ylabel("cells")
    return ax


def save(ax: Any, path: str) -> None:
    """Write the figure holding ``ax`` to ``path`` (PNG at 150 dpi) and close it."""
    fig = ax.figure
    fig.savefig(path, dpi=150, bbox_inches="tight")
    plt.close(fig)


def plot_cut(
    diagram: Diagram,
    ax: Any = None,
    *,
    axis: int = 0,
    at: float | None = None,
    vmin: float | None = None,
    vmax: float | None = None,
    colorbar: bool = True,
    title: str | None = None,
) -> Any:
    """Cut view of a 3D diagram (paper Fig. 1(e)): the cells behind a plane, faces by G.

    Cells whose centroid has coordinate ``axis`` at least ``at`` (default: the median
    centroid) are drawn, seen from the cut side, so that the interior cells show.
    ``at=-inf`` draws every cell: the boundary view.
    """
    if diagram.domain.dim != 3:
        raise ValueError("plot_cut draws 3D diagrams; use plot_cells for 2D")
    if ax is None:
        fig = plt.figure(figsize=(7, 7))
        ax = fig.add_subplot(projection="3d")
    low, high = g_colour_range(diagram.G, 3)
    vmin = low if vmin is None else vmin
    vmax = high if vmax is None else vmax
    draw_cut(diagram, ax, (vmin, vmax), axis=axis, at=at, colorbar=colorbar)
    ax.set_title(title or f"n = {diagram.n}, mean G = {diagram.mean_G:.5f}")
    return ax


def plot_convergence(histories: dict[str, tuple[ArrayLike, ArrayLike]], axes: Any = None) -> Any:
    """Mean G and energy against iterations (paper Fig. 12), one line per label.

    ``histories`` maps a label to ``(mean_G, energy)`` per iteration; returns the two Axes.
    """
    if axes is None:
        _, axes = plt.subplots(1, 2, figsize=(11, 4))
    for label, (mean_g, energy) in histories.items():
        axes[0].plot(np.asarray(mean_g), label=label)
        axes[1].plot(np.asarray(energy), label=label)
    for ax, name in zip(axes, ("mean G", "energy"), strict=True):
        ax.set_xlabel("L-BFGS iteration")
        ax.set_ylabel(name)
        ax.set_xscale("symlog", linthresh=10)
    axes[0].legend(fontsize=7)
    return axes


def shared_range(G_sets: list[ArrayLike], dim: int) -> tuple[float, float]:
    """One colour range for several diagrams: the widest of their default ranges."""
    ranges = [g_colour_range(G, dim) for G in G_sets]
    return min(r[0] for r in ranges), max(r[1] for r in ranges)


def comparison_figure(domains: dict[str, Any], runs: dict[str, dict], path: Any, *, kind: str):
    """One panel per labelled run with a shared colour scale, saved to ``path``.

    ``kind``: ``"cells"`` (2D cells by G), ``"defects"`` (the same with the interior
    defects marked, :func:`hcvt.defects`), ``"histograms"`` (G histograms with shared
    bins) or ``"cuts"`` (3D cut views). Each run holds ``sites`` and ``G``.
    """
    labels = list(runs)
    dim = next(iter(domains.values())).dim
    vmin, vmax = shared_range([runs[k]["G"] for k in labels], dim)
    cols = min(3, len(labels))
    rows = -(-len(labels) // cols)
    projection = "3d" if kind == "cuts" else None
    fig = plt.figure(figsize=(5 * cols, 5 * rows if kind != "histograms" else 4.2 * rows))
    for k, label in enumerate(labels):
        ax = fig.add_subplot(rows, cols, k + 1, projection=projection)
        run = runs[label]
        if kind == "histograms":
            plot_histogram(run["G"], ax, bins=40, range_=(G_OPTIMUM[dim] * 0.995, vmax))
            ax.set_title(f"{label}\nmean G = {np.mean(run['G']):.5f}", fontsize=9)
            continue
        diagram = voronoi(domains[label], run["sites"])
        title = f"{label}\nmean G = {diagram.mean_G:.5f}"
        if kind == "defects":  # 2D cells with the defective interior sites marked
            suffix = _mark_defects(ax, diagram)
            plot_cells(diagram, ax, vmin=vmin, vmax=vmax, colorbar=False, title=title + suffix)
            continue
        draw = plot_cells if kind == "cells" else plot_cut
        draw(diagram, ax, vmin=vmin, vmax=vmax, colorbar=False, title=title)
    if kind == "histograms":
        fig.tight_layout()  # two-line titles would overlap the x labels above them
    _shared_colorbar(fig, vmin, vmax, kind)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)


def levels_figure(domain: Any, run: dict, path: Any) -> None:
    """The CVT of every hierarchy level (paper Figs. 1 and 5), one shared colour scale.

    2D: the cells; 3D: cut views (the cells behind the median plane, Fig. 1 (e)).
    """
    diagrams = [voronoi(domain, sites) for sites in run["levels_sites"]]
    vmin, vmax = shared_range([d.G for d in diagrams], domain.dim)
    fig = plt.figure(figsize=(4 * len(diagrams), 4.4))
    for k, diagram in enumerate(diagrams):
        ax = fig.add_subplot(1, len(diagrams), k + 1, projection="3d" if domain.dim == 3 else None)
        draw = plot_cells if domain.dim == 2 else plot_cut
        draw(diagram, ax, vmin=vmin, vmax=vmax, colorbar=False)
    _shared_colorbar(fig, vmin, vmax, "cells")
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)


def convergence_figure(runs: dict[str, dict], path: Any) -> None:
    """Fig. 12 from runs holding ``history_G`` and ``history_energy``."""
    axes = plot_convergence({k: (r["history_G"], r["history_energy"]) for k, r in runs.items()})
    save(axes[0], path)


def _shared_colorbar(fig: Any, vmin: float, vmax: float, kind: str) -> None:
    if kind == "histograms":
        return
    mappable = plt.cm.ScalarMappable(cmap=CMAP, norm=matplotlib.colors.Normalize(vmin, vmax))
    fig.colorbar(mappable, ax=fig.axes, shrink=0.6, label="G")


def grading_figure(diagram: Diagram, path: Any) -> float:
    """A graded CVT (DESIGN §8): cells coloured by size (2D), and size against ρ.

    Left (2D only): each cell filled by its size ``V_i^(1/d)``. Right: ``V_i^(1/d)``
    against ``ρ(c_i)`` on log axes for the cells off the boundary, with the fitted line
    and Gersho's slope ``-1/(d+2)``. Writes ``path``; returns the fitted slope.
    """
    if diagram.density is None:
        raise ValueError("grading_figure needs a diagram computed with a density")
    dim = diagram.domain.dim
    slope, rho, size, interior = grading_slope(diagram)
    panels = 2 if dim == 2 else 1
    fig, axes = plt.subplots(1, panels, figsize=(6.5 * panels, 6), layout="constrained")
    axes = np.atleast_1d(axes)
    if dim == 2:
        sizes = diagram.volume**0.5
        draw_cells(diagram, sizes, axes[0], (sizes.min(), sizes.max()), "viridis", "V^(1/2)")
        axes[0].set_title(f"n = {diagram.n}, cells by size")
    ax = axes[-1]
    ax.loglog(rho[interior], size[interior], ".", markersize=2, alpha=0.5, label="cells")
    grid = np.geomspace(rho[interior].min(), rho[interior].max(), 50)
    fit = np.exp(np.polyfit(np.log(rho[interior]), np.log(size[interior]), 1)[1])
    ax.loglog(grid, fit * grid**slope, "r-", label=f"fit: slope {slope:.4f}")
    ax.loglog(
        grid,
        fit * grid ** (-1.0 / (dim + 2)) * (grid[0] ** (slope + 1.0 / (dim + 2))),
        "k--",
        label=f"Gersho: slope {-1.0 / (dim + 2):.4f}",
    )
    ax.set_xlabel("ρ at the cell's centroid")
    ax.set_ylabel(f"cell size V^(1/{dim})")
    ax.legend()
    fig.savefig(path, dpi=150, bbox_inches="tight")
    plt.close(fig)
    return slope
