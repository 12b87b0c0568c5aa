"""hcvt: regular centroidal Voronoi tessellations of polygons and closed meshes.

The public API (DESIGN §1): :class:`Domain` and :func:`load_domain` build domains,
:func:`voronoi` computes exact clipped Voronoi diagrams.
"""

from hcvt import io
from hcvt._core import get_num_threads, set_num_threads
from hcvt.diagram import Diagram, voronoi
from hcvt.domain import Domain, RepairReport
from hcvt.errors import InvalidDomainError, InvalidSitesError
from hcvt.io import load_domain, write_cells

__all__ = [
    "Diagram",
    "Domain",
    "InvalidDomainError",
    "InvalidSitesError",
    "RepairReport",
    "get_num_threads",
    "io",
    "load_domain",
    "set_num_threads",
    "voronoi",
    "write_cells",
]
__version__ = "0.1.0"
