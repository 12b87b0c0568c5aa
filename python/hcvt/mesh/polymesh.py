"""A conforming polygon (2D) or polyhedral (3D) mesh: the cells of a diagram as one mesh.

The layout is OpenFOAM's (face-based): every face is stored once with the cell on each
side, so that two neighbouring cells share exactly the same face and vertices.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import NamedTuple

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray

import hcvt._core as _core
from hcvt.core_results import MeshQualityArrays
from hcvt.errors import InvalidMeshError


class CellFaces(NamedTuple):
    """Each cell's faces in CSR layout (see :attr:`PolyMesh.cell_faces`)."""

    offsets: NDArray[np.intp]
    """Shape (n + 1,): cell ``c`` owns entries ``offsets[c]:offsets[c + 1]``."""
    faces: NDArray[np.intp]
    """Shape (m,): face indices, increasing within each cell."""
    outward: NDArray[np.bool_]
    """Shape (m,): whether the face's normal points out of this cell (it is the owner)."""


class FaceGeometry(NamedTuple):
    """Per-face geometry, OpenFOAM's definition (see :attr:`PolyMesh.face_geometry`)."""

    centre: NDArray[np.float64]
    """Shape (f, d): area centroid, L."""
    area_vector: NDArray[np.float64]
    """Shape (f, d): normal out of the owner, of length the face's area (length in 2D)."""


