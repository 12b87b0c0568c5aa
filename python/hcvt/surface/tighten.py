"""Lower a remeshed surface's Hausdorff distance to its input by moving vertices on it.

A restricted CVT spreads the vertices evenly, so its largest distances to the input sit at
a few places the even spacing cuts: a crease or a corner of the input (kitten, n = 5,000:
the largest distance, 0.56% of the diagonal, is at a 90° crease, 2.4 times the 99.9th
percentile of the distances), a tip whose triangles pass below it. :func:`tighten` moves
the vertex nearest such a place, one at a time, the worst place first:

- a point ``P`` of the input far from the mesh: a vertex of the mesh's triangle nearest
  ``P`` moves to ``P`` (onto the input, as every vertex is);
- a point ``Q`` of a mesh triangle far from the input (``Q*`` its nearest point there): a
  vertex of that triangle moves by ``Q* − Q`` (or a fraction of it), projected onto the
  input, and toward ``Q*`` along the input (a vertex into the hollow the triangle spans: ``Q* −
  Q`` is nearly normal to the surface, and projected back it moves the vertex little).

A move is kept only if every triangle around the vertex keeps its least angle and its
quality Q at or above the mesh's least ones (``min_angle`` may set the angle's floor),
turns its normal by less than 60°, and the distances around it all fall below the worst
one; the connectivity is not touched (the same faces, so the same manifold and genus).
Where no vertex can move alone (its triangles, already near the floors, would fall below
them), it moves with its neighbours following by half its shift, the distortion spread
over the next ring, or else with its neighbours evened out around its new place. Where
nothing passes, the triangles near the worst distance are searched finer
(:data:`_REFINE_SHARE`), and the farther places found are checked from then on, again
after a search that found a place much farther (:data:`_REFINE_AGAIN`); it stops when the
worst place cannot be improved and no farther one is found (or after ``max_moves``).
Bunny, n = 20,000, seed 0, uniform: where the checked points' worst was 0.141% of the
diagonal, the true largest distance was 0.158%; 0.148% after the search on a finer grid,
to which the exact search of each round's farthest point was added since. The distances
are the core's nearest points (its BVHs, :meth:`hcvt._core.SurfaceDomain.closest` for the
input, ``_core.closest_points`` for the mesh): from points of the input (its vertices and
samples by area, and 1 or 3 points along each of its creases) to the mesh, and from 13
points of each mesh triangle (a barycentric grid of step 1/4 and one more) to the input;
around a moved vertex they are updated over the triangles around its ring (upper bounds,
those that may be the largest made exact again, in one call, before the largest is used).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

import hcvt._core as _core
from hcvt.errors import InvalidDomainError
from hcvt.geometry.domain import Domain
from hcvt.geometry.surface_points import cross_rows, sample_by_area
from hcvt.surface.quality import (
    edge_counts,
    hausdorff_one_sided,
    triangle_angles,
    triangle_quality,
)

#: Steps of the barycentric grid of points checked on each mesh triangle. Bunny, n =
#: 20,000 (floor 30°, 200,000 samples, then the input's edges below): Hausdorff 0.160% of
#: the diagonal at 3 steps (7 points), 0.137% at 4 (12), the measure's own samples.
_GRID_STEPS = 4


def _barycentric_grid(steps: int) -> NDArray[np.float64]:
    """Barycentric coordinates (k, 3) of the grid i + j + k = ``steps`` without the corners."""
    return (
        np.array(
            [
                [i, j, steps - i - j]
                for i in range(steps + 1)
                for j in range(steps + 1 - i)
                if max(i, j, steps - i - j) < steps
            ],
            dtype=np.float64,
        )
        / steps
    )


#: Barycentric coordinates (12, 3) of those points: three inside, three on each edge.
_GRID = _barycentric_grid(_GRID_STEPS)
#: When no move improves the worst place, the triangles (of the mesh, and of the input around its
#: points) whose checked distances reach this fraction of the worst one are searched on a grid this
#: much finer, :data:`_REFINE_STEPS` (88 points each; an input's triangle smaller than the mesh's on
#: fewer, :func:`_fine_points`: armadillo, n = 5,000, 5 steps), for the place farthest from the
#: other surface: the worst places of a mesh finer than its input are where a chord crosses a crease
#: of the input, between the checked points (bunny, n = 20,000: the largest distance 0.176% of the
#: diagonal on a mesh edge, between grid points at 0.142% and 0.081%). The mesh's farthest point
#: found is checked from then on (one per triangle, at the same barycentric coordinates as it
#: moves), the input's ones join its points; then the moves go on, up to :data:`_REFINE_ROUNDS`
#: times. One round (uniform remesh, seed 0, 2 threads, quiet): armadillo 5,000 2.46 s against 2.84
#: s with two, Hausdorff 0.387% both; bunny 20,000 3.84 / 4.29 s, 0.159 / 0.158%; kitten 20,000 3.59
#: / 3.91 s, 0.129 / 0.126%; fandisk 5,000 1.22 / 1.43 s, 0.429 / 0.424%.
_REFINE_SHARE = 0.7
_REFINE_STEPS = 12
_REFINE_ROUNDS = 1
#: One round more (up to :data:`_REFINE_MOST` in all) after a round that found a place this
#: many times farther than the worst checked one: the checked points were too sparse there,
#: and may be elsewhere. The first round's find over the checked worst (seed 0): bunny
#: 20,000 1.41 (with the ring's evening out, :data:`_RELAX_SWEEPS`), its second round's
#: 1.13; kitten 20,000 1.095, fandisk 5,000 1.07, bunny 5,000 1.07, armadillo 5,000 1.04
#: (seed 1: 1.03), kitten 5,000 1.02. Bunny 20,000 seed 0, tighten alone (1 thread, under
#: load): one round 0.152%, 2.1 s; two 0.1475%, 2.5 s; three 0.141%, 2.8-3.1 s (seeds 1-3:
#: 0.215, 0.184, 0.158% against 0.215, 0.189, 0.169% with one round).
_REFINE_AGAIN = 1.1
_REFINE_MOST = 3
_FINE = _barycentric_grid(_REFINE_STEPS)


def _fine_points(
    corners: NDArray[np.float64], spacing: float
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Points (m, 3) of a grid on each triangle (k, 3, 3), and the triangle of each (m,).

    The grid's step is at most ``spacing`` (the longest edge over the steps), between 2
    and :data:`_REFINE_STEPS` steps.
    """
    longest = np.linalg.norm(corners - corners[:, [1, 2, 0]], axis=2).max(axis=1)
    steps = np.clip(np.ceil(longest / spacing), 2, _REFINE_STEPS).astype(np.intp)
    points, owner = [], []
    for step in np.unique(steps):
        these = np.flatnonzero(steps == step)
        grid = _barycentric_grid(int(step))
        points.append(np.einsum("gk,fkd->fgd", grid, corners[these]).reshape(-1, 3))
        owner.append(np.repeat(these, len(grid)))
    return np.concatenate(points), np.concatenate(owner)


