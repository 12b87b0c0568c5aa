"""The split's kernel in the Rust core: a cell cut by planes, a region measured.

:mod:`hcvt.mesh.split` searches for cuts; trying one is the core's work
(``hcvt_core::split``): the pieces of each face on either side of the plane, the sections
on it, the parts, and checkMesh's figures for every face of the parts against the
neighbours' true centres. This module translates between the search's editor (global
vertex, face and cell numbers, Python lists) and the core's local arrays.

The core rounds as numpy rounds :func:`hcvt.mesh.quality.face_quality`, so that a face
the search passes is a face the final check on the whole mesh passes. It replaced a Python
version of the same steps, which it matched bit for bit on the bunny and the cheese, about
40 times faster.
"""

from __future__ import annotations

from functools import cached_property
from typing import Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from hcvt import _core


class Editor(Protocol):
    """What the kernel reads of the split search's mesh (:class:`hcvt.mesh.split.Editor`)."""

    centroid: list[NDArray[np.float64]]  # per cell, (3,)

    def coords(self, ids: list[int]) -> NDArray[np.float64]:
        """The points of vertex ids ``ids``, shape (len(ids), 3)."""
        ...

    def other(self, c: int, k: int) -> int:
        """The cell across face ``k`` from cell ``c`` (-1 on the boundary)."""
        ...


#: A plane as (normal, a point on it), both shape (3,).
Plane = tuple[NDArray[np.float64], NDArray[np.float64]]

#: A cut's new vertices: edge (lower id, higher id) -> (new id ``-1 - j``, its point).
Crossings = dict[tuple[int, int], tuple[int, NDArray[np.float64]]]


class Face(NamedTuple):
    """A face of a part of a region, its loop oriented out of that part."""

    loop: list[int]
    source: int  # the editor's face it is (a piece of), or -1 for a face on a cut's plane
    part: int  # the part it bounds
    across: int  # the part on the other side, else -1
    ghost: int  # the editor's cell on the other side outside the parts, else -1


class Cut:
    """One cut of a cell by a plane, as the core made and measured it.

    A search tries some 150 planes per failing cell and applies one or a few, so the new
    vertices and faces (:attr:`crossings`, :attr:`faces`) are made as Python objects only
    when first read.
    """

    def __init__(self, batch: _Batch, row: int) -> None:
        out = batch.out
        self._batch, self._row = batch, row
        p0, p1 = out["part_offsets"][row : row + 2].tolist()
        self.parts: int = p1 - p0
        self.failing: int = int(out["failing"][row])
        """Faces of the parts that fail checkMesh."""
        self.worst: float = float(out["worst"][row])
        """Their total badness (0 when none fails; see ``Editor.measure``)."""
        self.oblique: float = float(out["oblique"][row])
        """Sum of ``1 - cos`` of the non-orthogonality of the faces with a cell across."""
        self.part_failing: list[int] = out["part_failing"][p0:p1].tolist()
        """Per part, its failing faces."""
        self.failing_sources: frozenset[int] = batch.failing_sources(row)
        """The editor's faces with a failing piece (-1: a section)."""

    @property
    def part_volumes(self) -> NDArray[np.float64]:
        """Shape (parts,): the parts' volumes."""
        p0, p1 = self._batch.out["part_offsets"][self._row : self._row + 2].tolist()
        return self._batch.out["volumes"][p0:p1]

    @property
    def part_centroids(self) -> NDArray[np.float64]:
        """Shape (parts, 3): the parts' centres."""
        p0, p1 = self._batch.out["part_offsets"][self._row : self._row + 2].tolist()
        return self._batch.out["centroids"][p0:p1]

    @cached_property
    def crossings(self) -> Crossings:
        """The new vertices where the plane crosses the cell's edges."""
        return self._batch.crossings(self._row)

    @cached_property
    def faces(self) -> list[Face]:
        """The parts' faces: the pieces of the cell's faces in order, then the sections."""
        return self._batch.faces(self._row)


def cut_by_planes(
    editor: Editor,
    c: int,
    faces: list[int],
    loops: list[list[int]],
    planes: list[Plane],
) -> list[Cut]:
    """Cell ``c`` of ``editor`` cut by each of ``planes``, in their order.

    ``faces`` are the cell's faces and ``loops`` their outward loops (``Editor.fix``).
    Planes that make no cut (missing the cell, or through it degenerately) give none.
    """
    if not planes:
        return []
    cell = _LocalCell(editor, c, faces, loops)
    normals = np.array([normal for normal, _ in planes], dtype=np.float64).reshape(-1, 3)
    origins = np.array([origin for _, origin in planes], dtype=np.float64).reshape(-1, 3)
    batch = _Batch(cell, cell.cut(normals, origins))
    return [Cut(batch, r) for r in range(len(batch.out["plane"]))]


