"""Meshes out, in one place: quality, boundary repairs and writers.

The names users import as ``hcvt.export.*`` (README), gathered from where they live:
:mod:`hcvt.mesh` (the conforming mesh, its quality, the merged boundary) and :mod:`hcvt.io`
(the writers).
"""

from hcvt.io import (
    as_polymesh,
    to_pyvista,
    write_geojson,
    write_mesh,
    write_mpas,
    write_openfoam,
    write_vtu,
)
from hcvt.io.solver import LaplaceCheck, OpenFOAMError, laplace_check
from hcvt.mesh import (
    MergeReport,
    MeshQuality,
    SphereQuality,
    boundary_patches,
    merged_boundary,
    mesh_quality,
    sphere_quality,
)

__all__ = [
    "LaplaceCheck",
    "MergeReport",
    "MeshQuality",
    "OpenFOAMError",
    "SphereQuality",
    "as_polymesh",
    "boundary_patches",
    "laplace_check",
    "merged_boundary",
    "mesh_quality",
    "sphere_quality",
    "to_pyvista",
    "write_geojson",
    "write_mesh",
    "write_mpas",
    "write_openfoam",
    "write_vtu",
]