#: The input's creases are checked at 1/4, 1/2 and 3/4 of each (a crease of the input is
#: where the mesh is farthest from it, and samples by area rarely fall on it), at its
#: middle only if shorter than 2 steps of this fraction of the mesh's mean edge (the
#: step of its grid, :data:`_GRID_STEPS`). Armadillo, n = 5,000: 95% of its 15,639 creases
#: shorter, 17,313 points instead of 46,917, tighten 0.94-0.99 -> 0.81 s (one thread, under
#: load), Hausdorff 0.399 -> 0.410% (seed 1: 0.379 -> 0.380%); bunny, kitten, fandisk: the
#: same points (n = 20,000) or 3-7% fewer (5,000).
_CREASE_STEP = 0.25
#: The input's edges checked are those whose two triangles' normals differ by more than
#: this (degrees): the creases. Armadillo, n = 5,000, under load (~20): 3 points on each
#: of its 129,723 edges, tightening 12.6 s; on its 15,639 creases 7.9 s, the same
#: Hausdorff distance (0.443%); bunny and kitten at 20,000 the same as with every edge.
_CREASE_DEGREES = 20.0


def _creases(rv: NDArray[np.float64], rf: NDArray[np.intp]) -> NDArray[np.intp]:
    """The input's edges (k, 2) whose two triangles' normals differ by > _CREASE_DEGREES."""
    normals = _normals(rv, rf)
    start, end = rf.T.ravel(), rf[:, [1, 2, 0]].T.ravel()  # edges 01 of all, then 12, 20
    edges = np.stack([np.minimum(start, end), np.maximum(start, end)], axis=1)
    faces = np.tile(np.arange(len(rf)), 3)
    key = edges[:, 0].astype(np.int64) * len(rv) + edges[:, 1]  # one sort key: faster
    # Not a stable sort (5 times faster): an edge's two triangles, in either order, give
    # the same cosine and the same edge.
    order = np.argsort(key)
    key, edges, faces = key[order], edges[order], faces[order]
    pair = np.flatnonzero(key[1:] == key[:-1])  # interior edges
    cosine = np.einsum("ij,ij->i", normals[faces[pair]], normals[faces[pair + 1]])
    return edges[pair[cosine < np.cos(np.radians(_CREASE_DEGREES))]]


