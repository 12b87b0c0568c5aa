"""Type stubs of ``hcvt._core``, the PyO3 binding of hcvt-core (crates/hcvt-py).

Arrays in are C-contiguous (``hcvt`` guarantees it); float arrays are float64, integer arrays
out are ``np.intp``. Keep in step with crates/hcvt-py/src/*.rs; ``mypy python/hcvt``
and ``python -m mypy.stubtest hcvt._core`` (scripts/test.sh) check the package against
these and these against the module.
"""

from collections.abc import Callable, Sequence
from typing import Any, final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hcvt.core_results import (
    CvtArrays,
    CvtRecord,
    DiagramArrays,
    MeshArrays,
    MeshPartArrays,
    MeshQualityArrays,
    PartCellsArrays,
    RestrictedDelaunayArrays,
    SurfacePiecesArrays,
    TransportArrays,
)

__all__ = [
    "BoxDomain2",
    "BoxDomain3",
    "PolygonDomain",
    "SolidDomain",
    "SphereDomain",
    "SphereRegionDomain",
    "SurfaceDomain",
    "check_settings",
    "closest_points",
    "cvt",
    "diagram_field",
    "get_num_threads",
    "lbfgs_coefficients",
    "lbfgs_direction",
    "line_search_accepts",
    "lloyd_step",
    "mesh",
    "mesh_part",
    "mesh_quality",
    "optimal_transport",
    "partition_cells",
    "positive_curvature",
    "restricted_delaunay",
    "set_num_threads",
    "step_fields",
    "surface_pieces",
    "voronoi",
]

_Float1 = NDArray[np.float64]
_Float2 = NDArray[np.float64]
_Index2 = NDArray[np.intp]
_Windings = tuple[NDArray[np.int32], NDArray[np.bool_]]

@final
class PolygonDomain:
    """Segments (S, 2) uint32 into vertices (V, 2), interior on the left of each."""

    def __new__(cls, vertices: _Float2, segments: NDArray[np.uint32]) -> PolygonDomain: ...
    @property
    def volume(self) -> float: ...
    @property
    def first_moment(self) -> tuple[float, float]: ...
    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]: ...
    @property
    def vertices(self) -> _Float2: ...
    @property
    def segments(self) -> _Index2: ...
    def winding_numbers(self, points: _Float2) -> _Windings: ...

@final
class SolidDomain:
    """Triangles (F, 3) uint32 into vertices (V, 3), counter-clockwise seen from outside."""

    def __new__(cls, vertices: _Float2, faces: NDArray[np.uint32]) -> SolidDomain: ...
    @property
    def volume(self) -> float: ...
    @property
    def first_moment(self) -> tuple[float, float, float]: ...
    @property
    def bounds(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]: ...
    @property
    def vertices(self) -> _Float2: ...
    @property
    def faces(self) -> _Index2: ...
    def winding_numbers(self, points: _Float2) -> _Windings: ...
    def crossing_triangles(self, max: int = 10) -> tuple[int, list[tuple[int, int]]]: ...
    def generalized_winding_numbers(self, points: _Float2) -> _Float1: ...

@final
class BoxDomain2:
    """The box [lo, hi] (2D), periodic along the axes marked so (2 values each)."""

    def __new__(
        cls, lo: Sequence[float], hi: Sequence[float], periodic: Sequence[bool]
    ) -> BoxDomain2: ...
    @property
    def volume(self) -> float: ...
    @property
    def first_moment(self) -> tuple[float, float]: ...
    @property
    def bounds(self) -> tuple[tuple[float, float], tuple[float, float]]: ...
    @property
    def periodic(self) -> tuple[bool, bool]: ...
    @property
    def vertices(self) -> _Float2: ...
    def winding_numbers(self, points: _Float2) -> _Windings: ...
    def wrap(self, points: _Float2) -> _Float2: ...

