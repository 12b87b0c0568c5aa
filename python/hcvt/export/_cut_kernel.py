"""The kernel of :mod:`hcvt.export.split` in the Rust core: a cell cut by planes, measured.

Drop-in replacements, with the inputs and outputs of the methods they replace, for
``_Editor.cut``, ``_Editor.try_planes`` and ``_Editor.measure``: each takes the editor as
its first argument, so that inside ``_Editor`` ::

    def try_planes(self, c, faces, loops, planes):
        from hcvt.export import _cut_kernel  # it subclasses _Cut: import it after

        return _cut_kernel.try_planes(self, c, faces, loops, planes)

The core (``hcvt_core::split``) does what those methods do, rounded as numpy rounds them,
so the cuts found are the same: the same None-ness, faces (loops, sources, parts), failing
flags, badness and centres (``tests/test_cut_kernel.py`` compares them on the bunny and the
cheese; a whole ``split_failing_cells`` of 300 random sites in the bunny gives the same
mesh bit for bit). There, on the 153 failing cells (22,157 cuts), ``try_planes`` takes
1.1 s where the Python methods take 44 s: the core 38 us a cut, the Python around it 11.
``cut`` converts the cell for each plane (9 times faster only); the search goes through
``try_planes``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from hcvt import _core
from hcvt.export import split as _split

if TYPE_CHECKING:
    from hcvt.export.split import _Cut, _Editor, _Face

_Plane = tuple[NDArray[np.float64], NDArray[np.float64]]
#: ``_Cut.crossings``: edge (lower id, higher id) -> (new id ``-1 - j``, its point).
_Crossings = dict[tuple[int, int], tuple[int, NDArray[np.float64]]]


class _LocalCell(NamedTuple):
    """A cell of the editor in the core's terms (``_core.cut_cell_3d``'s first arguments)."""

    vertices: list[int]  # the editor's id of each local vertex, increasing
    faces: list[int]  # the editor's face of each local face
    ghost_cells: list[int]  # the editor's cell of each ghost
    points: NDArray[np.float64]  # (m, 3)
    face_offsets: NDArray[np.int64]  # (f + 1,)
    face_vertices: NDArray[np.int64]  # local vertex ids
    ghosts: NDArray[np.int64]  # (f,) the ghost across each face, or -1
    ghost_centroids: NDArray[np.float64]  # (g, 3)

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


def cut(
    editor: _Editor,
    c: int,
    faces: list[int],
    loops: list[list[int]],
    normal: NDArray[np.float64],
    origin: NDArray[np.float64],
) -> _Cut | None:
    """``editor.cut(c, faces, loops, normal, origin)``: cell ``c`` cut by one plane, or None."""
    cell = _local_cell(editor, c, faces, loops)
    made = _cuts(cell, [(normal, origin)])
    return made[0][1] if made else None


def try_planes(
    editor: _Editor, c: int, faces: list[int], loops: list[list[int]], planes: list[_Plane]
) -> list[_Cut]:
    """``editor.try_planes(c, faces, loops, planes)``: the cuts until one passes, best first."""
    if not planes:
        return []
    tried = [made for _, made in _cuts(_local_cell(editor, c, faces, loops), planes)]
    tried.sort(key=lambda made: made.worst)
    return tried


def measure(
    editor: _Editor,
    faces: list[_Face],
    parts: int,
    coords: Callable[[list[int]], NDArray[np.float64]] | None = None,
) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]] | None:
    """``editor.measure(faces, parts, coords)``: failing flags (f,), badness (f,), centres.

    The centres have shape (parts, 3); None if a part has no positive volume.
    """
    coords = coords or editor.coords
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
        coords(list(ids)) if ids else np.zeros((0, 3)),
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


def _local_cell(editor: _Editor, c: int, faces: list[int], loops: list[list[int]]) -> _LocalCell:
    """Cell ``c`` (its faces and outward loops as ``_Editor.fix`` lists them) for the core.

    Local vertex numbers follow the global ones, so that each crossing is interpolated
    from the same end as in ``_Editor.cut``.
    """
    vertices = sorted({v for loop in loops for v in loop})
    local = {v: j for j, v in enumerate(vertices)}
    offsets = np.zeros(len(loops) + 1, dtype=np.int64)
    np.cumsum([len(loop) for loop in loops], out=offsets[1:])
    flat = np.array([local[v] for loop in loops for v in loop], dtype=np.int64)
    others = [editor.other(c, k) for k in faces]
    ghost_cells = sorted({cell for cell in others if cell >= 0})
    number = {cell: j for j, cell in enumerate(ghost_cells)}
    ghosts = np.array([number.get(cell, -1) for cell in others], dtype=np.int64)
    centroids = _centroids(editor, ghost_cells)
    points = editor.coords(vertices)
    return _LocalCell(vertices, faces, ghost_cells, points, offsets, flat, ghosts, centroids)


def _centroids(editor: _Editor, cells: list[int]) -> NDArray[np.float64]:
    """Shape (len(cells), 3): the editor's centres of ``cells``."""
    return np.array([editor.centroid[cell] for cell in cells], dtype=np.float64).reshape(-1, 3)


