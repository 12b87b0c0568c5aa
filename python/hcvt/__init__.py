"""hcvt: regular centroidal Voronoi tessellations of polygons and closed meshes.

The public API (DESIGN §1): :class:`Domain` and :func:`load_domain` build domains,
:func:`voronoi` computes exact clipped Voronoi diagrams, :func:`cvt` moves sites to a
centroidal Voronoi tessellation.
"""

import importlib
from typing import TYPE_CHECKING, Any

from hcvt import density, io
from hcvt._core import get_num_threads, set_num_threads
from hcvt.api import cvt, voronoi
from hcvt.density import Polynomial, SizingField
from hcvt.diagram import Diagram
from hcvt.errors import (
    InvalidDensityError,
    InvalidDomainError,
    InvalidMeshError,
    InvalidSitesError,
)
from hcvt.geometry import Domain, RepairReport
from hcvt.io import load_domain, write_cells, write_mesh, write_mpas
from hcvt.mesh import sphere_quality
from hcvt.optimise import CVTResult
from hcvt.seeding import (
    HierarchicalResult,
    LatticeResult,
    MonteCarloResult,
    RegularResult,
    defects,
    global_monte_carlo,
    hierarchical_cvt,
    initialise,
    regular_cvt,
)
from hcvt.surface import RemeshError, RemeshResult, SurfaceQuality, remesh, surface_quality
from hcvt.transport import TransportResult, optimal_transport

__all__ = [
    "CVTResult",
    "Diagram",
    "Domain",
    "HierarchicalResult",
    "InvalidDensityError",
    "InvalidDomainError",
    "InvalidMeshError",
    "InvalidSitesError",
    "LatticeResult",
    "RegularResult",
    "RemeshError",
    "RemeshResult",
    "RepairReport",
    "MonteCarloResult",
    "Polynomial",
    "SizingField",
    "SurfaceQuality",
    "TransportResult",
    "cvt",
    "defects",
    "density",
    "get_num_threads",
    "global_monte_carlo",
    "hierarchical_cvt",
    "initialise",
    "io",
    "load_domain",
    "optimal_transport",
    "plot",
    "regular_cvt",
    "remesh",
    "set_num_threads",
    "sphere_quality",
    "surface_quality",
    "voronoi",
    "write_cells",
    "write_mesh",
    "write_mpas",
]
__version__ = "0.1.0"

if TYPE_CHECKING:
    from hcvt import plot


def __getattr__(name: str) -> Any:
    # `hcvt.plot` imports matplotlib on first use only (PEP 562): `import hcvt` must not
    # pull it in, nor touch the backend.
    if name == "plot":
        return importlib.import_module("hcvt.plot")
    raise AttributeError(f"module 'hcvt' has no attribute {name!r}")
