"""Points on a triangle surface: uniform random samples by area, and nearest points.

Used by :func:`hcvt.initialise` on a surface (exactly ``n`` sites, random by area), by
:func:`hcvt.cvt` on a surface (its sites move freely in space and are projected onto the
surface at the end, as in Yan et al. 2009) and by :func:`hcvt.surface_quality` (Hausdorff
distances, bounded by the distances to single triangles). The nearest points come from the
core's BVH (``_core.closest_points``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

import hcvt._core as _core


def cross_rows(u: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.float64]:
    """``u × w`` row by row, both (m, 3).

    :func:`numpy.cross`'s products and differences, bit for bit, without its axis handling
    (which dominates for the few rows of a ring).
    """
    out = np.empty(u.shape)
    out[:, 0] = u[:, 1] * w[:, 2] - u[:, 2] * w[:, 1]
    out[:, 1] = u[:, 2] * w[:, 0] - u[:, 0] * w[:, 2]
    out[:, 2] = u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0]
    return out


def triangle_areas(vertices: NDArray[np.float64], faces: NDArray[np.intp]) -> NDArray[np.float64]:
    """Area of each triangle (F,), from vertices (V, 3) and faces (F, 3)."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return 0.5 * np.linalg.norm(cross_rows(b - a, c - a), axis=1)


def sample_by_area(
    vertices: NDArray[np.float64],
    faces: NDArray[np.intp],
    n: int,
    rng: np.random.Generator,
    weights: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """``n`` points uniform by area on the triangles, and the triangle of each (n,).

    A triangle is drawn with probability proportional to its area (times its entry of
    ``weights`` (F,), if given), then a point uniform in it (:func:`points_by_area` of
    three uniform streams).
    """
    u = rng.random(n)
    u = np.column_stack([u, rng.random(n), rng.random(n)])
    return points_by_area(vertices, faces, u, weights)


def points_by_area(
    vertices: NDArray[np.float64],
    faces: NDArray[np.intp],
    u: NDArray[np.float64],
    weights: NDArray[np.float64] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Points of the triangles from ``u`` (m, 3) in the unit cube, and the triangle of each.

    ``u[:, 0]`` picks a triangle by the inverse of the cumulative area (times ``weights``
    (F,), if given), ``u[:, 1:]`` the point in it (the square-root map to barycentric
    coordinates): uniform points give points uniform by area, low-discrepancy ones
    (Halton) spread by area.
    """
    areas = triangle_areas(vertices, faces)
    if weights is not None:
        areas = areas * weights
    cumulative = np.cumsum(areas)
    which = np.searchsorted(cumulative, u[:, 0] * cumulative[-1], side="right")
    which = np.minimum(which, len(faces) - 1)
    r1, r2 = np.sqrt(u[:, 1]), u[:, 2]
    a, b, c = (vertices[faces[which, k]] for k in range(3))
    points = (1.0 - r1)[:, None] * a + (r1 * (1.0 - r2))[:, None] * b + (r1 * r2)[:, None] * c
    return np.ascontiguousarray(points), which


def point_triangle_distances(
    points: NDArray[np.float64],
    a: NDArray[np.float64],
    b: NDArray[np.float64],
    c: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Distance (m,) of each of ``points`` (m, 3) to its triangle ``(a, b, c)`` (m, 3 each).

    The distance to the triangle's plane where the foot lies inside it, else the least
    distance to its three edges (a degenerate triangle: its edges).
    """
    ab, ac, ap = b - a, c - a, points - a
    normal = cross_rows(ab, ac)
    nn = np.einsum("ij,ij->i", normal, normal)
    flat = nn > 0.0
    safe = np.where(flat, nn, 1.0)
    # The foot a + s·ab + t·ac: s, t from the triple products.
    s = np.einsum("ij,ij->i", cross_rows(ap, ac), normal) / safe
    t = np.einsum("ij,ij->i", cross_rows(ab, ap), normal) / safe
    inside = flat & (s >= 0.0) & (t >= 0.0) & (s + t <= 1.0)
    plane = np.abs(np.einsum("ij,ij->i", ap, normal)) / np.sqrt(safe)

    def to_edge(u: NDArray[np.float64], w: NDArray[np.float64]) -> NDArray[np.float64]:
        d = w - u
        dd = np.einsum("ij,ij->i", d, d)
        h = np.clip(np.einsum("ij,ij->i", points - u, d) / np.where(dd > 0.0, dd, 1.0), 0.0, 1.0)
        return np.linalg.norm(points - u - h[:, None] * d, axis=1)

    edges = np.minimum(np.minimum(to_edge(a, b), to_edge(b, c)), to_edge(c, a))
    return np.where(inside, plane, edges)


def closest_points(
    vertices: ArrayLike, faces: ArrayLike, points: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """The nearest point of the triangles to each of ``points`` (m, 3), and its triangle.

    Parameters
    ----------
    vertices : array_like of float, shape (V, 3)
    faces : array_like of int, shape (F, 3)
        Any triangles (no manifold or orientation checks).
    points : array_like of float, shape (m, 3)

    Returns
    -------
    nearest : ndarray, shape (m, 3)
    triangle : ndarray of intp, shape (m,)
    """
    v = np.ascontiguousarray(vertices, dtype=np.float64)
    f = np.ascontiguousarray(faces, dtype=np.uint32)
    p = np.ascontiguousarray(points, dtype=np.float64)
    nearest, triangle = _core.closest_points(v, f, p)
    return np.asarray(nearest), np.asarray(triangle)


__all__ = [
    "closest_points",
    "cross_rows",
    "point_triangle_distances",
    "points_by_area",
    "sample_by_area",
    "triangle_areas",
]
