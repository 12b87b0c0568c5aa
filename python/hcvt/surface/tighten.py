"""Lower a remeshed surface's Hausdorff distance to its input by moving vertices on it.

A restricted CVT spreads the vertices evenly, so its largest distances to the input sit at
a few places the even spacing cuts: a crease or a corner of the input (kitten, n = 5,000:
the largest distance, 0.56% of the diagonal, is at a 90° crease, 2.4 times the 99.9th
percentile of the distances), a tip whose triangles pass below it. :func:`tighten` moves
the vertex nearest such a place, one at a time, the worst place first:

- a point ``P`` of the input far from the mesh: a vertex of the mesh's triangle nearest
  ``P`` moves to ``P`` (onto the input, as every vertex is);
- a point ``Q`` of a mesh triangle far from the input (``Q*`` its nearest point there): a
  vertex of that triangle moves by ``Q* − Q`` (or half of it), projected onto the input.

A move is kept only if every triangle around the vertex keeps its least angle and its
quality Q at or above the mesh's least ones (so those never fall), turns its normal by
less than 60°, and the distances around it all fall below the worst one; the connectivity
is not touched (the same faces, so the same manifold and genus). It stops when the worst
place cannot be improved (or after ``max_moves``). Distances are held as upper bounds:
points of the input (its vertices and samples by area) to the mesh, and 12 points of each
mesh triangle (a barycentric grid of step 1/4) to the input, each updated around a moved
vertex only.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from hcvt.geometry.surface_points import sample_by_area
from hcvt.surface.quality import triangle_angles, triangle_quality

#: Barycentric coordinates (7, 3) of the points checked on each mesh triangle: the grid
#: i + j + k = 3 without the corners (which lie on the input): the centroid and two
#: points on each edge.
_GRID = (
    np.array(
        [[i, j, 3 - i - j] for i in range(4) for j in range(4 - i) if max(i, j, 3 - i - j) < 3],
        dtype=np.float64,
    )
    / 3.0
)
#: Nearest triangles (by centroid) searched for a point's nearest point: the distances
#: held are upper bounds, exact wherever the nearest triangle is among them.
_NEAREST_K = 8
#: Most a triangle's normal may turn in one move (cosine of 60°).
_MIN_NORMAL_COSINE = 0.5
#: A move must bring the distances around it below (1 − this) × the worst one.
_GAIN = 1e-3
#: Distances below this × the input's bounding-box diagonal are not worth a move.
_NEGLIGIBLE = 1e-9


def _closest_on_triangles(p: NDArray[np.float64], tri: NDArray[np.float64]) -> NDArray[np.float64]:
    """The nearest point of triangle ``tri[i]`` (m, 3, 3) to ``p[i]`` (m, 3) (Ericson, 5.1.5)."""
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = np.einsum("ij,ij->i", ab, ap), np.einsum("ij,ij->i", ac, ap)
    bp, cp = p - b, p - c
    d3, d4 = np.einsum("ij,ij->i", ab, bp), np.einsum("ij,ij->i", ac, bp)
    d5, d6 = np.einsum("ij,ij->i", ab, cp), np.einsum("ij,ij->i", ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        # Inside the face (the default), then the edge and corner regions override.
        denom = va + vb + vc
        v, w = vb / denom, vc / denom
        out = a + v[:, None] * ab + w[:, None] * ac
        t_ab = d1 / (d1 - d3)
        on = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        out[on] = (a + t_ab[:, None] * ab)[on]
        t_ac = d2 / (d2 - d6)
        on = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        out[on] = (a + t_ac[:, None] * ac)[on]
        t_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        on = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
        out[on] = (b + t_bc[:, None] * (c - b))[on]
    out[(d1 <= 0) & (d2 <= 0)] = a[(d1 <= 0) & (d2 <= 0)]
    out[(d3 >= 0) & (d4 <= d3)] = b[(d3 >= 0) & (d4 <= d3)]
    out[(d6 >= 0) & (d5 <= d6)] = c[(d6 >= 0) & (d5 <= d6)]
    return out


def _nearest(
    points: NDArray[np.float64], corners: NDArray[np.float64], candidates: NDArray[np.intp]
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Distances of points (m, 3) to the nearest of their candidate triangles.

    ``candidates`` (m, k) index ``corners`` (F, 3, 3), -1 for none; returns the distances
    (m,) and the nearest candidate of each (m,).
    """
    m, k = candidates.shape
    flat = np.maximum(candidates, 0).ravel()
    near = _closest_on_triangles(np.repeat(points, k, axis=0), corners[flat])
    d = np.linalg.norm(near - np.repeat(points, k, axis=0), axis=1).reshape(m, k)
    d[candidates < 0] = np.inf
    best = np.argmin(d, axis=1)
    return d[np.arange(m), best], candidates[np.arange(m), best]


