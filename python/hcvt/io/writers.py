"""Writing conforming meshes: OpenFOAM cases, VTU files, GeoJSON; viewing them in pyvista.

:func:`write_mesh` takes a :class:`hcvt.mesh.PolyMesh` or anything with a ``mesh()``
method returning one (a :class:`hcvt.Diagram`), and picks the format from the path.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from hcvt.io.geojson import write_geojson
from hcvt.io.openfoam import write_openfoam
from hcvt.io.vtu import write_pieces_vtu, write_vtu
from hcvt.lazy import load
from hcvt.mesh.polymesh import PolyMesh

if TYPE_CHECKING:
    from hcvt.geometry.domain import Domain


def as_polymesh(source: Any) -> tuple[PolyMesh, Domain | None, dict[str, ArrayLike]]:
    """The mesh of ``source``, its domain (or None) and per-cell data to export with it.

    A PolyMesh is taken as it is. Anything else must have ``mesh()`` (a Diagram): its
    ``domain`` names the patches, and its ``volume`` and ``G`` go along as cell data.
    """
    if isinstance(source, PolyMesh):
        return source, None, {}
    make = getattr(source, "mesh", None)
    if make is None:
        raise NotImplementedError(
            f"{type(source).__name__} has no conforming mesh: pass a hcvt.mesh.polymesh.PolyMesh "
            "or a Diagram of a build with Diagram.mesh()"
        )
    data: dict[str, ArrayLike] = {}
    for name in ("volume", "G"):
        if hasattr(source, name):
            data[name] = getattr(source, name)
    return make(), getattr(source, "domain", None), data


def write_mesh(
    source: Any,
    path: str | Path,
    *,
    domain: Domain | None = None,
    labels: ArrayLike | None = None,
    binary: bool = False,
    thickness: float | None = None,
    cell_data: dict[str, ArrayLike] | None = None,
    boundary_faces: str | None = None,
    site: ArrayLike | None = None,
) -> Path:
    """Write the conforming mesh of a diagram (or a PolyMesh) to ``path``.

    Parameters
    ----------
    source : Diagram or PolyMesh
        A diagram's cells are its ``mesh()``; its domain names the patches and its
        ``volume`` and ``G`` are written as cell data. A diagram on a triangle surface
        has no ``mesh()``: as ``.vtu`` its cells' pieces are written as polygons
        (:func:`hcvt.io.vtu.write_pieces_vtu`, cell data ``site``, ``face``, ``area``,
        ``G`` and ``cell_data``).
    path : str or Path
        ``*.vtu``: VTK polyhedra (3D) or polygons (2D), see :func:`write_vtu`.
        ``*.geojson`` (2D): one Feature per cell on shared vertices, see
        :func:`write_geojson`. Anything else, without suffix: an OpenFOAM case directory,
        see :func:`write_openfoam`.
    domain : Domain, optional
        For the boundary patches (default: the diagram's).
    labels : array_like, shape (E,), optional
        One patch per label of the domain's boundary elements (OpenFOAM only).
    binary : bool, default False
        OpenFOAM: binary lists.
    thickness : float, optional
        OpenFOAM, 2D: the extrusion depth.
    cell_data : dict of str to array_like of shape (n,), optional
        More per-cell values to write (beside a diagram's ``volume`` and ``G``).
    boundary_faces : {"merged", "exact"}, optional
        OpenFOAM, 3D: ``"merged"``, the default, joins the boundary pieces checkMesh
        would flag (skew, inverted pyramids) into larger, non-planar faces so that it
        passes and ``laplacianFoam`` converges (:mod:`hcvt.io.solver`); ``"exact"``
        writes the exact planar pieces (checkMesh fails its skewness and pyramid checks).
        See :func:`write_openfoam`. Only for OpenFOAM cases (``"exact"``
        is accepted for other files, which are always exact).
    site : array_like of int, shape (n_cells,), optional
        OpenFOAM: the site of each cell, when they are not one per site.

    Returns
    -------
    Path
        What was written.

    Raises
    ------
    NotImplementedError
        ``source`` has no ``mesh()``.
    ValueError
        An unknown suffix; a GeoJSON of a 3D mesh; ``boundary_faces`` other than
        ``"exact"``, or ``site``, for a file that is not an OpenFOAM case.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".vtu" and _on_surface(source):
        data = _surface_data(source, cell_data)
        return write_pieces_vtu(source.surface_pieces(), path, cell_data=data)
    mesh, own_domain, data = as_polymesh(source)
    data = {**data, **(cell_data or {})}
    if suffix and (boundary_faces not in (None, "exact") or site is not None):
        raise ValueError("boundary_faces and site are for OpenFOAM cases only")
    if suffix == ".vtu":
        return write_vtu(mesh, path, cell_data=data)
    if suffix in (".geojson", ".json"):
        owner = domain if domain is not None else own_domain
        crs = owner.crs if owner is not None else None
        return write_geojson(mesh, path, cell_data=data, crs=crs)
    if suffix:
        raise ValueError(
            f"{path.name}: meshes are written as .vtu, .geojson (2D) or an OpenFOAM case "
            "directory (a path without suffix)"
        )
    return write_openfoam(
        mesh,
        path,
        domain=domain if domain is not None else own_domain,
        labels=labels,
        binary=binary,
        thickness=thickness,
        cell_data=data,
        boundary_faces="merged" if boundary_faces is None else boundary_faces,
        site=site,
    )


def to_pyvista(source: Any) -> Any:
    """The conforming mesh as a ``pyvista.UnstructuredGrid``, for interactive viewing.

    Needs pyvista (``pip install 'hcvt[viz]'``). Built by VTK's own reader from a
    temporary VTU (:func:`write_vtu`), so what you see is what the file holds: cell data
    ``site`` and, for a diagram, ``volume`` and ``G``.

    On the sphere (a diagram of :meth:`hcvt.Domain.sphere`): a ``pyvista.PolyData`` of
    the cells as polygons through their vertices (:meth:`hcvt.Diagram.spherical_mesh`),
    cell data ``site``, ``area`` and ``G``. On a triangle surface: a ``pyvista.PolyData``
    of the cells' pieces as polygons (:meth:`hcvt.Diagram.surface_pieces`), cell data
    ``site``, ``area`` and ``G`` (the cell's) and ``face`` (the input triangle).

    Raises
    ------
    ImportError
        pyvista is not installed.
    """
    pyvista = load("pyvista")
    domain = getattr(source, "domain", None)
    if domain is not None and domain.is_sphere:
        return _sphere_polydata(pyvista, source)
    if _on_surface(source):
        return _pieces_polydata(pyvista, source)
    mesh, _, data = as_polymesh(source)
    with tempfile.TemporaryDirectory() as tmp:
        file = write_vtu(mesh, Path(tmp) / "mesh.vtu", cell_data=data)
        grid = pyvista.read(file)
        grid.points = np.array(grid.points)  # detached from the reader before tmp goes
    return grid


def _sphere_polydata(pyvista: Any, diagram: Any) -> Any:
    """The spherical cells as a PolyData of polygons on the shared Voronoi vertices."""
    mesh = diagram.spherical_mesh()
    counts = mesh.n_edges_on_cell
    # VTK's legacy cell array: each polygon's vertex count, then its vertices.
    starts = mesh.cell_offsets[:-1] + np.arange(mesh.n_cells)
    faces = np.empty(len(mesh.vertices_on_cell) + mesh.n_cells, dtype=np.int64)
    faces[starts] = counts
    inside = np.ones(len(faces), dtype=bool)
    inside[starts] = False
    faces[inside] = mesh.vertices_on_cell
    poly = pyvista.PolyData(mesh.vertices * mesh.radius, faces=faces)
    poly.cell_data["site"] = np.arange(mesh.n_cells)
    poly.cell_data["area"] = diagram.volume
    poly.cell_data["G"] = diagram.G
    return poly


def _on_surface(source: Any) -> bool:
    """Whether ``source`` is a diagram on a triangle surface."""
    domain = getattr(source, "domain", None)
    return domain is not None and domain.is_surface


def _surface_data(diagram: Any, extra: dict[str, ArrayLike] | None = None) -> dict[str, ArrayLike]:
    """A surface diagram's per-cell data to write with its pieces: ``area``, ``G``, ``extra``."""
    return {"area": diagram.volume, "G": diagram.G, **(extra or {})}


def _pieces_polydata(pyvista: Any, diagram: Any) -> Any:
    """The pieces of the cells on a surface as a PolyData of polygons."""
    pieces = diagram.surface_pieces()
    counts = np.diff(pieces.piece_offsets)
    # VTK's legacy cell array: each polygon's vertex count, then its vertices.
    faces = np.insert(np.arange(len(pieces.points)), pieces.piece_offsets[:-1], counts)
    poly = pyvista.PolyData(pieces.points, faces=faces.astype(np.int64))
    poly.cell_data["site"] = pieces.piece_cell
    for name, values in _surface_data(diagram).items():
        poly.cell_data[name] = np.asarray(values)[pieces.piece_cell]
    poly.cell_data["face"] = pieces.piece_face
    return poly
