"""VTU (VTK XML UnstructuredGrid): polyhedron cells in 3D, polygon cells in 2D.

3D cells are VTK_POLYHEDRON (type 42): besides ``connectivity``/``offsets`` (the cell's
distinct points), the ``faces`` stream holds, per cell, its number of faces and then each
face as its vertex count and vertex ids, outward; ``faceoffsets`` is the end of each
cell's stream in ``faces`` (VTK's file format document, "Polyhedron"; VTK 9.4 and later
still read these arrays, and meshio reads them).

2D cells are VTK_POLYGON (type 7) in the plane z = 0, counter-clockwise. A cell the domain
cuts into pieces becomes one polygon per piece, and a cell with a hole its triangles (VTK
polygons have no holes); the cell data ``site`` says which cell each came from.

Faces VTK would triangulate wrongly (non-convex ones, and ones with a very short edge)
and faces with a hole (which ``Diagram.mesh()`` makes as one loop with a bridge walked
both ways, and VTK cannot take) are written as their triangles, each a face of the same
two cells (:func:`_split_for_vtk`).

Reading cells back: VTK measures a polyhedron two ways. vtkCellSizeFilter
(``compute_cell_sizes``) sums the Delaunay tetrahedra of the cell's points
(``vtkPolyhedron::TriangulateIds``, faces unused): at best their convex hull (measured,
VTK 9.7: scipy's hull to 1e-15 for most cells, up to 9% less for others), never a
non-convex cell; off by up to 14% on bunny boundary cells, 57% on the cheese's, and by
up to 6e-6 on a few convex cells (bunny, 50k cells). No file can change that. Through
its faces (vtkDataSetSurfaceFilter, vtkTriangleFilter, vtkMassProperties:
``grid.separate_cells().extract_surface().triangulate()``, then ``.volume`` or the
triangles' cones) VTK gets every cell to 1e-11 relative (tests/test_export.py), once the
float32 points that ``separate_cells`` (vtkShrinkFilter) makes are put back as read:
that rounding alone costs ~1e-7 per cell. In 2D, the cell-size filter also gets large
non-convex polygons wrong (a boundary cell of area 439.7 read as 1798); their triangles
through ``extract_surface().triangulate()`` are right.

Why our own writer and not meshio's: meshio 5.3 writes polyhedra that VTK reads as we do,
but takes them as a Python list of faces per cell, in blocks by point count, and loops
over cells in Python; benchmarks/export.py times both.
"""

from __future__ import annotations

import base64
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hcvt.errors import InvalidMeshError
from hcvt.mesh.cells import non_convex_faces, planar_triangles
from hcvt.mesh.pieces import SurfacePieces
from hcvt.mesh.polymesh import PolyMesh

VTK_POLYGON = 7
VTK_POLYHEDRON = 42
# Faces with an edge shorter than this fraction of their bounding-box diagonal are
# written as triangles (see _split_for_vtk).
_SHORT_EDGE = 1e-4


def write_vtu(
    mesh: PolyMesh, path: str | Path, *, cell_data: dict[str, ArrayLike] | None = None
) -> Path:
    """Write ``mesh`` as a ``.vtu`` file; its empty cells are left out.

    Parameters
    ----------
    mesh : PolyMesh
        A conforming mesh (checked with :meth:`PolyMesh.check`; in 3D faces with a hole
        may repeat a vertex, ``keyholes=True``).
    path : str or Path
        The file to write.
    cell_data : dict of str to array_like of shape (n,), optional
        Per-cell values, row ``i`` for cell ``i`` of ``mesh``, written as Float64 cell
        data beside ``site`` (Int64: the cell's index in ``mesh``).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InvalidMeshError
        ``mesh`` is not conforming, or GEOS cannot triangulate one of its faces with a
        hole.
    """
    mesh.check(keyholes=mesh.dim == 3)  # faces with a hole are written as triangles
    path = Path(path)
    polyhedra: list[str] = []
    if mesh.dim == 3:
        compact, kept = mesh.compacted()
        points = compact.points
        connectivity, offsets, faces, face_offsets = _polyhedra(_split_for_vtk(compact))
        # Cells by increasing point count (stable): meshio (5.3) reads polyhedra into
        # blocks by point count and pairs them with the cell data in that sorted order.
        order = np.argsort(np.diff(offsets, prepend=0), kind="stable")
        connectivity, offsets = _permute(connectivity, offsets, order)
        faces, face_offsets = _permute(faces, face_offsets, order)
        site = kept[order]
        types = np.full(len(kept), VTK_POLYHEDRON, dtype=np.uint8)
        polyhedra = [
            _data_array("faces", faces.astype(np.int64), "Int64"),
            _data_array("faceoffsets", face_offsets.astype(np.int64), "Int64"),
        ]
    else:
        points = np.column_stack([mesh.points, np.zeros(len(mesh.points))])
        site, connectivity, offsets = _polygons(mesh)
        types = np.full(len(site), VTK_POLYGON, dtype=np.uint8)
    cells = _cells(connectivity, offsets, types, *polyhedra)
    return _write(path, points, cells, site, mesh.n_cells, cell_data)


