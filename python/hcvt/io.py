"""Reading domains from files: polygons (.wkt, .geojson) and meshes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import shapely
from shapely.geometry import MultiPolygon, Polygon, shape

from hcvt.diagram import Diagram
from hcvt.domain import Domain
from hcvt.errors import InvalidDomainError

POLYGON_SUFFIXES = {".wkt", ".geojson", ".json"}


def load_domain(path: str | Path, *, repair: bool = False) -> Domain:
    """Read a domain from a file.

    Parameters
    ----------
    path : str or Path
        ``.wkt`` or ``.geojson`` (a Polygon, MultiPolygon, Feature or FeatureCollection of
        them: every polygonal part becomes part of the domain).
    repair : bool, default False
        Passed on to :meth:`Domain.from_polygon`.

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
    raise InvalidDomainError(f"{path.name}: unknown file type {suffix!r}; polygons: .wkt, .geojson")


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


def write_cells(diagram: Diagram, path: str | Path) -> None:
    """Write the clipped cells with per-cell ``id``, ``G``, ``volume``.

    2D: a GeoJSON FeatureCollection (``.geojson``), one Feature per cell.
    """
    path = Path(path)
    if diagram.domain.dim == 2:
        if path.suffix.lower() not in (".geojson", ".json"):
            raise ValueError(f"2D cells are written as .geojson, got {path.name}")
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
        return
    raise NotImplementedError("3D cells are written by hcvt.io.write_vtu / write_ply")


def _finite(x: float) -> float | None:
    return float(x) if np.isfinite(x) else None
