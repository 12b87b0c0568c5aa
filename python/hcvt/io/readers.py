"""Reading domains: polygons (.wkt, .geojson, any GIS format GeoPandas reads) and meshes."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon, shape

from hcvt.errors import InvalidDomainError
from hcvt.geometry.domain import Domain
from hcvt.io.geo import is_geo_object, read_geo
from hcvt.lazy import load

POLYGON_SUFFIXES = {".wkt", ".geojson", ".json"}
MESH_SUFFIXES = {".obj", ".off", ".ply", ".stl"}
#: Vector formats read through GeoPandas (pyogrio, GDAL); a folder (a File Geodatabase,
#: a folder of Shapefiles) too.
GIS_SUFFIXES = {
    ".gpkg", ".shp", ".fgb", ".gml", ".kml", ".gpx", ".sqlite", ".tab", ".mif", ".zip",
    ".geojsonl", ".geojsons", ".topojson",
}  # fmt: skip


def load_domain(
    path: str | Path | Any,
    *,
    repair: bool = False,
    layer: str | int | None = None,
    feature: int | None = None,
    query: str | None = None,
    crs: Any = None,
    surface: bool = False,
) -> Domain:
    """Read a domain from a file, or from a GeoDataFrame / GeoSeries.

    Parameters
    ----------
    path : str, Path, GeoDataFrame or GeoSeries
        A triangle mesh ``.obj``, ``.off``, ``.ply``, ``.stl``, read as indexed (vertices
        are not welded, except in STL, which stores every triangle's corners separately).
        A polygon: ``.wkt``; ``.geojson`` / ``.json`` (a Polygon, MultiPolygon, Feature or
        FeatureCollection of them: every polygonal part becomes part of the domain; the
        CRS of its ``crs`` member kept, and none assumed without one, since hcvt's GeoJSON
        is planar); a vector file GeoPandas reads (:data:`GIS_SUFFIXES`: GeoPackage
        ``.gpkg``, Shapefile ``.shp``, FlatGeobuf ``.fgb`` ..., or a folder such as a File
        Geodatabase), or a GeoDataFrame or GeoSeries itself, their CRS kept as
        ``domain.crs``.
    repair : bool, default False
        Passed on to :meth:`Domain.from_polygon` or :meth:`Domain.from_mesh`.
    layer : str or int, optional
        GIS files: the layer to read (GeoPackage).
    feature : int, optional
        GIS data: keep only this feature, by position (after ``query``).
    query : str, optional
        GIS data: keep the features ``GeoDataFrame.query(query)`` keeps, e.g.
        ``"BoroName == 'Staten Island'"``. With ``feature``, ``query`` and ``layer``, a
        GeoJSON file is read by GeoPandas too.
    crs : pyproj.CRS, str or int, optional
        Polygons: the coordinates' CRS, replacing the one the data declares (for data
        that declares none, or the wrong one). It must be projected.
    surface : bool, default False
        Meshes: the triangle surface itself (:meth:`Domain.from_surface`, restricted
        Voronoi diagrams on it) instead of the solid it bounds; open meshes allowed.

    Returns
    -------
    Domain
        2D domains read from GIS data carry their CRS in ``domain.crs``.

    Raises
    ------
    FileNotFoundError
        No such file.
    InvalidDomainError
        Unreadable content, no polygon in it, an invalid polygon, no such feature, a
        geographic (longitude/latitude) CRS: project the data first.
    ValueError
        ``layer``, ``feature``, ``query`` or ``crs`` for a mesh.
    ModuleNotFoundError
        GIS data without geopandas (``pip install 'hcvt[geo]'``).

    Examples
    --------
    >>> import hcvt
    >>> from hcvt.experiments.base import data_dir
    >>> island = data_dir() / "2d" / "nybb_staten_island_main.geojson"
    >>> hcvt.load_domain(island, crs="EPSG:2263")  # State Plane feet, undeclared in the file
    <hcvt.Domain polygon, volume=1.62242e+09, crs=EPSG:2263>
    """
    gis: dict[str, Any] = dict(layer=layer, feature=feature, query=query)
    if is_geo_object(path):
        return read_geo(path, layer=layer, feature=feature, query=query, crs=crs, repair=repair)
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"no such file: {path}")
    suffix = path.suffix.lower()
    if suffix in MESH_SUFFIXES:
        given = [name for name, value in {**gis, "crs": crs}.items() if value is not None]
        if given:
            raise ValueError(f"{', '.join(given)}: for polygon data only, not {path.name}")
        vertices, faces = read_mesh(path)
        if surface:
            if repair:
                raise ValueError("repair: for solids only, not with surface=True")
            return Domain.from_surface(vertices, faces)
        return Domain.from_mesh(vertices, faces, repair=repair)
    if surface:
        raise ValueError(f"surface=True: for triangle meshes only, not {path.name}")
    plain = all(value is None for value in gis.values())
    if suffix in POLYGON_SUFFIXES and plain:
        geometry, declared = read_polygon_and_crs(path)
        return Domain.from_polygon(
            geometry, repair=repair, crs=crs if crs is not None else declared
        )
    if suffix == ".wkt":
        raise ValueError("layer, feature and query are for GIS files, not .wkt")
    if suffix in GIS_SUFFIXES | POLYGON_SUFFIXES or path.is_dir():
        return read_geo(path, layer=layer, feature=feature, query=query, crs=crs, repair=repair)
    raise InvalidDomainError(
        f"{path.name}: unknown file type {suffix!r}; polygons: .wkt, .geojson, or a GIS file "
        f"GeoPandas reads ({', '.join(sorted(GIS_SUFFIXES))}); meshes: .obj, .off, .ply, .stl"
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
    return read_polygon_and_crs(path)[0]


def read_polygon_and_crs(path: Path) -> tuple[Polygon | MultiPolygon, str | None]:
    """The polygonal content of a ``.wkt`` or ``.geojson`` file, and its declared CRS.

    The CRS is the name in a GeoJSON ``crs`` member (``"urn:ogc:def:crs:EPSG::2263"``),
    as GDAL writes it for projected data; None for WKT and for GeoJSON without one.
    """
    crs = None
    try:
        text = path.read_text(encoding="utf-8")  # UnicodeDecodeError is a ValueError
        if path.suffix.lower() == ".wkt":
            geometries = [shapely.from_wkt(text.strip())]
        else:
            content = json.loads(text)
            geometries = [shape(g) for g in _geojson_geometries(content)]
            crs = _crs_member(content)
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
    return (polygons[0] if len(polygons) == 1 else MultiPolygon(polygons)), crs


def _crs_member(content: dict) -> str | None:
    """The name of a GeoJSON 2008 ``{"type": "name", ...}`` crs member, or None."""
    member = content.get("crs")
    if member is None:
        return None
    name = member.get("properties", {}).get("name") if isinstance(member, dict) else None
    if not isinstance(name, str):
        raise ValueError(f"a crs member names its CRS in properties.name, got {member!r}")
    return name


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
