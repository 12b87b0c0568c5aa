"""What the binding returns: the dicts of arrays built by ``hcvt._core``, typed.

Each dict is built in one place of the binding (crates/hcvt-py/src): a diagram's arrays by
``diagram_dict`` (diagram.rs), a mesh's by ``mesh_dict`` (mesh.rs), a CVT's by
``outcome_dict`` and its per-iterate record by ``call`` (optimise.rs), a mesh's quality by
``quality_dict`` (quality.rs). The stubs
(``_core.pyi``) return these types, so that mypy checks every key the package reads.

Shapes: ``n`` sites, dimension ``d``; ``k`` neighbour entries; float arrays are float64 in
the core's frame (``hcvt.geometry.frame``), index arrays ``np.intp``.
"""

from __future__ import annotations

from typing import Literal, NotRequired, TypedDict

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "CellField",
    "CvtArrays",
    "CvtHistory",
    "CvtRecord",
    "DiagramArrays",
    "MeshArrays",
    "MeshPartArrays",
    "MeshQualityArrays",
    "PartCellsArrays",
    "RestrictedDelaunayArrays",
    "SurfacePiecesArrays",
]

Floats = NDArray[np.float64]
Indices = NDArray[np.intp]


class DiagramArrays(TypedDict):
    """A clipped diagram, row ``i`` the cell of site ``i``: one shape for every producer.

    ``_core.voronoi``, the CVT's, the transport's, a part's and
    ``_core.restricted_delaunay``'s ``diagram`` all return the cells' ``moments`` (and
    ``weighted``) and the faces; the quantities of :class:`hcvt.Diagram` (volume,
    centroid, G, ...) are made from the moments when read (``_core.diagram_field``;
    issue 32: memory per site).
    """

    # Rows (mass, first moment (d), second moment) of each cell about its site.
    moments: Floats  # (n, d + 2)
    weighted: NotRequired[Floats]  # (n, d + 2), ρ-weighted: only with a density
    energy: float
    boundary_measure: Floats  # (n,) share of the domain boundary, L^(d−1)
    neighbor_offsets: Indices  # (n + 1,)
    neighbor_sites: Indices | NDArray[np.uint32]  # (k,): uint32; a part's, problem rows
    neighbor_measures: Floats  # (k,) L^(d−1)
    # In a periodic box: the image shift of each neighbour, in {-1, 0, 1}^d.
    neighbor_images: NotRequired[NDArray[np.int8]]  # (k, d)
    # With keep_cells: 2D, each site's convex cell counter-clockwise, absolute.
    cell_offsets: NotRequired[Indices]  # (n + 1,)
    cell_vertices: NotRequired[Floats]  # (m, d)
    # With keep_cells: 3D, each cell a closed outward triangle mesh (local indices).
    cell_vertex_offsets: NotRequired[Indices]  # (n + 1,)
    cell_face_offsets: NotRequired[Indices]  # (n + 1,)
    cell_faces: NotRequired[Indices]  # (f, 3)


#: The per-cell fields of a :class:`DiagramArrays` (and ``energy``), as names to read.
CellField = Literal[
    "volume",
    "mass",
    "centroid",
    "second_moment",
    "G",
    "energy_terms",
    "energy",
    "gradient",
    "boundary_measure",
    "neighbor_measures",
]


class PartCellsArrays(DiagramArrays):
    """A part's own cells (``_core.partition_cells``): neighbours in the problem's rows."""

    reach2: Floats  # (n_own,) L²


class MeshArrays(TypedDict):
    """The conforming mesh (``_core.mesh``), OpenFOAM's layout (``hcvt.mesh.PolyMesh``)."""

    points: Floats  # (p, d)
    face_offsets: Indices  # (f + 1,)
    face_vertices: Indices
    owner: Indices  # (f,)
    neighbour: Indices  # (f,), −1 on the boundary
    boundary_element: Indices  # (f,), −1 inside
    open_chains: int


