"""Where the samplers of :mod:`hcvt.seeding.initialisation` draw: a cover of the domain.

Rejection in the bounding box needs ``V_box / V`` draws per point inside: two billion for
a thin diagonal triangle of area 5e-10 of its box (issue 30: 20 sites did not come in
120 s). A cover is a set of cells whose union contains the domain and in which a point is
easy to place uniformly: the bounding box itself, the triangles of a polygon's constrained
Delaunay triangulation (2D, the domain itself up to round-off), or the boxes of an octree
kept when inside or touching the boundary (3D). A point uniform in the cover and kept
when strictly inside (:meth:`hcvt.Domain.contains`) is uniform in the domain, whatever the
cover; the cover only sets how many draws are wasted.

:func:`cover` keeps the bounding box when the domain fills at least
:data:`BOX_MIN_FRACTION` of it, so that the sites of ordinary domains are those drawn
before covers existed (the behaviour fingerprints of issue 29).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray

from hcvt.geometry.domain import Domain

#: Domains filling at least this fraction of their bounding box are sampled in the box.
BOX_MIN_FRACTION = 0.05
#: Octree (3D): refinement stops once the domain fills this fraction of the boxes kept...
OCTREE_TARGET_FRACTION = 0.25
#: ... or when the next level would hold more boxes, or more (box, triangle) pairs to
#: test, than these (a few seconds of numpy at most).
OCTREE_MAX_BOXES = 1 << 16
OCTREE_MAX_PAIRS = 1 << 23
#: ... or after this many levels (boxes 2^-40 of the bounding box).
OCTREE_MAX_LEVELS = 40
#: Relative growth of a box for the triangle-box test: a triangle that grazes a box
#: within round-off counts as meeting it, so no part of the domain is left uncovered.
BOX_GROWTH = 1e-6


@dataclass(frozen=True)
class Cover:
    """Cells whose union contains the domain, each sampled uniformly.

    Attributes
    ----------
    kind : {"box", "triangles", "boxes"}
        The bounding box (one cell), triangles (2D) or axis-aligned boxes (3D).
    cells : ndarray of float64
        ``"box"`` and ``"boxes"``: (K, 2, d) low and high corners; ``"triangles"``:
        (K, 3, 2) corners, in L.
    volumes : ndarray of float64, shape (K,)
        Area or volume of each cell, L^d, all positive.
    fraction : float
        ``domain.volume / volumes.sum()``: the expected share of draws kept.
    """

    kind: str
    cells: NDArray[np.float64]
    volumes: NDArray[np.float64]
    fraction: float

    @property
    def volume(self) -> float:
        """Total volume of the cells, L^d."""
        return float(self.volumes.sum())

    def place(self, unit: NDArray[np.float64]) -> NDArray[np.float64]:
        """Points of the cover (m, d) from points of the unit cube (m, ≥ d), measure-preserving.

        Only the first ``d`` coordinates are used. The first one picks the cell by its
        share of the total volume (inverse CDF) and, rescaled within that share, serves
        again as the cell's first coordinate, so a low-discrepancy stream stays
        stratified over the cells. A triangle is the unit square folded on its diagonal.
        """
        dim = self.cells.shape[2]
        if self.kind == "box":
            lo, hi = self.cells[0]
            return lo + unit[:, :dim] * (hi - lo)
        ends = np.cumsum(self.volumes)
        at = unit[:, 0] * ends[-1]
        cell = np.minimum(np.searchsorted(ends, at, side="right"), len(ends) - 1)
        first = np.clip((at - (ends[cell] - self.volumes[cell])) / self.volumes[cell], 0.0, 1.0)
        local = np.column_stack([first, unit[:, 1:dim]])
        corners = self.cells[cell]
        if self.kind == "boxes":
            return corners[:, 0] + local * (corners[:, 1] - corners[:, 0])
        s, t = local[:, 0], local[:, 1]
        fold = s + t > 1.0
        s, t = np.where(fold, 1.0 - s, s), np.where(fold, 1.0 - t, t)
        a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
        return a + s[:, None] * (b - a) + t[:, None] * (c - a)


def cover(domain: Domain) -> Cover:
    """The cover the samplers draw in: the box, else triangles (2D) or octree boxes (3D)."""
    lo, hi = domain.bounds
    box_volume = float(np.prod(hi - lo))
    if domain.volume >= BOX_MIN_FRACTION * box_volume:
        return Cover("box", np.stack([lo, hi])[None], np.array([box_volume]), 1.0)
    if domain.dim == 2:
        return _triangles(domain)
    return _octree(domain)


def _make(kind: str, cells: NDArray[np.float64], volume: float) -> Cover:
    if kind == "triangles":
        a, b, c = cells[:, 0], cells[:, 1], cells[:, 2]
        e, f = b - a, c - a
        volumes = 0.5 * np.abs(e[:, 0] * f[:, 1] - e[:, 1] * f[:, 0])
    else:
        volumes = np.prod(cells[:, 1] - cells[:, 0], axis=1)
    keep = volumes > 0
    cells, volumes = cells[keep], volumes[keep]
    return Cover(kind, cells, volumes, min(1.0, volume / float(volumes.sum())))


def _triangles(domain: Domain) -> Cover:
    """The polygon's constrained Delaunay triangles (shapely): the domain itself."""
    triangles = shapely.get_parts(shapely.constrained_delaunay_triangles(domain.geometry))
    corners = np.stack([np.asarray(t.exterior.coords)[:3] for t in triangles])
    return _make("triangles", corners.astype(np.float64), domain.volume)


