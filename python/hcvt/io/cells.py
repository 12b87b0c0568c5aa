"""A diagram's cells written for viewing: GeoJSON or GeoPackage (2D), VTU or PLY (3D).

The VTU is the conforming mesh's (:func:`hcvt.io.vtu.write_vtu`, the one VTU writer):
each cell a VTK polyhedron with its planar faces. PLY and the 2D GeoJSON are a cell soup:
each cell's own closed boundary (:meth:`hcvt.diagram.Diagram.cells`), with no shared
vertices.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray

from hcvt.geometry.crs import geojson_crs_member
from hcvt.io.geo import Diagram, write_geopackage
from hcvt.io.vtu import write_pieces_vtu, write_vtu


def write_cells(diagram: Diagram, path: str | Path) -> Path:
    """Write the clipped cells with per-cell ``G`` and ``volume``.

    2D: ``.geojson`` (or ``.json``), a FeatureCollection with one Feature per cell and the
    properties ``id`` (the site's row), ``G`` and ``volume``, and a ``crs`` member naming
    the domain's CRS when it has one (as GDAL writes projected GeoJSON); or ``.gpkg``, a
    GeoPackage layer ``cells`` with every column of :meth:`hcvt.Diagram.to_geopandas`
    (``site`` the row) in the domain's CRS (needs geopandas, ``pip install 'hcvt[geo]'``).
    3D: ``.vtu``, an UnstructuredGrid for ParaView with one VTK polyhedron per non-empty
    cell, its faces those of the conforming mesh (``Diagram.mesh()``), and cell data
    ``site`` (the site's row), ``G`` and ``volume``; or ``.ply``, binary PLY of every
    cell's boundary triangles with the face property ``cell`` (the site's row).
    On a triangle surface: ``.vtu``, one VTK polygon per piece of a cell
    (:func:`hcvt.io.vtu.write_pieces_vtu`, cell data ``site``, ``face``, ``G`` and
    ``area``); ``.ply``, the pieces' fan triangles (:meth:`hcvt.Diagram.cells`).

    Returns
    -------
    Path
        The path written.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if diagram.domain.dim == 2:
        if suffix == ".gpkg":
            return write_geopackage(diagram, path)
        if suffix not in (".geojson", ".json"):
            raise ValueError(f"2D cells are written as .geojson or .gpkg, got {path.name}")
        _write_geojson(path, diagram)
        return path
    if suffix == ".vtu" and diagram.domain.is_surface:
        data: dict[str, ArrayLike] = {"area": diagram.volume, "G": diagram.G}
        return write_pieces_vtu(diagram.surface_pieces(), path, cell_data=data)
    if suffix == ".vtu":
        return write_vtu(diagram.mesh(), path, cell_data={"G": diagram.G, "volume": diagram.volume})
    if suffix != ".ply":
        raise ValueError(f"3D cells are written as .vtu or .ply, got {path.name}")
    points, faces = _stack_cells(diagram.cells())
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
    collection: dict[str, Any] = {"type": "FeatureCollection"}
    if diagram.domain.crs is not None:
        collection["crs"] = geojson_crs_member(diagram.domain.crs)
    collection["features"] = features
    path.write_text(json.dumps(collection))


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None


def _stack_cells(
    cells: list[tuple[NDArray[np.float64], NDArray[np.intp]]],
) -> tuple[NDArray[np.float64], list[tuple[int, NDArray[np.int64]]]]:
    """All non-empty cells' points (P, 3), and (row, faces into those points) per cell."""
    points, faces = [], []
    start = 0
    for i, (v, f) in enumerate(cells):
        if len(f) == 0:
            continue
        points.append(v)
        faces.append((i, f + start))
        start += len(v)
    pts = np.concatenate(points) if points else np.zeros((0, 3))
    return pts, faces


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