@final
class BoxDomain3:
    """The box [lo, hi] (3D), periodic along the axes marked so (3 values each)."""

    def __new__(
        cls, lo: Sequence[float], hi: Sequence[float], periodic: Sequence[bool]
    ) -> BoxDomain3: ...
    @property
    def volume(self) -> float: ...
    @property
    def first_moment(self) -> tuple[float, float, float]: ...
    @property
    def bounds(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]: ...
    @property
    def periodic(self) -> tuple[bool, bool, bool]: ...
    @property
    def vertices(self) -> _Float2: ...
    def winding_numbers(self, points: _Float2) -> _Windings: ...
    def wrap(self, points: _Float2) -> _Float2: ...

@final
class SphereDomain:
    """The unit sphere about the origin: sites are unit vectors (n, 3)."""

    def __new__(cls) -> SphereDomain: ...
    @property
    def volume(self) -> float: ...
    @property
    def first_moment(self) -> tuple[float, float, float]: ...
    @property
    def bounds(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]: ...
    def winding_numbers(self, points: _Float2) -> _Windings: ...

@final
class SphereRegionDomain:
    """A region of the unit sphere bounded by rings of great-circle arcs."""

    def __new__(cls, rings: list[_Float2]) -> SphereRegionDomain: ...
    @property
    def volume(self) -> float: ...
    @property
    def perimeter(self) -> float: ...
    @property
    def centre(self) -> tuple[float, float, float]: ...
    @property
    def bounds(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]: ...
    @property
    def rings(self) -> list[NDArray[np.float64]]: ...
    def winding_numbers(self, points: _Float2) -> _Windings: ...

@final
class SurfaceDomain:
    """A triangle surface: restricted Voronoi cells, sites anywhere in space."""

    def __new__(cls, vertices: _Float2, faces: NDArray[np.uint32]) -> SurfaceDomain: ...
    @property
    def volume(self) -> float: ...
    @property
    def first_moment(self) -> tuple[float, float, float]: ...
    @property
    def bounds(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]: ...
    @property
    def vertices(self) -> _Float2: ...
    @property
    def faces(self) -> NDArray[np.intp]: ...
    def closest(self, points: _Float2) -> tuple[_Float2, NDArray[np.intp]]: ...

def closest_points(
    vertices: _Float2, faces: NDArray[np.uint32], points: _Float2
) -> tuple[_Float2, NDArray[np.intp]]: ...
def restricted_delaunay(
    surface: SurfaceDomain, sites: _Float2, with_diagram: bool = False
) -> RestrictedDelaunayArrays: ...
def surface_pieces(surface: SurfaceDomain, sites: _Float2) -> SurfacePiecesArrays: ...

# A density is either `polynomial=(constant, linear (d,), quadratic (d, d))` or
# `function=f` with f(points (m, d)) -> (m,), sampled by a rule of `quadrature_degree`,
# or (a triangle surface only) `function=values`, a float64 array (V,) of one value per
# vertex of the surface, linear on each triangle.
_Coefficients = tuple[float, Sequence[float], Sequence[Sequence[float]]]
_Function = Callable[[NDArray[np.float64]], ArrayLike] | NDArray[np.float64]

# Each function takes any kind of domain: a polygon (d = 2), a solid (d = 3), a box (mesh
# and mesh_part raise InvalidDomainError for a box) or the
# unit sphere or a triangle surface (sites in 3D, cells of dimension 2; mesh and mesh_part
# refuse them); the dicts
# it returns are typed in hcvt.core_results.
_Domain = (
    PolygonDomain
    | SolidDomain
    | BoxDomain2
    | BoxDomain3
    | SphereDomain
    | SphereRegionDomain
    | SurfaceDomain
)

def voronoi(
    domain: _Domain,
    sites: _Float2,
    allow_outside: bool = False,
    keep_cells: bool = False,
    polynomial: _Coefficients | None = None,
    function: _Function | None = None,
    quadrature_degree: int = 4,
    weights: _Float1 | None = None,
) -> DiagramArrays: ...
def diagram_field(
    domain: _Domain,
    sites: _Float2,
    moments: NDArray[np.float64],
    weighted: NDArray[np.float64] | None,
    name: str,
) -> NDArray[np.float64]: ...
def optimal_transport(
    domain: _Domain,
    sites: _Float2,
    masses: _Float1,
    tol: float = 1e-10,
    max_iter: int = 100,
    normalise: bool = False,
    polynomial: _Coefficients | None = None,
    function: _Function | None = None,
    quadrature_degree: int = 4,
) -> TransportArrays: ...
def mesh(
    domain: _Domain,
    sites: _Float2,
    allow_outside: bool = False,
    weights: NDArray[np.float64] | None = None,
) -> MeshArrays: ...