def measure_region(
    editor: Editor, faces: list[Face], parts: int
) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]] | None:
    """Failing flags and badness of ``faces`` (f,), the centres of their parts (parts, 3).

    ``faces`` bound parts ``0..parts-1``; None if a part has no positive volume. The
    cells across the faces from outside (``Face.ghost``) count with their centres in
    ``editor``.
    """
    ids: dict[int, int] = {}
    flat = [ids.setdefault(v, len(ids)) for face in faces for v in face.loop]
    offsets = np.zeros(len(faces) + 1, dtype=np.int64)
    np.cumsum([len(face.loop) for face in faces], out=offsets[1:])
    ghosts: dict[int, int] = {}  # the editor's cell -> ghost number, in order of meeting
    neighbour = []
    for face in faces:
        if face.across >= 0:
            neighbour.append(face.across)
        elif face.ghost >= 0:
            neighbour.append(parts + ghosts.setdefault(face.ghost, len(ghosts)))
        else:
            neighbour.append(-1)
    measured = _core.measure_region_3d(
        editor.coords(list(ids)) if ids else np.zeros((0, 3)),
        offsets,
        np.array(flat, dtype=np.int64),
        np.array([face.part for face in faces], dtype=np.int64),
        np.array(neighbour, dtype=np.int64),
        parts,
        _centroids(editor, list(ghosts)),
    )
    if measured is None:
        return None
    bad, badness, _, centroids = measured
    return bad, badness, centroids


class _LocalCell:
    """A cell of the editor in the core's terms (``_core.cut_cell_3d``'s first arguments).

    Local vertex numbers follow the global ones, so that each crossing is interpolated
    from its lower-numbered end whichever cell cuts the edge.
    """

    def __init__(self, editor: Editor, c: int, faces: list[int], loops: list[list[int]]):
        self.vertices = sorted({v for loop in loops for v in loop})
        local = {v: j for j, v in enumerate(self.vertices)}
        self.faces = faces
        self.face_offsets = np.zeros(len(loops) + 1, dtype=np.int64)
        np.cumsum([len(loop) for loop in loops], out=self.face_offsets[1:])
        self.face_vertices = np.array([local[v] for loop in loops for v in loop], dtype=np.int64)
        others = [editor.other(c, k) for k in faces]
        self.ghost_cells = sorted({cell for cell in others if cell >= 0})
        number = {cell: j for j, cell in enumerate(self.ghost_cells)}
        self.ghosts = np.array([number.get(cell, -1) for cell in others], dtype=np.int64)
        self.ghost_centroids = _centroids(editor, self.ghost_cells)
        self.points = editor.coords(self.vertices)

    def cut(self, normals: NDArray[np.float64], origins: NDArray[np.float64]) -> dict[str, Any]:
        """``_core.cut_cell_3d`` of this cell by the planes (p, 3)."""
        return _core.cut_cell_3d(
            self.points,
            self.face_offsets,
            self.face_vertices,
            self.ghosts,
            self.ghost_centroids,
            normals,
            origins,
        )


class _Batch:
    """The core's cuts of one cell, numbered as the editor numbers.

    Its vertex m + j is crossing j (``-1 - j`` in a :class:`Cut`); its faces and ghosts
    the cell's local ones. Each table ends with -1, which "none" (-1) indexes.
    """

    def __init__(self, cell: _LocalCell, out: dict[str, Any]) -> None:
        self.out = out
        most = int(np.diff(out["crossing_offsets"]).max(initial=0))
        self.vertex = np.concatenate(
            [np.asarray(cell.vertices, dtype=np.int64), -1 - np.arange(most, dtype=np.int64)]
        )
        self.source = np.array([*cell.faces, -1], dtype=np.int64)
        self.ghost = np.array([*cell.ghost_cells, -1], dtype=np.int64)

    def failing_sources(self, r: int) -> frozenset[int]:
        out = self.out
        f0, f1 = out["face_offsets"][r : r + 2]
        bad = np.flatnonzero(out["bad"][f0:f1]) + f0
        return frozenset(self.source[out["source"][bad]].tolist())

    def crossings(self, r: int) -> Crossings:
        out = self.out
        x0, x1 = out["crossing_offsets"][r : r + 2].tolist()
        ends = self.vertex[out["crossing_edges"][x0:x1]].tolist()
        points = out["crossing_points"][x0:x1].copy()  # not a view of every cut's
        return {(a, b): (-1 - j, points[j]) for j, (a, b) in enumerate(ends)}

    def faces(self, r: int) -> list[Face]:
        out = self.out
        f0, f1 = out["face_offsets"][r : r + 2].tolist()
        bounds = out["loop_offsets"][f0 : f1 + 1]
        flat = self.vertex[out["loop_vertices"][bounds[0] : bounds[-1]]].tolist()
        starts = (bounds - bounds[0]).tolist()
        fields = zip(
            [flat[a:b] for a, b in zip(starts, starts[1:], strict=False)],
            self.source[out["source"][f0:f1]].tolist(),
            out["part"][f0:f1].tolist(),
            out["across"][f0:f1].tolist(),
            self.ghost[out["ghost"][f0:f1]].tolist(),
            strict=True,
        )
        return [Face(*face) for face in fields]


def _centroids(editor: Editor, cells: list[int]) -> NDArray[np.float64]:
    """Shape (len(cells), 3): the editor's centres of ``cells``."""
    return np.array([editor.centroid[cell] for cell in cells], dtype=np.float64).reshape(-1, 3)