def write_pieces_vtu(
    pieces: SurfacePieces, path: str | Path, *, cell_data: dict[str, ArrayLike] | None = None
) -> Path:
    """Write the pieces of restricted Voronoi cells on a surface as VTK polygons in 3D.

    One VTK_POLYGON (type 7) per piece (:class:`hcvt.mesh.pieces.SurfacePieces`, convex
    and planar), counter-clockwise about its input triangle's normal; cell data ``site``
    (the cell of each piece), ``face`` (its input triangle) and ``cell_data`` (one value
    per cell, written on each of its pieces). Pieces are written by increasing vertex
    count (stable): meshio (5.3) reads polygons into blocks by vertex count and pairs them
    with the cell data in that order.

    Returns
    -------
    Path
        ``path``.
    """
    path = Path(path)
    offsets = pieces.piece_offsets
    order = np.argsort(np.diff(offsets), kind="stable")
    connectivity, ends = _permute(np.arange(len(pieces.points)), offsets[1:], order)
    cells = _cells(connectivity, ends, np.full(pieces.n_pieces, VTK_POLYGON, dtype=np.uint8))
    face = _data_array("face", pieces.piece_face[order].astype(np.int64), "Int64")
    site = pieces.piece_cell[order]
    return _write(path, pieces.points, cells, site, pieces.n_cells, cell_data, (face,))


def _cells(
    connectivity: NDArray[np.intp], offsets: NDArray[np.intp], types: NDArray[np.uint8], *more: str
) -> list[str]:
    """VTK's cell arrays: ``connectivity``, the ``offsets`` of each cell's end, ``types``."""
    return [
        _data_array("connectivity", connectivity.astype(np.int64), "Int64"),
        _data_array("offsets", offsets.astype(np.int64), "Int64"),
        _data_array("types", types, "UInt8"),
        *more,
    ]


def _write(
    path: Path,
    points: NDArray[np.float64],
    cells: list[str],
    site: NDArray[np.intp],
    n_cells: int,
    cell_data: dict[str, ArrayLike] | None,
    more: tuple[str, ...] = (),
) -> Path:
    """Write the UnstructuredGrid of ``points`` and ``cells`` (:func:`_cells`) to ``path``.

    Cell data ``site``, ``more`` and ``cell_data`` (one value per site of ``n_cells``,
    written on each VTK cell of the site).
    """
    arrays = [_data_array("site", site.astype(np.int64), "Int64"), *more]
    for name, values in (cell_data or {}).items():
        column = np.asarray(values, dtype=np.float64)
        if column.shape != (n_cells,):
            raise ValueError(f"cell_data[{name!r}] must have shape ({n_cells},)")
        arrays.append(_data_array(name, column[site], "Float64"))
    body = "".join(
        [
            '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" ',
            'byte_order="LittleEndian" header_type="UInt64"><UnstructuredGrid>',
            f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{len(site)}">',
            "<Points>",
            _data_array("Points", np.ascontiguousarray(points, dtype=np.float64), "Float64", 3),
            "</Points><Cells>",
            *cells,
            '</Cells><CellData Scalars="site">',
            *arrays,
            "</CellData></Piece></UnstructuredGrid></VTKFile>\n",
        ]
    )
    path.write_text(body)
    return path