class MeshPartArrays(MeshArrays):
    """A part's faces (``_core.mesh_part``): the cells computed and their reach."""

    computed: Indices  # (c,)
    reach2: Floats  # (c,) L²


class MeshQualityArrays(TypedDict):
    """A mesh's geometry and checkMesh quality (``_core.mesh_quality``, ``hcvt.mesh.quality``).

    Rows are the mesh's faces (f) or cells (n); NaN marks a boundary face's figures that
    need two cells, and the centroid of a cell without faces.
    """

    face_centre: Floats  # (f, d) L, OpenFOAM's fan centre
    area_vector: Floats  # (f, d) L^(d−1), out of the owner
    volume: Floats  # (n,) L^d
    centroid: Floats  # (n, d) L
    aspect_ratio: Floats  # (n,)
    non_orthogonality: Floats  # (f,) degrees, NaN on the boundary
    skewness: Floats  # (f,)
    inverted_pyramid: NDArray[np.bool_]  # (f,)
    volume_ratio: Floats  # (f,) NaN on the boundary


class CvtRecord(TypedDict):
    """One iterate of a CVT, as the callback of ``_core.cvt`` sees it."""

    energy: float
    mean_G: float
    rms_gap: float
    max_gap: float
    grad_norm: float
    pinned: int
    seconds: float
    evaluations: int
    step: str
    sites: Floats  # (n, d)


class CvtHistory(TypedDict):
    """Every iterate's record, one array per field."""

    energy: Floats
    mean_G: Floats
    rms_gap: Floats
    max_gap: Floats
    grad_norm: Floats
    pinned: Indices
    seconds: Floats
    evaluations: Indices
    step: list[str]
    max_volume_error: NotRequired[Floats]  # with volumes: after each outer iteration
    newton_steps: NotRequired[Indices]  # with volumes: the transport's Newton steps


class CvtArrays(TypedDict):
    """A CVT (``_core.cvt``): the final sites, their diagram, the history, why it stopped."""

    sites: Floats  # (n, d)
    diagram: DiagramArrays
    history: CvtHistory
    stop_reason: str
    iterations: int
    evaluations: int
    weights: NotRequired[Floats]  # (n,), with volumes: the power diagram's
    targets: NotRequired[Floats]  # (n,), with volumes: scaled when normalised


class TransportHistory(TypedDict):
    """Per Newton step of ``_core.optimal_transport``, one array per field."""

    max_error: Floats
    step: Floats
    min_mass: Floats
    cg_iterations: Indices
    diagrams: Indices


class TransportArrays(TypedDict):
    """Prescribed masses (``_core.optimal_transport``): the weights and their diagram."""

    weights: Floats  # (n,)
    diagram: DiagramArrays
    targets: Floats  # (n,)
    max_error: float
    converged: bool
    history: TransportHistory


class RestrictedDelaunayArrays(TypedDict):
    """The restricted Delaunay triangulation on a surface (``_core.restricted_delaunay``)."""

    triangles: Indices  # (m, 3) site indices, counter-clockwise about the surface normal
    points: Floats  # (m, 3) where the three cells meet
    faces: Indices  # (m,) the surface triangle of each meeting point
    repeated: Indices  # (r, 3) triples of cells meeting at more than one point
    diagram: NotRequired[DiagramArrays]  # with_diagram=True: the sites' voronoi dict


class SurfacePiecesArrays(TypedDict):
    """Restricted Voronoi cells as convex planar pieces (``_core.surface_pieces``)."""

    points: Floats  # (p, 3) every piece's nodes, counter-clockwise about its triangle's normal
    piece_offsets: Indices  # (m + 1,) piece k's nodes are points[piece_offsets[k]:[k + 1]]
    piece_cell: Indices  # (m,) the site of each piece, non-decreasing
    piece_face: Indices  # (m,) the input triangle of each piece
