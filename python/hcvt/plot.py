"""Pictures in the paper's conventions: cells coloured by G from blue (regular) to red.

Every function draws into a matplotlib Axes (a new figure when none is given) and returns
it; pass one ``vmin``/``vmax`` to several calls to share a colour scale across a figure.
"""

from __future__ import annotations

from typing import Any

import matplotlib

matplotlib.use("Agg", force=False)
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import shapely  # noqa: E402
from matplotlib.collections import PolyCollection  # noqa: E402
from numpy.typing import ArrayLike  # noqa: E402

from hcvt.diagram import Diagram  # noqa: E402

G_OPTIMUM = {2: 5.0 / (36.0 * np.sqrt(3.0)), 3: 19.0 / (192.0 * 2.0 ** (1.0 / 3.0))}
CMAP = "RdYlBu_r"


def g_colour_range(G: ArrayLike, dim: int) -> tuple[float, float]:
    """Default colour range: the optimum G of the dimension up to the 98th percentile."""
    values = np.asarray(G, dtype=float)
    values = values[np.isfinite(values)]
    low = G_OPTIMUM[dim]
    high = float(np.percentile(values, 98)) if len(values) else low * 1.2
    return low, max(high, low * 1.05)


def plot_cells(
    diagram: Diagram,
    ax: Any = None,
    *,
    vmin: float | None = None,
    vmax: float | None = None,
    show_sites: bool = False,
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
    colorbar : bool
        Add a colour bar labelled G.
    title : str, optional
    """
    if diagram.domain.dim != 2:
        raise ValueError("plot_cells draws 2D diagrams; use a cut view for 3D")
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 7))
    low, high = g_colour_range(diagram.G, 2)
    vmin = low if vmin is None else vmin
    vmax = high if vmax is None else vmax
    polygons, values = [], []
    for cell, g in zip(diagram.cells(), diagram.G, strict=True):
        for part in shapely.get_parts(cell):
            if part.is_empty or part.geom_type != "Polygon":
                continue
            polygons.append(np.asarray(part.exterior.coords))
            values.append(g)
    collection = PolyCollection(
        polygons, array=np.asarray(values), cmap=CMAP, edgecolors="k", linewidths=0.2
    )
    collection.set_clim(vmin, vmax)
    ax.add_collection(collection)
    if show_sites:
        ax.plot(diagram.sites[:, 0], diagram.sites[:, 1], "k.", markersize=1)
    lo, hi = diagram.domain.bounds
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_axis_off()
    if colorbar:
        plt.colorbar(collection, ax=ax, shrink=0.7, label="G")
    ax.set_title(title or f"n = {diagram.n}, mean G = {diagram.mean_G:.5f}")
    return ax


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
