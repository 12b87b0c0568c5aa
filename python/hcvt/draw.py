"""Cells coloured by G drawn into matplotlib Axes, and the pictures Jupyter shows.

The drawing itself (:func:`draw_cells`, :func:`draw_cut`) lives here, below the diagram
and the optimisers, so that a :class:`hcvt.Diagram` and every CVT result can show
itself in a notebook (``_repr_png_``, ``_repr_html_``, through :class:`Shows`);
:mod:`hcvt.plot` builds its figures on the same functions. Nothing here imports
``matplotlib.pyplot``: a picture for Jupyter is a bare ``matplotlib.figure.Figure``
written to PNG bytes, which touches neither the user's backend nor pyplot's list of open
figures. matplotlib is imported on first use (:mod:`hcvt.lazy`).
"""

from __future__ import annotations

import base64
import html
import io
from typing import Any, Protocol

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray

from hcvt.lazy import load

#: G of the regular hexagon (2D) and truncated octahedron (3D), the lower ends of the scale.
G_OPTIMUM = {2: 5.0 / (36.0 * np.sqrt(3.0)), 3: 19.0 / (192.0 * 2.0 ** (1.0 / 3.0))}
CMAP = "RdYlBu_r"
#: Largest diagrams drawn inline by ``_repr_png_`` (drawing costs ~0.1 ms a cell in 2D,
#: ~1 ms in 3D); larger ones show their summary only.
INLINE_LIMIT = {2: 20_000, 3: 3_000}


class Drawable(Protocol):
    """What the drawing reads of a :class:`hcvt.Diagram`."""

    @property
    def domain(self) -> Any: ...  # noqa: D102

    @property
    def n(self) -> int: ...  # noqa: D102

    @property
    def mean_G(self) -> float: ...  # noqa: D102, N802 (the paper's G)

    @property
    def G(self) -> NDArray[np.float64]: ...  # noqa: D102, N802 (the paper's G)

    @property
    def volume(self) -> NDArray[np.float64]: ...  # noqa: D102

    @property
    def centroid(self) -> NDArray[np.float64]: ...  # noqa: D102

    @property
    def energy(self) -> float: ...  # noqa: D102

    def cells(self) -> list[Any]: ...  # noqa: D102


def g_colour_range(G: ArrayLike, dim: int) -> tuple[float, float]:  # noqa: N803
    """Default colour range: the optimum G of the dimension up to the 98th percentile."""
    values = np.asarray(G, dtype=float)
    values = values[np.isfinite(values)]
    low = G_OPTIMUM[dim]
    high = float(np.percentile(values, 98)) if len(values) else low * 1.2
    return low, max(high, low * 1.05)


def draw_cells(
    diagram: Drawable,
    values: ArrayLike,
    ax: Any,
    clim: tuple[float, float],
    cmap: str = CMAP,
    label: str | None = None,
) -> Any:
    """Fill the clipped cells of a 2D diagram by ``values`` (n,) on ``ax``.

    A colour bar labelled ``label`` is added beside ``ax`` unless ``label`` is None.
    Returns ``ax``.
    """
    collections = load("matplotlib.collections")
    polygons, colours = [], []
    for cell, value in zip(diagram.cells(), np.asarray(values), strict=True):
        for part in shapely.get_parts(cell):
            if part.is_empty or part.geom_type != "Polygon":
                continue
            polygons.append(np.asarray(part.exterior.coords))
            colours.append(value)
    collection = collections.PolyCollection(
        polygons, array=np.asarray(colours), cmap=cmap, edgecolors="k", linewidths=0.2
    )
    collection.set_clim(*clim)
    ax.add_collection(collection)
    lo, hi = diagram.domain.bounds
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_axis_off()
    if label is not None:
        ax.figure.colorbar(collection, ax=ax, shrink=0.7, label=label)
    return ax


def draw_cut(
    diagram: Drawable,
    ax: Any,
    clim: tuple[float, float],
    *,
    axis: int = 0,
    at: float | None = None,
    colorbar: bool = True,
) -> Any:
    """Cut view of a 3D diagram on a 3D ``ax``: the cells behind a plane, faces by G.

    Cells whose centroid has coordinate ``axis`` at least ``at`` (default: the median
    centroid) are drawn, seen from the cut side. Returns ``ax``.
    """
    colors = load("matplotlib.colors")
    art3d = load("mpl_toolkits.mplot3d.art3d")
    colormap = load("matplotlib").colormaps[CMAP]
    at = float(np.median(diagram.centroid[:, axis])) if at is None else at
    keep = np.flatnonzero((diagram.centroid[:, axis] >= at) & (diagram.volume > 0))
    triangles, values = [], []
    cells = diagram.cells()
    for i in keep:
        vertices, faces = _fanned(cells[i])
        if len(faces):
            triangles.append(vertices[faces])
            values.append(np.full(len(faces), diagram.G[i]))
    norm = colors.Normalize(*clim)
    colours = colormap(norm(np.concatenate(values)))
    ax.add_collection3d(
        art3d.Poly3DCollection(
            np.concatenate(triangles), facecolors=colours, edgecolors=colours, linewidths=0.1
        )
    )
    lo, hi = diagram.domain.bounds
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_zlim(lo[2], hi[2])
    ax.set_box_aspect(np.asarray(hi) - np.asarray(lo))
    # Look along +axis, from the cut side.
    ax.view_init(elev=20 if axis != 2 else -90, azim={0: 180, 1: -90, 2: -90}[axis], roll=0)
    ax.set_axis_off()
    if colorbar:
        # A ScalarMappable: a 3D collection has no colours before it is projected.
        mappable = load("matplotlib.cm").ScalarMappable(cmap=CMAP, norm=norm)
        ax.figure.colorbar(mappable, ax=ax, shrink=0.6, label="G")
    return ax


