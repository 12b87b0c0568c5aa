"""Reading domains from files: polygons (.wkt, .geojson) and meshes."""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import TYPE_CHECKING, cast

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon, shape

from hcvt.domain import Domain
from hcvt.errors import InvalidDomainError

if TYPE_CHECKING:
    from hcvt.diagram import Diagram

POLYGON_SUFFIXES = {".wkt", ".geojson", ".json"}
MESH_SUFFIXES = {".obj", ".off", ".ply", ".stl"}


def load_domain(path: str | Path, *, repair: bool = False) -> Domain:
    """Read a domain from a file.

    Parameters
    ----------
    path : str or Path
        ``.wkt`` or ``.geojson`` (a Polygon, MultiPolygon, Feature or FeatureCollection of
        them: every polygonal part becomes part of the domain), or a triangle mesh
        ``.obj``, ``.off``, ``.ply``, ``.stl`` read as indexed (vertices are not welded,
        except in STL, which stores every triangle's corners separately).
    repair : bool, default False
        Passed on to :meth:`Domain.from_polygon` or :meth:`Domain.from_mesh`.

    Raises
    ------
    FileNotFoundError
        No such file.
    InvalidDomainError
        Unreadable content, no polygon in it, or an invalid polygon.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no such file: {path}")
    suffix = path.suffix.lower()
    if suffix in POLYGON_SUFFIXES:
        return Domain.from_polygon(read_polygon(path), repair=repair)
    if suffix in MESH_SUFFIXES:
        vertices, faces = read_mesh(path)
        return Domain.from_mesh(vertices, faces, repair=repair)
    raise InvalidDomainError(
        f"{path.name}: unknown file type {suffix!r}; "
        "polygons: .wkt, .geojson; meshes: .obj, .off, .ply, .stl"
    )


def read_mesh(path: str | Path) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    """Vertices (V, 3) and triangles (F, 3) of a mesh file, as indexed in the file.

    OBJ is read directly (``v`` and ``f`` records; polygons fanned; texture and normal
    indices ignored), because trimesh splits OBJ vertices by normal; OFF, PLY and STL go
    through ``trimesh.load(process=False)``; STL corners are welded by exact position.
    """
    path = Path(path)
    if path.suffix.lower() == ".obj":
        return _read_obj(path)
    try:
        import trimesh  # slow to import (~0.5 s): only when a file needs it

        loaded = cast("trimesh.Trimesh", trimesh.load(path, process=False, force="mesh"))
    except (ValueError, KeyError, IndexError, TypeError) as err:
        raise InvalidDomainError(f"{path.name}: cannot read a mesh ({err})") from err
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.intp)
    if path.suffix.lower() == ".stl":
        vertices, inverse = np.unique(vertices, axis=0, return_inverse=True)
        faces = inverse.ravel()[faces]
    return vertices, faces


def _read_obj(path: Path) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    vertices: list[list[float]] = []
    faces: list[list[int]] = []
    try:
        for line in path.read_text(errors="replace").splitlines():
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                vertices.append([float(x) for x in parts[1:4]])
            elif parts[0] == "f":
                idx = [int(p.split("/")[0]) for p in parts[1:]]
                idx = [i - 1 if i > 0 else len(vertices) + i for i in idx]
                faces.extend([idx[0], idx[k], idx[k + 1]] for k in range(1, len(idx) - 1))
    except ValueError as err:
        raise InvalidDomainError(f"{path.name}: cannot read OBJ ({err})") from err
    if not vertices or not faces:
        raise InvalidDomainError(f"{path.name}: no vertices or faces in the file")
    return np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.intp)


def read_polygon(path: Path) -> Polygon | MultiPolygon:
    """Read the polygonal content of a ``.wkt`` or ``.geojson`` file as one geometry."""
    text = path.read_text()
    try:
        if path.suffix.lower() == ".wkt":
            geometries = [shapely.from_wkt(text.strip())]
        else:
            geometries = [shape(g) for g in _geojson_geometries(json.loads(text))]
    except (ValueError, KeyError, TypeError, shapely.errors.ShapelyError) as err:
        raise InvalidDomainError(f"{path.name}: cannot read a polygon ({err})") from err
    polygons: list[Polygon] = []
    for g in geometries:
        if isinstance(g, Polygon):
            polygons.append(g)
        elif isinstance(g, MultiPolygon):
            polygons.extend(g.geoms)
    if not polygons:
        raise InvalidDomainError(f"{path.name}: no Polygon or MultiPolygon in the file")
    return polygons[0] if len(polygons) == 1 else MultiPolygon(polygons)


def _geojson_geometries(obj: dict) -> list[dict]:
    kind = obj.get("type")
    if kind == "FeatureCollection":
        return [f["geometry"] for f in obj["features"] if f.get("geometry")]
    if kind == "Feature":
        return [obj["geometry"]]
    if kind == "GeometryCollection":
        return list(obj["geometries"])
    return [obj]


# ---------------------------------------------------------------------------- export
def write_cells(diagram: Diagram, path: str | Path) -> Path:
    """Write the clipped cells with per-cell ``id`` (the site's row), ``G`` and ``volume``.

    2D: ``.geojson`` (or ``.json``), a FeatureCollection with one Feature per cell.
    3D: ``.vtu``, an UnstructuredGrid for ParaView with one VTK polyhedron per non-empty
    cell (its closed boundary triangulation from :meth:`Diagram.cells`) and those values as
    cell data; or ``.ply``, binary PLY of every cell's triangles with the face property
    ``cell`` (the site's row).

    Returns
    -------
    Path
        The path written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if diagram.domain.dim == 2:
        if suffix not in (".geojson", ".json"):
            raise ValueError(f"2D cells are written as .geojson, got {path.name}")
        _write_geojson(path, diagram)
        return path
    if suffix not in (".vtu", ".ply"):
        raise ValueError(f"3D cells are written as .vtu or .ply, got {path.name}")
    ids, points, faces = _stack_cells(diagram.cells())
    if suffix == ".vtu":
        _write_vtu(path, ids, points, faces, diagram)
    else:
        _write_ply(path, points, faces)
    return path


def _write_geojson(path: Path, diagram: Diagram) -> None:
    features = [
        {
            "type": "Feature",
            "geometry": shapely.geometry.mapping(cell),
            "properties": {"id": i, "G": _finite(g), "volume": float(v)},
        }
        for i, (cell, g, v) in enumerate(
            zip(diagram.cells(), diagram.G, diagram.volume, strict=True)
        )
    ]
    path.write_text(json.dumps({"type": "FeatureCollection", "features": features}))


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def _stack_cells(
    cells: list[tuple[NDArray[np.float64], NDArray[np.intp]]],
) -> tuple[NDArray[np.int64], NDArray[np.float64], list[tuple[int, NDArray[np.int64]]]]:
    """Non-empty cells' ids, all their points (P, 3), and (id, global faces) per cell."""
    ids, points, faces = [], [], []
    start = 0
    for i, (v, f) in enumerate(cells):
        if len(f) == 0:
            continue
        ids.append(i)
        points.append(v)
        faces.append((i, f + start))
        start += len(v)
    pts = np.concatenate(points) if points else np.zeros((0, 3))
    return np.asarray(ids, dtype=np.int64), pts, faces


def _b64(array: NDArray) -> str:
    """VTK inline binary: a UInt64 byte count, then the data, base64 together."""
    raw = np.ascontiguousarray(array).tobytes()
    return base64.b64encode(np.uint64(len(raw)).tobytes() + raw).decode("ascii")


def _data_array(name: str, array: NDArray, vtk_type: str, components: int = 1) -> str:
    return (
        f'<DataArray type="{vtk_type}" Name="{name}" NumberOfComponents="{components}" '
        f'format="binary">{_b64(array)}</DataArray>'
    )


def _write_vtu(
    path: Path,
    ids: NDArray[np.int64],
    points: NDArray[np.float64],
    faces: list[tuple[int, NDArray[np.int64]]],
    diagram: Diagram,
) -> None:
    connectivity, offsets, face_stream, face_offsets = [], [], [], []
    n_conn = n_face = 0
    for _, f in faces:
        used = np.unique(f)
        connectivity.append(used)
        n_conn += len(used)
        offsets.append(n_conn)
        stream = np.column_stack([np.full(len(f), 3), f]).ravel()
        face_stream.append(np.concatenate([[len(f)], stream]))
        n_face += len(stream) + 1
        face_offsets.append(n_face)
    i64 = np.int64
    body = "".join(
        [
            '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" ',
            'byte_order="LittleEndian" header_type="UInt64"><UnstructuredGrid>',
            f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{len(ids)}">',
            "<Points>",
            _data_array("Points", points.astype(np.float64), "Float64", 3),
            "</Points><Cells>",
            _data_array("connectivity", np.concatenate(connectivity).astype(i64), "Int64"),
            _data_array("offsets", np.asarray(offsets, dtype=i64), "Int64"),
            _data_array("types", np.full(len(ids), 42, dtype=np.uint8), "UInt8"),
            _data_array("faces", np.concatenate(face_stream).astype(i64), "Int64"),
            _data_array("faceoffsets", np.asarray(face_offsets, dtype=i64), "Int64"),
            '</Cells><CellData Scalars="G">',
            _data_array("id", ids, "Int64"),
            _data_array("G", diagram.G[ids].astype(np.float64), "Float64"),
            _data_array("volume", diagram.volume[ids].astype(np.float64), "Float64"),
            "</CellData></Piece></UnstructuredGrid></VTKFile>\n",
        ]
    )
    path.write_text(body)


def _write_ply(
    path: Path, points: NDArray[np.float64], faces: list[tuple[int, NDArray[np.int64]]]
) -> None:
    n_faces = sum(len(f) for _, f in faces)
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(points)}\nproperty double x\nproperty double y\nproperty double z\n"
        f"element face {n_faces}\nproperty list uchar int vertex_indices\nproperty int cell\n"
        "end_header\n"
    )
    record = np.dtype([("n", "u1"), ("v", "<i4", (3,)), ("cell", "<i4")])
    table = np.zeros(n_faces, dtype=record)
    at = 0
    for i, f in faces:
        table["n"][at : at + len(f)] = 3
        table["v"][at : at + len(f)] = f
        table["cell"][at : at + len(f)] = i
        at += len(f)
    with path.open("wb") as out:
        out.write(header.encode("ascii"))
        out.write(np.ascontiguousarray(points, dtype="<f8").tobytes())
        out.write(table.tobytes())
