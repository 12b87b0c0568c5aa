"""GeoPandas in and out: GIS files and GeoDataFrames as domains, cells as a GeoDataFrame.

Reading goes through ``geopandas.read_file`` (pyogrio, so every vector format GDAL reads:
GeoPackage, Shapefile, GeoJSON, FlatGeobuf, ...), one feature or several chosen by
position or by a pandas query, the CRS kept on the domain (:mod:`hcvt.geometry.crs`).
Writing gives a GeoDataFrame whose row ``i`` is the cell of site ``i`` with the
diagram's per-cell quantities as columns, and the domain's CRS; ``.gpkg`` files are that
table written by pyogrio. geopandas is optional (``pip install 'hcvt[geo]'``) and
imported on first use only.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Protocol

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon

from hcvt.errors import InvalidDomainError
from hcvt.geometry.domain import Domain
from hcvt.lazy import load
from hcvt.mesh.pieces import SurfacePieces
from hcvt.mesh.polymesh import PolyMesh


class Diagram(Protocol):
    """What :func:`to_geodataframe` and :func:`hcvt.io.write_cells` read of a Diagram."""

    @property
    def domain(self) -> Domain: ...  # noqa: D102

    @property
    def sites(self) -> NDArray[np.float64]: ...  # noqa: D102

    @property
    def density(self) -> Any: ...  # noqa: D102

    @property
    def volume(self) -> NDArray[np.float64]: ...  # noqa: D102

    @property
    def mass(self) -> NDArray[np.float64]: ...  # noqa: D102

    @property
    def centroid(self) -> NDArray[np.float64]: ...  # noqa: D102

    @property
    def second_moment(self) -> NDArray[np.float64]: ...  # noqa: D102

    @property
    def G(self) -> NDArray[np.float64]: ...  # noqa: D102, N802 (the paper's G)

    @property
    def energy_terms(self) -> NDArray[np.float64]: ...  # noqa: D102

    @property
    def boundary_measure(self) -> NDArray[np.float64]: ...  # noqa: D102

    @property
    def neighbors(self) -> NDArray[np.intp]: ...  # noqa: D102

    def cells(self) -> list[Any]: ...  # noqa: D102

    def mesh(self) -> PolyMesh: ...  # noqa: D102

    def surface_pieces(self) -> SurfacePieces: ...  # noqa: D102


def is_geo_object(source: Any) -> bool:
    """Whether ``source`` is a GeoPandas GeoDataFrame or GeoSeries (without importing it)."""
    module = type(source).__module__ or ""
    return module.split(".")[0] == "geopandas"


def read_geo(
    source: Any,
    *,
    layer: str | int | None = None,
    feature: int | None = None,
    query: str | None = None,
    crs: Any = None,
    repair: bool = False,
) -> Domain:
    """The domain of a GIS file or of a GeoDataFrame / GeoSeries (:func:`load_domain`).

    Parameters
    ----------
    source : str, Path, GeoDataFrame or GeoSeries
        A file ``geopandas.read_file`` reads, or the data itself.
    layer : str or int, optional
        The layer of a multi-layer file (GeoPackage).
    feature : int, optional
        Keep only this row, by position (after ``query``); negative counts from the end.
    query : str, optional
        Keep the rows ``GeoDataFrame.query(query)`` keeps, e.g. ``"BoroName == 'Bronx'"``.
    crs : pyproj.CRS, str or int, optional
        The coordinates' CRS, replacing the one the data declares (for files that declare
        none, or the wrong one).
    repair : bool, default False
        Passed on to :meth:`Domain.from_polygon`.

    Returns
    -------
    Domain
        The polygonal parts of the rows kept (other geometry types are ignored; z is
        dropped), several rows united into the region they cover, with ``domain.crs``
        the data's (or ``crs``).

    Raises
    ------
    InvalidDomainError
        No such feature, a query that keeps nothing or fails, no polygon in what is kept,
        a geographic CRS, or an invalid polygon.
    """
    geopandas = load("geopandas")
    if is_geo_object(source):
        frame = source
        where = f"the {type(source).__name__}"
    else:
        path = Path(source)
        if not path.exists():
            raise FileNotFoundError(f"no such file: {path}")
        where = path.name
        try:
            frame = geopandas.read_file(path, layer=layer)
        except Exception as err:  # pyogrio's DataSourceError and friends, GDAL's words
            raise InvalidDomainError(f"{where}: cannot read it with GeoPandas ({err})") from err
    if isinstance(frame, geopandas.GeoSeries):
        frame = geopandas.GeoDataFrame(geometry=frame)
    if not isinstance(frame, geopandas.GeoDataFrame):
        raise TypeError(f"expected a GeoDataFrame or GeoSeries, got {type(frame).__name__}")
    rows = len(frame)
    if query is not None:
        try:
            frame = frame.query(query)
        except Exception as err:  # pandas raises whatever its expression parser meets
            raise InvalidDomainError(f"{where}: query {query!r} failed ({err})") from err
        if len(frame) == 0:
            raise InvalidDomainError(f"{where}: query {query!r} kept none of {rows} features")
    if feature is not None:
        if not -len(frame) <= feature < len(frame):
            raise InvalidDomainError(
                f"{where}: no feature {feature}; there are {len(frame)}"
                + (f" (of {rows}, after the query)" if query is not None else "")
            )
        frame = frame.iloc[[feature]]
    polygons: list[Polygon] = []
    for geometry in frame.geometry:
        if geometry is None or geometry.is_empty:
            continue
        for part in shapely.get_parts(shapely.force_2d(geometry)):
            if isinstance(part, Polygon):
                polygons.append(part)
            elif isinstance(part, MultiPolygon):  # parts of a GeometryCollection
                polygons.extend(part.geoms)
    if not polygons:
        raise InvalidDomainError(f"{where}: no Polygon or MultiPolygon in the features kept")
    # Features of a layer often tile a region (boroughs, parcels): several are the region
    # they cover together, their shared edges dissolved.
    outline = polygons[0] if len(frame) == 1 and len(polygons) == 1 else MultiPolygon(polygons)
    if len(frame) > 1:
        outline = shapely.union_all(polygons)
    declared = crs if crs is not None else frame.crs
    return Domain.from_polygon(outline, repair=repair, crs=declared)


def to_geodataframe(diagram: Diagram) -> Any:
    """The 2D cells as a ``geopandas.GeoDataFrame``, row ``i`` the cell of site ``i``.

    Columns (one value per cell, in the domain's length unit L):

    ====================  ==========================================================
    ``site_x, site_y``    the site (L)
    ``centroid_x, _y``    the centroid, ρ-weighted with a density (L)
    ``volume``            the area (L²)
    ``mass``              ``∫ρ`` over the cell (with a density only)
    ``second_moment``     ``∫|x - c|²`` about the geometric centroid (L⁴)
    ``G``                 the dimensionless second moment (paper eq. 2)
    ``energy``            the cell's term of the CVT energy (ρ·L⁴)
    ``boundary_measure``  length of the domain's boundary in the cell (L)
    ``neighbors``         number of restricted Delaunay neighbours
    ``geometry``          the clipped cell: Polygon, MultiPolygon, or empty
    ====================  ==========================================================

    The index is ``site`` (0 … n-1) and the CRS the domain's (None when unknown).

    Raises
    ------
    ValueError
        A 3D diagram (use ``Diagram.to_pyvista()`` or ``write_cells(.., "cells.vtu")``).
    ModuleNotFoundError
        geopandas is not installed (``pip install 'hcvt[geo]'``).
    """
    if diagram.domain.dim != 2:
        raise ValueError(
            "a GeoDataFrame holds 2D cells; view 3D cells with Diagram.to_pyvista() or "
            "write them with write_cells(diagram, 'cells.vtu')"
        )
    geopandas = load("geopandas")
    n = len(diagram.sites)
    degree = np.bincount(diagram.neighbors.ravel(), minlength=n)
    columns: dict[str, Any] = {
        "site_x": diagram.sites[:, 0],
        "site_y": diagram.sites[:, 1],
        "centroid_x": diagram.centroid[:, 0],
        "centroid_y": diagram.centroid[:, 1],
        "volume": diagram.volume,
    }
    if diagram.density is not None:
        columns["mass"] = diagram.mass
    columns |= {
        "second_moment": diagram.second_moment,
        "G": diagram.G,
        "energy": diagram.energy_terms,
        "boundary_measure": diagram.boundary_measure,
        "neighbors": degree,
    }
    index = load("pandas").RangeIndex(n, name="site")
    return geopandas.GeoDataFrame(
        columns, geometry=diagram.cells(), crs=diagram.domain.crs, index=index
    )


def write_geopackage(diagram: Diagram, path: str | Path, *, layer: str = "cells") -> Path:
    """Write :func:`to_geodataframe` of ``diagram`` to a GeoPackage, one row per site.

    The column ``site`` holds the site's row (GeoPackage keys its own ``fid``); the
    layer's CRS is the domain's. Every cell is stored as a MultiPolygon (one geometry
    type per layer, as GIS tools expect; a cell the domain cuts in pieces needs it), with
    the coordinates of :meth:`hcvt.Diagram.cells` bit for bit. An existing layer of that
    name is replaced.
    """
    path = Path(path)
    table = to_geodataframe(diagram).reset_index()
    table.to_file(path, layer=layer, driver="GPKG", engine="pyogrio", promote_to_multi=True)
    return path
