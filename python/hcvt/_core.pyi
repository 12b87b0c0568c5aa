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

__all__ = [
    "PolygonDomain",
    "SolidDomain",
    "check_settings",
    "cvt_2d",
    "cvt_3d",
    "get_num_threads",
    "lbfgs_coefficients",
    "lbfgs_direction_2d",
    "lbfgs_direction_3d",
    "line_search_accepts",
    "lloyd_step_2d",
    "lloyd_step_3d",
    "mesh_2d",
    "mesh_3d",
    "mesh_part_2d",
    "mesh_part_3d",
    "partition_cells_2d",
    "partition_cells_3d",
    "positive_curvature",
    "set_num_threads",
    "step_fields_2d",
    "step_fields_3d",
    "voronoi_2d",
    "voronoi_3d",
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

# A density is either `polynomial=(constant, linear (d,), quadratic (d, d))` or
# `function=f` with f(points (m, d)) -> (m,), sampled by a rule of `quadrature_degree`.
_Coefficients = tuple[float, Sequence[float], Sequence[Sequence[float]]]
_Function = Callable[[NDArray[np.float64]], ArrayLike]

# Diagram dicts: volume, mass, centroid, second_moment, G, energy_terms, energy, gradient,
# boundary_measure, neighbor_offsets, neighbor_sites, neighbor_measures; with keep_cells the
# cells too (see hcvt.diagram).
def voronoi_2d(
    domain: PolygonDomain,
    sites: _Float2,
    allow_outside: bool = False,
    keep_cells: bool = False,
    polynomial: _Coefficients | None = None,
    function: _Function | None = None,
    quadrature_degree: int = 4,
) -> dict[str, Any]: ...
def voronoi_3d(
    domain: SolidDomain,
    sites: _Float2,
    allow_outside: bool = False,
    keep_cells: bool = False,
    polynomial: _Coefficients | None = None,
    function: _Function | None = None,
    quadrature_degree: int = 4,
) -> dict[str, Any]: ...

# Conforming mesh dicts (hcvt.mesh.polymesh.PolyMesh): points (p, d), face_offsets (f+1,),
# face_vertices, owner, neighbour, boundary_element (intp), open_chains (int).
def mesh_2d(
    domain: PolygonDomain, sites: _Float2, allow_outside: bool = False
) -> dict[str, Any]: ...
def mesh_3d(domain: SolidDomain, sites: _Float2, allow_outside: bool = False) -> dict[str, Any]: ...

# A part's mesh dicts (hcvt.distributed.partition_mesh): a mesh dict of the own cells' faces,
# owner and neighbour indexing the sites given, plus computed (c,) intp and reach2 (c,).
def mesh_part_2d(
    domain: PolygonDomain,
    sites: _Float2,
    rows: NDArray[np.int64],
    own: NDArray[np.uint32],
    total_sites: int,
    allow_outside: bool = False,
) -> dict[str, Any]: ...
def mesh_part_3d(
    domain: SolidDomain,
    sites: _Float2,
    rows: NDArray[np.int64],
    own: NDArray[np.uint32],
    total_sites: int,
    allow_outside: bool = False,
) -> dict[str, Any]: ...

# Partition dicts: a diagram dict with one row per own site, neighbor_sites in the
# problem's rows, first (k, d) moments about the sites, reach2 (k,) (see hcvt.distributed).
def partition_cells_2d(
    domain: PolygonDomain,
    sites: _Float2,
    rows: NDArray[np.int64],
    own: NDArray[np.uint32],
    total_sites: int,
    allow_outside: bool = False,
    polynomial: _Coefficients | None = None,
    function: _Function | None = None,
    quadrature_degree: int = 4,
) -> dict[str, Any]: ...
def partition_cells_3d(
    domain: SolidDomain,
    sites: _Float2,
    rows: NDArray[np.int64],
    own: NDArray[np.uint32],
    total_sites: int,
    allow_outside: bool = False,
    polynomial: _Coefficients | None = None,
    function: _Function | None = None,
    quadrature_degree: int = 4,
) -> dict[str, Any]: ...

# CVT dicts: sites, diagram (a diagram dict), history (arrays per field), stop_reason,
# iterations, evaluations (see hcvt.optimise). `frame=(centre, scale)`: the sites are in
# the frame x' = (x - centre) / scale, and grad_norm (the paper's rule) is measured in x.
def cvt_2d(
    domain: PolygonDomain,
    sites: _Float2,
    method: str = "lbfgs",
    rule: str = "gap",
    tol: float | None = None,
    max_iter: int = 10_000,
    memory: int = 7,
    callback: Callable[[dict[str, Any]], Any] | None = None,
    polynomial: _Coefficients | None = None,
    function: _Function | None = None,
    quadrature_degree: int = 4,
    frame: tuple[Sequence[float], float] | None = None,
) -> dict[str, Any]: ...
def cvt_3d(
    domain: SolidDomain,
    sites: _Float2,
    method: str = "lbfgs",
    rule: str = "gap",
    tol: float | None = None,
    max_iter: int = 10_000,
    memory: int = 7,
    callback: Callable[[dict[str, Any]], Any] | None = None,
    polynomial: _Coefficients | None = None,
    function: _Function | None = None,
    quadrature_degree: int = 4,
    frame: tuple[Sequence[float], float] | None = None,
) -> dict[str, Any]: ...

# The optimiser's settings, checked once for every driver: the tol to use.
def check_settings(
    method: str, rule: str, tol: float | None, max_iter: int, memory: int
) -> float: ...

# One part's steps of a partitioned CVT (hcvt.distributed.partition): shift (k, d), pinned (k,),
# preconditioner (k,); the Lloyd step; the L-BFGS direction from the coefficients of the
# two-loop recursion on the summed Gram matrices; the line search's acceptance.
def step_fields_2d(
    domain: PolygonDomain, sites: _Float2, mass: _Float1, first: _Float2, boundary_measure: _Float1
) -> tuple[_Float2, NDArray[np.bool_], _Float1]: ...
def step_fields_3d(
    domain: SolidDomain, sites: _Float2, mass: _Float1, first: _Float2, boundary_measure: _Float1
) -> tuple[_Float2, NDArray[np.bool_], _Float1]: ...
def lloyd_step_2d(domain: PolygonDomain, sites: _Float2, shifts: _Float2) -> _Float2: ...
def lloyd_step_3d(domain: SolidDomain, sites: _Float2, shifts: _Float2) -> _Float2: ...
def lbfgs_direction_2d(
    domain: PolygonDomain,
    sites: _Float2,
    gradient: _Float2,
    s: NDArray[np.float64],
    y: NDArray[np.float64],
    preconditioner: _Float1,
    c: _Float1,
    e: _Float1,
) -> _Float2: ...
def lbfgs_direction_3d(
    domain: SolidDomain,
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