def _octree(domain: Domain) -> Cover:
    """Boxes of an octree of the bounding box: those inside, and those meeting the boundary.

    A box that meets no boundary triangle (separating-axis test, :func:`_meets`) lies
    wholly inside or wholly outside: its centre decides. Boxes meeting the boundary are
    split, level by level, until the domain fills :data:`OCTREE_TARGET_FRACTION` of the
    boxes kept or the next level exceeds :data:`OCTREE_MAX_BOXES` boxes or
    :data:`OCTREE_MAX_PAIRS` pairs to test. A thin solid (a plate far thinner than its
    extent) may stay far below the target: the caller says so.
    """
    triangles = domain.vertices[domain.faces]
    lo, hi = domain.bounds
    half = 0.5 * (hi - lo)
    centres = (0.5 * (lo + hi))[None]
    pair_box = np.zeros(len(triangles), dtype=np.int64)
    pair_triangle = np.arange(len(triangles))
    inside: list[NDArray[np.float64]] = []  # (k, 2, 3) boxes, per level
    inside_volume = 0.0
    signs = np.array([[(k >> a) & 1 for a in range(3)] for k in range(8)]) * 2.0 - 1.0
    for _ in range(OCTREE_MAX_LEVELS):
        kept = inside_volume + len(centres) * float(np.prod(2.0 * half))
        if (
            domain.volume >= OCTREE_TARGET_FRACTION * kept
            or 8 * len(centres) > OCTREE_MAX_BOXES
            or 8 * len(pair_box) > OCTREE_MAX_PAIRS
        ):
            break
        half = 0.5 * half
        children = (centres[:, None, :] + signs[None] * half).reshape(-1, 3)
        child_box = (8 * pair_box[:, None] + np.arange(8)).ravel()
        child_triangle = np.repeat(pair_triangle, 8)
        meets = _meets(children[child_box], half, triangles[child_triangle])
        child_box, child_triangle = child_box[meets], child_triangle[meets]
        touched = np.zeros(len(children), dtype=bool)
        touched[child_box] = True
        free = children[~touched]
        free = free[domain.contains(free)]
        inside.append(np.stack([free - half, free + half], axis=1))
        inside_volume += len(free) * float(np.prod(2.0 * half))
        renumber = np.cumsum(touched) - 1
        centres, pair_box, pair_triangle = children[touched], renumber[child_box], child_triangle
    boundary = np.stack([centres - half, centres + half], axis=1)
    return _make("boxes", np.concatenate([*inside, boundary]), domain.volume)


def _meets(
    centres: NDArray[np.float64], half: NDArray[np.float64], triangles: NDArray[np.float64]
) -> NDArray[np.bool_]:
    """Whether each triangle (P, 3, 3) meets its box (centres (P, 3), half sides (3,)).

    Separating axes (Akenine-Möller 2001): the box's three axes, the triangle's normal,
    and the nine cross products of box axes with triangle edges. The box is grown by
    :data:`BOX_GROWTH` so that round-off can only add pairs, never lose one.
    """
    h = half * (1.0 + BOX_GROWTH)
    v = triangles - centres[:, None, :]
    apart = (v.min(axis=1) > h).any(axis=1) | (v.max(axis=1) < -h).any(axis=1)
    edges = np.roll(v, -1, axis=1) - v  # (P, 3, 3): edge j from vertex j
    normal = np.cross(edges[:, 0], edges[:, 1])
    apart |= np.abs(np.einsum("pj,pj->p", normal, v[:, 0])) > np.abs(normal) @ h
    for j in range(3):
        f = edges[:, j]
        zero = np.zeros(len(f))
        for axis in (
            np.column_stack([zero, -f[:, 2], f[:, 1]]),
            np.column_stack([f[:, 2], zero, -f[:, 0]]),
            np.column_stack([-f[:, 1], f[:, 0], zero]),
        ):
            p = np.einsum("pj,pkj->pk", axis, v)
            r = np.abs(axis) @ h
            apart |= (p.min(axis=1) > r) | (p.max(axis=1) < -r)
    return ~apart
