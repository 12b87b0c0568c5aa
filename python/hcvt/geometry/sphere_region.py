"""A region of the sphere bounded by lon/lat polygons: ``hcvt.Domain.sphere(region=...)``.

The region is given in degrees of longitude and latitude, as an (m, 2) array of
``(lon, lat)`` (one ring) or a shapely Polygon in lon/lat (its holes are islands). The edge
between consecutive vertices is the **great-circle arc** (the shortest path), not a line of
constant latitude: a long edge along a parallel bows towards the pole; densify such edges
first (e.g. ``shapely.segmentize(polygon, 1.0)``, a vertex every degree) to follow the
parallel. The region must lie within 89° of its vertices' mean direction (inside an open
hemisphere); the core checks the rings (``hcvt-core/src/diagram/sphere_region.rs``).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hcvt.errors import InvalidDomainError


def lonlat_to_unit(lonlat: ArrayLike) -> NDArray[np.float64]:
    """Unit vectors (m, 3) of ``lonlat`` (m, 2) in degrees: ``(cosφ cosλ, cosφ sinλ, sinφ)``."""
    ll = np.asarray(lonlat, dtype=np.float64)
    lon, lat = np.radians(ll[:, 0]), np.radians(ll[:, 1])
    return np.column_stack((np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)))


def unit_to_lonlat(points: ArrayLike) -> NDArray[np.float64]:
    """``(lon, lat)`` (m, 2) in degrees of points (m, 3) (any length), lon in (-180, 180]."""
    p = np.asarray(points, dtype=np.float64)
    lon = np.degrees(np.arctan2(p[:, 1], p[:, 0]))
    lat = np.degrees(np.arctan2(p[:, 2], np.hypot(p[:, 0], p[:, 1])))
    return np.column_stack((lon, lat))


def _ring(coords: Any, what: str) -> NDArray[np.float64]:
    """One ring (m, 2) of lon/lat degrees: checked finite and in range, closing vertex dropped."""
    ring = np.asarray(coords, dtype=np.float64)
    if ring.ndim != 2 or ring.shape[1] < 2:
        raise InvalidDomainError(
            f"{what}: expected (m, 2) lon/lat in degrees, got shape {ring.shape}"
        )
    ring = ring[:, :2]
    bad = ~np.isfinite(ring).all(axis=1)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InvalidDomainError(f"{what}: vertex {k} is not finite ({ring[k].tolist()})")
    if np.any(np.abs(ring[:, 1]) > 90.0):
        k = int(np.flatnonzero(np.abs(ring[:, 1]) > 90.0)[0])
        raise InvalidDomainError(f"{what}: vertex {k} has latitude {ring[k, 1]:g}, beyond ±90°")
    if len(ring) > 1 and np.array_equal(ring[0], ring[-1]):
        ring = ring[:-1]
    return ring


def region_rings(region: Any) -> list[NDArray[np.float64]]:
    """The lon/lat rings (each (m, 2), degrees, not closed) of ``region``.

    ``region``: an (m, 2) array (one ring), a list of such rings (the outline, then holes)
    or a shapely Polygon (exterior, then interiors).

    Raises
    ------
    InvalidDomainError
        A MultiPolygon (one region at a time), an empty polygon, non-finite vertices or
        latitudes beyond ±90°.
    """
    geom_type = getattr(region, "geom_type", None)
    if geom_type == "Polygon":
        if region.is_empty:
            raise InvalidDomainError("region: the polygon is empty")
        rings = [region.exterior, *region.interiors]
        return [
            _ring(np.asarray(r.coords), "region" if k == 0 else f"region hole {k}")
            for k, r in enumerate(rings)
        ]
    if geom_type is not None:
        raise InvalidDomainError(
            f"region: expected an (m, 2) lon/lat array or a shapely Polygon, got a {geom_type} "
            "(give one polygon at a time)"
        )
    if isinstance(region, (list, tuple)) and region and np.ndim(region[0]) == 2:
        # A list of rings (each (m, 2)): the outline, then holes (``Domain.region``).
        return [_ring(r, "region" if k == 0 else f"region hole {k}") for k, r in enumerate(region)]
    return [_ring(region, "region")]
