"""MPAS mesh files: a spherical Voronoi diagram as an MPAS ``base_mesh.nc`` (NetCDF).

The fields of the MPAS mesh specification (version 1.0) that MPAS-Tools'
``MpasMeshConverter.x`` writes, on the same conventions: 1-based indices padded with 0,
``verticesOnCell`` counter-clockwise seen from outside with vertex ``j`` between edges
``j`` and ``j + 1``, each edge's normal from ``cellsOnEdge[0]`` to ``cellsOnEdge[1]`` and
its tangent, ``verticesOnEdge[0] → [1]``, that normal turned counter-clockwise
(``t = k × n``); ``cellsOnVertex`` counter-clockwise with cell ``j`` between
``edgesOnVertex[j]`` and ``[j + 1]``; ``weightsOnEdge`` of Thuburn et al. (2009) as the
converter builds them. Lengths are great-circle arcs and areas spherical, times the
sphere's radius (``sphere_radius``). ``areaCell`` is the core's exact cell area;
``kiteAreasOnVertex`` are signed (see :attr:`hcvt.mesh.sphere.SphereMesh.kite_areas_on_vertex`).
The mesh quality fields of the converter (``cellQuality``, ``gridSpacing``,
``triangleQuality``, ``triangleAngleQuality``, ``obtuseTriangle``) and ``meshDensity``
(1) come along.

Needs xarray and netCDF4 (``pip install 'hcvt[mpas]'``).
"""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from hcvt.lazy import load
from hcvt.mesh.sphere import SphereMesh, Width, lat_lon, sphere_quality

#: The MPAS mesh specification the files follow (the ``mesh_spec`` attribute).
MESH_SPEC = "1.0"


class SphericalDiagram(Protocol):
    """What :func:`write_mpas` reads of a :class:`hcvt.Diagram` on the sphere."""

    @property
    def volume(self) -> NDArray[np.float64]: ...  # noqa: D102

    def spherical_mesh(self) -> SphereMesh: ...  # noqa: D102


def mpas_dataset(diagram: SphericalDiagram, *, width: Width | None = None) -> Any:
    """The MPAS mesh of a diagram on the sphere as an ``xarray.Dataset`` (see the module).

    Parameters
    ----------
    diagram : Diagram
        A diagram of :meth:`hcvt.Domain.sphere`.
    width : array_like or callable, optional
        A requested cell width (:func:`hcvt.mesh.sphere.sphere_quality`): adds
        ``cellWidthRequested`` and ``gridSpacingRatio`` per cell.
    """
    xr = load("xarray")
    mesh = diagram.spherical_mesh()
    radius = mesh.radius
    quality = sphere_quality(mesh, width)
    max_edges = int(mesh.n_edges_on_cell.max())
    edges_on_edge, weights_on_edge, n_edges_on_edge = trisk_weights(mesh, diagram.volume)

    def index(values: NDArray[np.intp]) -> NDArray[np.int32]:
        return (np.asarray(values) + 1).astype(np.int32)  # 1-based; -1 padding becomes 0

    def padded(values: NDArray[np.intp]) -> NDArray[np.int32]:
        out = np.zeros((mesh.n_cells, max_edges), dtype=np.int32)
        out[:] = index(mesh.padded(values))
        return out

    data: dict[str, Any] = {}
    for name, points, dim in (
        ("Cell", mesh.cells, "nCells"),
        ("Edge", mesh.edge_points, "nEdges"),
        ("Vertex", mesh.vertices, "nVertices"),
    ):
        lat, lon = lat_lon(points)
        data[f"lat{name}"] = ((dim,), lat)
        data[f"lon{name}"] = ((dim,), lon)
        for k, axis in enumerate("xyz"):
            data[f"{axis}{name}"] = ((dim,), radius * points[:, k])
        data[f"indexTo{name}ID"] = ((dim,), np.arange(1, len(points) + 1, dtype=np.int32))
    cell_sides = ("nCells", "maxEdges")
    data.update(
        {
            "nEdgesOnCell": (("nCells",), mesh.n_edges_on_cell.astype(np.int32)),
            "cellsOnCell": (cell_sides, padded(mesh.cells_on_cell)),
            "edgesOnCell": (cell_sides, padded(mesh.edges_on_cell)),
            "verticesOnCell": (cell_sides, padded(mesh.vertices_on_cell)),
            "cellsOnEdge": (("nEdges", "TWO"), index(mesh.cells_on_edge)),
            "verticesOnEdge": (("nEdges", "TWO"), index(mesh.vertices_on_edge)),
            "nEdgesOnEdge": (("nEdges",), n_edges_on_edge.astype(np.int32)),
            "edgesOnEdge": (("nEdges", "maxEdges2"), index(edges_on_edge)),
            "weightsOnEdge": (("nEdges", "maxEdges2"), weights_on_edge),
            "cellsOnVertex": (("nVertices", "vertexDegree"), index(mesh.cells_on_vertex)),
            "edgesOnVertex": (("nVertices", "vertexDegree"), index(mesh.edges_on_vertex)),
            "areaCell": (("nCells",), np.asarray(diagram.volume, dtype=np.float64)),
            "areaTriangle": (("nVertices",), mesh.area_triangle),
            "kiteAreasOnVertex": (("nVertices", "vertexDegree"), mesh.kite_areas_on_vertex),
            "dcEdge": (("nEdges",), mesh.dc_edge),
            "dvEdge": (("nEdges",), mesh.dv_edge),
            "angleEdge": (("nEdges",), mesh.angle_edge),
            "meshDensity": (("nCells",), np.ones(mesh.n_cells)),
            "cellQuality": (("nCells",), quality.cell_quality),
            "gridSpacing": (("nCells",), quality.grid_spacing),
            "triangleQuality": (("nVertices",), quality.triangle_quality),
            "triangleAngleQuality": (("nVertices",), quality.triangle_angle_quality),
            "obtuseTriangle": (("nVertices",), quality.obtuse.astype(np.int32)),
        }
    )
    if quality.spacing_ratio is not None:
        data["cellWidthRequested"] = (("nCells",), quality.grid_spacing / quality.spacing_ratio)
        data["gridSpacingRatio"] = (("nCells",), quality.spacing_ratio)
    attrs = {
        "on_a_sphere": "YES",
        "sphere_radius": float(radius),
        "is_periodic": "NO",
        "mesh_spec": MESH_SPEC,
        "Conventions": "MPAS",
        "source": "hcvt",
        "history": "hcvt.write_mpas: exact spherical Voronoi cells (areaCell) of the sites",
    }
    return xr.Dataset(data, attrs=attrs)


