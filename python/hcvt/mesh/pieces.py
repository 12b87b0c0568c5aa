"""The cells of a restricted Voronoi diagram on a triangle surface, as planar pieces.

Each cell of a diagram on :meth:`hcvt.Domain.from_surface` is the part of the surface
nearer its site than any other: a union of convex polygons, each the part of one input
triangle in the cell (DESIGN §12). The core hands over exactly the polygons whose
moments make the diagram's ``volume`` and ``centroid`` (``_core.surface_pieces``); this
module holds them and fans them into triangles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


@dataclass(frozen=True)
class SurfacePieces:
    """Restricted Voronoi cells as convex planar pieces (:meth:`hcvt.Diagram.surface_pieces`).

    Attributes
    ----------
    points : ndarray of float64, shape (p, 3)
        Every piece's vertices, L, counter-clockwise about its input triangle's normal
        (as the triangle's corners run); pieces share no rows.
    piece_offsets : ndarray of intp, shape (m + 1,)
        Piece ``k``'s vertices are ``points[piece_offsets[k]:piece_offsets[k + 1]]`` (at
        least three).
    piece_cell : ndarray of intp, shape (m,)
        The cell (site) of each piece, non-decreasing.
    piece_face : ndarray of intp, shape (m,)
        The input triangle (row of ``Domain.faces``) each piece lies in.
    n_cells : int
        Number of cells (sites); a cell with no piece is empty (its site far from the
        surface).
    """

    points: NDArray[np.float64]
    piece_offsets: NDArray[np.intp]
    piece_cell: NDArray[np.intp]
    piece_face: NDArray[np.intp]
    n_cells: int

    @property
    def n_pieces(self) -> int:
        """Number of pieces."""
        return len(self.piece_cell)

    def fan(self) -> NDArray[np.intp]:
        """Every piece as triangles fanned from its first vertex: (t, 3) rows of ``points``.

        Piece by piece, ``k - 2`` triangles for a piece of ``k`` vertices.
        """
        sizes = np.diff(self.piece_offsets) - 2
        piece = np.repeat(np.arange(self.n_pieces), sizes)
        first = self.piece_offsets[:-1][piece]
        step = np.arange(len(piece)) - np.repeat(np.cumsum(sizes) - sizes, sizes) + 1
        return np.column_stack([first, first + step, first + step + 1]).astype(np.intp)

    def cell_triangles(self) -> list[tuple[NDArray[np.float64], NDArray[np.intp]]]:
        """Per cell ``(vertices (k, 3), faces (f, 3))``: its pieces' vertices, fanned.

        The faces are local rows, counter-clockwise about the surface's normal; both
        arrays are empty for an empty cell.
        """
        triangles = self.fan()
        counts = np.bincount(self.piece_cell, minlength=self.n_cells)
        first_piece = np.concatenate([[0], np.cumsum(counts)])
        point_start = self.piece_offsets[first_piece]
        tri_cell = np.repeat(self.piece_cell, np.diff(self.piece_offsets) - 2)
        tri_start = np.searchsorted(tri_cell, np.arange(self.n_cells + 1))
        return [
            (
                self.points[point_start[i] : point_start[i + 1]],
                triangles[tri_start[i] : tri_start[i + 1]] - point_start[i],
            )
            for i in range(self.n_cells)
        ]
