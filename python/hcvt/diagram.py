"""The clipped Voronoi diagram of sites in a domain, exact to round-off."""

from __future__ import annotations

from functools import cached_property
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import sparse

import hcvt._core as _core
from hcvt.core_results import CellField, DiagramArrays
from hcvt.density import DEFAULT_QUADRATURE_DEGREE, DensityLike, core_arguments
from hcvt.draw import Shows
from hcvt.errors import InvalidSitesError
from hcvt.geometry.domain import Domain
from hcvt.geometry.frame import Frame
from hcvt.io.geo import to_geodataframe
from hcvt.io.writers import to_pyvista
from hcvt.mesh.cells import polygons, triangulated
from hcvt.mesh.periodic import bounded, periodic_mesh
from hcvt.mesh.pieces import SurfacePieces
from hcvt.mesh.polymesh import PolyMesh
from hcvt.mesh.sphere import SphereMesh, spherical_mesh

# Faces shorter (2D) or smaller (3D) than this fraction of h^(d-1), h = (V/n)^(1/d), are
# not restricted Delaunay edges: lattices produce faces of zero measure up to round-off.
NEIGHBOR_REL_TOL = 1e-9


class Diagram(Shows):
    """A clipped Voronoi diagram; row ``i`` of every array is site ``i``.

    Integer arrays are ``np.intp``, the dtype numpy indexes with.

    Attributes
    ----------
    domain : Domain
        The domain the cells are clipped to.
    sites : ndarray of float64, shape (n, d)
        The generators, L (a private C-contiguous copy).
    n : int
        Number of sites.
    density : Polynomial, SizingField, callable or None
        The density ρ the weighted quantities carry (:mod:`hcvt.density`); None for ρ = 1.
    weights : ndarray of float64, shape (n,), or None
        The power diagram's weights, L² (cell ``i`` is ``{x : |x - z_i|² - w_i <=
        |x - z_j|² - w_j}``: possibly empty, possibly not holding its site); None for
        the Voronoi diagram.
    volume : ndarray, shape (n,)
        Cell areas (2D) or volumes (3D), L^d. Geometric, whatever the density.
    mass : ndarray, shape (n,)
        ``∫_cell ρ dx``; equal to ``volume`` without a density.
    centroid : ndarray, shape (n, d)
        Cell centroids, ρ-weighted with a density (where a CVT drives the sites), L; the
        site itself for an empty cell.
    second_moment : ndarray, shape (n,)
        ``∫ |x - c|² dx`` over each cell about its geometric centroid ``c``, L^(d+2).
        Geometric, whatever the density.
    G : ndarray, shape (n,)
        Dimensionless second moment of each cell (paper eq. 2): the geometric regularity
        of its shape, whatever the density; NaN only for the empty cell of a site
        outside the domain.
    mean_G : float
        Average of ``G`` over the non-empty cells (paper eq. 3).
    energy : float
        CVT energy ``Σ_i ∫_cell_i ρ |x - x_i|² dx`` about the sites (ρ = 1 without a
        density), ρ·L^(d+2).
    energy_terms : ndarray, shape (n,)
        Each cell's term of ``energy``: its ρ-weighted energy, ρ·L^(d+2).
    gradient : ndarray, shape (n, d)
        ``∂E/∂x_i = 2 m_i (x_i - c_i)`` with ρ-weighted ``m_i`` and ``c_i``, ρ·L^(d+1).
    boundary_measure : ndarray, shape (n,)
        Length (2D) or area (3D) of each cell's part of the domain boundary.
    neighbor_offsets : ndarray of intp, shape (n + 1,)
        Cell ``i``'s faces are entries ``neighbor_offsets[i]:neighbor_offsets[i + 1]`` of
        the two arrays below (CSR layout, as seen from ``i``, every face of the clipped
        cell, however small).
    neighbor_sites : ndarray of intp, shape (m,)
        The site across each face.
    neighbor_measures : ndarray, shape (m,)
        Length (2D) or area (3D) of each face inside the domain.
    neighbor_images : ndarray of int8, shape (m, d), or None
        In a periodic box (:meth:`hcvt.Domain.box`): the image of the site across each
        face, ``k`` in {-1, 0, 1}^d: the face is shared with ``w_j + k * (hi - lo)``, ``w``
        the sites wrapped into the box (:meth:`hcvt.Domain.wrap`). A site may then be a
        neighbour across several faces (one per image) or its own neighbour (few sites);
        each row is sorted by site, then image. None for every other domain.
    neighbors : ndarray of intp, shape (k, 2)
        Restricted Delaunay edges ``(i, j)``, ``i < j``, sorted: the faces above of
        positive measure (more than ``NEIGHBOR_REL_TOL · h^(d-1)``). In a periodic box a
        pair appears once per image it shares a face across, and a cell's faces with its
        own images are left out.
    face_measures : ndarray, shape (k,)
        The measure of each face of ``neighbors``.
    adjacency : scipy.sparse.csr_array of float64, shape (n, n)
        ``neighbors`` as a symmetric sparse matrix whose entries are ``face_measures``.

    Methods ``cell_neighbors(i)``, ``mesh()`` and ``cells()`` give one cell's faces, all
    cells as one conforming mesh, and every cell's geometry. In Jupyter a diagram shows
    its cells coloured by G (a cut view in 3D) beside a summary (``_repr_html_``,
    ``_repr_png_``; up to :data:`hcvt.draw.INLINE_LIMIT` cells).

    The core computes in the domain's frame (:mod:`hcvt.geometry.frame`); ``arrays`` are
    its results there, and each quantity above is mapped back to L when first read. One
    that float64 cannot hold in L (the second moments of cells 1e100 wide) raises
    :class:`hcvt.errors.UnrepresentableError` then, and only then.
    """

    def __init__(
        self,
        domain: Domain,
        sites: NDArray[np.float64],
        arrays: DiagramArrays,
        density: DensityLike = None,
        *,
        allow_outside: bool = False,
        core_sites: NDArray[np.float64] | None = None,
        frame: Frame | None = None,
        weights: NDArray[np.float64] | None = None,
    ):
        self.domain = domain
        self.sites = sites
        self.density = density
        self.weights = weights
        self._arrays = arrays
        # The frame `arrays` are in: the domain's, unless the caller mapped them already.
        self._frame = domain.frame if frame is None else frame
        # The sites the core computed with (the frame's), for the mesh.
        self._core_sites = domain.frame.to_core(sites) if core_sites is None else core_sites
        self.neighbor_offsets: NDArray[np.intp] = arrays["neighbor_offsets"]
        self._allow_outside = allow_outside
        self._mesh: PolyMesh | None = None
        self._sphere_mesh: SphereMesh | None = None
        self._pieces: SurfacePieces | None = None

    @property
    def neighbor_images(self) -> NDArray[np.int8] | None:
        """Image shift of the site across each face, shape (m, d), in a periodic box."""
        return self._arrays.get("neighbor_images")

    def _in_input(self, name: CellField) -> Any:
        return self._frame.to_input(name, self._in_frame(name))

    def _in_frame(self, name: CellField) -> Any:
        """The core's ``name`` in the frame, as returned or made from the moments now.

        The core returns the cells' moments, not the quantities (issue 32: memory per
        site): each is made from them when first read (``_core.diagram_field``).
        """
        if name in ("energy", "boundary_measure", "neighbor_measures"):
            return self._arrays[name]
        return _core.diagram_field(
            self.domain._core,
            self._core_sites,
            self._arrays["moments"],
            self._arrays.get("weighted"),
            name,
        )

    @cached_property
    def neighbor_sites(self) -> NDArray[np.intp]:
        """The site across each face, shape (m,), intp (uint32 in the core's arrays)."""
        return np.asarray(self._arrays["neighbor_sites"], dtype=np.intp)

    @cached_property
    def volume(self) -> NDArray[np.float64]:
        """Cell areas (2D) or volumes (3D), shape (n,), L^d."""
        return self._in_input("volume")

    @cached_property
    def mass(self) -> NDArray[np.float64]:
        """``∫_cell ρ dx``, shape (n,); ``volume`` without a density."""
        return self._in_input("mass")

    @cached_property
    def centroid(self) -> NDArray[np.float64]:
        """Cell centroids (ρ-weighted with a density), shape (n, d), L."""
        return self._in_input("centroid")

    @cached_property
    def second_moment(self) -> NDArray[np.float64]:
        """``∫ |x - c|² dx`` about each geometric centroid, shape (n,), L^(d+2)."""
        return self._in_input("second_moment")

    @cached_property
    def G(self) -> NDArray[np.float64]:  # noqa: N802 (the paper's G)
        """Dimensionless second moment of each cell (paper eq. 2), shape (n,)."""
        return self._in_input("G")

    @cached_property
    def energy_terms(self) -> NDArray[np.float64]:
        """Each cell's ρ-weighted energy about its site, shape (n,), ρ·L^(d+2)."""
        return self._in_input("energy_terms")

    @cached_property
    def energy(self) -> float:
        """CVT energy ``Σ_i ∫_cell_i ρ |x - x_i|² dx``, ρ·L^(d+2)."""
        return float(self._in_input("energy"))

    @cached_property
    def gradient(self) -> NDArray[np.float64]:
        """``∂E/∂x_i = 2 m_i (x_i - c_i)``, shape (n, d), ρ·L^(d+1)."""
        return self._in_input("gradient")

    @cached_property
    def boundary_measure(self) -> NDArray[np.float64]:
        """Each cell's length (2D) or area (3D) of domain boundary, shape (n,)."""
        return self._in_input("boundary_measure")

    @cached_property
    def neighbor_measures(self) -> NDArray[np.float64]:
        """Length (2D) or area (3D) of each face of ``neighbor_sites``, shape (m,)."""
        return self._in_input("neighbor_measures")

    @property
    def n(self) -> int:
        """Number of sites."""
        return len(self.sites)

    @property
    def mean_G(self) -> float:  # noqa: N802 (the paper's G)
        """Average of G over the non-empty cells (paper eq. 3)."""
        return float(np.nanmean(self.G))

    @cached_property
    def _pairs(self) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
        counts = np.diff(self.neighbor_offsets)
        owner = np.repeat(np.arange(self.n, dtype=np.intp), counts)
        other = self.neighbor_sites
        # In the frame: h and the measures are representable there at every scale.
        measures = self._arrays["neighbor_measures"]
        volume = (
            self.domain._core.volume if self._frame is self.domain.frame else self.domain.volume
        )
        d = self.domain.cell_dim
        h = (float(volume) / self.n) ** (1.0 / d)
        floor = NEIGHBOR_REL_TOL * h ** (d - 1)
        keep = (owner < other) & (measures > floor)
        pairs = np.column_stack([owner[keep], other[keep]])
        return pairs, self._frame.to_input("neighbor_measures", measures[keep])

    @property
    def neighbors(self) -> NDArray[np.intp]:
        """Restricted Delaunay edges, shape (k, 2), ``i < j``, sorted by ``(i, j)``.

        Pairs of cells sharing a face of positive measure inside the domain (DESIGN §3.5).
        """
        return self._pairs[0]

    @property
    def face_measures(self) -> NDArray[np.float64]:
        """Face measure inside the domain of each pair in :attr:`neighbors`, shape (k,).

        Length in 2D, area in 3D.
        """
        return self._pairs[1]

    @cached_property
    def adjacency(self) -> sparse.csr_array:
        """Restricted Delaunay graph, (n, n) symmetric, entry ``(i, j)`` the face measure.

        For scipy.sparse.csgraph (components, shortest paths) and graph Laplacians.

        Examples
        --------
        >>> import hcvt
        >>> square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
        >>> d = hcvt.voronoi(square, [[0.25, 0.25], [0.75, 0.25], [0.25, 0.75], [0.75, 0.75]])
        >>> d.adjacency.toarray()
        array([[0. , 0.5, 0.5, 0. ],
               [0.5, 0. , 0. , 0.5],
               [0.5, 0. , 0. , 0.5],
               [0. , 0.5, 0.5, 0. ]])
        """
        (i, j), measure = self.neighbors.T, self.face_measures
        rows, cols = np.concatenate([i, j]), np.concatenate([j, i])
        values = np.concatenate([measure, measure])
        return sparse.csr_array((values, (rows, cols)), shape=(self.n, self.n))

    def cell_neighbors(self, i: int) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
        """Sites sharing a face with cell ``i`` and that face's measure, as seen from ``i``."""
        s, e = int(self.neighbor_offsets[i]), int(self.neighbor_offsets[i + 1])
        return self.neighbor_sites[s:e], self.neighbor_measures[s:e]

    def mesh(self) -> PolyMesh:
        """The cells as one conforming mesh, made on first call and kept.

        Every vertex once, every face once with the cell on each side (OpenFOAM's layout):
        neighbouring cells share exactly the same face and vertices. Made from the core's
        own clipped pieces (DESIGN §9): bisector faces restricted to the domain and the
        boundary triangles (segments) inside each cell, vertices named by the bisectors and
        boundary elements that make them. Each cell's volume and centroid recomputed from
        its faces agree with ``volume`` and ``centroid`` to round-off.

        A power diagram (``weights``) is meshed alike, its vertices named by the power
        bisectors; an empty cell has no faces (``n_cells`` stays the number of sites: the
        writers leave such cells out and write each kept cell's site). In a box periodic
        along some axes the cells are unwrapped around their wrapped sites and the faces
        across periodic sides are paired (:mod:`hcvt.mesh.periodic`).

        Returns
        -------
        PolyMesh
            ``points`` (p, d), faces with ``owner``, ``neighbour`` (``-1`` on the boundary)
            and ``boundary_element``; interior faces first, sorted by (owner, neighbour).
        """
        if self.domain.is_sphere:
            raise NotImplementedError(
                "spherical cells have no PolyMesh: use Diagram.spherical_mesh() (MPAS's "
                "layout), Diagram.cells() (each cell's vertices) or hcvt.write_mpas"
            )
        if self.domain.is_surface:
            raise NotImplementedError(
                "restricted Voronoi cells on a surface have no PolyMesh (they are pieces of "
                "the surface, not solids): use Diagram.surface_pieces(), Diagram.cells(), "
                "Diagram.to_pyvista() or hcvt.io.write_cells(diagram, 'cells.vtu')"
            )
        if self._mesh is None and any(self.domain.periodic):
            self._mesh = periodic_mesh(self)
        if self._mesh is None:
            # A box is meshed as the polygon or solid it is (boundary elements to name
            # the vertices on its sides).
            target = bounded(self.domain)
            frame = target.frame
            core_sites = self._core_sites if target is self.domain else frame.to_core(self.sites)
            core_weights = None
            if self.weights is not None and np.any(self.weights):
                core_weights = frame.quantity_to_core("weights", self.weights)
            with frame.input_errors():
                arrays = _core.mesh(
                    target._core,
                    core_sites,
                    allow_outside=self._allow_outside,
                    weights=core_weights,
                )
            self._mesh = PolyMesh(
                points=frame.to_input("points", arrays["points"]),
                face_offsets=arrays["face_offsets"],
                face_vertices=arrays["face_vertices"],
                owner=arrays["owner"],
                neighbour=arrays["neighbour"],
                boundary_element=arrays["boundary_element"],
                n_cells=self.n,
            )
        return self._mesh

    def spherical_mesh(self) -> SphereMesh:
        """The cells on the sphere as a mesh of cells, edges and vertices, made once.

        MPAS's layout (0-based): topology from :attr:`neighbors`, each cell's neighbours
        counter-clockwise seen from outside, the Delaunay triangles between them, and the
        Voronoi vertices as their circumcentres on the sphere (from the sites alone);
        cocircular sites give edges of length zero (:mod:`hcvt.mesh.sphere`). Each arc's
        length (``dv_edge``) equals :attr:`face_measures` to round-off. Written by
        :func:`hcvt.write_mpas`; its quality by :func:`hcvt.sphere_quality`.

        Raises
        ------
        ValueError
            The domain is not :meth:`hcvt.Domain.sphere`, or the sites are too few (a
            cell with fewer than three neighbours, or cells reaching a hemisphere).
        """
        if not self.domain.is_sphere:
            raise ValueError("spherical_mesh() is for diagrams on hcvt.Domain.sphere; use mesh()")
        if self.domain.is_sphere_region:
            raise NotImplementedError(
                "spherical_mesh() of a region of the sphere (cells cut by its boundary) is not "
                "implemented yet; the diagram's measures, neighbours and arcs are"
            )
        if self._sphere_mesh is None:
            self._sphere_mesh = spherical_mesh(self._core_sites, self.neighbors, self.domain.radius)
        return self._sphere_mesh

    def surface_pieces(self) -> SurfacePieces:
        """The cells on a triangle surface as convex planar pieces, made on first call and kept.

        Each piece is the part of one input triangle in one cell, its vertices (L)
        counter-clockwise about the triangle's normal: the very polygons whose moments
        give ``volume`` and ``centroid`` (the core notes them as it measures the cells;
        the diagram is computed once more for them, without a density, which changes
        no cell). See :class:`hcvt.mesh.pieces.SurfacePieces`.

        Raises
        ------
        ValueError
            The domain is not :meth:`hcvt.Domain.from_surface`.
        """
        if not self.domain.is_surface:
            raise ValueError("surface_pieces() is for diagrams on a triangle surface; use mesh()")
        if self._pieces is None:
            frame = self.domain.frame
            with frame.input_errors():
                arrays = _core.surface_pieces(self.domain._core, self._core_sites)
            self._pieces = SurfacePieces(
                points=frame.to_input("points", arrays["points"]),
                piece_offsets=arrays["piece_offsets"],
                piece_cell=arrays["piece_cell"],
                piece_face=arrays["piece_face"],
                n_cells=self.n,
            )
        return self._pieces

    def cells(self) -> list[Any]:
        """Geometry of every clipped cell, read off :meth:`mesh`.

        On the sphere: each cell's vertices, (k, 3) in L, counter-clockwise seen from
        outside (:meth:`spherical_mesh`; consecutive vertices joined by great-circle arcs).

        2D: a list of shapely Polygons (with holes where a cell has them), MultiPolygons
        for cells in several pieces, or empty Polygons.

        3D: a list of ``(vertices (k, 3), faces (f, 3))`` pairs, the closed, outward
        triangulation of each clipped cell's boundary (its mesh faces fanned from their
        first vertex; both arrays empty for an empty cell).

        On a triangle surface: the same pairs, each cell's pieces of the surface
        (:meth:`surface_pieces`) fanned into triangles counter-clockwise about the
        surface's normal (an open surface, not closed; the pieces' vertices are not
        merged); both arrays empty for an empty cell.
        """
        if self.domain.is_sphere:
            return list(self.spherical_mesh().cell_polygons())
        if self.domain.is_surface:
            return self.surface_pieces().cell_triangles()
        mesh = self.mesh()
        return triangulated(mesh) if self.domain.dim == 3 else polygons(mesh)

    def to_pyvista(self) -> Any:
        """The conforming mesh of the cells as a ``pyvista.UnstructuredGrid``.

        For interactive viewing (``diagram.to_pyvista().plot()``); cell data ``site``,
        ``volume``, ``G``. Needs pyvista, an optional extra (``pip install 'hcvt[viz]'``),
        and ``Diagram.mesh()``. See :func:`hcvt.io.to_pyvista`. On the sphere a
        ``pyvista.PolyData`` of the cells as polygons through their vertices (flat between
        them), cell data ``site``, ``area`` and ``G``. On a triangle surface a
        ``pyvista.PolyData`` of the cells' pieces (:meth:`surface_pieces`) as polygons,
        cell data ``site``, ``area`` (the cell's), ``G`` and ``face`` (the input
        triangle).
        """
        return to_pyvista(self)

    def to_geopandas(self) -> Any:
        """The 2D cells as a ``geopandas.GeoDataFrame``: row ``i`` the cell of site ``i``.

        Columns ``site_x``, ``site_y``, ``centroid_x``, ``centroid_y``, ``volume`` (the
        area, L²), ``mass`` (with a density), ``second_moment``, ``G``, ``energy``,
        ``boundary_measure``, ``neighbors`` (count) and the cell as ``geometry``; index
        ``site``; CRS the domain's (``domain.crs``). Needs geopandas
        (``pip install 'hcvt[geo]'``). See :func:`hcvt.io.geo.to_geodataframe`.

        Raises
        ------
        ValueError
            A 3D diagram.
        """
        return to_geodataframe(self)

    def __repr__(self) -> str:
        return (
            f"<hcvt.Diagram n={self.n} d={self.domain.dim} "
            f"mean G={self.mean_G:.6f} energy={self.energy:.6g}>"
        )

    def _shown(self) -> Diagram:
        return self