def _fanned(cell: Any) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """A cell of ``cells()`` as ``(vertices, triangles)``, fanned if needed.

    A solid's or a surface's pair as it is; a spherical cell's polygon (k, 3) fanned from
    its first vertex.
    """
    if isinstance(cell, tuple):
        return cell
    k = len(cell)
    fan = np.column_stack([np.zeros(max(k - 2, 0)), np.arange(1, k - 1), np.arange(2, k)])
    return np.asarray(cell, dtype=np.float64), fan.astype(np.intp)


def png(diagram: Drawable, *, title: str | None = None, dpi: int = 80) -> bytes | None:
    """A PNG of the cells coloured by G: 2D, a cut view (3D), a surface whole; None when too large.

    Drawn on a bare ``Figure`` (no pyplot). ``None`` above :data:`INLINE_LIMIT` cells,
    which is what IPython expects of a ``_repr_png_`` with nothing to show.
    """
    dim = diagram.domain.dim
    if diagram.n > INLINE_LIMIT[dim]:
        return None
    figure = load("matplotlib.figure").Figure(figsize=(5.5, 5), layout="constrained")
    clim = g_colour_range(diagram.G, diagram.domain.cell_dim)
    if dim == 2:
        ax = draw_cells(diagram, diagram.G, figure.add_subplot(), clim, CMAP, "G")
    else:
        # A triangle surface's or the sphere's cells are drawn whole, a solid's cut.
        whole = -np.inf if diagram.domain.cell_dim == 2 else None
        ax = draw_cut(diagram, figure.add_subplot(projection="3d"), clim, at=whole)
    ax.set_title(title or f"n = {diagram.n}, mean G = {diagram.mean_G:.5f}", fontsize=10)
    out = io.BytesIO()
    figure.savefig(out, format="png", dpi=dpi)
    return out.getvalue()


def html_summary(
    title: str, rows: dict[str, str], picture: bytes | None, *, too_large: str = ""
) -> str:
    """A small HTML block: ``title``, a two-column table of ``rows``, the picture inline."""
    cells = "".join(
        f"<tr><th style='text-align:left'>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>"
        for k, v in rows.items()
    )
    image = (
        f"<img src='data:image/png;base64,{base64.b64encode(picture).decode()}' "
        "alt='cells coloured by G' style='max-width:420px'/>"
        if picture is not None
        else f"<p><i>{html.escape(too_large)}</i></p>"
    )
    return (
        f"<div class='hcvt'><b>{html.escape(title)}</b><div style='display:flex;gap:1em'>"
        f"<table>{cells}</table>{image}</div></div>"
    )


def diagram_rows(diagram: Drawable) -> dict[str, str]:
    """The summary rows of a diagram for :func:`html_summary`."""
    finite = diagram.G[np.isfinite(diagram.G)]
    unit = "area" if diagram.domain.dim == 2 else "volume"
    return {
        "sites": f"{diagram.n} (d = {diagram.domain.dim})",
        f"{unit} of the cells": f"{float(np.sum(diagram.volume)):.6g}",
        "mean G": f"{diagram.mean_G:.6f}",
        "G range": f"{finite.min():.6f} - {finite.max():.6f}" if len(finite) else "-",
        "energy": f"{diagram.energy:.6g}",
    }


class Shows:
    """Jupyter display of a diagram, or of a result holding one: picture and summary.

    ``_repr_png_`` is the picture of :func:`png`; ``_repr_html_`` the one-line ``repr``
    as a title, the rows of :meth:`_summary_rows` and the picture inline. A result shows
    its ``diagram``; a diagram overrides :meth:`_shown` to show itself.
    """

    def _shown(self) -> Any:
        return getattr(self, "diagram")  # noqa: B009 (results are dataclasses with it)

    def _summary_rows(self) -> dict[str, str]:
        return diagram_rows(self._shown())

    def _repr_png_(self) -> bytes | None:
        return png(self._shown())

    def _repr_html_(self) -> str:
        limit = INLINE_LIMIT[self._shown().domain.dim]
        return html_summary(
            repr(self),
            self._summary_rows(),
            self._repr_png_(),
            too_large=f"more than {limit} cells: not drawn inline (hcvt.plot draws any size)",
        )
