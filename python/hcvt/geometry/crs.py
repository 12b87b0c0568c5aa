"""Coordinate reference systems of 2D domains from GIS data (issue 31).

A domain keeps the CRS of the data it was read from (``Domain.crs``, a ``pyproj.CRS``),
and every table or file of cells made from it carries that CRS on. Voronoi cells, areas,
centroids and G are planar quantities in the coordinates' own length unit, so a
geographic CRS (longitude and latitude in degrees) is refused: a degree of longitude is
not a length, and its ground size changes with latitude. Projecting is the user's choice
(an equal-area or a conformal projection answer different questions), so hcvt asks for it
rather than picking one.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hcvt.errors import InvalidDomainError
from hcvt.lazy import load


def projected_crs(crs: Any, coordinates: ArrayLike | None = None) -> Any:
    """``crs`` as a ``pyproj.CRS``, or an error unless it is a projected (planar) one.

    Parameters
    ----------
    crs : pyproj.CRS, str or int
        Anything ``pyproj.CRS.from_user_input`` takes: ``"EPSG:2263"``, ``2263``, a WKT or
        PROJ string, a ``pyproj.CRS``.
    coordinates : array_like, shape (m, 2), optional
        The domain's coordinates, for a better message when a CRS says degrees but the
        numbers cannot be (a GeoJSON file without a ``crs`` member is read as WGS 84 by
        GDAL, whatever its coordinates are).

    Returns
    -------
    pyproj.CRS

    Raises
    ------
    InvalidDomainError
        ``crs`` is not a CRS pyproj knows, or it is geographic (longitude/latitude).
    ModuleNotFoundError
        pyproj is not installed (``pip install 'hcvt[geo]'``).
    """
    pyproj = load("pyproj")
    try:
        parsed = pyproj.CRS.from_user_input(crs)
    except pyproj.exceptions.CRSError as err:
        raise InvalidDomainError(f"not a coordinate reference system: {crs!r} ({err})") from err
    if parsed.is_geographic:
        message = (
            f"the domain's CRS {_name(parsed)} is geographic (longitude/latitude in degrees): "
            "cells, areas and G need planar coordinates in a length unit, so project it first, "
            "e.g. gdf.to_crs(gdf.estimate_utm_crs()) for a GeoDataFrame gdf"
        )
        if coordinates is not None:
            extent = float(np.max(np.abs(np.asarray(coordinates, dtype=np.float64))))
            if extent > 360:
                message += (
                    f"; its coordinates reach {extent:.6g}, which are not degrees: if they "
                    "are already projected, say in which CRS with crs= (GDAL reads a GeoJSON "
                    "file without a 'crs' member as WGS 84)"
                )
        raise InvalidDomainError(message)
    return parsed


def _name(crs: Any) -> str:
    authority = crs.to_authority()
    return f"{authority[0]}:{authority[1]} ({crs.name})" if authority else repr(crs.name)


def geojson_crs_member(crs: Any) -> dict[str, Any]:
    """The GeoJSON 2008 ``crs`` member naming ``crs``, as GDAL writes and reads it.

    RFC 7946 dropped the member (its coordinates are always WGS 84), but GDAL, QGIS and
    GeoPandas still write and honour it for projected data, which is what hcvt's cells
    are in.
    """
    authority = crs.to_authority()
    name = f"urn:ogc:def:crs:{authority[0]}::{authority[1]}" if authority else crs.to_wkt()
    return {"type": "name", "properties": {"name": name}}