#: Most a triangle's normal may turn in one move (cosine of 60°).
_MIN_NORMAL_COSINE = 0.5
#: A move must bring the distances around it below (1 − this) × the worst one.
_GAIN = 1e-3
#: Distances below this × the input's bounding-box diagonal are not worth a move.
_NEGLIGIBLE = 1e-9


def _along_creases(ends: NDArray[np.float64], step: float) -> NDArray[np.float64]:
    """The points (m, 3) checked on the creases with these ends (k, 2, 3) (:data:`_CREASE_STEP`)."""
    long = ends[np.linalg.norm(ends[:, 1] - ends[:, 0], axis=1) >= 2.0 * step]
    points = [0.5 * (ends[:, 0] + ends[:, 1])]  # every crease's middle
    for t in (0.25, 0.75):
        points.append((1.0 - t) * long[:, 0] + t * long[:, 1])
    return np.concatenate(points)


def _mean_edge(v: NDArray[np.float64], f: NDArray[np.intp]) -> float:
    """The mean length of the edges of the triangles ``f`` of ``v`` (inner ones twice)."""
    corners = v[f]
    return float(np.linalg.norm(corners - corners[:, [1, 2, 0]], axis=2).mean())


def _nearest_on_input(
    surface: Domain, points: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """The nearest points (m, 3) of ``surface`` to ``points`` (m, 3), and their triangles (m,).

    In the input's frame, by the surface's own BVH, built once with it
    (:meth:`hcvt._core.SurfaceDomain.closest`).
    """
    frame = surface.frame
    nearest, which = surface._core.closest(frame.to_core(np.ascontiguousarray(points)))
    return frame.points_to_input(np.asarray(nearest)), np.asarray(which)


def _on_input(surface: Domain, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """The nearest points (m, 3) of ``surface`` to ``points`` (m, 3), in the input's frame."""
    return _nearest_on_input(surface, points)[0]


def _tree(points: NDArray[np.float64]) -> cKDTree:
    """A k-d tree of ``points`` (m, 3) for :meth:`cKDTree.query_ball_point`.

    Split at the middle of each box, not the median, and the boxes not shrunk to their
    points: built twice as fast (armadillo, 90,556 points: 27 -> 13 ms), the same points
    found (the moves use them as a set).
    """
    return cKDTree(points, balanced_tree=False, compact_nodes=False)


def _mesh_nearest(
    v: NDArray[np.float64], f: NDArray[np.intp]
) -> Callable[[NDArray[np.float64]], tuple[NDArray[np.float64], NDArray[np.intp]]]:
    """Nearest points (m, 3) of the mesh ``(v, f)`` and their triangles (m,), one BVH for all calls.

    The core's surface when it takes the mesh (a manifold, consistently oriented, no
    degenerate triangle), else :func:`hcvt._core.closest_points` (a BVH each call).
    """
    faces = f.astype(np.uint32)
    try:
        return _core.SurfaceDomain(v, faces).closest
    except InvalidDomainError:
        return partial(_core.closest_points, v, faces)


def _to_triangles(
    points: NDArray[np.float64], corners: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Distances of ``points`` (m, 3) to the nearest of the triangles ``corners`` (k, 3, 3).

    Returns the distances (m,) and the nearest triangle of each (m,), by the core's BVH.
    """
    k = len(corners)
    nearest, which = _core.closest_points(
        np.ascontiguousarray(corners.reshape(-1, 3)),
        np.arange(3 * k, dtype=np.uint32).reshape(k, 3),
        np.ascontiguousarray(points),
    )
    return np.linalg.norm(np.asarray(nearest) - points, axis=1), np.asarray(which)


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


class _Mesh:
    """The mesh being moved, the points checked on it and on the input, their distances.

    The distances of the mesh's points to the input are exact (the input does not move);
    those of the input's points to the mesh are upper bounds after a move (over the moved
    vertex's two-ring), made exact by :meth:`worst` before the largest is used.
    """

    def __init__(
        self,
        vertices: NDArray[np.float64],
        faces: NDArray[np.intp],
        surface: Domain,
        samples: int,
        rng: np.random.Generator,
    ) -> None:
        self.v = np.array(vertices, dtype=np.float64)
        self.f = np.asarray(faces, dtype=np.intp)
        self.surface = surface
        # The input's vertices and triangles, kept (the domain copies them at each reading).
        self.rv, self.rf = rv, rf = surface.vertices, surface.faces
        # Vertex -> its triangles (CSR).
        order = np.argsort(self.f.ravel(), kind="stable")
        self.ring_start = np.searchsorted(self.f.ravel()[order], np.arange(len(self.v) + 1))
        self.ring_faces = order // 3
        # Points of the input (samples, its vertices, points along its edges) and their
        # distances to the mesh.
        points, self.sample_faces = sample_by_area(rv, rf, samples, rng)
        edges = _creases(rv, rf)
        along = _along_creases(rv[edges], _CREASE_STEP * _mean_edge(self.v, self.f))
        self.input_vertices = np.flatnonzero(np.bincount(rf.ravel(), minlength=len(rv)))
        self.s = np.concatenate([points, rv[self.input_vertices], along])
        self.s_tree = _tree(self.s)  # of these points; :meth:`refine`'s join unindexed
        self.in_tree = len(self.s)
        self.ds, self.s_face = _to_triangles(self.s, self.v[self.f])
        self.ds_exact = np.ones(len(self.s), dtype=bool)
        # The checked points of every triangle (the grid, and one more, its centroid until
        # :meth:`refine` finds a farther one) and their distances to the input.
        self.extra = np.full((len(self.f), 3), 1.0 / 3.0)
        # For :meth:`refine`: the step of its grid on the input's triangles.
        self.spacing = _mean_edge(self.v, self.f) / _REFINE_STEPS
        self.dt = self.initial_distances()

    def initial_distances(self) -> NDArray[np.float64]:
        """Distances (f, 13) of every triangle's checked points to the input, in one call.

        A point on an edge is the same for the edge's two triangles: asked once (13 points a
        triangle, 8.5 of them distinct on a closed mesh; armadillo, n = 5,000: 85,000
        points instead of 130,000).
        """
        grid = np.vstack([_GRID, self.extra[:1]])  # the extra point: the centroid here
        corners = self.v[self.f]
        out = np.empty((len(self.f), len(grid)))
        inner = np.flatnonzero((grid > 0).all(axis=1))
        out[:, inner] = self.to_input(np.einsum("gk,fkd->fgd", grid[inner], corners))
        # Each edge point keyed by its edge's ends (smaller first) and its step from the
        # smaller one: (a·n + b)·(steps + 1) + i.
        edge = np.flatnonzero(~(grid > 0).all(axis=1))
        ends = np.argsort(grid[edge] == 0, axis=1, kind="stable")[:, :2]  # its two corners
        a, b = self.f[:, ends[:, 0]], self.f[:, ends[:, 1]]  # (f, edge points)
        low, high = np.minimum(a, b), np.maximum(a, b)
        weight = np.where(a == high, grid[edge, ends[:, 0]], grid[edge, ends[:, 1]])
        step = np.rint(weight * _GRID_STEPS).astype(np.int64)
        key = (low.astype(np.int64) * len(self.v) + high) * (_GRID_STEPS + 1) + step
        keys, first, back = np.unique(key.ravel(), return_index=True, return_inverse=True)
        t = (step.ravel()[first] / _GRID_STEPS)[:, None]
        points = (1.0 - t) * self.v[low.ravel()[first]] + t * self.v[high.ravel()[first]]
        out[:, edge] = self.to_input(points)[back].reshape(low.shape)
        return out

    def triangle_points(
        self, faces: NDArray[np.intp], v: NDArray[np.float64]
    ) -> NDArray[np.float64]:
        """The checked points (len(faces), 13, 3) of these triangles with vertices ``v``."""
        corners = v[self.f[faces]]
        extra = np.einsum("fk,fkd->fd", self.extra[faces], corners)
        return np.concatenate([np.einsum("gk,fkd->fgd", _GRID, corners), extra[:, None]], 1)

    def ring(self, a: int) -> NDArray[np.intp]:
        """The triangles around vertex ``a``."""
        return self.ring_faces[self.ring_start[a] : self.ring_start[a + 1]]

    def around(self, vertices: NDArray[np.intp]) -> NDArray[np.intp]:
        """The triangles around any of ``vertices`` (sorted, once each)."""
        if len(vertices) == 1:  # a vertex's own ring is sorted, once each (a stable sort)
            return self.ring(int(vertices[0]))
        return np.unique(np.concatenate([self.ring(b) for b in vertices]))

    def neighbours(self, a: int) -> NDArray[np.intp]:
        """The vertices sharing a triangle with ``a``, not ``a`` itself."""
        near = np.unique(self.f[self.ring(a)])
        return near[near != a]

    def near(self, centre: NDArray[np.float64], radius: float) -> NDArray[np.intp]:
        """The input's points within ``radius`` of ``centre`` (3,): their indices.

        Through the k-d tree for the points of the start, one by one for the few that
        :meth:`refine` added (a new tree of all cost 14 ms a round on the armadillo).
        """
        found = np.asarray(self.s_tree.query_ball_point(centre, radius), dtype=np.intp)
        added = self.s[self.in_tree :]
        if len(added) == 0:
            return found
        close = np.einsum("ij,ij->i", added - centre, added - centre) <= radius * radius
        return np.concatenate([found, self.in_tree + np.flatnonzero(close)])

    def to_input(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """Distances (f, g) of points (f, g, 3) to the input."""
        flat = points.reshape(-1, 3)
        d = np.linalg.norm(_on_input(self.surface, flat) - flat, axis=1)
        return d.reshape(points.shape[:-1])

    def project(self, point: NDArray[np.float64]) -> NDArray[np.float64]:
        """The nearest point of the input to ``point`` (3,)."""
        return _on_input(self.surface, point[None])[0]

    def worst(self) -> tuple[float, str, int]:
        """The largest distance (exact), which side it is on, and its point's index."""
        while True:
            i, j = int(np.argmax(self.ds)), int(np.argmax(self.dt))
            if self.ds[i] < self.dt.flat[j]:
                return float(self.dt.flat[j]), "mesh", j
            if self.ds_exact[i]:
                return float(self.ds[i]), "input", i
            # The bounds left by the moves that may be the largest (a bound is at least the
            # distance: those below the largest exact one cannot be), exact in one call.
            exact = self.ds.max(where=self.ds_exact, initial=0.0)
            self.make_exact(max(float(self.dt.flat[j]), float(exact)))

    def make_exact(self, least: float) -> None:
        """The distances to the mesh held as bounds and reaching ``least``, exact in one call."""
        stale = np.flatnonzero(~self.ds_exact & (self.ds >= least))
        if len(stale) == 0:
            return
        # Only the triangles whose boxes meet the points' box widened by their largest
        # bound: a point's nearest triangle is no farther than its bound, so its nearest
        # point lies in that box (the same answers, ties to the least index as over all;
        # the BVH of all 10,000 triangles of the armadillo at 5,000 cost 2.6 ms a call).
        points = self.s[stale]
        reach = float(self.ds[stale].max())
        low, high = points.min(axis=0) - reach, points.max(axis=0) + reach
        a, b, c = (self.v[self.f[:, k]] for k in range(3))
        meets = (np.maximum(np.maximum(a, b), c) >= low) & (np.minimum(np.minimum(a, b), c) <= high)
        local = np.flatnonzero(meets.all(axis=1))
        self.ds[stale], which = _to_triangles(points, self.v[self.f[local]])
        self.s_face[stale] = local[which]
        self.ds_exact[stale] = True

    def refine(self, worst: float) -> float:
        """Search the triangles near the worst distance finer (:data:`_REFINE_SHARE`).

        Returns the largest distance found (0 if none was searched).
        """
        bar = _REFINE_SHARE * worst
        found = 0.0
        rv, rf = self.rv, self.rf
        # The mesh's triangles: the farthest point of each becomes its extra point.
        hot = np.flatnonzero(self.dt.max(axis=1) >= bar)
        if len(hot):
            d = self.to_input(np.einsum("gk,fkd->fgd", _FINE, self.v[self.f[hot]]))
            g = np.argmax(d, axis=1)
            top = d[np.arange(len(hot)), g]
            self.extra[hot], self.dt[hot, -1] = _FINE[g], top
            # And the farthest point of them all, exactly (a peak between the grid's points),
            # from the input's triangles within reach of them.
            _, point, _ = hausdorff_one_sided(
                (self.v, self.f[hot]), (rv, rf), nearest=partial(_nearest_on_input, self.surface)
            )
            far = float(self.to_input(point[None])[0])
            _, which = _core.closest_points(
                self.v, self.f[hot].astype(np.uint32), np.ascontiguousarray(point[None])
            )
            face = int(hot[int(which[0])])
            if far > self.dt[face, -1]:
                corners = self.v[self.f[face]]
                weights = np.linalg.lstsq(corners.T, point, rcond=None)[0]
                self.extra[face], self.dt[face, -1] = weights / weights.sum(), far
            found = max(float(top.max()), far)
        # The input's triangles with a point near the worst distance (a sample in it, or
        # a corner): their farthest points join the input's points.
        n_samples = len(self.sample_faces)
        self.make_exact(bar)  # (the bounds below it cannot be hot)
        hot_points = self.ds >= bar
        corner = np.zeros(len(rv), dtype=bool)
        corner[self.input_vertices] = hot_points[n_samples : n_samples + len(self.input_vertices)]
        faces = np.union1d(
            self.sample_faces[hot_points[:n_samples]], np.flatnonzero(corner[rf].any(1))
        )
        if len(faces):
            # On a grid as fine as the mesh's (:func:`_fine_points`), through one BVH of the
            # mesh (the exact search asks it many times).
            on_mesh_of = _mesh_nearest(self.v, self.f)
            points, owner = _fine_points(rv[rf[faces]], self.spacing)
            on_mesh, _ = on_mesh_of(points)
            d = np.linalg.norm(np.asarray(on_mesh) - points, axis=1)
            order = np.lexsort((-d, owner))
            first = order[np.flatnonzero(np.diff(owner[order], prepend=-1))]
            # And the farthest point of them all, exactly.
            _, peak, _ = hausdorff_one_sided((rv, rf[faces]), (self.v, self.f), nearest=on_mesh_of)
            new = np.vstack([points[first], peak])
            on_mesh, which = on_mesh_of(new)
            d = np.linalg.norm(np.asarray(on_mesh) - new, axis=1)
            self.s = np.concatenate([self.s, new])  # not in the tree: :meth:`near`
            self.ds = np.concatenate([self.ds, d])
            self.s_face = np.concatenate([self.s_face, np.asarray(which)])
            self.ds_exact = np.concatenate([self.ds_exact, np.ones(len(new), dtype=bool)])
            found = max(found, float(d.max()))
        return found


#: Where no vertex can move alone, its neighbours follow it by this fraction of its shift.
_DRAG = 0.5
#: Sweeps of the ring's evening out where neither the vertex alone nor dragging its
#: neighbours passes (:func:`_relaxed`). Bunny, n = 20,000, seed 0 (the 30° floor binds:
#: every candidate's least angle falls to 28.4-29.4° at 1/8 of the way): tighten's
#: Hausdorff 0.159 -> 0.152% (0.141% with :data:`_REFINE_AGAIN`); seeds 1-3, armadillo,
#: kitten, fandisk 5,000 and kitten 20,000 unchanged (seed 0, tighten alone).
_RELAX_SWEEPS = 2
#: Fractions of the way to a target tried for a vertex, the whole way first.
_STEPS = (1.0, 0.75, 0.5, 0.25, 0.125)


def _candidates(
    mesh: _Mesh, side: str, index: int, movable: NDArray[np.bool_]
) -> Iterator[tuple[int, NDArray[np.float64]]]:
    """Moves that may lower the distance at the worst point.

    (vertex, new positions (len(_STEPS), 3) before projection, the longest move first),
    one kind of move of one vertex each. A point ``P`` of the input: its nearest
    triangle's vertices toward ``P``. A point ``Q`` of the mesh: its triangle's vertices
    by ``Q* − Q`` (nearly along the normal: it moves little once projected), then toward
    ``Q*`` (along the surface: a vertex into the hollow the triangle spans).
    """
    if side == "input":
        target = mesh.s[index]
        corners = mesh.f[mesh.s_face[index]]
    else:
        face, g = divmod(index, mesh.dt.shape[1])
        point = mesh.triangle_points(np.array([face]), mesh.v)[0, g]
        target = mesh.project(point)
        corners = mesh.f[face]
    steps = np.array(_STEPS)[:, None]
    for a in corners:
        if movable[a]:
            if side == "mesh":
                yield int(a), mesh.v[a] + steps * (target - point)
            yield int(a), mesh.v[a] + steps * (target - mesh.v[a])


#: What a passing move changes: (ring faces, their points' distances to the input, input
#: points near it, their distances to the mesh, their nearest faces).
_Update = tuple[
    NDArray[np.intp], NDArray[np.float64], NDArray[np.intp], NDArray[np.float64], NDArray[np.intp]
]


def _shapes_pass(
    mesh: _Mesh, moved: NDArray[np.intp], xs: NDArray[np.float64], floors: tuple[float, float]
) -> NDArray[np.bool_]:
    """Which of the moves of vertices ``moved`` (k,) to ``xs`` (s, k, 3) keep the shapes (s,).

    Every triangle around them keeps its least angle and Q at ``floors`` (degrees, Q) or
    above and turns its normal by less than 60°; the ``s`` moves at once.
    """
    tri = mesh.f[mesh.around(moved)]
    corners, local = np.unique(tri, return_inverse=True)
    count, size = len(xs), len(corners)
    positions = np.repeat(mesh.v[corners][None], count, axis=0)
    positions[:, np.searchsorted(corners, moved)] = xs
    flat = positions.reshape(-1, 3)
    faces = (local.reshape(-1, 3)[None] + size * np.arange(count)[:, None, None]).reshape(-1, 3)
    angle = triangle_angles(flat, faces).reshape(count, -1).min(axis=1)
    quality = triangle_quality(flat, faces).reshape(count, -1).min(axis=1)
    after = _normals(flat, faces).reshape(count, -1, 3)
    cosine = np.einsum("stj,tj->st", after, _normals(mesh.v, tri)).min(axis=1)
    return (angle >= floors[0]) & (quality >= floors[1]) & (cosine >= _MIN_NORMAL_COSINE)


def _try(
    mesh: _Mesh,
    moved: NDArray[np.intp],
    x: NDArray[np.float64],
    worst: float,
    limit: float,
) -> _Update | None:
    """The move of vertices ``moved`` (k,) to ``x`` (k, 3) if its distances pass, else None.

    Its shapes passed (:func:`_shapes_pass`); ``worst``: the worst distance now;
    ``limit``: what every distance around the move must fall below.
    """
    ring = mesh.around(moved)
    v = mesh.v  # moved in place below, put back in `finally`
    old = v[moved].copy()
    tri = mesh.f[ring]
    v[moved] = x
    try:
        dt = mesh.to_input(mesh.triangle_points(ring, v))
        if dt.max() >= limit:
            return None
        # Input points whose distance may change: within reach of the ring, before or
        # after the move.
        corners = np.vstack([v[np.unique(tri)], old])
        centre = corners.mean(axis=0)
        radius = float(np.linalg.norm(corners - centre, axis=1).max())
        near = mesh.near(centre, radius + worst)
        if len(near) == 0:
            return ring, dt, near, np.zeros(0), np.zeros(0, dtype=np.intp)
        # Bounds first: a point nearest a triangle off the ring keeps its bound; one nearest
        # a ring triangle is at most the vertices' largest shift farther (every point of
        # the triangle moves by at most that). Only those whose bound reaches the ring's
        # own largest distance can raise the move's peak or fail it: they are asked.
        faces = mesh.s_face[near]
        shift = float(np.linalg.norm(x - old, axis=1).max())
        d = np.where(np.isin(faces, ring), mesh.ds[near] + shift, mesh.ds[near])
        ask = np.flatnonzero(d >= dt.max())
        if len(ask):
            local = mesh.around(np.unique(tri))
            exact, which = _to_triangles(mesh.s[near[ask]], v[mesh.f[local]])
            # Off the ring before: the old bound still holds; keep the smaller.
            smaller = exact < d[ask]
            d[ask[smaller]] = exact[smaller]
            faces[ask[smaller]] = local[which[smaller]]
        if d.max(initial=0.0) >= limit:
            return None
        return ring, dt, near, d, faces
    finally:
        v[moved] = old


def _best_move(
    mesh: _Mesh,
    side: str,
    index: int,
    movable: NDArray[np.bool_],
    floors: tuple[float, float],
    worst: float,
    neighbours: str,
) -> tuple[NDArray[np.intp], NDArray[np.float64], _Update] | None:
    """The passing move (vertices, positions, update) that leaves the least distance around it.

    Each candidate of :func:`_candidates` moves its vertex; its neighbours (all movable)
    stay (``neighbours="stay"``), follow by :data:`_DRAG` times its shift, projected onto
    the input (``"drag"``: a patch moved nearly whole, where the vertex alone would spoil
    its triangles), or move to the mean of their own neighbours, projected, in
    :data:`_RELAX_SWEEPS` sweeps (``"relax"``: the ring evened out around the vertex's new
    place, where neither passes).
    """
    limit = worst * (1.0 - _GAIN)
    best = None
    for a, toward in _candidates(mesh, side, index, movable):
        moved = np.array([a], dtype=np.intp)
        towards = toward[:, None]  # (steps, moved, 3)
        if neighbours != "stay":
            around = mesh.neighbours(a)
            if not movable[around].all():
                continue
            moved = np.concatenate([moved, around])
        if neighbours == "drag":
            follow = mesh.v[around][None] + _DRAG * (toward - mesh.v[a])[:, None]
            towards = np.concatenate([towards, follow], axis=1)
        xs = _on_input(mesh.surface, towards.reshape(-1, 3)).reshape(towards.shape)
        if neighbours == "relax":
            xs = np.stack([_relaxed(mesh, a, around, x) for x in xs[:, 0]])
        # The longest move that passes; its shorter ones are not tried.
        for step in np.flatnonzero(_shapes_pass(mesh, moved, xs, floors)):
            found = _try(mesh, moved, xs[step], worst, limit)
            if found is None:
                continue
            peak = max(float(found[1].max()), float(found[3].max(initial=0.0)))
            if best is None or peak < best[0]:
                best = (peak, moved, xs[step], found)
            break
    return None if best is None else best[1:]


def _relaxed(
    mesh: _Mesh, a: int, around: NDArray[np.intp], x: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Vertex ``a`` at ``x`` (3,), its neighbours ``around`` (k,) evened out: (k + 1, 3).

    Each neighbour moves to the mean of its own neighbours, projected onto the input,
    :data:`_RELAX_SWEEPS` times (all at once each time).
    """
    rings = [mesh.neighbours(b) for b in around]
    positions = mesh.v.copy()
    positions[a] = x
    for _ in range(_RELAX_SWEEPS):
        means = np.array([positions[ring].mean(axis=0) for ring in rings])
        positions[around] = _on_input(mesh.surface, means)
    return np.vstack([x, positions[around]])


def _normals(v: NDArray[np.float64], tri: NDArray[np.intp]) -> NDArray[np.float64]:
    n = cross_rows(v[tri[:, 1]] - v[tri[:, 0]], v[tri[:, 2]] - v[tri[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]


def check_min_angle(min_angle: float | None) -> float | None:
    """``min_angle`` as a float in [0, 60] degrees (None passes).

    Raises
    ------
    ValueError
        Not a number, not finite, or outside [0, 60] (no triangle's least angle exceeds 60°).
    """
    if min_angle is None:
        return None
    if isinstance(min_angle, bool) or not isinstance(min_angle, (int, float, np.number)):
        raise ValueError(
            f"min_angle must be a number of degrees in [0, 60] or None, not {min_angle!r}"
        )
    angle = float(min_angle)
    if not 0.0 <= angle <= 60.0:  # NaN fails too
        raise ValueError(
            f"min_angle must be in [0, 60] degrees (a triangle's least angle is at most 60°), "
            f"got {min_angle!r}"
        )
    return angle


def tighten(
    vertices: NDArray[np.float64],
    faces: NDArray[np.intp],
    surface: Domain,
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
    surface : Domain
        The input surface (:meth:`hcvt.Domain.from_surface`), whose BVH answers the
        nearest points on it.
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
    if not surface.is_surface:
        raise ValueError("tighten takes the input as a surface (hcvt.Domain.from_surface)")
    floor_angle = check_min_angle(min_angle)
    rng = np.random.default_rng(seed)
    mesh = _Mesh(vertices, faces, surface, samples, rng)
    movable = np.ones(len(mesh.v), dtype=bool)
    if fixed is not None:
        movable &= ~np.asarray(fixed, dtype=bool)
    pairs, counts = edge_counts(mesh.f)
    movable[pairs[counts == 1].ravel()] = False  # border vertices stay on the border
    least = float(triangle_angles(mesh.v, mesh.f).min())
    floors = (
        least if floor_angle is None else floor_angle,
        float(triangle_quality(mesh.v, mesh.f).min()),
    )
    before = mesh.worst()[0]
    # Below this the distances are round-off (a flat part, a mesh already on the input).
    negligible = _NEGLIGIBLE * float(np.linalg.norm(np.ptp(mesh.rv, axis=0)))
    moves = rounds = 0
    allowed = _REFINE_ROUNDS
    while moves < max_moves:
        worst, side, index = mesh.worst()
        if worst <= negligible:
            break
        for neighbours in ("stay", "drag", "relax"):
            best = _best_move(mesh, side, index, movable, floors, worst, neighbours)
            if best is not None:
                break
        if best is None:
            if rounds < allowed:
                rounds += 1
                found = mesh.refine(worst)
                if found > _REFINE_AGAIN * worst:  # the checked points too sparse there
                    allowed = min(allowed + 1, _REFINE_MOST)
                if found > worst:
                    continue  # a farther place was missed: work on it
            break  # the worst place cannot be improved: the distance is what it is
        moved, x, (ring, dt, near, d, near_faces) = best
        mesh.v[moved] = x
        mesh.dt[ring] = dt
        mesh.ds[near], mesh.s_face[near] = d, near_faces
        mesh.ds_exact[near] = False  # over the triangles around the move only: bounds
        moves += 1
    return TightenResult(mesh.v, moves, before, mesh.worst()[0])


__all__ = ["TightenResult", "check_min_angle", "tighten"]
