"""A per-vertex density from a surface's curvature, for curvature-adapted remeshing.

A restricted CVT's cells have dimension 2, so their size follows ``ρ^(-1/4)`` (Gersho,
``ρ ∝ h^-(d+2)``). A mesh whose spacing is ``h ∝ κ^(-a)`` (``κ`` the larger absolute
principal curvature) is given by ``ρ ∝ κ^(4a)``: ``power = 4a``. The deviation of a
chord from the surface is ``κ h² / 8``, equal everywhere for ``a = 1/2`` (``power = 2``);
``power = 1`` (``h ∝ κ^(-1/4)``) is a milder grading that keeps more vertices on the flat
parts.

The curvatures are the discrete ones of Meyer, Desbrun, Schröder and Barr (2003) on
barycentric vertex areas: the mean curvature ``H = |L x · n| / (2 A)`` from the cotangent
Laplacian along the vertex normal, the Gaussian curvature ``K`` from the angle defect (0
at a border vertex, where the defect holds the border's curvature), ``κ = |H| + (max(H² −
K, 0))^(1/2)``; then averaged with the 1-ring
``smooth`` times (the raw values of a scanned mesh are noisy).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse
from numpy.typing import NDArray

from hcvt.geometry.domain import Domain
from hcvt.geometry.surface_points import cross_rows


def _edge_matrix(faces: NDArray[np.intp], n: int) -> scipy.sparse.csr_matrix:
    """(n, n): at (i, j) and (j, i) the number of triangles with the edge ij (1 on a border).

    A sparse sum, not :func:`hcvt.surface.quality.edge_counts`'s sort of the edges
    (armadillo, 346k triangles: most of the density's time).
    """
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    return scipy.sparse.coo_matrix(
        (np.ones(2 * len(edges)), (edges.ravel(), edges[:, ::-1].ravel())), shape=(n, n)
    ).tocsr()


def vertex_curvature(vertices: NDArray[np.float64], faces: NDArray[np.intp]) -> NDArray[np.float64]:
    """``κ``, the larger absolute principal curvature (V,) at each vertex, ``1/L``.

    Discrete (module docs); 0 at a vertex in no triangle.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.intp)
    n = len(v)
    corners = [v[f[:, k]] for k in range(3)]
    face_normal = cross_rows(corners[1] - corners[0], corners[2] - corners[0])  # 2 × area
    double_area = np.linalg.norm(face_normal, axis=1)
    area = np.bincount(f.ravel(), np.repeat(double_area / 6.0, 3), minlength=n)
    laplace = np.zeros((n, 3))
    angle_sum = np.zeros(n)
    for k in range(3):
        # The corner at vertex k, between the edges to k + 1 and k + 2.
        i, j, m = f[:, k], f[:, (k + 1) % 3], f[:, (k + 2) % 3]
        u, w = v[j] - v[i], v[m] - v[i]
        cos = np.einsum("ij,ij->i", u, w)
        sin = np.linalg.norm(cross_rows(u, w), axis=1)
        angle_sum += np.bincount(i, np.arctan2(sin, cos), minlength=n)
        # The cotangent at vertex k weighs the opposite edge (j, m).
        half_cot = 0.5 * cos / np.maximum(sin, np.finfo(float).tiny)
        edge = (v[m] - v[j]) * half_cot[:, None]
        for axis in range(3):
            laplace[:, axis] += np.bincount(j, edge[:, axis], minlength=n)
            laplace[:, axis] -= np.bincount(m, edge[:, axis], minlength=n)
    # A border vertex's angles sum to π on a flat sheet, an inner one's to 2π.
    edges = _edge_matrix(f, n).tocoo()
    border = np.zeros(n, dtype=bool)
    border[edges.row[edges.data == 1]] = True
    # The Laplacian's part along the vertex normal (at a border vertex it has an in-plane
    # part, the border's own curvature, even on a flat sheet).
    normal = np.zeros((n, 3))
    for k in range(3):
        for axis in range(3):
            normal[:, axis] += np.bincount(f[:, k], face_normal[:, axis], minlength=n)
    normal /= np.maximum(np.linalg.norm(normal, axis=1), np.finfo(float).tiny)[:, None]
    safe = np.where(area > 0, area, 1.0)
    mean = np.abs(np.einsum("ij,ij->i", laplace, normal)) / (2.0 * safe)
    # A border vertex's angle defect holds the border's curvature too: K taken as 0 there.
    gauss = np.where(border, 0.0, (2.0 * np.pi - angle_sum) / safe)
    kappa = mean + np.sqrt(np.maximum(mean * mean - gauss, 0.0))
    return np.where(area > 0, kappa, 0.0)


def curvature_density(
    surface: Domain, power: float = 1.0, *, floor: float = 1.0, smooth: int = 5
) -> NDArray[np.float64]:
    """A per-vertex density ``ρ = (floor + κ / κ̄)^power`` for ``density=`` on ``surface``.

    Parameters
    ----------
    surface : Domain
        A triangle surface (:meth:`hcvt.Domain.from_surface`).
    power : float
        ``4a`` for a spacing ``h ∝ κ^(-a)`` where the curvature dominates (module docs):
        2 makes the chords' deviation from the surface even, 1 (the default) is milder.
    floor : float
        Added to the scaled curvature: ``ρ ≥ floor^power`` on flat parts, > 0.
    smooth : int
        Passes of averaging each vertex's ``κ`` with the mean of its neighbours'.

    Returns
    -------
    ndarray, shape (V,)
        One value per vertex of the surface, finite and positive; ``κ̄`` is the
        area-weighted mean of ``κ`` (the density does not depend on the surface's scale).

    Examples
    --------
    >>> import hcvt, numpy as np, trimesh
    >>> ball = trimesh.creation.icosphere(3)  # κ = κ̄ = 1 nearly everywhere: ρ ≈ 1 + 1
    >>> rho = hcvt.surface.curvature_density(hcvt.Domain.from_surface(ball.vertices, ball.faces))
    >>> bool(np.allclose(rho, 2.0, rtol=0.03))
    True
    """
    if not surface.is_surface:
        raise ValueError("curvature_density takes a surface (hcvt.Domain.from_surface)")
    if not (np.isfinite(power) and np.isfinite(floor) and floor > 0):
        raise ValueError(f"power must be finite and floor > 0, got {power!r}, {floor!r}")
    if isinstance(smooth, bool) or not isinstance(smooth, int) or smooth < 0:
        raise ValueError(f"smooth must be an int >= 0, got {smooth!r}")
    vertices = np.asarray(surface.vertices, dtype=np.float64)
    faces = np.asarray(surface.faces, dtype=np.intp)
    n = len(vertices)
    kappa = vertex_curvature(vertices, faces)
    ring = _edge_matrix(faces, n)
    ring.data[:] = 1.0  # each neighbour once (an edge is in two triangles)
    degree = np.maximum(np.asarray(ring.sum(axis=1)).ravel(), 1.0)
    for _ in range(smooth):
        kappa = 0.5 * (kappa + (ring @ kappa) / degree)
    corners = vertices[faces]
    area = 0.5 * np.linalg.norm(
        cross_rows(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    mean = float(np.sum(area * kappa[faces].mean(axis=1)) / np.sum(area))
    scaled = kappa / mean if mean > 0 else np.zeros(n)
    return np.ascontiguousarray((floor + scaled) ** power)


__all__ = ["curvature_density", "vertex_curvature"]
