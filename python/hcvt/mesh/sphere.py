"""The spherical Voronoi mesh of a diagram on the sphere, in MPAS's layout, and its quality.

Topology comes from the core's neighbour lists (:attr:`hcvt.Diagram.neighbors`, the pairs
of cells sharing an arc of positive length), never from a second triangulation: each
cell's neighbours sorted counter-clockwise seen from outside (by the direction to each in
the site's tangent plane) is a rotation system of the Delaunay graph; its faces, traced
half-edge by half-edge, are the Delaunay triangles. Each triangle ``(a, b, c)``
(counter-clockwise seen from outside) gives a Voronoi vertex, its circumcentre on the
sphere ``((b − a) × (c − a)) / |(b − a) × (c − a)|``: vertex positions come from the sites
alone.

Cocircular sites (four or more on one circle, as a cube's corners or a latitude-longitude
grid) make a Delaunay face with more than three sides, where the core reports no arc
between the diagonal cells. MPAS needs three cells at every vertex, so such a face is fanned
from its smallest site: each diagonal becomes an edge of length exactly zero between two
vertices at the same position (the mean of the fan's circumcentres, normalised), and the
two diagonal cells gain that edge as a side. :attr:`SphereMesh.zero_length_edges` counts
them. (MPAS-Atmosphere divides by ``dvEdge``: move such sites, or run a CVT, first.)

Every array is 0-based here; :mod:`hcvt.io.mpas` writes MPAS's 1-based indices.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

IntArray = NDArray[np.intp]
FloatArray = NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class SphereMesh:
    """Cells, edges and vertices of a spherical Voronoi diagram (MPAS's mesh, 0-based).

    Positions are unit vectors; lengths and areas are in the units of ``radius`` (times
    ``radius`` and ``radius²``). Edge ``e`` joins cells ``cells_on_edge[e] = (c1, c2)``,
    ``c1 < c2``, and vertices ``vertices_on_edge[e] = (v1, v2)`` ordered so that the
    tangent ``v1 → v2`` is the normal ``c1 → c2`` turned 90° counter-clockwise seen from
    outside (MPAS's ``t = k × n``).

    Attributes
    ----------
    radius : float
        The sphere's radius R, L.
    cells : ndarray, shape (n, 3)
        The sites on the unit sphere.
    vertices : ndarray, shape (v, 3)
        The Voronoi vertices (Delaunay circumcentres) on the unit sphere.
    cells_on_vertex : ndarray of intp, shape (v, 3)
        The Delaunay triangle of each vertex, counter-clockwise seen from outside.
    edges_on_vertex : ndarray of intp, shape (v, 3)
        ``edges_on_vertex[v, j]`` is the edge between cells ``j − 1`` and ``j`` of
        ``cells_on_vertex[v]``: counter-clockwise, cell ``j`` lies between edges ``j`` and
        ``j + 1`` (MPAS-Tools' ``MpasMeshConverter.x`` convention).
    cells_on_edge, vertices_on_edge : ndarray of intp, shape (e, 2)
        Edges sorted by ``cells_on_edge``.
    cell_offsets : ndarray of intp, shape (n + 1,)
        Cell ``i``'s sides are entries ``cell_offsets[i]:cell_offsets[i + 1]`` of the
        three arrays below, counter-clockwise seen from outside.
    cells_on_cell, edges_on_cell, vertices_on_cell : ndarray of intp, shape (2e,)
        Side ``j`` of a cell: the cell across it, the edge, and the vertex at its
        counter-clockwise end (the vertex between sides ``j`` and ``j + 1``).
    zero_length_edges : int
        Diagonals added to fan faces of cocircular sites (length 0; see the module).
    """

    radius: float
    cells: FloatArray
    vertices: FloatArray
    cells_on_vertex: IntArray
    edges_on_vertex: IntArray
    cells_on_edge: IntArray
    vertices_on_edge: IntArray
    cell_offsets: IntArray
    cells_on_cell: IntArray
    edges_on_cell: IntArray
    vertices_on_cell: IntArray
    zero_length_edges: int

    @property
    def n_cells(self) -> int:
        """Number of cells (sites)."""
        return len(self.cells)

    @property
    def n_edges(self) -> int:
        """Number of edges (Delaunay edges, Voronoi arcs)."""
        return len(self.cells_on_edge)

    @property
    def n_vertices(self) -> int:
        """Number of vertices (Delaunay triangles)."""
        return len(self.vertices)

    @cached_property
    def n_edges_on_cell(self) -> IntArray:
        """Sides of each cell, shape (n,)."""
        return np.diff(self.cell_offsets)

    @cached_property
    def edge_points(self) -> FloatArray:
        """Where each edge's normal velocity lives, shape (e, 3), unit vectors.

        The midpoint of the arc between the two sites, which lies on the Voronoi arc's
        great circle (MPAS-Tools: the crossing of the two great circles).
        """
        c1, c2 = self.cells[self.cells_on_edge[:, 0]], self.cells[self.cells_on_edge[:, 1]]
        return _normalised(c1 + c2)

    @cached_property
    def dc_edge(self) -> FloatArray:
        """Great-circle distance between the two sites of each edge, shape (e,), L."""
        c = self.cells[self.cells_on_edge]
        return self.radius * arc_length(c[:, 0], c[:, 1])

    @cached_property
    def dv_edge(self) -> FloatArray:
        """Arc length between the two vertices of each edge (the Voronoi arc), (e,), L."""
        v = self.vertices[self.vertices_on_edge]
        return self.radius * arc_length(v[:, 0], v[:, 1])

    @cached_property
    def area_triangle(self) -> FloatArray:
        """Area of each Delaunay triangle, shape (v,), L²."""
        a, b, c = (self.cells[self.cells_on_vertex[:, k]] for k in range(3))
        return self.radius**2 * signed_triangle_area(a, b, c)

    @cached_property
    def kite_areas_on_vertex(self) -> FloatArray:
        """Each triangle's part in each of its cells, shape (v, 3), L².

        Kite ``j`` of vertex ``v``: the triangles (vertex, edge point ``j``, cell ``j``)
        and (vertex, cell ``j``, edge point ``j + 1``), with signed areas (MPAS-Tools
        adds unsigned ones): a kite is negative where the circumcentre lies outside its
        triangle, and the kites of a vertex sum to ``area_triangle``, those of a cell to
        its area, whatever the triangle's shape.
        """
        v = self.vertices[:, None, :]
        cell = self.cells[self.cells_on_vertex]
        points = self.edge_points
        first = points[self.edges_on_vertex]
        second = points[np.roll(self.edges_on_vertex, -1, axis=1)]
        kites = signed_triangle_area(v, first, cell) + signed_triangle_area(v, cell, second)
        return self.radius**2 * kites

    @cached_property
    def angle_edge(self) -> FloatArray:
        """Angle of each edge's normal ``c1 → c2`` from local east, towards north, (e,).

        Radians in ``(−π, π]``; at a pole, where east is undefined, east is taken as the
        x axis's direction.
        """
        e = self.edge_points
        normal = self.cells[self.cells_on_edge[:, 1]] - self.cells[self.cells_on_edge[:, 0]]
        east = np.cross([0.0, 0.0, 1.0], e)
        norm = np.linalg.norm(east, axis=1)
        pole = norm < 1e-15
        east[pole] = [1.0, 0.0, 0.0]
        east = _normalised(east)
        north = np.cross(e, east)
        return np.arctan2(np.einsum("ij,ij->i", normal, north), np.einsum("ij,ij->i", normal, east))

    def cell_polygons(self) -> list[FloatArray]:
        """Each cell's vertices counter-clockwise seen from outside, (k, 3) each, in L."""
        points = self.vertices * self.radius
        return [
            points[self.vertices_on_cell[s:e]]
            for s, e in zip(self.cell_offsets[:-1], self.cell_offsets[1:], strict=True)
        ]

    def padded(self, values: IntArray | FloatArray, fill: float = -1) -> Any:
        """A per-side CSR array (2e,) as (n, max sides), rows padded with ``fill``."""
        counts = self.n_edges_on_cell
        out = np.full((self.n_cells, int(counts.max())), fill, dtype=values.dtype)
        rows = np.repeat(np.arange(self.n_cells), counts)
        out[rows, np.arange(len(values)) - self.cell_offsets[rows]] = values
        return out


def spherical_mesh(sites: ArrayLike, pairs: ArrayLike, radius: float = 1.0) -> SphereMesh:
    """The Voronoi mesh of ``sites`` on the sphere from the pairs of cells that touch.

    Parameters
    ----------
    sites : array_like, shape (n, 3)
        Unit vectors (the core's sites: ``x / |x|``).
    pairs : array_like of int, shape (k, 2)
        Cells sharing an arc of positive length (:attr:`hcvt.Diagram.neighbors`).
    radius : float
        The sphere's radius R, L: lengths come out times R, areas times R².

    Raises
    ------
    ValueError
        A cell with fewer than three neighbours, or a Delaunay triangle whose circumcircle
        reaches a hemisphere (too few sites for a mesh), or pairs that are no Delaunay
        graph of a sphere.
    """
    x = np.ascontiguousarray(sites, dtype=np.float64)
    n = len(x)
    pairs = np.asarray(pairs, dtype=np.intp).reshape(-1, 2)
    offsets, ring = _rings(x, pairs)
    triangles, fans = _delaunay_triangles(offsets, ring)
    if len(triangles) != 2 * n - 4:  # Euler: v − e + f = 2 with 3f = 2e
        raise ValueError(
            f"{n} cells whose neighbours make {len(triangles)} Delaunay triangles, not "
            f"2n − 4 = {2 * n - 4}: the pairs are not the Delaunay graph of a sphere"
        )
    vertices = _circumcentres(x, triangles, fans)
    cells_on_edge, vertices_on_edge, edge_of = _edges(n, triangles)
    side_offsets, cells_on_cell, vertices_on_cell = _cell_sides(x, triangles)
    owner = np.repeat(np.arange(n), np.diff(side_offsets))
    edges_on_cell = edge_of(owner, cells_on_cell)
    a, b, c = triangles.T
    edges_on_vertex = np.stack([edge_of(c, a), edge_of(a, b), edge_of(b, c)], axis=1)
    return SphereMesh(
        radius=float(radius),
        cells=x,
        vertices=vertices,
        cells_on_vertex=triangles,
        edges_on_vertex=edges_on_vertex,
        cells_on_edge=cells_on_edge,
        vertices_on_edge=vertices_on_edge,
        cell_offsets=side_offsets,
        cells_on_cell=cells_on_cell,
        edges_on_cell=edges_on_cell,
        vertices_on_cell=vertices_on_cell,
        zero_length_edges=int(len(cells_on_edge) - len(pairs)),
    )


def _normalised(v: FloatArray) -> FloatArray:
    return np.asarray(v / np.linalg.norm(v, axis=-1, keepdims=True), dtype=np.float64)


def arc_length(a: FloatArray, b: FloatArray) -> FloatArray:
    """Great-circle distance between unit vectors (rows), accurate for short arcs."""
    return np.asarray(np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), np.sum(a * b, -1)))


def signed_triangle_area(a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
    """Area of the spherical triangles ``(a, b, c)`` on the unit sphere, (…,).

    Van Oosterom–Strackee: ``tan(Ω/2) = a·(b×c) / (1 + a·b + b·c + c·a)``; positive for a
    triangle counter-clockwise seen from outside.
    """
    triple = np.sum(a * np.cross(b, c), axis=-1)
    denominator = 1.0 + np.sum(a * b, -1) + np.sum(b * c, -1) + np.sum(c * a, -1)
    return np.asarray(2.0 * np.arctan2(triple, denominator))


def _tangent_angles(x: FloatArray, src: IntArray, dst: IntArray) -> FloatArray:
    """Angle of the direction ``src → dst`` in a right-handed tangent frame at ``src``.

    Increasing counter-clockwise seen from outside (frame ``e1, e2 = x × e1``, ``x``).
    """
    # e1: x crossed with the axis least aligned with it, so that it is never short; one
    # frame per site.
    axis = np.zeros_like(x)
    axis[np.arange(len(x)), np.argmin(np.abs(x), axis=1)] = 1.0
    e1 = _normalised(np.cross(x, axis))
    e2 = np.cross(x, e1)
    d = x[dst] - x[src]
    return np.asarray(
        np.arctan2(np.einsum("ij,ij->i", d, e2[src]), np.einsum("ij,ij->i", d, e1[src]))
    )


def _rings(x: FloatArray, pairs: IntArray) -> tuple[IntArray, IntArray]:
    """Each cell's neighbours counter-clockwise seen from outside, CSR (offsets, ring)."""
    n = len(x)
    src = np.concatenate([pairs[:, 0], pairs[:, 1]])
    dst = np.concatenate([pairs[:, 1], pairs[:, 0]])
    order = np.lexsort((_tangent_angles(x, src, dst), src))
    src, dst = src[order], dst[order]
    offsets = np.searchsorted(src, np.arange(n + 1)).astype(np.intp)
    few = np.flatnonzero(np.diff(offsets) < 3)
    if len(few):
        raise ValueError(
            f"cell {few[0]} has {np.diff(offsets)[few[0]]} neighbour(s) ({len(few)} such "
            "cells): a spherical mesh needs at least three around every cell (n >= 4 sites "
            "not all on one great circle)"
        )
    return offsets, dst.astype(np.intp)


def _delaunay_triangles(offsets: IntArray, ring: IntArray) -> tuple[IntArray, list[IntArray]]:
    """The Delaunay triangles (t, 3), counter-clockwise, and the fans of larger faces.

    Faces are traced on half-edges: the face left of ``i → j`` continues with ``j → k``,
    ``k`` the neighbour of ``j`` just before ``i`` counter-clockwise. A face of ``k > 3``
    sites (cocircular) is fanned from its smallest site; the rows of each fan are listed.
    Triangles start at their smallest site and are sorted: the numbering does not depend
    on the tangent frames (a rotated mesh is numbered alike).
    """
    n = len(offsets) - 1
    degree = np.diff(offsets)
    src = np.repeat(np.arange(n, dtype=np.intp), degree)
    start = offsets[src]
    pos = np.arange(len(ring)) - start
    prev_ccw = start + (pos - 1) % degree[src]
    key = src.astype(np.int64) * n + ring
    sorter = np.argsort(key)
    wanted = ring.astype(np.int64) * n + src
    twin = sorter[np.clip(np.searchsorted(key, wanted, sorter=sorter), 0, len(key) - 1)]
    if not np.array_equal(key[twin], wanted):
        raise ValueError("the neighbour pairs are not symmetric")
    succ = prev_ccw[twin]
    s2 = succ[succ]
    in_triangle = succ[s2] == np.arange(len(ring))
    first = in_triangle & (np.arange(len(ring)) < succ) & (np.arange(len(ring)) < s2)
    e = np.flatnonzero(first)
    traced = np.stack([src[e], src[succ[e]], src[s2[e]]], axis=1)
    lowest = np.argmin(traced, axis=1)
    traced = np.take_along_axis(traced, (lowest[:, None] + np.arange(3)) % 3, axis=1)
    triangles = [traced]
    fans: list[IntArray] = []
    count = len(e)
    seen = in_triangle.copy()
    for h in np.flatnonzero(~in_triangle):
        if seen[h]:
            continue
        cycle = [int(h)]
        seen[h] = True
        while (nxt := int(succ[cycle[-1]])) != cycle[0]:
            if seen[nxt] or len(cycle) > len(ring):
                raise ValueError("the neighbour lists are no planar map of the sphere")
            seen[nxt] = True
            cycle.append(nxt)
        face = src[cycle]
        if len(face) < 3:
            raise ValueError(f"cells {face.tolist()} make a Delaunay face of two sides")
        face = np.roll(face, -int(np.argmin(face)))
        fan = np.stack([np.full(len(face) - 2, face[0]), face[1:-1], face[2:]], axis=1)
        triangles.append(fan)
        fans.append(np.arange(count, count + len(fan)))
        count += len(fan)
    out = np.concatenate(triangles).astype(np.intp)
    order = np.lexsort((out[:, 2], out[:, 1], out[:, 0]))
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return out[order], [np.sort(rank[rows]) for rows in fans]


def _circumcentres(x: FloatArray, triangles: IntArray, fans: list[IntArray]) -> FloatArray:
    """The circumcentre on the sphere of each triangle; one shared point for each fan."""
    a, b, c = (x[triangles[:, k]] for k in range(3))
    vertices = _normalised(np.cross(b - a, c - a))
    for rows in fans:
        vertices[rows] = _normalised(vertices[rows].sum(axis=0))
    # Counter-clockwise and within a hemisphere of each corner: the vertex is the Voronoi
    # vertex of its three cells (beyond 90°, it would be its antipode's).
    reach = np.min(np.einsum("tkj,tj->tk", x[triangles], vertices), axis=1)
    bad = np.flatnonzero(~(reach > 0))
    if len(bad):
        t = bad[0]
        raise ValueError(
            f"the Delaunay triangle of cells {triangles[t].tolist()} has its circumcentre 90° "
            f"or more from a corner ({len(bad)} such): too few sites for a spherical mesh"
        )
    return vertices


def _edges(
    n: int, triangles: IntArray
) -> tuple[IntArray, IntArray, Callable[[IntArray, IntArray], IntArray]]:
    """``cells_on_edge`` (c1 < c2), ``verticesOnEdge`` in MPAS's order, and a lookup.

    The triangle left of ``c1 → c2`` is ``v2``: going from ``v1`` to ``v2`` is the normal
    turned counter-clockwise. The lookup gives the edge of cells ``(i, j)``, either order.
    """
    t = np.arange(len(triangles), dtype=np.intp)
    tail = triangles.ravel()
    head = triangles[:, [1, 2, 0]].ravel()
    left = np.repeat(t, 3)
    lo, hi = np.minimum(tail, head), np.maximum(tail, head)
    key = lo.astype(np.int64) * n + hi
    order = np.lexsort((tail > head, key))  # per edge: forward (c1 → c2) first
    key, forward = key[order], (tail < head)[order]
    if not (np.all(key[0::2] == key[1::2]) and np.all(forward[0::2]) and not np.any(forward[1::2])):
        raise ValueError("Delaunay triangles that do not meet two by two along each edge")
    cells_on_edge = np.stack([lo[order][0::2], hi[order][0::2]], axis=1)
    vertices_on_edge = np.stack([left[order][1::2], left[order][0::2]], axis=1)
    edge_keys = key[0::2]

    def edge_of(i: IntArray, j: IntArray) -> IntArray:
        wanted = np.minimum(i, j).astype(np.int64) * n + np.maximum(i, j)
        return np.searchsorted(edge_keys, wanted).astype(np.intp)

    return cells_on_edge.astype(np.intp), vertices_on_edge.astype(np.intp), edge_of


def _cell_sides(x: FloatArray, triangles: IntArray) -> tuple[IntArray, IntArray, IntArray]:
    """Each cell's neighbours and vertices counter-clockwise, CSR, from the triangles.

    Corner ``(i; j, k)`` of triangle ``t`` puts neighbour ``j`` and then vertex ``t`` in
    cell ``i``; the next corner around ``i`` must begin with ``k`` (checked). Each cell's
    sides start at its smallest neighbour.
    """
    n = len(x)
    t = np.repeat(np.arange(len(triangles), dtype=np.intp), 3)
    centre = triangles.ravel()
    first = triangles[:, [1, 2, 0]].ravel()
    second = triangles[:, [2, 0, 1]].ravel()
    order = np.lexsort((_tangent_angles(x, centre, first), centre))
    centre, first, second, t = centre[order], first[order], second[order], t[order]
    offsets = np.searchsorted(centre, np.arange(n + 1)).astype(np.intp)
    degree = np.diff(offsets)
    pos = np.arange(len(centre)) - offsets[centre]
    following = offsets[centre] + (pos + 1) % degree[centre]
    if not np.array_equal(first[following], second):
        bad = int(centre[np.flatnonzero(first[following] != second)[0]])
        raise ValueError(f"the triangles around cell {bad} do not close up in order")
    smallest = np.full(n, np.iinfo(np.intp).max)
    np.minimum.at(smallest, centre, first)
    shift = np.zeros(n, dtype=np.intp)
    at_smallest = first == smallest[centre]
    shift[centre[at_smallest]] = pos[at_smallest]
    rotated = offsets[centre] + (pos + shift[centre]) % degree[centre]
    return offsets, first[rotated].astype(np.intp), t[rotated]


# ---------------------------------------------------------------------------- quality


@dataclass(frozen=True, eq=False)
class SphereQuality:
    """A spherical mesh's quality as MPAS users read it (MPAS-Tools' mesh fields).

    Attributes
    ----------
    sides : ndarray of intp, shape (n,)
        Sides of each cell (``nEdgesOnCell``; zero-length edges count).
    cell_quality : ndarray, shape (n,)
        Shortest over longest side (``dvEdge``) of each cell: 1 for a regular hexagon
        (``cellQuality``).
    grid_spacing : ndarray, shape (n,)
        Mean distance to the neighbouring sites (``dcEdge``) of each cell, L
        (``gridSpacing``).
    triangle_quality : ndarray, shape (v,)
        Shortest over longest side (``dcEdge``) of each Delaunay triangle
        (``triangleQuality``).
    triangle_angles : ndarray, shape (v, 3)
        The spherical triangle's angle at each of its cells, radians.
    triangle_angle_quality : ndarray, shape (v,)
        Smallest over largest angle (``triangleAngleQuality``; MPAS-Tools takes planar
        angles of the arc lengths, which differ by O(h²)).
    obtuse : ndarray of bool, shape (v,)
        Triangles with an angle above 90° (``obtuseTriangle``): their circumcentre, the
        Voronoi vertex, lies outside them.
    spacing_ratio : ndarray, shape (n,), or None
        ``grid_spacing`` over the requested width at each site, when one was given.
    """

    sides: IntArray
    cell_quality: FloatArray
    grid_spacing: FloatArray
    triangle_quality: FloatArray
    triangle_angles: FloatArray
    triangle_angle_quality: FloatArray
    obtuse: NDArray[np.bool_]
    spacing_ratio: FloatArray | None
    zero_length_edges: int

    @property
    def non_hexagonal(self) -> int:
        """Cells with other than six sides (12 pentagons on a good icosahedral mesh)."""
        return int(np.count_nonzero(self.sides != 6))

    def summary(self) -> dict[str, Any]:
        """The figures above as plain numbers (JSON-ready): counts, min, mean, max."""
        counts = np.bincount(self.sides)
        angles = np.degrees(self.triangle_angles)
        out: dict[str, Any] = {
            "cells": len(self.sides),
            "triangles": len(self.triangle_quality),
            "sides": {str(k): int(c) for k, c in enumerate(counts) if c},
            "non_hexagonal": self.non_hexagonal,
            "zero_length_edges": self.zero_length_edges,
            "cell_quality_min": float(self.cell_quality.min()),
            "cell_quality_mean": float(self.cell_quality.mean()),
            "triangle_quality_min": float(self.triangle_quality.min()),
            "triangle_quality_mean": float(self.triangle_quality.mean()),
            "triangle_angle_min_deg": float(angles.min()),
            "triangle_angle_max_deg": float(angles.max()),
            "triangle_angle_quality_min": float(self.triangle_angle_quality.min()),
            "obtuse_triangles": int(np.count_nonzero(self.obtuse)),
            "grid_spacing_min": float(self.grid_spacing.min()),
            "grid_spacing_mean": float(self.grid_spacing.mean()),
            "grid_spacing_max": float(self.grid_spacing.max()),
        }
        if self.spacing_ratio is not None:
            out["spacing_ratio_min"] = float(self.spacing_ratio.min())
            out["spacing_ratio_mean"] = float(self.spacing_ratio.mean())
            out["spacing_ratio_max"] = float(self.spacing_ratio.max())
        return out


#: A requested cell width: per-cell values (n,), or ``width(lat, lon)`` of degrees
#: (arrays) returning the width in the radius's units.
Width = ArrayLike | Callable[[FloatArray, FloatArray], ArrayLike]


def lat_lon(points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Latitude in ``[−π/2, π/2]`` and longitude in ``[0, 2π)`` of points, radians."""
    lat = np.arctan2(points[:, 2], np.hypot(points[:, 0], points[:, 1]))
    lon = np.mod(np.arctan2(points[:, 1], points[:, 0]), 2.0 * np.pi)
    lon[lon >= 2.0 * np.pi] = 0.0  # mod of −0.0-ish rounds up to 2π
    return lat, lon


class HasSphericalMesh(Protocol):
    """A diagram on the sphere: what :func:`sphere_quality` takes besides a mesh."""

    def spherical_mesh(self) -> SphereMesh: ...  # noqa: D102


def sphere_quality(
    source: SphereMesh | HasSphericalMesh, width: Width | None = None
) -> SphereQuality:
    """The quality of a spherical mesh (see :class:`SphereQuality`).

    Parameters
    ----------
    source : SphereMesh or Diagram
        A diagram on :meth:`hcvt.Domain.sphere` or its :meth:`~hcvt.Diagram.spherical_mesh`.
    width : array_like of shape (n,), or callable, optional
        The requested cell width (as MPAS-Tools' ``cellWidth``), in the radius's units:
        per cell, or a function ``width(lat, lon)`` of degree arrays evaluated at the
        sites. Gives ``spacing_ratio``.

    Examples
    --------
    >>> import hcvt
    >>> earth = hcvt.Domain.sphere(6371.0)
    >>> d = hcvt.voronoi(earth, hcvt.initialise(earth, 642, method="icosahedral"))
    >>> hcvt.sphere_quality(d).summary()["sides"]
    {'5': 12, '6': 630}
    """
    mesh = source if isinstance(source, SphereMesh) else source.spherical_mesh()
    rows = np.repeat(np.arange(mesh.n_cells), mesh.n_edges_on_cell)
    dv = mesh.dv_edge[mesh.edges_on_cell]
    longest = np.zeros(mesh.n_cells)
    shortest = np.full(mesh.n_cells, np.inf)
    np.maximum.at(longest, rows, dv)
    np.minimum.at(shortest, rows, dv)
    cell_quality = np.divide(shortest, longest, out=np.zeros(mesh.n_cells), where=longest > 0)
    spacing = np.bincount(rows, mesh.dc_edge[mesh.edges_on_cell]) / mesh.n_edges_on_cell
    dc = mesh.dc_edge[mesh.edges_on_vertex]
    angles = _triangle_angles(mesh.cells[mesh.cells_on_vertex])
    angle_quality = angles.min(axis=1) / angles.max(axis=1)
    ratio = None
    if width is not None:
        if callable(width):
            lat, lon = lat_lon(mesh.cells)
            requested = np.asarray(width(np.degrees(lat), np.degrees(lon)), dtype=np.float64)
        else:
            requested = np.asarray(width, dtype=np.float64)
        requested = np.broadcast_to(requested, (mesh.n_cells,))
        if not np.all(np.isfinite(requested) & (requested > 0)):
            raise ValueError("the requested width must be positive and finite at every site")
        ratio = spacing / requested
    return SphereQuality(
        sides=mesh.n_edges_on_cell,
        cell_quality=cell_quality,
        grid_spacing=spacing,
        triangle_quality=dc.min(axis=1) / dc.max(axis=1),
        triangle_angles=angles,
        triangle_angle_quality=angle_quality,
        obtuse=angles.max(axis=1) > np.pi / 2,
        spacing_ratio=ratio,
        zero_length_edges=mesh.zero_length_edges,
    )


def _triangle_angles(corners: FloatArray) -> FloatArray:
    """The angle of spherical triangles (t, 3, 3) at each corner, (t, 3), radians.

    At corner ``a`` between the great circles to ``b`` and ``c``: the angle between the
    normals ``a × b`` and ``a × c``.
    """
    a = corners
    b = np.roll(corners, -1, axis=1)
    c = np.roll(corners, -2, axis=1)
    nb, nc = np.cross(a, b), np.cross(a, c)
    return np.asarray(
        np.arctan2(np.linalg.norm(np.cross(nb, nc), axis=-1), np.sum(nb * nc, axis=-1))
    )


__all__ = [
    "HasSphericalMesh",
    "SphereMesh",
    "SphereQuality",
    "Width",
    "arc_length",
    "lat_lon",
    "signed_triangle_area",
    "sphere_quality",
    "spherical_mesh",
]
