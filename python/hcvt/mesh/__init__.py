"""The conforming mesh of a diagram's cells and what is done to it before it is written.

| module | owns |
|--------|------|
| :mod:`~hcvt.mesh.polymesh` | :class:`PolyMesh`, OpenFOAM's face-based layout; its geometry |
| :mod:`~hcvt.mesh.cells` | each cell's own geometry (triangles, polygons) read off the mesh |
| :mod:`~hcvt.mesh.quality` | quality as OpenFOAM's checkMesh defines it |
| :mod:`~hcvt.mesh.patches` | the boundary's patches (connected components or labels) |
| :mod:`~hcvt.mesh.parts` | cells in several parts: all but the largest joined to neighbours |
| :mod:`~hcvt.mesh.merge` | boundary pieces checkMesh would flag, merged |
| :mod:`~hcvt.mesh.sphere` | a spherical diagram as MPAS's cells, edges, vertices; its quality |
"""

from hcvt.mesh.merge import MergeReport, merged_boundary
from hcvt.mesh.patches import boundary_patches
from hcvt.mesh.polymesh import PolyMesh
from hcvt.mesh.quality import MeshQuality, mesh_quality
from hcvt.mesh.sphere import SphereMesh, SphereQuality, sphere_quality

__all__ = [
    "MergeReport",
    "MeshQuality",
    "PolyMesh",
    "SphereMesh",
    "SphereQuality",
    "boundary_patches",
    "merged_boundary",
    "mesh_quality",
    "sphere_quality",
]
