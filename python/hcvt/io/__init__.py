"""Files in and out: domains read, cells and conforming meshes written.

:mod:`~hcvt.io.readers`
    :func:`load_domain`: polygons, GIS data and triangle meshes
:mod:`~hcvt.io.geo`
    GeoPandas: GIS files and GeoDataFrames in, cells as a GeoDataFrame or GeoPackage out
:mod:`~hcvt.io.writers`
    :func:`write_mesh` (format by path), :func:`to_pyvista`
:mod:`~hcvt.io.cells`
    :func:`write_cells`: a diagram's cells for viewing
:mod:`~hcvt.io.vtu`
    the one VTU writer (VTK polyhedra / polygons)
:mod:`~hcvt.io.pvtu`
    the index of a VTU written in pieces
:mod:`~hcvt.io.openfoam`
    OpenFOAM cases (constant/polyMesh, system/, 0/)
:mod:`~hcvt.io.mpas`
    MPAS mesh files (NetCDF) of diagrams on the sphere
:mod:`~hcvt.io.geojson`
    2D cells on shared vertices
:mod:`~hcvt.io.solver`
    a written case checked by OpenFOAM's laplacianFoam on a linear field
"""

from hcvt.io.cells import write_cells
from hcvt.io.geojson import write_geojson
from hcvt.io.mpas import mpas_dataset, write_mpas
from hcvt.io.openfoam import write_openfoam
from hcvt.io.readers import load_domain, read_mesh, read_polygon
from hcvt.io.solver import LaplaceCheck, OpenFOAMError, laplace_check
from hcvt.io.vtu import write_vtu
from hcvt.io.writers import as_polymesh, to_pyvista, write_mesh

__all__ = [
    "LaplaceCheck",
    "OpenFOAMError",
    "as_polymesh",
    "laplace_check",
    "mpas_dataset",
    "load_domain",
    "read_mesh",
    "read_polygon",
    "to_pyvista",
    "write_cells",
    "write_geojson",
    "write_mesh",
    "write_mpas",
    "write_openfoam",
    "write_vtu",
]
