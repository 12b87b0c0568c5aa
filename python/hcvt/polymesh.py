"""A conforming polygon (2D) or polyhedral (3D) mesh: the cells of a diagram as one mesh.

The layout is OpenFOAM's (face-based): every face is stored once with the cell on each
side, so that two neighbouring cells share exactly the same face and vertices.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True, eq=False)
class PolyMesh:
    """Cells as one mesh with shared vertices and faces.

    Attributes
    ----------
    points : ndarray of float64, shape (p, d)
        Every vertex once, L.
    face_offsets : ndarray of intp, shape (f + 1,)
        Face ``k`` is ``face_vertices[face_offsets[k]:face_offsets[k + 1]]``.
    face_vertices : ndarray of intp, shape (face_offsets[-1],)
        Indices into ``points``. 3D: each face's vertex loop, counter-clockwise seen from
        outside its owner (right-hand normal out of ``owner``, into ``neighbour``).
        2D: a face is an edge of two vertices, ordered so that its owner lies on its left
        (the owner's boundary runs counter-clockwise).
    owner : ndarray of intp, shape (f,)
        The cell (site index) each face belongs to.
    neighbour : ndarray of intp, shape (f,)
        The cell on the other side, or ``-1`` for a face on the domain boundary.
    boundary_element : ndarray of intp, shape (f,)
        For a boundary face, the input triangle (3D) or boundary segment (2D) it lies on
        (``Domain`` order); ``-1`` for an interior face.
    n_cells : int
        Number of cells (sites); a cell may have no faces (an empty cell).
    """

    points: NDArray[np.float64]
    face_offsets: NDArray[np.intp]
    face_vertices: NDArray[np.intp]
    owner: NDArray[np.intp]
    neighbour: NDArray[np.intp]
    boundary_element: NDArray[np.intp]
    n_cells: int

    def __post_init__(self) -> None:
        f = len(self.owner)
        if self.points.ndim != 2 or self.points.shape[1] not in (2, 3):
            raise ValueError(f"points must have shape (p, 2) or (p, 3), got {self.points.shape}")
        if self.face_offsets.shape != (f + 1,) or self.face_offsets[-1] != len(self.face_vertices):
            raise ValueError("face_offsets must have f + 1 entries ending at len(face_vertices)")
        for name in ("neighbour", "boundary_element"):
            if getattr(self, name).shape != (f,):
                raise ValueError(f"{name} must have shape ({f},) like owner")

    @property
    def dim(self) -> int:
        """2 or 3."""
        return int(self.points.shape[1])

    @property
    def n_faces(self) -> int:
        """Number of faces, interior and boundary."""
        return len(self.owner)

    @cached_property
    def interior(self) -> NDArray[np.bool_]:
        """Shape (f,): whether each face lies between two cells."""
        return self.neighbour >= 0

    def face(self, k: int) -> NDArray[np.intp]:
        """Vertex indices of face ``k``, in order."""
        return self.face_vertices[self.face_offsets[k] : self.face_offsets[k + 1]]
