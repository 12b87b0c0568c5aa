"""Surfaces: isotropic remeshing by restricted CVTs, and the quality of triangle meshes.

:func:`remesh` places exactly ``n`` vertices on a surface by a restricted CVT (Yan, Lévy,
Liu, Sun, Wang 2009) and connects them by the restricted Delaunay triangulation;
:func:`surface_quality` measures any triangle mesh (shape quality, angles, valences,
Hausdorff distance to a reference, genus and manifoldness by edge counts);
:func:`curvature_density` gives a per-vertex density for a curvature-adapted remesh.
"""

from hcvt.surface.curvature import curvature_density
from hcvt.surface.quality import SurfaceQuality, surface_quality
from hcvt.surface.remesh import RemeshError, RemeshResult, remesh

__all__ = [
    "RemeshError",
    "RemeshResult",
    "SurfaceQuality",
    "curvature_density",
    "remesh",
    "surface_quality",
]
