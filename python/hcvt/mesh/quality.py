"""Mesh quality as OpenFOAM's ``checkMesh`` measures it.

Cell volume, face non-orthogonality and skewness, computed once in the core
(``hcvt._core.mesh_quality``, crates/hcvt-core/src/quality.rs) from the mesh's arrays: every
figure depends on the mesh's bits alone, not on numpy's summation order or the thread count.

Definitions (OpenFOAM ``primitiveMeshTools``; centres as in
:attr:`hcvt.mesh.polymesh.PolyMesh.face_geometry` and ``cell_geometry``, which follow it):

- **non-orthogonality** of an interior face: the angle, in degrees, between its area
  vector ``S`` and ``d = C_N - C_P``, the segment from the owner's centroid to the
  neighbour's. 0 for a Voronoi face whose cells' centroids are their sites (a CVT).
- **skewness** of an interior face: how far ``d`` misses the face centre ``c_f``. With
  ``s = (c_f - C_P) - (S·(c_f - C_P) / S·d) d`` (from the point where ``d`` crosses the
  face's plane to the face centre), skewness ``|s| / max(0.2 |d|, max_v |ŝ·(v - c_f)|)``
  over the face's vertices ``v``: ``|s|`` relative to the face's extent in that direction.
  A boundary face takes ``d`` as the normal projection of ``c_f - C_P`` and ``0.4 |d|``
  (as if mirrored across the face). ``checkMesh`` flags faces above 4.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from hcvt.mesh.polymesh import PolyMesh

#: checkMesh's thresholds: non-orthogonality (degrees) and skewness it reports as bad, and
#: the cell aspect ratio above which it fails the mesh ("High aspect ratio cells").
NON_ORTHOGONALITY_LIMIT = 70.0
SKEWNESS_LIMIT = 4.0
ASPECT_RATIO_LIMIT = 1000.0

#: Skewness a face must not exceed to be sure to pass: checkMesh's limit 4 less a margin
#: far above the 1e-9 by which our figures and checkMesh's printed ones have been seen to
#: differ, so that a face we pass at 3.999999 is not failed by OpenFOAM's rounding.
SKEWNESS_TARGET = SKEWNESS_LIMIT * (1.0 - 1e-6)


@dataclass(frozen=True)
class MeshQuality:
    """Per-cell and per-face quality of a mesh (see module docs for definitions).

    Attributes
    ----------
    volume : ndarray, shape (n,)
        Cell areas (2D) or volumes (3D) from the faces, L^d (0 for an empty cell).
    non_orthogonality : ndarray, shape (f,)
        Degrees, for interior faces; NaN on boundary faces.
    skewness : ndarray, shape (f,)
        Dimensionless, every face.
    aspect_ratio : ndarray, shape (n,)
        checkMesh's aspect ratio of each cell (:func:`cell_aspect_ratio`).
    inverted_pyramid : ndarray of bool, shape (f,)
        Whether the cone from a cell's centroid over this face has negative volume on
        either side (checkMesh's "face pyramids" error): the centroid lies beyond the
        face's plane, as in a cell that wraps around a reflex corner of the domain.
    interior : ndarray of bool, shape (f,)
        Whether each face lies between two cells.
    """

    volume: NDArray[np.float64]
    aspect_ratio: NDArray[np.float64]
    non_orthogonality: NDArray[np.float64]
    skewness: NDArray[np.float64]
    inverted_pyramid: NDArray[np.bool_]
    interior: NDArray[np.bool_]
    volume_ratio: NDArray[np.float64] | None = None
    """Shape (f,): smaller over larger volume of an interior face's two cells (OpenFOAM's
    ``minVolRatio``), NaN on boundary faces; a small cell beside large ones scores low
    (issue 30: parts at 3.5e-3 of their neighbours stalled laplacianFoam)."""

    def summary(self) -> dict[str, Any]:
        """Figures in the style of ``checkMesh``, as plain numbers for JSON.

        ``volume_min``, ``volume_max``, ``volume_total`` (non-empty cells),
        ``non_orthogonality_max``, ``non_orthogonality_average`` (interior faces; the
        angle of the mean cosine, as checkMesh prints it),
        ``skewness_max``, and the counts of faces beyond checkMesh's limits and of faces
        with an inverted pyramid; ``volume_ratio_min``, the smallest cell against its
        neighbour (1 without interior faces).
        """
        cells = self.volume[self.volume > 0]
        angle = self.non_orthogonality[self.interior]
        # Sums by math.fsum: correctly rounded, so in no order of numpy's either.
        cosine = np.cos(np.radians(angle))
        return {
            "cells": int(len(cells)),
            "faces": int(len(self.skewness)),
            "volume_min": float(cells.min()) if len(cells) else 0.0,
            "volume_max": float(cells.max()) if len(cells) else 0.0,
            "volume_total": math.fsum(cells),
            "non_orthogonality_max": float(angle.max()) if len(angle) else 0.0,
            # checkMesh's "average": the angle of the mean cosine, not the mean angle.
            "non_orthogonality_average": (
                math.degrees(math.acos(math.fsum(cosine) / len(cosine))) if len(angle) else 0.0
            ),
            "non_orthogonal_faces": int((angle > NON_ORTHOGONALITY_LIMIT).sum()),
            "skewness_max": float(self.skewness.max()) if len(self.skewness) else 0.0,
            "skew_faces": int((self.skewness > SKEWNESS_LIMIT).sum()),
            "inverted_pyramids": int(self.inverted_pyramid.sum()),
            "aspect_ratio_max": float(self.aspect_ratio.max()) if len(cells) else 0.0,
            "high_aspect_cells": int((self.aspect_ratio > ASPECT_RATIO_LIMIT).sum()),
            "volume_ratio_min": _min_ratio(self.volume_ratio, self.interior),
        }


def mesh_quality(mesh: PolyMesh) -> MeshQuality:
    """Cell volumes, face non-orthogonality and skewness of ``mesh`` (module docs).

    A thin wrapper: the figures are those the core measured once for the mesh
    (:attr:`PolyMesh.measured <hcvt.mesh.polymesh.PolyMesh.measured>`), which also serve
    its ``face_geometry`` and ``cell_geometry``.

    Raises
    ------
    InvalidMeshError
        The mesh's arrays are malformed (an index out of range, a face with the wrong
        number of vertices, a non-finite point); the message names the first offender.

    Examples
    --------
    A grid of boxes is orthogonal and unskewed:

    >>> import numpy as np
    >>> from hcvt.mesh.polymesh import PolyMesh
    >>> pts = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]], dtype=float)
    >>> edges = [[1, 4], [0, 1], [4, 3], [3, 0], [1, 2], [2, 5], [5, 4]]
    >>> m = PolyMesh(pts, np.arange(0, 15, 2), np.array(edges).ravel(),
    ...              owner=np.array([0, 0, 0, 0, 1, 1, 1]),
    ...              neighbour=np.array([1, -1, -1, -1, -1, -1, -1]),
    ...              boundary_element=np.array([-1, 0, 1, 2, 0, 3, 1]), n_cells=2)
    >>> q = mesh_quality(m)
    >>> q.non_orthogonality[0], q.skewness.max()
    (np.float64(0.0), np.float64(0.0))
    """
    m = mesh.measured
    return MeshQuality(
        volume=m["volume"],
        aspect_ratio=m["aspect_ratio"],
        non_orthogonality=m["non_orthogonality"],
        skewness=m["skewness"],
        inverted_pyramid=m["inverted_pyramid"],
        interior=mesh.interior,
        volume_ratio=m["volume_ratio"],
    )


def cell_aspect_ratio(mesh: PolyMesh) -> NDArray[np.float64]:
    """The aspect ratio checkMesh gives each cell, shape (n,) (0 for a cell with no faces).

    OpenFOAM's ``primitiveMeshTools::cellClosedness``: with ``s`` the sum over a cell's
    faces of the absolute components of their area vectors, ``max(s) / min(s)``, and in 3D
    at least ``(s_x + s_y + s_z) / 6 / V^(2/3)``. 1 for an axis-aligned cube or square;
    checkMesh fails a mesh with a cell above :data:`ASPECT_RATIO_LIMIT` (a sliver). A 2D
    mesh is measured as OpenFOAM measures its one-cell-thick extrusion (the empty
    direction left out).
    """
    return mesh.measured["aspect_ratio"]


def face_quality(
    mesh: PolyMesh, centroid: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]:
    """Non-orthogonality, skewness and inverted pyramids of the faces of ``mesh``.

    As :func:`mesh_quality`, but measured against the cell centres ``centroid`` (shape
    (n, d)) given: :mod:`hcvt.mesh.merge` measures candidate faces with it before it
    makes them. Returns the three per-face arrays of :class:`MeshQuality`.
    """
    m = mesh.measure(centroid)
    return m["non_orthogonality"], m["skewness"], m["inverted_pyramid"]


def fails_checkmesh(
    angle: NDArray[np.float64], skewness: NDArray[np.float64], inverted: NDArray[np.bool_]
) -> NDArray[np.bool_]:
    """Faces checkMesh's skewness, face-pyramid or orthogonality checks fail.

    From :func:`face_quality`'s arrays: skewness above :data:`SKEWNESS_TARGET`, an
    inverted pyramid, or non-orthogonality of 90° or more (an error; a boundary face's NaN
    angle passes).
    """
    return (skewness > SKEWNESS_TARGET) | inverted | (np.nan_to_num(angle) >= 90.0)


def _min_ratio(ratio: NDArray[np.float64] | None, interior: NDArray[np.bool_]) -> float:
    if ratio is None or not interior.any():
        return 1.0
    return float(ratio[interior].min())