class CellGeometry(NamedTuple):
    """Per-cell volume and centroid from the faces (see :attr:`PolyMesh.cell_geometry`)."""

    volume: NDArray[np.float64]
    """Shape (n,): area (2D) or volume (3D), L^d; 0 for a cell without faces."""
    centroid: NDArray[np.float64]
    """Shape (n, d): centre of mass, L; NaN for a cell without faces."""


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
    periodic_partner : ndarray of intp, shape (f,), or None
        In a periodic box (:mod:`hcvt.mesh.periodic`): for a periodic face (a boundary
        face of the unwrapped cells), the index of the same face seen from the cell on its
        other side; -1 for other faces. None outside periodic boxes.
    periodic_image : ndarray of int8, shape (f, d), or None
        With ``periodic_partner``: the whole periods that carry the other cell's site to
        this face's side (zeros for other faces).
    """

    points: NDArray[np.float64]
    face_offsets: NDArray[np.intp]
    face_vertices: NDArray[np.intp]
    owner: NDArray[np.intp]
    neighbour: NDArray[np.intp]
    boundary_element: NDArray[np.intp]
    n_cells: int
    periodic_partner: NDArray[np.intp] | None = None
    periodic_image: NDArray[np.int8] | None = None

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

    @cached_property
    def face_sizes(self) -> NDArray[np.intp]:
        """Shape (f,): number of vertices of each face (2 in 2D)."""
        return np.diff(self.face_offsets)

    @cached_property
    def cell_faces(self) -> CellFaces:
        """Each cell's faces, owned and neighboured, in CSR layout (:class:`CellFaces`).

        Examples
        --------
        Two unit squares side by side share face 0 (owner 0, neighbour 1):

        >>> import numpy as np
        >>> from hcvt.mesh.polymesh import PolyMesh
        >>> pts = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]], dtype=float)
        >>> edges = [[1, 4], [0, 1], [4, 3], [3, 0], [1, 2], [2, 5], [5, 4]]
        >>> m = PolyMesh(pts, np.arange(0, 15, 2), np.array(edges).ravel(),
        ...              owner=np.array([0, 0, 0, 0, 1, 1, 1]),
        ...              neighbour=np.array([1, -1, -1, -1, -1, -1, -1]),
        ...              boundary_element=np.array([-1, 0, 1, 2, 0, 3, 1]), n_cells=2)
        >>> m.cell_faces.offsets, m.cell_faces.faces[4:]
        (array([0, 4, 8]), array([0, 4, 5, 6]))
        >>> m.cell_geometry.volume, m.cell_geometry.centroid[1]
        (array([1., 1.]), array([1.5, 0.5]))
        """
        f = self.n_faces
        inner = np.flatnonzero(self.interior)
        cells = np.concatenate([self.owner, self.neighbour[inner]])
        faces = np.concatenate([np.arange(f, dtype=np.intp), inner])
        outward = np.concatenate([np.ones(f, dtype=bool), np.zeros(len(inner), dtype=bool)])
        order = np.lexsort((faces, cells))
        offsets = np.zeros(self.n_cells + 1, dtype=np.intp)
        np.cumsum(np.bincount(cells, minlength=self.n_cells), out=offsets[1:])
        return CellFaces(offsets, faces[order], outward[order])

    @cached_property
    def face_geometry(self) -> FaceGeometry:
        """Centre and area vector of every face (:class:`FaceGeometry`).

        3D: OpenFOAM's rule (``primitiveMeshTools::makeFaceCentresAndAreas``): a fan of
        triangles from the vertex average; the area vector is their sum, the centre their
        area-weighted centroid. For a planar convex face both are exact, and using
        OpenFOAM's rule makes our quality figures those ``checkMesh`` prints. 2D: the
        edge's midpoint and its right-hand normal (the owner lies on the left). From
        :attr:`measured`.
        """
        return FaceGeometry(self.measured["face_centre"], self.measured["area_vector"])

    @cached_property
    def cell_geometry(self) -> CellGeometry:
        """Volume and centroid of every cell from its faces (:class:`CellGeometry`).

        The divergence theorem on planar faces: the cell is cut into one cone (pyramid in
        3D, triangle in 2D) per face with apex ``x0``, the average of its face centres; a
        cone's measure is ``S_f · (c_f - x0) / d`` and its centroid ``(d c_f + x0) /
        (d + 1)``. Exact for planar faces, whatever ``x0``; the same rule as OpenFOAM's
        ``makeCellCentresAndVols``, so centroids agree with ``checkMesh``'s. From
        :attr:`measured`.
        """
        return CellGeometry(self.measured["volume"], self.measured["centroid"])

    @cached_property
    def measured(self) -> MeshQualityArrays:
        """Geometry and checkMesh figures of every face and cell (:meth:`measure`), cached."""
        return self.measure()

    def measure(self, centres: ArrayLike | None = None) -> MeshQualityArrays:
        """Geometry and checkMesh figures of every face and cell, computed by the core.

        One pass of ``hcvt._core.mesh_quality`` (crates/hcvt-core/src/quality.rs, where
        the definitions are): face centres and area vectors, cell volumes and centroids,
        and the figures of :class:`hcvt.mesh.quality.MeshQuality`. Each value depends on
        the mesh's bits alone (no summation order of numpy's, no thread count).

        Parameters
        ----------
        centres : array_like of float, shape (n_cells, d), optional
            Cell centres to measure the faces' non-orthogonality, skewness and pyramids
            against, instead of the cells' own centroids (:func:`hcvt.mesh.quality.face_quality`).

        Raises
        ------
        InvalidMeshError
            An index out of range, a face with the wrong number of vertices or one cell on
            both sides, a non-finite point: the message names the first.
        ValueError
            ``centres`` of another shape.
        """
        given = None if centres is None else np.ascontiguousarray(centres, dtype=np.float64)
        if given is not None and given.shape != (self.n_cells, self.dim):
            raise ValueError(
                f"centres must have shape ({self.n_cells}, {self.dim}), got {given.shape}"
            )
        return _core.mesh_quality(
            np.ascontiguousarray(self.points, dtype=np.float64),
            np.ascontiguousarray(self.face_offsets, dtype=np.intp),
            np.ascontiguousarray(self.face_vertices, dtype=np.intp),
            np.ascontiguousarray(self.owner, dtype=np.intp),
            np.ascontiguousarray(self.neighbour, dtype=np.intp),
            self.n_cells,
            centres=given,
        )

    def check(self, *, keyholes: bool = False) -> None:
        """Raise :class:`hcvt.errors.InvalidMeshError` unless this is a conforming mesh.

        Checked: indices in range; an owner differs from its neighbour; an interior face
        has no boundary element; faces have 2 vertices (2D) or at least 3 distinct ones
        (3D); every cell is closed -- in 3D each directed edge of its outward faces is
        matched by the reverse edge of another of its faces, in 2D each vertex starts as
        many of its edges as it ends; every cell with faces has positive volume.

        ``keyholes=True`` lets a face repeat a vertex: a face with a hole, joined to its rim
        by an edge walked both ways (``Diagram.mesh()`` makes them on the cheese), for
        writers that triangulate such faces.

        A mesh that passed is not checked again (the arrays are the caller's: do not
        change them in place).
        """
        if self.__dict__.get("_checked") or (keyholes and self.__dict__.get("_checked_keyholes")):
            return
        n, f = self.n_cells, self.n_faces
        _require(self.owner, 0, n, "owner")
        _require(self.neighbour, -1, n, "neighbour")
        _require(self.face_vertices, 0, len(self.points), "face_vertices")
        same = np.flatnonzero(self.owner == self.neighbour)
        if len(same):
            raise InvalidMeshError(f"face {same[0]} has cell {self.owner[same[0]]} on both sides")
        marked = np.flatnonzero(self.interior & (self.boundary_element >= 0))
        if len(marked):
            raise InvalidMeshError(f"interior face {marked[0]} has a boundary element")
        sizes = self.face_sizes
        bad = np.flatnonzero(sizes != 2) if self.dim == 2 else np.flatnonzero(sizes < 3)
        if len(bad):
            raise InvalidMeshError(f"face {bad[0]} has {sizes[bad[0]]} vertices")
        key = np.sort(
            np.repeat(np.arange(f, dtype=np.intp), sizes) * len(self.points) + self.face_vertices
        )
        repeated = key[1:][key[1:] == key[:-1]]
        if len(repeated) and not keyholes:
            raise InvalidMeshError(f"face {repeated[0] // len(self.points)} repeats a vertex")
        self._check_closed()
        volume = self.cell_geometry.volume
        used = np.diff(self.cell_faces.offsets) > 0
        flat = np.flatnonzero(used & ~(volume > 0))
        if len(flat):
            raise InvalidMeshError(f"cell {flat[0]} has volume {volume[flat[0]]:.3g} <= 0")
        # Frozen dataclass: a private memo, of which check passed.
        memo = "_checked_keyholes" if keyholes and len(repeated) else "_checked"
        object.__setattr__(self, memo, True)

    def _check_closed(self) -> None:
        """Every cell's outward boundary is a closed cycle (see :meth:`check`)."""
        starts = self.face_offsets[:-1]
        following = np.arange(1, len(self.face_vertices) + 1, dtype=np.intp)
        following[self.face_offsets[1:] - 1] = starts
        a, b = self.face_vertices, self.face_vertices[following]
        face_of = np.repeat(np.arange(self.n_faces, dtype=np.intp), self.face_sizes)
        if self.dim == 2:  # one directed edge per face: a -> b
            a, b, face_of = a[0::2], a[1::2], face_of[0::2]
        inner = self.interior[face_of]
        # As seen from each cell: the owner walks a -> b, the neighbour b -> a.
        cell = np.concatenate([self.owner[face_of], self.neighbour[face_of][inner]])
        tail = np.concatenate([a, b[inner]])
        head = np.concatenate([b, a[inner]])
        p = len(self.points)
        # Each use becomes one integer: (group << 1) | direction, where a group is (cell,
        # vertex) in 2D (leaving / arriving) and (cell, undirected edge) in 3D (the two
        # ways round). A cell is closed when every group has as many uses each way: after
        # one sort of the integers, runs 2g and 2g + 1 have equal lengths.
        if self.dim == 2:
            group = np.concatenate([cell * p + tail, cell * p + head]).astype(np.int64)
            way = np.concatenate([np.zeros(len(tail), np.int64), np.ones(len(head), np.int64)])
            per_cell = p
        else:
            lo, hi = np.minimum(tail, head).astype(np.int64), np.maximum(tail, head)
            if self.n_cells * float(p) * p < 2.0**61:
                edge, edges = lo * p + hi, p * p
            else:  # too many for one int64: number the edges first (slower)
                _, edge = np.unique(lo * p + hi, return_inverse=True)
                edges = int(edge.max()) + 1
            group = cell.astype(np.int64) * edges + edge
            way = (tail > head).astype(np.int64)
            per_cell = edges
        keys = np.sort((group << 1) | way)
        starts = np.flatnonzero(np.diff(keys, prepend=-1))
        value, length = keys[starts], np.diff(starts, append=len(keys))
        matched = np.zeros(len(value), dtype=bool)
        first = np.flatnonzero((value[:-1] & 1) == 0)
        pair = (value[first + 1] == value[first] + 1) & (length[first + 1] == length[first])
        matched[first[pair]] = matched[first[pair] + 1] = True
        if not matched.all():
            bad = value[np.flatnonzero(~matched)[0]] >> 1
            raise InvalidMeshError(f"cell {int(bad // per_cell)} is not closed")

    def cell_loops(self) -> list[list[NDArray[np.intp]]]:
        """2D only: each cell's boundary as closed loops of point ids.

        Loop ``[v0, v1, ..., vk]`` stands for the edges ``v0 v1, ..., vk v0``, in the
        cell's own orientation: an outer boundary counter-clockwise, a hole clockwise. A
        cell cut in pieces by the domain has one outer loop per piece; an empty cell none.
        """
        if self.dim != 2:
            raise ValueError("cell loops exist for 2D meshes only")
        a, b = self.face_vertices[0::2], self.face_vertices[1::2]
        inner = self.interior
        cell = np.concatenate([self.owner, self.neighbour[inner]])
        tail = np.concatenate([a, b[inner]])
        head = np.concatenate([b, a[inner]])
        order = np.lexsort((tail, cell))
        loops: list[list[NDArray[np.intp]]] = [[] for _ in range(self.n_cells)]
        bounds = np.searchsorted(cell[order], np.arange(self.n_cells + 1))
        for c in range(self.n_cells):
            edges = order[bounds[c] : bounds[c + 1]]
            following: dict[int, list[int]] = {}
            for e in edges.tolist():
                following.setdefault(int(tail[e]), []).append(int(head[e]))
            while following:
                start = next(iter(following))
                ring = [start]
                while True:
                    ahead = following[ring[-1]]
                    nxt = ahead.pop()
                    if not ahead:
                        del following[ring[-1]]
                    if nxt == start:
                        break
                    ring.append(nxt)
                loops[c].append(np.asarray(ring, dtype=np.intp))
        return loops

    def cell_polygons(self) -> list[list[NDArray[np.intp]]]:
        """2D only: each cell as polygons without holes, point ids counter-clockwise.

        For formats without holes in a cell (VTK polygons, OpenFOAM faces): a cell's outer
        loops as they are when it has no hole; a cell with a hole as the triangles of its
        constrained Delaunay triangulation (shapely), on its own vertices.
        """
        out = []
        for loops in self.cell_loops():
            if all(_shoelace(self.points[r]) > 0 for r in loops):
                out.append(loops)
            else:
                out.append(self._triangulate(loops))
        return out

    def _triangulate(self, loops: list[NDArray[np.intp]]) -> list[NDArray[np.intp]]:
        shells = [r for r in loops if _shoelace(self.points[r]) > 0]
        holes = [shapely.Polygon(self.points[r]) for r in loops if _shoelace(self.points[r]) < 0]
        ids = {tuple(self.points[v].tolist()): int(v) for r in loops for v in r}
        triangles = []
        for shell in shells:
            polygon = shapely.Polygon(self.points[shell])
            inside = [
                h.exterior.coords for h in holes if polygon.contains(h.representative_point())
            ]
            cdt = shapely.constrained_delaunay_triangles(shapely.Polygon(polygon.exterior, inside))
            for t in shapely.get_parts(cdt):
                corners = np.asarray(t.exterior.coords)[:3]
                if _shoelace(corners) < 0:
                    corners = corners[::-1]
                triangles.append(np.array([ids[tuple(c)] for c in corners.tolist()], dtype=np.intp))
        return triangles

    def compacted(self) -> tuple[PolyMesh, NDArray[np.intp]]:
        """The mesh without its empty cells and unused points, and the kept cells' ids.

        Formats that have no empty cells (OpenFOAM, VTU) take this; ``kept[c]`` is the
        original index (the site) of new cell ``c``, shape (n_kept,).
        """
        count = np.diff(self.cell_faces.offsets)
        kept = np.flatnonzero(count > 0)
        renumber = np.full(self.n_cells + 1, -1, dtype=np.intp)  # entry -1 maps -1 to -1
        renumber[kept] = np.arange(len(kept))
        used = np.zeros(len(self.points), dtype=bool)
        used[self.face_vertices] = True
        points_map = np.cumsum(used) - 1
        mesh = PolyMesh(
            points=self.points[used],
            face_offsets=self.face_offsets,
            face_vertices=points_map[self.face_vertices],
            owner=renumber[self.owner],
            neighbour=renumber[self.neighbour],
            boundary_element=self.boundary_element,
            n_cells=len(kept),
            periodic_partner=self.periodic_partner,
            periodic_image=self.periodic_image,
        )
        return mesh, kept


def _shoelace(xy: NDArray[np.float64]) -> float:
    """Signed area of a closed ring (k, 2): positive counter-clockwise."""
    x, y = xy[:, 0], xy[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def _require(values: NDArray[np.intp], lo: int, hi: int, name: str) -> None:
    bad = np.flatnonzero((values < lo) | (values >= hi))
    if len(bad):
        raise InvalidMeshError(f"{name}[{bad[0]}] = {values[bad[0]]} is outside [{lo}, {hi})")