def voronoi(
    domain: Domain,
    sites: ArrayLike,
    *,
    allow_outside: bool = False,
    density: DensityLike = None,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
    weights: ArrayLike | None = None,
) -> Diagram:
    """The clipped Voronoi (or, with ``weights``, power) diagram of ``sites`` in ``domain``.

    :func:`hcvt.voronoi` without ``client``, which documents the parameters.
    """
    points = as_sites(sites, domain.dim)
    frame = domain.frame
    weighted = core_arguments(frame.density_to_core(density), domain.dim, quadrature_degree)
    core_sites = frame.to_core(points)
    power = None if weights is None else as_weights(weights, len(points))
    core_weights = None if power is None else frame.quantity_to_core("weights", power)
    with frame.input_errors():
        arrays = _core.voronoi(
            domain._core,
            core_sites,
            allow_outside=allow_outside,
            weights=core_weights,
            **weighted,
        )
    return Diagram(
        domain,
        points,
        arrays,
        density,
        allow_outside=allow_outside,
        core_sites=core_sites,
        weights=power,
    )


def as_weights(values: ArrayLike, n: int, name: str = "weights") -> NDArray[np.float64]:
    """Check and copy one value per site (``weights``, ``masses``): finite, shape (n,)."""
    arr = np.asarray(values)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be real numbers, got dtype {arr.dtype}")
    if arr.ndim == 0:
        arr = np.full(n, arr)
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), one per site, got {arr.shape}")
    out = np.array(arr, dtype=np.float64, order="C", copy=True)
    if not np.all(np.isfinite(out)):
        bad = int(np.flatnonzero(~np.isfinite(out))[0])
        one = {"masses": "mass"}.get(name, name.removesuffix("s"))
        raise ValueError(f"{one} {bad} is not finite ({out[bad]})")
    return out


def as_sites(sites: ArrayLike, dim: int) -> NDArray[np.float64]:
    """Check and copy ``sites`` to a C-contiguous float64 array of shape (n, dim)."""
    arr = np.asarray(sites)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"sites must be real numbers, got dtype {arr.dtype}")
    if arr.ndim != 2 or arr.shape[1] != dim:
        raise ValueError(f"sites must have shape (n, {dim}), got {arr.shape}")
    if arr.shape[0] == 0:
        raise InvalidSitesError("no sites given: a diagram needs n >= 1 sites")
    return np.array(arr, dtype=np.float64, order="C", copy=True)
