"""GeoJSON of a 2D mesh: one Feature per cell, built on the mesh's shared vertices.

Unlike :func:`hcvt.io.write_cells` (each cell cut by GEOS on its own), neighbouring cells
here have bitwise the same coordinates along their shared edges: the features form a
valid polygonal coverage (``shapely.coverage_is_valid``), which GIS tools can turn into a
topology (TopoJSON, PostGIS topology) without snapping.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from numpy.typing import ArrayLike

from hcvt.geometry.crs import geojson_crs_member
from hcvt.mesh.polymesh import PolyMesh


def write_geojson(
    mesh: PolyMesh,
    path: str | Path,
    *,
    cell_data: dict[str, ArrayLike] | None = None,
    crs: Any = None,
) -> Path:
    """Write a 2D ``mesh`` as a GeoJSON FeatureCollection, one Feature per cell.

    Feature ``i`` is cell ``i``: a Polygon, a MultiPolygon (a cell the domain cuts in
    pieces), or null geometry for an empty cell; properties ``id`` and one per
    ``cell_data`` entry (shape (n,) each; NaN becomes null). ``crs`` (a ``pyproj.CRS``,
    e.g. a domain's ``crs``) is named in a ``crs`` member, as GDAL writes projected data.

    Raises
    ------
    ValueError
        A 3D mesh.
    """
    if mesh.dim != 2:
        raise ValueError("GeoJSON holds 2D meshes only; write a 3D mesh as .vtu or OpenFOAM")
    mesh.check()
    columns = {k: np.asarray(v, dtype=np.float64) for k, v in (cell_data or {}).items()}
    features = []
    for i, loops in enumerate(mesh.cell_loops()):
        properties: dict[str, int | float | None] = {"id": i}
        for name, values in columns.items():
            properties[name] = float(values[i]) if np.isfinite(values[i]) else None
        geometry = _geometry([mesh.points[r] for r in loops])
        features.append({"type": "Feature", "geometry": geometry, "properties": properties})
    collection: dict[str, Any] = {"type": "FeatureCollection"}
    if crs is not None:
        collection["crs"] = geojson_crs_member(crs)
    collection["features"] = features
    path = Path(path)
    path.write_text(json.dumps(collection))
    return path


def _geometry(rings: list[np.ndarray]) -> dict | None:
    """GeoJSON geometry of a cell's loops, or None for an empty cell.

    Outer rings counter-clockwise, holes clockwise (RFC 7946 §3.1.6), each hole in the
    outer ring that contains it.
    """
    if not rings:
        return None
    signed = [shapely.Polygon(r).area * (1 if _ccw(r) else -1) for r in rings]
    shells = [r for r, a in zip(rings, signed, strict=True) if a > 0]
    holes = [r for r, a in zip(rings, signed, strict=True) if a < 0]
    polygons: list[list[list[list[float]]]] = [[_closed(s)] for s in shells]
    for hole in holes:
        inside = shapely.Point(hole.mean(axis=0))
        k = next(
            (k for k, s in enumerate(shells) if shapely.Polygon(s).contains(inside)),
            0,
        )
        polygons[k].append(_closed(hole))
    if len(polygons) == 1:
        return {"type": "Polygon", "coordinates": polygons[0]}
    return {"type": "MultiPolygon", "coordinates": polygons}


def _ccw(ring: np.ndarray) -> bool:
    x, y = ring[:, 0], ring[:, 1]
    return float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)) > 0


def _closed(ring: np.ndarray) -> list[list[float]]:
    return np.vstack([ring, ring[:1]]).tolist()