def _cuts(cell: _LocalCell, planes: list[_Plane]) -> list[tuple[int, _Cut]]:
    """The cuts of ``cell`` by ``planes`` until one passes, with their planes' rows."""
    normals = np.array([normal for normal, _ in planes], dtype=np.float64).reshape(-1, 3)
    origins = np.array([origin for _, origin in planes], dtype=np.float64).reshape(-1, 3)
    batch = _Batch(cell, cell.cut(normals, origins))
    out = batch.out
    face_at = out["face_offsets"]
    part_at = out["part_offsets"].tolist()
    part_failing = out["part_failing"].tolist()
    # The sources of each cut's failing faces: few faces fail, so go through those only.
    failing = np.flatnonzero(out["bad"])
    cut_of = (np.searchsorted(face_at, failing, side="right") - 1).tolist()
    sources: list[list[int]] = [[] for _ in range(len(face_at) - 1)]
    for r, k in zip(cut_of, batch.source[out["source"][failing]].tolist(), strict=True):
        sources[r].append(k)
    rows = zip(out["plane"].tolist(), out["failing"].tolist(), out["worst"].tolist(), strict=True)
    made: list[tuple[int, _Cut]] = []
    for r, (row, bad, worst) in enumerate(rows):
        p0, p1 = part_at[r], part_at[r + 1]
        cut = _KernelCut({}, [], p1 - p0, bad, worst, part_failing[p0:p1], frozenset(sources[r]))
        cut._batch, cut._row = batch, r
        made.append((row, cut))
    return made


class _Batch:
    """The core's cuts of one cell (``_core.cut_cell_3d``), numbered as the editor numbers.

    Its vertex m + j is crossing j (``-1 - j`` in ``_Editor.cut``); its faces and ghosts
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

    def items(self, r: int) -> tuple[_Crossings, list[_Face]]:
        """Cut ``r``'s ``crossings`` and ``faces``, as ``_Editor.cut`` makes them."""
        out = self.out
        x0, x1 = out["crossing_offsets"][r : r + 2].tolist()
        ends = self.vertex[out["crossing_edges"][x0:x1]].tolist()
        points = out["crossing_points"][x0:x1].copy()  # not a view of every cut's
        crossings = {(a, b): (-1 - j, points[j]) for j, (a, b) in enumerate(ends)}
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
        return crossings, [_split._Face(*face) for face in fields]


class _KernelCut(_split._Cut):
    """A ``_Cut`` from the core whose ``crossings`` and ``faces`` are made when first read.

    A failing cell's search tries some 150 cuts (300 random sites in the bunny) and
    applies one or a few: making every cut's faces as Python objects took six times the
    core's time, most of it in the garbage collector. The tuple's own items for those two
    fields are empty placeholders: read them as attributes.
    """

    _batch: _Batch
    _row: int

    @property
    def crossings(self) -> _Crossings:
        """The new vertices: edge (lower id, higher id) -> (id ``-1 - j``, point)."""
        return self._items()[0]

    @property
    def faces(self) -> list[_Face]:
        """The parts' faces, as ``_Editor.cut`` lists them."""
        return self._items()[1]

    def _items(self) -> tuple[_Crossings, list[_Face]]:
        made = self.__dict__.get("_made")
        if made is None:
            made = self.__dict__["_made"] = self._batch.items(self._row)
        return made
