"""Sites on the sphere: uniform random, Fibonacci spiral, icosahedral (DESIGN §13).

Every function returns unit vectors (n, 3); :func:`hcvt.initialise` scales them by the
sphere's radius.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from hcvt.density import SizingField, evaluate

#: ``initialise``'s methods on the sphere.
SPHERE_METHODS = ("random", "fibonacci", "icosahedral")


def random_sphere(n: int, rng: np.random.Generator) -> NDArray[np.float64]:
    """``n`` points uniform on the unit sphere: normalised standard normal vectors."""
    while True:
        v = rng.standard_normal((n, 3))
        r = np.linalg.norm(v, axis=1)
        if np.all(r > 0):  # a zero vector has probability 0; draw again if it happens
            return np.asarray(v / r[:, None], dtype=np.float64)


def fibonacci(n: int) -> NDArray[np.float64]:
    """The Fibonacci (golden spiral) lattice of ``n`` points: equal-area bands in ``z``.

    Point ``i`` at height ``z_i = 1 − (2i + 1)/n`` and longitude ``i · π(3 − √5)``; every
    point lies in its own band of area ``4π/n`` (Swinbank and Purser 2006).
    """
    i = np.arange(n, dtype=np.float64)
    z = 1.0 - (2.0 * i + 1.0) / n
    r = np.sqrt(np.maximum(0.0, (1.0 - z) * (1.0 + z)))
    phi = i * (math.pi * (3.0 - math.sqrt(5.0)))
    return np.ascontiguousarray(np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1))


def icosahedral_level(n: int) -> int | None:
    """``k`` with ``n = 10 · 4^k + 2``, or None."""
    k, size = 0, 12
    while size < n:
        k, size = k + 1, 10 * 4 ** (k + 1) + 2
    return k if size == n else None


def icosahedron() -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """The 12 unit vertices and 20 faces (counter-clockwise seen from outside)."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    v = np.array(
        [
            [-1, t, 0],
            [1, t, 0],
            [-1, -t, 0],
            [1, -t, 0],
            [0, -1, t],
            [0, 1, t],
            [0, -1, -t],
            [0, 1, -t],
            [t, 0, -1],
            [t, 0, 1],
            [-t, 0, -1],
            [-t, 0, 1],
        ],
        dtype=np.float64,
    )
    faces = np.array(
        [
            [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
            [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
            [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
            [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
        ],
        dtype=np.intp,
    )  # fmt: skip
    return v / np.linalg.norm(v, axis=1)[:, None], faces


def icosahedral(n: int) -> NDArray[np.float64]:
    """The vertices of the icosahedron subdivided ``k`` times, ``n = 10 · 4^k + 2``.

    Each step splits every triangle into four at its edges' midpoints, pushed out onto the
    sphere (the MPAS standard meshes start from these: 2,562 at k = 4, 40,962 at k = 6).

    Raises
    ------
    ValueError
        ``n`` is not of the form ``10 · 4^k + 2`` (the message names the nearest two).
    """
    k = icosahedral_level(n)
    if k is None:
        below = max(j for j in range(0, 20) if 10 * 4**j + 2 <= max(n, 12))
        raise ValueError(
            f"icosahedral sites come in n = 10·4^k + 2 (12, 42, 162, 642, 2562, ...), got "
            f"{n}; the nearest are {10 * 4**below + 2} and {10 * 4 ** (below + 1) + 2}"
        )
    v, faces = icosahedron()
    vertices = [v]
    count = len(v)
    for _ in range(k):
        edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
        edges.sort(axis=1)
        unique, inverse = np.unique(edges, axis=0, return_inverse=True)
        points = np.concatenate(vertices)
        mid = points[unique[:, 0]] + points[unique[:, 1]]
        vertices.append(mid / np.linalg.norm(mid, axis=1)[:, None])
        m = count + inverse.reshape(3, -1).T  # midpoints of edges 01, 12, 20 per face
        a, b, c = faces.T
        ab, bc, ca = m.T
        faces = np.concatenate(
            [
                np.stack([a, ab, ca], axis=1),
                np.stack([ab, b, bc], axis=1),
                np.stack([ca, bc, c], axis=1),
                np.stack([ab, bc, ca], axis=1),
            ]
        )
        count += len(unique)
    return np.ascontiguousarray(np.concatenate(vertices))


def distance_to_meridian(points: NDArray[np.float64], lon0: float = 0.0) -> NDArray[np.float64]:
    """Arc distance (radians) from each of ``points`` (m, 3) to the meridian at ``lon0``.

    The meridian is the half great circle from pole to pole at ``lon0`` degrees: the
    distance is ``asin |x·n|`` (``n`` the normal of its plane) on the meridian's side of the
    globe, the distance to the nearer pole on the other side. Shape (m,).
    """
    x = points / np.linalg.norm(points, axis=1)[:, None]
    lon = math.radians(lon0)
    normal = np.array([-math.sin(lon), math.cos(lon), 0.0])
    towards = np.array([math.cos(lon), math.sin(lon), 0.0])
    across = np.arcsin(np.clip(np.abs(x @ normal), 0.0, 1.0))
    to_pole = np.arccos(np.clip(np.abs(x[:, 2]), 0.0, 1.0))
    return np.where(x @ towards >= 0.0, across, to_pole)


def meridian_band_width(
    points: NDArray[np.float64],
    fine: float,
    coarse: float,
    *,
    lon0: float = 0.0,
    half_band: float = 10.0,
    transition: float = 10.0,
) -> NDArray[np.float64]:
    """A regionally refined cell width (MPAS style) at ``points`` (m, 3), shape (m,).

    ``fine`` within ``half_band`` degrees of the meridian at ``lon0`` (a band of
    ``2 · half_band``), ``coarse`` far from it, and between them a tanh ramp over
    ``transition`` degrees: with ``δ`` the arc distance (:func:`distance_to_meridian`) and
    ``s = (δ − half_band − transition/2) / (transition/4)``,
    ``h = fine + (coarse − fine) (1 + tanh s) / 2`` (within 1.8% of ``coarse − fine`` of
    each end at the band's edge and ``transition`` beyond it). Same unit as ``fine``.
    """
    delta = np.degrees(distance_to_meridian(points, lon0))
    s = (delta - half_band - 0.5 * transition) / (0.25 * transition)
    return np.asarray(fine + (coarse - fine) * 0.5 * (1.0 + np.tanh(s)), dtype=np.float64)


def cells_for_width(
    width: Callable[[NDArray[np.float64]], NDArray[np.float64]], radius: float
) -> int:
    """The number of hexagonal cells that tile the sphere of ``radius`` at a cell width.

    A hexagon has area ``(√3/2) h²`` with ``h`` the distance between neighbouring sites;
    ``width(points (m, 3)) -> (m,)`` is in the unit of ``radius``. ``∫ dA / ((√3/2) h²)``
    by the midpoint rule on a 2,000 × 1,000 lon/lat grid.
    """
    lon = np.radians(np.linspace(-180.0, 180.0, 2001)[:-1] + 0.09)
    lat = np.radians(np.linspace(-90.0, 90.0, 1001)[:-1] + 0.09)
    lo, la = np.meshgrid(lon, lat)
    x = np.stack([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)], axis=-1)
    h = width(x.reshape(-1, 3) * radius).reshape(la.shape)
    area = np.cos(la) * math.radians(0.18) ** 2 * radius**2
    return int(round(float(np.sum(area / (0.5 * math.sqrt(3.0) * h**2)))))


#: Lattice points per site in :func:`rebalance`'s estimate of each cell's ``∫ρ^(1/2)``.
REBALANCE_LATTICE = 64


def point_density(density: Any, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """A CVT's point density ``ρ^(1/2)`` at ``points`` (m, 3) on the sphere.

    Cells there have dimension 2: a :class:`hcvt.density.SizingField` ``h`` is
    ``ρ = h^-4`` (as the sphere's frame gives the core), not ``h^-5``.
    """
    rho = density.density(2) if isinstance(density, SizingField) else density
    return evaluate(rho, points) ** 0.5


def rebalance(
    coarse: NDArray[np.float64], sites: NDArray[np.float64], density: Any
) -> NDArray[np.float64]:
    """``sites`` (a subdivided level) with each ``coarse`` cell holding its share of ``ρ^(1/2)``.

    Subdividing gives every cell of the coarse level about four sites, but a coarse CVT
    of a graded density does not follow it where its cells are wider than the density's
    features: on the 120/960 km meridian band (5,037 sites) the 1,259-site level holds
    twice the far region's share, and the last level, a local optimisation, keeps 10% too
    many sites there (grid spacing 0.956 of the width asked). Here each coarse cell
    (the points nearest its site) gets ``n ∫_cell ρ^(1/2) / ∫ ρ^(1/2)`` sites (a CVT's
    point density, Gersho; largest remainders to round), both integrals over a
    Fibonacci lattice of ``REBALANCE_LATTICE`` points per site. A cell with too many
    drops its sites of least ``∫ρ^(1/2)`` over their own cells; a cell with too few gets,
    one per round, the lattice point of largest ``ρ^(1/2) d²`` (``d`` the distance to
    the nearest site), where a site is most wanted. Same sites, same result.
    """
    n, m = len(sites), len(coarse)
    radius = float(np.linalg.norm(sites[0]))
    lattice = fibonacci(max(REBALANCE_LATTICE * n, 1 << 14)) * radius
    weight = point_density(density, lattice)
    cell = cKDTree(coarse).query(lattice)[1]
    want = np.bincount(cell, weight, m) * (n / weight.sum())
    target = np.floor(want).astype(np.int64)
    target[np.argsort(target - want, kind="stable")[: n - int(target.sum())]] += 1
    owner = cKDTree(coarse).query(sites)[1]
    surplus = np.bincount(owner, minlength=m) - target
    own_share = np.bincount(cKDTree(sites).query(lattice)[1], weight, n)
    keep = _rank_in_group(own_share, owner, m) >= np.maximum(surplus, 0)[owner]
    kept = sites[keep]
    deficit = np.maximum(-surplus, 0)
    live = np.flatnonzero(deficit[cell] > 0)
    gap = cKDTree(kept).query(lattice[live])[0]
    added = []
    while len(live):
        best = _rank_in_group(-weight[live] * gap**2, cell[live], m) == 0
        new = lattice[live[best]]
        added.append(new)
        deficit[cell[live[best]]] -= 1
        gap = np.minimum(gap, cKDTree(new).query(lattice[live])[0])
        still = deficit[cell[live]] > 0
        live, gap = live[still], gap[still]
    return np.ascontiguousarray(np.vstack([kept, *added]))


def _rank_in_group(key: NDArray[Any], group: NDArray[np.intp], groups: int) -> NDArray[np.int64]:
    """Each entry's rank by ``key`` (ascending, ties by index) among those of its group."""
    order = np.lexsort((key, group))
    count = np.bincount(group, minlength=groups)
    rank = np.empty(len(key), dtype=np.int64)
    rank[order] = np.arange(len(key)) - np.repeat(np.cumsum(count) - count, count)
    return rank