def _k_nearest(tree: cKDTree, points: NDArray[np.float64], k: int) -> NDArray[np.intp]:
    """The ``k`` nearest centroids' triangles (m, k), -1 where there are fewer."""
    k = min(k, tree.n)
    _, idx = tree.query(points, k=k)
    idx = np.asarray(idx).reshape(len(points), k)
    idx[idx >= tree.n] = -1
    return idx


@dataclass
class TightenResult:
    """What :func:`tighten` returns.

    Attributes
    ----------
    vertices : ndarray, shape (n, 3)
        The vertices after the moves (the input's own where none was made).
    moves : int
        Vertices moved (a vertex may move more than once).
    before, after : float
        The largest held distance both ways before and after, in the input's units
        (upper bounds on the checked points; :func:`hcvt.surface_quality` samples its own).
    """

    vertices: NDArray[np.float64]
    moves: int
    before: float
    after: float


def _reach(corners: NDArray[np.float64]) -> float:
    """The farthest any triangle's corner is from its centroid."""
    return float(np.linalg.norm(corners - corners.mean(axis=1)[:, None], axis=2).max())


def _exact(
    point: NDArray[np.float64],
    bound: float,
    corners: NDArray[np.float64],
    tree: cKDTree,
    reach: float,
) -> tuple[float, int]:
    """The distance of ``point`` (3,) to the triangles ``corners`` and the nearest one.

    Exact given an upper ``bound`` on it: the nearest triangle's centroid is within
    ``bound + reach`` of the point (``tree`` holds the centroids, ``reach`` bounds every
    corner's distance from its centroid).
    """
    near = np.asarray(tree.query_ball_point(point, bound + reach), dtype=np.intp)
    if len(near) == 0:
        return np.inf, -1
    d, which = _nearest(point[None], corners, near[None])
    return float(d[0]), int(which[0])