# A part's mesh (hcvt.distributed.partition_mesh): the own cells' faces, owner and
# neighbour indexing the sites given.
def mesh_part(
    domain: _Domain,
    sites: _Float2,
    rows: NDArray[np.int64],
    own: NDArray[np.uint32],
    total_sites: int,
    allow_outside: bool = False,
) -> MeshPartArrays: ...

# A mesh's geometry and checkMesh figures (hcvt.mesh.quality); with `centres` (n_cells, d)
# the face figures are measured against those cell centres.
def mesh_quality(
    points: _Float2,
    face_offsets: NDArray[np.intp],
    face_vertices: NDArray[np.intp],
    owner: NDArray[np.intp],
    neighbour: NDArray[np.intp],
    n_cells: int,
    centres: _Float2 | None = None,
) -> MeshQualityArrays: ...

# A part's cells (hcvt.distributed): one row per own site, neighbor_sites in the problem's
# rows.
def partition_cells(
    domain: _Domain,
    sites: _Float2,
    rows: NDArray[np.int64],
    own: NDArray[np.uint32],
    total_sites: int,
    allow_outside: bool = False,
    polynomial: _Coefficients | None = None,
    function: _Function | None = None,
    quadrature_degree: int = 4,
    weights: NDArray[np.float64] | None = None,
    power_whole: tuple[list[float], list[float], float] | None = None,
) -> PartCellsArrays: ...

# `frame=(centre, scale)`: the sites are in the frame x' = (x - centre) / scale, and
# grad_norm (the paper's rule) is measured in x.
def cvt(
    domain: _Domain,
    sites: _Float2,
    method: str = "lbfgs",
    rule: str = "gap",
    tol: float | None = None,
    max_iter: int = 10_000,
    memory: int = 7,
    callback: Callable[[CvtRecord], Any] | None = None,
    polynomial: _Coefficients | None = None,
    function: _Function | None = None,
    quadrature_degree: int = 4,
    frame: tuple[Sequence[float], float] | None = None,
    volumes: _Float1 | None = None,
    normalise: bool = False,
    volume_tol: float | None = None,
    fixed: NDArray[np.bool_] | None = None,
) -> CvtArrays: ...

# The optimiser's settings, checked once for every driver: the tol to use.
def check_settings(
    method: str, rule: str, tol: float | None, max_iter: int, memory: int
) -> float: ...

# One part's steps of a partitioned CVT (hcvt.distributed.partition): shift (k, d), pinned (k,),
# preconditioner (k,); the Lloyd step; the L-BFGS direction from the coefficients of the
# two-loop recursion on the summed Gram matrices; the line search's acceptance.
def step_fields(
    domain: _Domain, sites: _Float2, mass: _Float1, first: _Float2, boundary_measure: _Float1
) -> tuple[_Float2, NDArray[np.bool_], _Float1]: ...
def lloyd_step(domain: _Domain, sites: _Float2, shifts: _Float2) -> _Float2: ...
def lbfgs_direction(
    domain: _Domain,
    sites: _Float2,
    gradient: _Float2,
    s: NDArray[np.float64],
    y: NDArray[np.float64],
    preconditioner: _Float1,
    c: _Float1,
    e: _Float1,
) -> _Float2: ...
def lbfgs_coefficients(plain: _Float2, weighted: _Float2) -> tuple[_Float1, _Float1]: ...
def line_search_accepts(
    phi0: float, slope0: float, t: float, value: float, slope: float
) -> bool: ...
def positive_curvature(sy: float, ss: float, yy: float) -> bool: ...

# The thread pool every computation runs in.
def set_num_threads(n: int) -> None: ...
def get_num_threads() -> int: ...
