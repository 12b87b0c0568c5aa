"""Reading domains from files: polygons (.wkt, .geojson) and meshes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon, shape

from hcvt.errors import InvalidDomainError
from hcvt.geometry.domain import Domain
from hcvt.lazy import load

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
        loaded = load("trimesh").load(path, process=False, force="mesh")
    except (ValueError, KeyError, IndexError, TypeError) as err:
        raise InvalidDomainError(f"{path.name}: cannot read a mesh ({err})") from err
    vertices = np.asarray(loaded.vertices, dtype=np.float64)
    faces = np.asarray(loaded.faces, dtype=np.intp)
    if len(faces) == 0:  # trimesh reads text, an empty file or a bare header as no mesh
        raise InvalidDomainError(f"{path.name}: cannot read a mesh (no triangles in the file)")
    if path.suffix.lower() == ".stl":
        vertices, inverse = np.unique(vertices, axis=0, return_inverse=True)
        faces = inverse.ravel()[faces]
    return vertices, faces


def _read_obj(path: Path) -> tuple[NDArray[np.float64], NDArray[np.intp]]:
    vertices: list[list[float]] = []
    faces: list[list[int]] = []
    try:
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            parts = line.split()
            if not parts:
                continue
            if parts[0] == "v":
                if len(parts) < 4:
                    raise ValueError(f"line {number}: a vertex needs 3 coordinates: {line!r}")
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
    try:
        text = path.read_text(encoding="utf-8")  # UnicodeDecodeError is a ValueError
        if path.suffix.lower() == ".wkt":
            geometries = [shapely.from_wkt(text.strip())]
        else:
            geometries = [shape(g) for g in _geojson_geometries(json.loads(text))]
    except (
        ValueError,
        KeyError,
        TypeError,
        AttributeError,  # shapely's shape() of a mapping without "type"
        shapely.errors.ShapelyError,
    ) as err:
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


def _geojson_geometries(obj: object) -> list[dict]:
    if not isinstance(obj, dict) or not isinstance(obj.get("type"), str):
        raise ValueError(f"a GeoJSON object has a string 'type', got {str(obj)[:60]}")
    kind = obj.get("type")
    if kind == "FeatureCollection":
        return [f["geometry"] for f in obj["features"] if f.get("geometry")]
    if kind == "Feature":
        return [obj["geometry"]]
    if kind == "GeometryCollection":
        return list(obj["geometries"])
    return [obj]