class _Mesh:
    """The mesh being moved, its triangles' checked points and their distances.

    Every held distance is an upper bound; :meth:`worst` makes the largest exact before it
    is used (by :func:`_exact`), so the searches by nearest centroids cost little.
    """

    def __init__(
        self,
        vertices: NDArray[np.float64],
        faces: NDArray[np.intp],
        reference: tuple[NDArray[np.float64], NDArray[np.intp]],
        samples: int,
        rng: np.random.Generator,
    ) -> None:
        self.v = np.array(vertices, dtype=np.float64)
        self.f = np.asarray(faces, dtype=np.intp)
        self.rv, self.rf = reference
        # Vertex -> its triangles (CSR).
        order = np.argsort(self.f.ravel(), kind="stable")
        self.ring_start = np.searchsorted(self.f.ravel()[order], np.arange(len(self.v) + 1))
        self.ring_faces = order // 3
        # The input's triangles by centroid.
        self.ref_corners = self.rv[self.rf]
        self.ref_tree = cKDTree(self.ref_corners.mean(axis=1))
        self.ref_reach = _reach(self.ref_corners)
        # The mesh's triangles by centroid, as built; its vertices have since moved by at
        # most `drift` each (which widens the exact searches).
        self.index_mesh()
        # Points of the input (its vertices and samples) and their distances to the mesh,
        # over the mesh's triangles nearest by centroid.
        points, _ = sample_by_area(self.rv, self.rf, samples, rng)
        self.s = np.concatenate([points, self.rv[np.unique(self.rf)]])
        self.s_tree = cKDTree(self.s)
        corners = self.v[self.f]
        near = _k_nearest(self.mesh_tree, self.s, _NEAREST_K)
        self.ds, self.s_face = _nearest(self.s, corners, near)
        self.ds_exact = np.zeros(len(self.s), dtype=bool)
        # The checked points of every triangle and their distances to the input.
        tp = self.triangle_points(np.arange(len(self.f)), self.v).reshape(-1, 3)
        near = _k_nearest(self.ref_tree, tp, _NEAREST_K)
        self.dt = _nearest(tp, self.ref_corners, near)[0].reshape(len(self.f), len(_GRID))
        self.dt_exact = np.zeros(self.dt.shape, dtype=bool)

    def index_mesh(self) -> None:
        """The mesh's centroids' tree, as the vertices are now."""
        corners = self.v[self.f]
        self.mesh_tree = cKDTree(corners.mean(axis=1))
        self.mesh_reach = _reach(corners)
        self.drift = 0.0

    def triangle_points(
        self, faces: NDArray[np.intp], v: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """The checked points (len(faces), 7, 3) of these triangles with vertices ``v``."""
        return np.einsum("gk,fkd->fgd", _GRID, v[self.f[faces]])

    def ring(self, a: int) -> NDArray[np.intp]:
        """The triangles around vertex ``a``."""
        return self.ring_faces[self.ring_start[a] : self.ring_start[a + 1]]

    def two_ring(self, a: int) -> NDArray[np.intp]:
        """The triangles around ``a``'s neighbours."""
        near = np.unique(self.f[self.ring(a)])
        return np.unique(np.concatenate([self.ring(b) for b in near]))

    def to_input(self, points: NDArray[np.float64], limit: float) -> NDArray[np.float64]:
        """Distances of ``points`` (m, 3) to the input.

        Upper bounds, exact where they reach ``limit`` (so a move is judged alike).
        """
        near = _k_nearest(self.ref_tree, points, _NEAREST_K)
        d = _nearest(points, self.ref_corners, near)[0]
        over = d >= limit
        if not over.any():
            return d
        # Those beyond the bound: every input triangle that could be nearer than `limit`.
        centre = points[over].mean(axis=0)
        radius = float(np.linalg.norm(points[over] - centre, axis=1).max())
        near = np.asarray(
            self.ref_tree.query_ball_point(centre, radius + limit + self.ref_reach), dtype=np.intp
        )
        if len(near):
            candidates = np.broadcast_to(near, (int(over.sum()), len(near)))
            d[over] = np.minimum(d[over], _nearest(points[over], self.ref_corners, candidates)[0])
        return d

    def project(self, point: NDArray[np.float64]) -> NDArray[np.float64]:
        """A nearest point of the input to ``point`` (3,) (on the input in any case)."""
        near = _k_nearest(self.ref_tree, point[None], _NEAREST_K)[0]
        corners = self.ref_corners[np.maximum(near, 0)]
        found = _closest_on_triangles(np.repeat(point[None], len(near), axis=0), corners)
        return found[np.argmin(np.linalg.norm(found - point, axis=1))]

    def moved(self, a: int, x: NDArray[np.float64]) -> None:
        """Vertex ``a`` moves to ``x``."""
        self.drift = max(self.drift, float(np.linalg.norm(x - self.v[a])))
        self.v[a] = x
        if self.drift > self.mesh_reach:
            self.index_mesh()

    def worst(self) -> tuple[float, str, int]:
        """The largest distance (exact), which side it is on, and its point's index."""
        while True:
            i, j = int(np.argmax(self.ds)), int(np.argmax(self.dt))
            if self.ds[i] >= self.dt.flat[j]:
                if self.ds_exact[i]:
                    return float(self.ds[i]), "input", i
                # The tree's triangles have moved by `drift` at most since it was built.
                d, face = _exact(
                    self.s[i],
                    float(self.ds[i]) + self.drift,
                    self.v[self.f],
                    self.mesh_tree,
                    self.mesh_reach + 2.0 * self.drift,
                )
                self.ds[i], self.s_face[i], self.ds_exact[i] = d, face, True
                continue
            if self.dt_exact.flat[j]:
                return float(self.dt.flat[j]), "mesh", j
            face, g = divmod(j, len(_GRID))
            point = self.triangle_points(np.array([face]), self.v)[0, g]
            d, _ = _exact(
                point, float(self.dt.flat[j]), self.ref_corners, self.ref_tree, self.ref_reach
            )
            self.dt.flat[j], self.dt_exact.flat[j] = d, True


#: Fractions of the way to a target tried for a vertex, the whole way first.
_STEPS = (1.0, 0.75, 0.5, 0.25, 0.125)


def _candidates(
    mesh: _Mesh, side: str, index: int, movable: NDArray[np.bool_]
) -> Iterator[tuple[int, NDArray[np.float64]]]:
    """(vertex, new position) moves that may lower the distance at the worst point."""
    if side == "input":
        target = mesh.s[index]
        for a in mesh.f[mesh.s_face[index]]:
            if movable[a]:
                for step in _STEPS:
                    yield int(a), mesh.project(mesh.v[a] + step * (target - mesh.v[a]))
        return
    face, g = divmod(index, len(_GRID))
    point = mesh.triangle_points(np.array([face]), mesh.v)[0, g]
    shift = mesh.project(point) - point
    for a in mesh.f[face]:
        if movable[a]:
            for step in _STEPS:
                yield int(a), mesh.project(mesh.v[a] + step * shift)


#: What a passing move changes: (ring faces, their points' distances to the input, input
#: points near it, their distances to the mesh, their nearest faces).
_Update = tuple[
    NDArray[np.intp], NDArray[np.float64], NDArray[np.intp], NDArray[np.float64], NDArray[np.intp]
]


def _try(
    mesh: _Mesh,
    a: int,
    x: NDArray[np.float64],
    floors: tuple[float, float],
    worst: float,
    limit: float,
) -> _Update | None:
    """The move of vertex ``a`` to ``x`` if it passes (module docs), else None.

    ``floors``: the least angle (degrees) and Q allowed; ``worst``: the worst distance
    now; ``limit``: what every distance around the move must fall below.
    """
    ring = mesh.ring(a)
    v = mesh.v  # moved in place below, put back in `finally`
    old = v[a].copy()
    tri = mesh.f[ring]
    old_normals = _normals(v, tri)
    v[a] = x
    try:
        if triangle_angles(v, tri).min() < floors[0] or triangle_quality(v, tri).min() < floors[1]:
            return None
        if np.min(np.einsum("ij,ij->i", _normals(v, tri), old_normals)) < _MIN_NORMAL_COSINE:
            return None
        dt = mesh.to_input(mesh.triangle_points(ring, v).reshape(-1, 3), limit)
        if dt.max() >= limit:
            return None
        dt = dt.reshape(len(ring), len(_GRID))
        # Input points whose distance may change: within reach of the ring, before or
        # after the move.
        corners = np.vstack([v[np.unique(tri)], old])
        centre = corners.mean(axis=0)
        radius = float(np.linalg.norm(corners - centre, axis=1).max())
        near = np.asarray(mesh.s_tree.query_ball_point(centre, radius + worst), dtype=np.intp)
        if len(near) == 0:
            return ring, dt, near, np.zeros(0), np.zeros(0, dtype=np.intp)
        local = mesh.two_ring(a)
        candidates = np.broadcast_to(np.arange(len(local)), (len(near), len(local)))
        d, which = _nearest(mesh.s[near], v[mesh.f[local]], candidates)
        faces = local[which]
        was_on_ring = np.isin(mesh.s_face[near], ring)
        # Off the ring before: the old bound still holds; keep the smaller.
        keep_old = ~was_on_ring & (mesh.ds[near] <= d)
        d = np.where(keep_old, mesh.ds[near], d)
        faces = np.where(keep_old, mesh.s_face[near], faces)
        if d.max(initial=0.0) >= limit:
            return None
        return ring, dt, near, d, faces
    finally:
        v[a] = old


def _normals(v: NDArray[np.float64], tri: NDArray[np.intp]) -> NDArray[np.float64]:
    n = np.cross(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]


def tighten(
    vertices: NDArray[np.float64],
    faces: NDArray[np.intp],
    reference: tuple[NDArray[np.float64], NDArray[np.intp]],
    *,
    fixed: NDArray[np.bool_] | None = None,
    samples: int = 30_000,
    seed: int = 0,
    max_moves: int = 10_000,
    min_angle: float | None = None,
) -> TightenResult:
    """Move vertices of a mesh along the surface it stands for, to lower its Hausdorff distance.

    Parameters
    ----------
    vertices : ndarray, shape (n, 3)
        The mesh's vertices, on the input surface.
    faces : ndarray of int, shape (m, 3)
        Its triangles (not changed).
    reference : (vertices (V, 3), faces (F, 3))
        The input surface.
    fixed : ndarray of bool, shape (n,), optional
        Vertices that must not move (feature sites, the border of an open mesh: vertices
        on a border edge never move).
    samples : int
        Points sampled by area on the input (besides its vertices).
    seed : int
        Seeds the samples.
    max_moves : int
        The most moves.
    min_angle : float or None
        The least angle (degrees) a moved triangle may have; None: the mesh's least angle
        (which then never falls).

    Returns
    -------
    TightenResult
        The least angle and the least Q of the mesh are not lowered (module docs).
    """
    rng = np.random.default_rng(seed)
    mesh = _Mesh(vertices, faces, reference, samples, rng)
    movable = np.ones(len(mesh.v), dtype=bool)
    if fixed is not None:
        movable &= ~np.asarray(fixed, dtype=bool)
    edges = np.sort(np.concatenate([mesh.f[:, [0, 1]], mesh.f[:, [1, 2]], mesh.f[:, [2, 0]]]), 1)
    pairs, counts = np.unique(edges, axis=0, return_counts=True)
    movable[pairs[counts == 1].ravel()] = False  # border vertices stay on the border
    least = float(triangle_angles(mesh.v, mesh.f).min())
    floors = (
        least if min_angle is None else float(min_angle),
        float(triangle_quality(mesh.v, mesh.f).min()),
    )
    before = mesh.worst()[0]
    # Below this the distances are round-off (a flat part, a mesh already on the input).
    negligible = _NEGLIGIBLE * float(np.linalg.norm(np.ptp(mesh.rv, axis=0)))
    moves = 0
    while moves < max_moves:
        worst, side, index = mesh.worst()
        if worst <= negligible:
            break
        limit = worst * (1.0 - _GAIN)
        best = None
        for a, x in _candidates(mesh, side, index, movable):
            found = _try(mesh, a, x, floors, worst, limit)
            if found is None:
                continue
            peak = max(float(found[1].max()), float(found[3].max(initial=0.0)))
            if best is None or peak < best[0]:
                best = (peak, a, x, found)
        if best is None:
            break  # the worst place cannot be improved: the distance is what it is
        _, a, x, (ring, dt, near, d, near_faces) = best
        mesh.moved(a, x)
        mesh.dt[ring], mesh.dt_exact[ring] = dt, False  # bounds below `limit`
        mesh.ds[near], mesh.s_face[near] = d, near_faces
        mesh.ds_exact[near] = False  # over the two-ring only: bounds
        moves += 1
    return TightenResult(mesh.v, moves, before, mesh.worst()[0])


__all__ = ["TightenResult", "tighten"]