def write_mpas(
    diagram: SphericalDiagram,
    path: str | Path,
    *,
    width: Width | None = None,
    format: str = "NETCDF3_64BIT",  # noqa: A002 (xarray's name)
) -> Path:
    """Write a diagram on the sphere as an MPAS mesh file (see :mod:`hcvt.io.mpas`).

    Parameters
    ----------
    diagram : Diagram
        A diagram of :meth:`hcvt.Domain.sphere` (a CVT's, for a model).
    path : str or Path
        The NetCDF file, e.g. ``base_mesh.nc``.
    width : array_like or callable, optional
        A requested cell width, for ``gridSpacingRatio`` (see :func:`mpas_dataset`).
    format : str, default "NETCDF3_64BIT"
        The NetCDF format (xarray's ``format=``): CDF-2 (64-bit offsets), which every MPAS
        core and MPAS-Tools read; ``"NETCDF4"`` for HDF5.

    Returns
    -------
    Path
        The path written.

    Warns
    -----
    UserWarning
        The mesh has edges of length zero (cocircular sites, :mod:`hcvt.mesh.sphere`):
        MPAS-Atmosphere divides by ``dvEdge``.
    """
    dataset = mpas_dataset(diagram, width=width)
    zero = diagram.spherical_mesh().zero_length_edges
    if zero:
        warnings.warn(
            f"{zero} edge(s) of length zero between cocircular sites (dvEdge = 0): MPAS "
            "divides by dvEdge in places; move those sites or run a CVT first",
            UserWarning,
            stacklevel=2,
        )
    path = Path(path)
    encoding = {name: {"_FillValue": None} for name in dataset.variables}
    dataset.to_netcdf(path, format=format, engine="netcdf4", encoding=encoding)
    return path


def trisk_weights(
    mesh: SphereMesh, area_cell: NDArray[np.float64]
) -> tuple[NDArray[np.intp], NDArray[np.float64], NDArray[np.intp]]:
    """``edgesOnEdge`` (0-based, −1 padded), ``weightsOnEdge`` and ``nEdgesOnEdge``.

    Thuburn et al. (2009) as ``MpasMeshConverter.x`` builds them: for edge ``e`` and each
    of its cells ``i``, the cell's other edges ``q`` counter-clockwise from ``e``, with
    weight ``s_i(e) s_i(q) (1/2 − Σ kites of i passed so far / A_i) dvEdge_q / dcEdge_e``,
    ``s_i(e) = +1`` where ``i`` is ``cellsOnEdge[e, 0]``; cell 1's edges first.
    """
    counts = mesh.n_edges_on_cell
    owner = np.repeat(np.arange(mesh.n_cells), counts)
    start = mesh.cell_offsets[owner]
    side = np.arange(len(owner)) - start
    degree = counts[owner]
    edge = mesh.edges_on_cell
    sign = np.where(mesh.cells_on_edge[edge, 0] == owner, 1.0, -1.0)
    # The kite of the side's cell at the vertex closing the side (between sides j, j + 1).
    v = mesh.vertices_on_cell
    corner = np.argmax(mesh.cells_on_vertex[v] == owner[:, None], axis=1)
    kite = mesh.kite_areas_on_vertex[v, corner] / np.asarray(area_cell)[owner]
    width = int(counts.max()) - 1
    others = np.full((len(owner), width), -1, dtype=np.intp)
    weights = np.zeros((len(owner), width))
    passed = np.zeros(len(owner))
    for k in range(1, width + 1):
        valid = k < degree
        passed = passed + kite[start + (side + k - 1) % degree]
        q = start + (side + k) % degree
        w = sign * sign[q] * (0.5 - passed) * mesh.dv_edge[edge[q]] / mesh.dc_edge[edge]
        others[valid, k - 1] = edge[q][valid]
        weights[valid, k - 1] = w[valid]
    # Each edge's two sides: cell 1's first.
    first = sign > 0
    by_edge = np.lexsort((~first, edge))
    rows = np.concatenate([others[by_edge[0::2]], others[by_edge[1::2]]], axis=1)
    values = np.concatenate([weights[by_edge[0::2]], weights[by_edge[1::2]]], axis=1)
    packed = np.argsort(rows < 0, axis=1, kind="stable")  # the valid ones first, in order
    rows = np.take_along_axis(rows, packed, axis=1)
    values = np.take_along_axis(values, packed, axis=1)
    pad = 2 * (width + 1) - rows.shape[1]  # maxEdges2 = 2 maxEdges columns
    rows = np.pad(rows, ((0, 0), (0, pad)), constant_values=-1)
    values = np.pad(values, ((0, 0), (0, pad)))
    return rows, values, np.count_nonzero(rows >= 0, axis=1)


__all__ = ["MESH_SPEC", "SphericalDiagram", "mpas_dataset", "trisk_weights", "write_mpas"]