def _polyhedra(
    mesh: PolyMesh,
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """VTK polyhedron arrays of every cell (none empty).

    ``connectivity``, ``offsets``, ``faces``, ``faceoffsets``, as the module docs say.
    """
    cf = mesh.cell_faces
    per_cell = np.diff(cf.offsets)
    sizes = mesh.face_sizes[cf.faces]
    # Each face's vertices as the cell sees it: reversed (first vertex kept) where the
    # cell is the neighbour, so that every face of the stream points out of its cell.
    within = np.arange(sizes.sum()) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    k = np.repeat(sizes, sizes)
    position = np.where(np.repeat(cf.outward, sizes), within, (k - within) % k)
    vertices = mesh.face_vertices[np.repeat(mesh.face_offsets[cf.faces], sizes) + position]
    # The stream: per cell [n_faces, then per face: size, vertices...].
    stream_len = 1 + np.add.reduceat(sizes + 1, cf.offsets[:-1])
    face_offsets = np.cumsum(stream_len)
    stream = np.empty(int(face_offsets[-1]), dtype=np.intp)
    cell_start = face_offsets - stream_len
    stream[cell_start] = per_cell
    entry_cell = np.repeat(np.arange(mesh.n_cells), per_cell)
    # Entry j (a face of cell c) starts after the cell's count and the earlier entries.
    before = np.cumsum(sizes + 1) - (sizes + 1)
    entry_start = cell_start[entry_cell] + 1 + before - before[cf.offsets[:-1]][entry_cell]
    stream[entry_start] = sizes
    stream[np.repeat(entry_start + 1, sizes) + within] = vertices
    # Connectivity: each cell's distinct points, in increasing order.
    # np.sort and a mask, not np.unique: numpy 2's hashing unique is 5x slower here.
    pairs = np.sort(np.repeat(entry_cell, sizes).astype(np.int64) * len(mesh.points) + vertices)
    pairs = pairs[np.diff(pairs, prepend=-1) != 0]
    owner_of_pair = pairs // len(mesh.points)
    connectivity = pairs % len(mesh.points)
    offsets = np.cumsum(np.bincount(owner_of_pair, minlength=mesh.n_cells))
    return connectivity, offsets, stream, face_offsets


def _split_for_vtk(mesh: PolyMesh) -> PolyMesh:
    """``mesh`` with the faces VTK would triangulate wrongly replaced by their triangles.

    VTK triangulates a polygon face (``vtkPolygon::EarCutTriangulation``: its triangle
    filter, surface filters and rendering) by an ear cut that treats corners closer than
    1e-6 of the face's bounding-box diagonal as one, and that can stop halfway on a
    non-convex face whose reflex corners turn by ~1e-3 (measured, VTK 9.7: up to 8.5e-6
    of a boundary cell's volume lost on the bunny, 6.8e-5 on the cheese). So every
    non-convex face, and every face with an edge shorter than ``_SHORT_EDGE`` of its
    diagonal, is written as its constrained Delaunay triangles (GEOS, as
    :meth:`Diagram.cells` triangulates them), which VTK takes as they are. Each triangle
    is a face of the same cells, so it is still written once each way round, and every
    cell keeps its points.
    """
    split = non_convex_faces(mesh) | _has_short_edge(mesh) | _repeats_a_vertex(mesh)
    if not split.any():
        return mesh
    made_face, made = planar_triangles(mesh, np.flatnonzero(split))
    flat = (made[:, 0] == made[:, 1]) | (made[:, 1] == made[:, 2]) | (made[:, 2] == made[:, 0])
    if flat.any():  # GEOS failed on a face with a hole, whose fan would fold onto itself
        raise InvalidMeshError(f"face {made_face[flat][0]} (with a hole) cannot be triangulated")
    kept = np.flatnonzero(~split)
    # Faces then triangles, each triangle where its face was (stable sort by face).
    origin = np.concatenate([kept, made_face])
    sizes = np.concatenate([mesh.face_sizes[kept], np.full(len(made), 3)])
    within = np.arange(mesh.face_sizes[kept].sum()) - np.repeat(
        np.cumsum(mesh.face_sizes[kept]) - mesh.face_sizes[kept], mesh.face_sizes[kept]
    )
    old = mesh.face_vertices[np.repeat(mesh.face_offsets[kept], mesh.face_sizes[kept]) + within]
    order = np.argsort(origin, kind="stable")
    vertices, ends = _permute(
        np.concatenate([old, made.ravel()]).astype(np.intp), np.cumsum(sizes), order
    )
    origin = origin[order]
    return PolyMesh(
        points=mesh.points,
        face_offsets=np.concatenate([[0], ends]).astype(np.intp),
        face_vertices=vertices,
        owner=mesh.owner[origin],
        neighbour=mesh.neighbour[origin],
        boundary_element=mesh.boundary_element[origin],
        n_cells=mesh.n_cells,
    )


def _repeats_a_vertex(mesh: PolyMesh) -> NDArray[np.bool_]:
    """Shape (f,): keyhole faces (a face with a hole, its bridge edge walked both ways)."""
    sizes = mesh.face_sizes
    face_of = np.repeat(np.arange(mesh.n_faces, dtype=np.int64), sizes)
    key = np.sort(face_of * len(mesh.points) + mesh.face_vertices)
    out = np.zeros(mesh.n_faces, dtype=bool)
    out[key[1:][key[1:] == key[:-1]] // len(mesh.points)] = True
    return out


def _has_short_edge(mesh: PolyMesh) -> NDArray[np.bool_]:
    """Shape (f,): faces with an edge shorter than ``_SHORT_EDGE`` of their diagonal.

    The diagonal is the face's bounding box's, as VTK's polygon tolerance (1e-6 of it).
    """
    sizes = mesh.face_sizes
    start = mesh.face_offsets[:-1]
    face_of = np.repeat(np.arange(mesh.n_faces), sizes)
    pos = np.arange(len(mesh.face_vertices)) - start[face_of]
    p = mesh.points[mesh.face_vertices]
    following = p[start[face_of] + (pos + 1) % sizes[face_of]]
    shortest = np.minimum.reduceat(np.linalg.norm(following - p, axis=1), start)
    low = np.minimum.reduceat(p, start, axis=0)
    high = np.maximum.reduceat(p, start, axis=0)
    return shortest < _SHORT_EDGE * np.linalg.norm(high - low, axis=1)


def _permute(
    values: NDArray[np.intp], ends: NDArray[np.intp], order: NDArray[np.intp]
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Segments ``values[ends[i-1]:ends[i]]`` rearranged as ``order`` says; new ends."""
    sizes = np.diff(ends, prepend=0)[order]
    starts = (ends - np.diff(ends, prepend=0))[order]
    within = np.arange(sizes.sum()) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    return values[np.repeat(starts, sizes) + within], np.cumsum(sizes)


def _polygons(
    mesh: PolyMesh,
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Per polygon piece (2D): its cell, then VTK connectivity and offsets."""
    site, rings = [], []
    for cell, pieces in enumerate(mesh.cell_polygons()):
        for ring in pieces:
            site.append(cell)
            rings.append(ring)
    connectivity = np.concatenate(rings) if rings else np.zeros(0, dtype=np.intp)
    offsets = np.cumsum([len(r) for r in rings]).astype(np.intp)
    return np.asarray(site, dtype=np.intp), connectivity, offsets


def _data_array(name: str, array: NDArray, vtk_type: str, components: int = 1) -> str:
    """A DataArray in VTK's inline binary: UInt64 byte count, then the data, base64."""
    raw = np.ascontiguousarray(array).tobytes()
    encoded = base64.b64encode(np.uint64(len(raw)).tobytes() + raw).decode("ascii")
    # NumberOfComponents only for vectors: meshio reshapes a declared single component
    # into a column, which its polyhedron reader then cannot index.
    count = f' NumberOfComponents="{components}"' if components > 1 else ""
    head = f'<DataArray type="{vtk_type}" Name="{name}"{count} format="binary">'
    return f"{head}{encoded}</DataArray>"
