"""Domains: 2D polygons with holes, 3D solids bounded by closed triangle meshes, and boxes.

A polygon or solid is stored by its oriented boundary only (outer rings counter-clockwise,
holes clockwise; mesh triangles counter-clockwise seen from outside), checked once, and
indexed by a BVH in the Rust core. A box is its corners and which axes are periodic
(:meth:`Domain.box`). Every diagram, CVT and initialisation takes a :class:`Domain`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.polygon import orient

import hcvt._core as _core
from hcvt.errors import InvalidDomainError
from hcvt.geometry import repair as mesh
from hcvt.geometry.crs import projected_crs
from hcvt.geometry.frame import Frame
from hcvt.geometry.sphere import ON_SPHERE_RTOL, SphereFrame, check_radius
from hcvt.geometry.sphere_region import lonlat_to_unit, region_rings
from hcvt.geometry.surface_frame import SurfaceFrame

# VTK's cell type of a triangle (vtkCellType.h).
_VTK_TRIANGLE = 5

#: The 12 outward triangles of a 3D box's corners as :attr:`Domain.vertices` orders them
#: (corner ``k`` takes ``hi`` along axis ``a`` where bit ``a`` of ``k`` is set).
BOX_FACES = np.array(
    [
        [0, 2, 1], [1, 2, 3],  # z = lo
        [4, 5, 6], [5, 7, 6],  # z = hi
        [0, 1, 5], [0, 5, 4],  # y = lo
        [2, 6, 7], [2, 7, 3],  # y = hi
        [0, 4, 6], [0, 6, 2],  # x = lo
        [1, 3, 7], [1, 7, 5],  # x = hi
    ],
    dtype=np.intp,
)  # fmt: skip


@dataclass(frozen=True)
class RepairReport:
    """What ``repair=True`` changed in an input.

    Attributes
    ----------
    changed : bool
        Whether anything was changed at all.
    actions : list of str
        One line per change, in the order applied.
    volume_before, volume_after : float
        Area (2D) or volume (3D) before and after, where defined (NaN otherwise).
    notes : list of str
        Degeneracies that are valid and kept as they are (a hole touching the outline at
        one point pinches the domain there).
    """

    changed: bool
    actions: list[str] = field(default_factory=list)
    volume_before: float = float("nan")
    volume_after: float = float("nan")
    notes: list[str] = field(default_factory=list)

    def __str__(self) -> str:
        text = "repair: " + ("; ".join(self.actions) if self.changed else "nothing to change")
        return text + "".join(f"; note: {note}" for note in self.notes)


class Domain:
    """A 2D polygon with holes, a 3D solid or a box, checked and indexed for exact clipping.

    Build one with :meth:`from_polygon`, :meth:`from_mesh`, :meth:`box` or
    :func:`hcvt.load_domain`.

    Attributes
    ----------
    dim : int
        2 or 3.
    volume : float
        Area (2D) or volume (3D), in L^d.
    bounds : tuple of ndarray
        ``(lo, hi)`` corners of the bounding box, each shape (d,).
    repair_report : RepairReport or None
        What ``repair=True`` changed, when it was asked for.
    frame : Frame
        Where the core works: ``x' = (x - frame.centre) / frame.scale``, the domain about
        its own centre at a size near 1 (:mod:`hcvt.geometry.frame`); every result comes
        back in the input's coordinates. The identity for a domain near the origin of
        moderate size.
    crs : pyproj.CRS or None
        2D: the projected coordinate reference system of the input (GIS data read by
        :func:`hcvt.load_domain`, or ``crs=`` given to :meth:`from_polygon`); carried on to
        :meth:`hcvt.Diagram.to_geopandas` and the cells written. None when unknown.
    periodic : tuple of bool
        Which axes are periodic (a box made so by :meth:`box`); all False otherwise.
    """

    crs: Any = None

    def __init__(
        self,
        core: Any,
        dim: int,
        geometry: Any = None,
        repair_report: RepairReport | None = None,
        frame: Frame | None = None,
    ) -> None:
        self._core = core
        self.dim = dim
        self.geometry = geometry
        self.repair_report = repair_report
        self.frame = Frame(np.zeros(dim), 1.0) if frame is None else frame

    # ------------------------------------------------------------------ sphere
    @classmethod
    def sphere(cls, radius: float = 1.0, region: Any = None) -> Domain:
        """The sphere of ``radius`` about the origin: cells are spherical polygons.

        Sites are points of the sphere, shape (n, 3) (to a relative ``1e-9`` of the
        radius; they are pushed onto it exactly). Cells have dimension 2: ``volume`` is
        the area ``4πR²``, a diagram's ``volume`` the cells' areas, its ``centroid`` the
        constrained centroid ``∫x / |∫x|`` scaled to the sphere (Du, Gunzburger and Ju
        2003), ``second_moment`` ``∫|x − c|² dA`` about it, ``G`` with ``d = 2``, and
        ``neighbor_measures`` the great-circle arc lengths (DESIGN §13).

        With ``region``, a region of the sphere (a regional ocean): ``(lon, lat)`` in
        degrees, an (m, 2) array (one ring, closed or not) or a shapely Polygon in lon/lat
        whose holes are islands. Consecutive vertices are joined by great-circle arcs
        (densify long edges along a parallel first, :mod:`hcvt.geometry.sphere_region`).
        Cells are the spherical Voronoi cells clipped to it, exactly; ``volume`` is its
        area, ``boundary_measure`` the length of its boundary in each cell, sites must lie
        inside it. Diagrams, :func:`hcvt.cvt` (L-BFGS, the default there, and Lloyd; not
        Newton) and :func:`hcvt.initialise` (``method="random"``) take it; not yet a
        density, partitions, ``hierarchical_cvt`` or MPAS output.

        Raises
        ------
        InvalidDomainError
            ``region``: fewer than 3 vertices, non-finite ones or latitudes beyond ±90°,
            repeated consecutive vertices, edges that cross or touch (a ring that is not
            simple, holes meeting the outline or each other), a hole outside the outline,
            a region not within 89° of its vertices' mean direction (it must fit in an open
            hemisphere); each names the ring and vertex or edge.

        Examples
        --------
        >>> import hcvt
        >>> earth = hcvt.Domain.sphere(6371.0)
        >>> round(earth.volume / 1e6, 3)
        510.064
        >>> band = hcvt.Domain.sphere(1.0, region=[(0, 0), (10, 0), (10, 10), (0, 10)])
        >>> round(band.volume, 6)
        0.030382
        """
        r = check_radius(radius)
        if region is None:
            return cls(_core.SphereDomain(), 3, None, None, SphereFrame.of_radius(r))
        rings = region_rings(region)
        core = _core.SphereRegionDomain([lonlat_to_unit(ring) for ring in rings])
        domain = cls(core, 3, None, None, SphereFrame.of_radius(r, has_region=True))
        domain._region_lonlat = rings  # type: ignore[attr-defined]
        return domain

    @property
    def region(self) -> list[NDArray[np.float64]] | None:
        """The lon/lat rings of a region of the sphere, as given; None for other domains.

        Each ring (m, 2) in degrees, not closed; the outline first, then holes.
        """
        return getattr(self, "_region_lonlat", None)

    @property
    def is_sphere_region(self) -> bool:
        """Whether this is a region of the sphere (:meth:`sphere` with ``region``)."""
        return isinstance(self.frame, SphereFrame) and self.frame.has_region

    @property
    def is_sphere(self) -> bool:
        """Whether this is :meth:`sphere` (cells of dimension 2 on a surface)."""
        return isinstance(self.frame, SphereFrame)

    @property
    def radius(self) -> float:
        """The sphere's radius; AttributeError for other domains."""
        if not self.is_sphere:
            raise AttributeError("only a sphere has a radius")
        return float(self.frame.scale)

    @property
    def cell_dim(self) -> int:
        """The dimension of the cells: ``dim``, or 2 on the sphere and on a surface."""
        return 2 if self.is_sphere or self.is_surface else self.dim

    # ------------------------------------------------------------------ surfaces
    @classmethod
    def from_surface(cls, vertices: ArrayLike, faces: ArrayLike) -> Domain:
        """A triangle surface in 3D: restricted Voronoi diagrams and CVTs on it (DESIGN §12).

        Closed or open (its border loops kept), any number of components. Cell ``i`` of a
        diagram is the part of the surface nearer site ``i`` than any other site, exactly:
        the surface's triangles clipped by the site's convex 3D Voronoi cell. Sites may lie
        anywhere in space (a site far from the surface gets an empty cell). Cells have
        dimension 2: ``volume`` is the area, a diagram's ``volume`` the cells' areas, its
        ``centroid`` the 3D centroid ``∫x dA / A`` (off the surface, inside its
        curvature), ``second_moment`` ``∫|x − c|² dA``, ``G`` with ``d = 2``,
        ``neighbor_measures`` the lengths of the arcs two cells share and
        ``boundary_measure`` the length of the surface's border in each cell.

        Parameters
        ----------
        vertices : array_like of float, shape (V, 3)
        faces : array_like of int, shape (F, 3)
            Triangles, consistently oriented (every interior edge run both ways).

        Raises
        ------
        InvalidDomainError
            Non-finite coordinates, out-of-range indices, degenerate triangles (a repeated
            vertex or zero area), a triangle repeated on the same vertices, non-manifold
            edges (in three or more triangles), inconsistent orientation (an edge run the
            same way by two triangles); each with its count and the first offender.

        Examples
        --------
        >>> import hcvt
        >>> square = hcvt.Domain.from_surface(
        ...     [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)], [(0, 1, 2), (0, 2, 3)])
        >>> square.volume, square.cell_dim
        (1.0, 2)
        """
        v, f = mesh.as_mesh_arrays(vertices, faces)
        frame = SurfaceFrame.fit_surface(v)
        core = _core.SurfaceDomain(
            frame.to_core(v, "vertices"), np.ascontiguousarray(f, dtype=np.uint32)
        )
        return cls(core, 3, None, None, frame)

    @property
    def is_surface(self) -> bool:
        """Whether this is a triangle surface (:meth:`from_surface`)."""
        return isinstance(self.frame, SurfaceFrame)

    # ------------------------------------------------------------------ 2D
    @classmethod
    def from_polygon(
        cls,
        polygon: Polygon | MultiPolygon | ArrayLike | tuple[ArrayLike, Sequence[ArrayLike]],
        holes: Sequence[ArrayLike] | None = None,
        *,
        repair: bool = False,
        crs: Any = None,
    ) -> Domain:
        """Domain bounded by a polygon with any number of holes (non-convex allowed).

        Parameters
        ----------
        polygon : shapely Polygon or MultiPolygon, array_like (k, 2), or (outer, holes)
            The outline; a bare ring of vertices, or a pair ``(outer, [hole, ...])``.
        holes : sequence of array_like (k, 2), optional
            Hole rings, when ``polygon`` is a bare outer ring.
        repair : bool, default False
            Fix invalid input with ``shapely.make_valid(method="structure")``: the union of
            the outer rings minus the holes, so a bow-tie becomes two triangles, a zero-width
            spike is cut off and a hole sharing an edge with the outline becomes a notch;
            parts of zero area are dropped. ``domain.repair_report`` says what changed.
            Without it invalid input raises. Repeated consecutive vertices are always
            removed (zero-length edges change nothing), and a hole touching the outline at a
            single vertex is valid (OGC) and accepted: the domain is pinched there.
        crs : pyproj.CRS, str or int, optional
            The coordinates' reference system (``"EPSG:2263"``, ...), kept as
            ``domain.crs``; it must be projected (needs pyproj, ``pip install 'hcvt[geo]'``).

        Raises
        ------
        InvalidDomainError
            Non-finite coordinates, a ring with fewer than 3 distinct vertices, a
            self-intersection (with its location), zero area; each message names the ring.
            A geographic (longitude/latitude) ``crs``: project the data first.

        Examples
        --------
        >>> import hcvt
        >>> square = hcvt.Domain.from_polygon([(0, 0), (2, 0), (2, 2), (0, 2)],
        ...                                   holes=[[(0.5, 0.5), (1, 0.5), (1, 1)]])
        >>> float(square.volume)
        3.875
        """
        geometry = _as_shapely(polygon, holes)
        parsed_crs = None
        if crs is not None:
            parsed_crs = projected_crs(crs, shapely.get_coordinates(geometry))
        report = None
        if repair:
            geometry, report = _repair_polygon(geometry)
        else:
            _check_polygon(geometry)
        geometry = _normalise_polygon(geometry)
        vertices, segments = polygon_boundary(geometry)
        frame = Frame.fit(vertices)
        core = _core.PolygonDomain(frame.to_core(vertices, "vertices"), segments)
        domain = cls(core, 2, geometry, report, frame)
        domain.crs = parsed_crs
        return domain

    # ------------------------------------------------------------------ boxes
    @classmethod
    def box(
        cls, lo: ArrayLike, hi: ArrayLike, *, periodic: bool | Sequence[bool] = False
    ) -> Domain:
        """The axis-aligned box ``[lo, hi]`` in 2D or 3D, periodic along some axes or all.

        Along a periodic axis the box is a torus (DESIGN §14): a cell that crosses the side
        at ``lo_k`` continues at ``hi_k``, every neighbour face carries the image shift of
        its neighbour (:attr:`hcvt.Diagram.neighbor_images`), sites may lie anywhere along
        the axis (each stands for its image in ``[lo_k, hi_k)``, :meth:`wrap`) and a CVT
        moves them freely across the sides and returns them wrapped. Along the other axes
        the sides clip the cells, as for a polygon or solid box.

        Parameters
        ----------
        lo, hi : array_like of float, shape (d,)
            Opposite corners, ``lo < hi`` on every axis; d = 2 or 3.
        periodic : bool or sequence of d bools, default False
            Periodic along every axis (True), none (False), or those marked.

        Raises
        ------
        InvalidDomainError
            Non-finite corners, a side of zero or negative length, d not 2 or 3, or a
            ``periodic`` of the wrong length.

        Notes
        -----
        Partitions (``client=``) take a box, periodic or not (halos wrap across the
        periodic sides). Not yet on a box: a density, Newton's method and partitioned power
        diagrams of a periodic box; each raises. The conforming mesh
        (:meth:`hcvt.Diagram.mesh`) pairs the faces across periodic sides
        (:mod:`hcvt.mesh.periodic`).

        Examples
        --------
        >>> import hcvt
        >>> torus = hcvt.Domain.box([0, 0], [2, 1], periodic=True)
        >>> d = hcvt.voronoi(torus, [[0.5, 0.5], [1.5, 0.5]])
        >>> d.volume.tolist()
        [1.0, 1.0]
        >>> d.neighbor_sites[:4].tolist(), d.neighbor_images[:4].tolist()
        ([0, 0, 1, 1], [[0, -1], [0, 1], [-1, 0], [0, 0]])
        """
        corners = np.array([_as_corner(lo, "lo"), _as_corner(hi, "hi")])
        dim = corners.shape[1]
        if dim not in (2, 3):
            raise InvalidDomainError(f"a box has 2 or 3 axes, got lo and hi of length {dim}")
        axes = (bool(periodic),) * dim if isinstance(periodic, bool) else tuple(periodic)
        if len(axes) != dim or not all(isinstance(a, (bool, np.bool_)) for a in axes):
            raise InvalidDomainError(f"periodic must be a bool or {dim} bools, got {periodic!r}")
        frame = Frame.fit(corners)
        core_lo, core_hi = frame.to_core(corners, "vertices")
        core_box = _core.BoxDomain2 if dim == 2 else _core.BoxDomain3
        core = core_box(tuple(core_lo), tuple(core_hi), tuple(bool(a) for a in axes))
        # In 2D the shapely rectangle too, for what reads a polygon (plots, lattice seeds).
        geometry = shapely.box(*corners[0], *corners[1]) if dim == 2 else None
        return cls(core, dim, geometry, None, frame)

    @property
    def periodic(self) -> tuple[bool, ...]:
        """Which axes are periodic, length d (all False but for a periodic :meth:`box`)."""
        if isinstance(self._core, (_core.BoxDomain2, _core.BoxDomain3)):
            return tuple(bool(p) for p in self._core.periodic)
        return (False,) * self.dim

    def wrap(self, points: ArrayLike) -> NDArray[np.float64]:
        """``points`` (m, d) moved by whole periods into ``[lo, hi)`` along periodic axes.

        Unchanged along the other axes (and for a domain that is not periodic), in the
        input's coordinates: ``lo + (x − lo) mod (hi − lo)``, and ``lo`` where rounding
        lands on ``hi``.
        """
        lo, hi = self.bounds
        return wrapped(_as_points(points, self.dim, "points"), lo, hi, self.periodic)

    # ------------------------------------------------------------------ 3D
    @classmethod
    def from_mesh(cls, vertices: ArrayLike, faces: ArrayLike, *, repair: bool = False) -> Domain:
        """Solid bounded by a closed triangle mesh, taken as indexed.

        Parameters
        ----------
        vertices : array_like of float, shape (V, 3)
        faces : array_like of int, shape (F, 3)
            Triangles, counter-clockwise seen from outside.
        repair : bool, default False
            Merge duplicate vertices (equal positions), drop degenerate and duplicate faces
            and the faces on non-manifold edges, orient every component consistently, fill
            each hole with a fan from its centroid, split pinched vertices, and orient each
            shell by the parity of its nesting (inside an even number of other shells it
            faces outward, inside an odd number it bounds a cavity and faces inward); shells
            that cross each other are united (manifold3d). ``domain.repair_report`` says
            what changed. The diagram is then exact for the repaired surface. A shell that
            crosses itself cannot be repaired: it is left, the report says where, and the
            overlaps count with their winding number (2, or -1) near the crossing.

        Raises
        ------
        InvalidDomainError
            Without ``repair``: any of degenerate faces, duplicate vertices, open boundary
            edges, non-manifold edges, inconsistent winding, pinched vertices, inward
            orientation, zero volume, triangles crossing each other (exact test of pairs
            sharing no vertex; the message names their shells), shells whose nesting makes
            the winding number other than 0 or 1 somewhere (a shell inside another facing
            the same way, a cavity facing outward), each with its count and first offending
            element.
            Always: NaN/inf coordinates, out-of-range indices, nothing left after repair.

        Examples
        --------
        >>> import hcvt
        >>> v = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
        >>> f = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
        >>> round(hcvt.Domain.from_mesh(v, f).volume, 12)
        0.166666666667
        """
        v, f = mesh.as_mesh_arrays(vertices, faces)
        # Checks and repairs are free of scale and position: made in the domain's frame,
        # where volumes are representable for a mesh 1e-150 or 1e150 wide (issue 30).
        frame = Frame.fit(v)
        v = frame.to_core(v, "vertices")
        actions: list[str] = []
        before = mesh.signed_volume(v, f)
        if repair:
            v, f, actions = mesh.repair_mesh(v, f)
        mesh.check_mesh(v, f, repaired=repair)
        core = _core.SolidDomain(v, np.ascontiguousarray(f, dtype=np.uint32))
        count, pairs = core.crossing_triangles(1)
        if count:
            if not repair:
                where = mesh.describe_crossings(f, count, pairs)
                mesh.refuse(
                    [f"self-intersection: {where}"],
                    advice="pass repair=True to unite overlapping shells",
                )
            v, f = mesh.unite_shells(v, f, core.crossing_triangles(count)[1], actions)
            core = _core.SolidDomain(v, np.ascontiguousarray(f, dtype=np.uint32))
        else:
            nested = mesh.nesting_defects(mesh.nesting(v, f, crossing_is_error=True))
            if nested:
                mesh.refuse(nested, repaired=repair)
        report = None
        if repair:
            after = mesh.signed_volume(v, f)
            report = RepairReport(
                bool(actions), actions, frame.volume_or_nan(before), frame.volume_or_nan(after)
            )
        return cls(core, 3, None, report, frame)

    @classmethod
    def from_trimesh(cls, mesh: Any, *, repair: bool = False) -> Domain:
        """Solid bounded by a ``trimesh.Trimesh``, its vertices and faces as indexed.

        Parameters
        ----------
        mesh : trimesh.Trimesh
            A closed triangle mesh (``mesh.vertices`` (V, 3), ``mesh.faces`` (F, 3)). A
            ``trimesh.Scene`` is refused: join its geometry first (``scene.to_mesh()``).
        repair : bool, default False
            As in :meth:`from_mesh`.

        Raises
        ------
        TypeError
            ``mesh`` has no vertices and faces.
        InvalidDomainError
            As :meth:`from_mesh`.

        Examples
        --------
        >>> import hcvt, trimesh
        >>> round(hcvt.Domain.from_trimesh(trimesh.creation.box((1, 2, 3))).volume, 12)
        6.0
        """
        if not (hasattr(mesh, "vertices") and hasattr(mesh, "faces")):
            raise TypeError(
                f"expected a trimesh.Trimesh, got {type(mesh).__name__}"
                + (
                    "; join a Scene's geometry with scene.to_mesh()"
                    if hasattr(mesh, "dump")
                    else ""
                )
            )
        return cls.from_mesh(np.asarray(mesh.vertices), np.asarray(mesh.faces), repair=repair)

    @classmethod
    def from_pyvista(cls, dataset: Any, *, repair: bool = False) -> Domain:
        """Solid bounded by the triangles of a PyVista dataset.

        Parameters
        ----------
        dataset : pyvista.PolyData or pyvista.UnstructuredGrid
            A closed surface. Triangles are taken as indexed (``pv.read("bunny.off")`` is
            the file's mesh, bit for bit); other polygons are fanned into triangles
            (``triangulate()``); a volume mesh (tetrahedra, hexahedra ...) stands for the
            solid it fills, bounded by its ``extract_surface()``.
        repair : bool, default False
            As in :meth:`from_mesh`.

        Raises
        ------
        TypeError
            Not a PyVista dataset.
        InvalidDomainError
            As :meth:`from_mesh`.

        Examples
        --------
        >>> import hcvt, pyvista
        >>> round(hcvt.Domain.from_pyvista(pyvista.Cube(x_length=2.0)).volume, 12)
        2.0
        """
        if not hasattr(dataset, "extract_surface"):
            raise TypeError(f"expected a pyvista dataset, got {type(dataset).__name__}")
        celltypes = getattr(dataset, "celltypes", None)
        if celltypes is not None and len(celltypes) and np.all(celltypes == _VTK_TRIANGLE):
            faces = dataset.cells_dict[_VTK_TRIANGLE]
        else:
            surface = dataset if hasattr(dataset, "is_all_triangles") else _surface(dataset)
            if not surface.is_all_triangles:
                surface = surface.triangulate()
            dataset, faces = surface, surface.regular_faces
        return cls.from_mesh(np.asarray(dataset.points), np.asarray(faces), repair=repair)

    @property
    def vertices(self) -> NDArray[np.float64]:
        """Boundary vertices as indexed, shape (V, d), bit for bit the input's."""
        if self.is_sphere:
            raise AttributeError("the sphere has no boundary vertices")
        return self.frame.points_to_input(np.asarray(self._core.vertices))

    @property
    def faces(self) -> NDArray[np.intp]:
        """3D only: boundary triangles, shape (F, 3), counter-clockwise seen from outside.

        A 3D box: its six sides as 12 triangles of :attr:`vertices` (its corners), also for
        a periodic box (where the sides along periodic axes are no boundary of the cells).
        """
        if self.dim != 3 or self.is_sphere:
            raise AttributeError("faces exist for 3D solids only")
        if isinstance(self._core, _core.BoxDomain3):
            return BOX_FACES.copy()
        return np.asarray(self._core.faces)

    def generalized_winding_numbers(self, points: ArrayLike) -> NDArray[np.float64]:
        """Generalised winding number (Jacobson et al. 2013) of each point (m,), 3D only.

        About 1 inside and 0 outside, changing smoothly near small defects of the surface.
        Cost O(F) per point.
        """
        if self.dim != 3 or self.is_sphere:
            raise NotImplementedError("generalised winding numbers are implemented for solids")
        if self.is_surface:
            raise NotImplementedError("a surface bounds no solid: no winding numbers")
        pts = self.frame.to_core(_as_points(points, 3, "points"), "points")
        return np.asarray(self._core.generalized_winding_numbers(pts))

    # ------------------------------------------------------------------ queries
    @property
    def volume(self) -> float:
        """Area (2D) or volume (3D) of the domain, L^d.

        Raises :class:`hcvt.errors.UnrepresentableError` when it is outside float64's range
        (a solid of size 1e150); the work in the frame does not need it.
        """
        return float(self.frame.to_input("volume", float(self._core.volume)))

    @property
    def first_moment(self) -> NDArray[np.float64]:
        """``∫ x dx`` over the domain, shape (d,), L^(d+1)."""
        first = np.asarray(self._core.first_moment, dtype=np.float64)
        return np.asarray(self.frame.first_moment(first, float(self._core.volume)))

    @property
    def centroid(self) -> NDArray[np.float64]:
        """Centre of mass of the domain, shape (d,)."""
        if self.frame.is_identity:
            return self.first_moment / self.volume
        first = np.asarray(self._core.first_moment, dtype=np.float64)
        return self.frame.points_to_input(first / float(self._core.volume))

    @property
    def bounds(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(lo, hi)`` corners of the bounding box, each shape (d,)."""
        lo, hi = (np.asarray(b, dtype=np.float64) for b in self._core.bounds)
        return self.frame.points_to_input(lo), self.frame.points_to_input(hi)

    def winding_numbers(self, points: ArrayLike) -> tuple[NDArray[np.int32], NDArray[np.bool_]]:
        """Exact winding number of each point, and whether it lies on the boundary.

        On the sphere: 1 for points on it (to a relative ``1e-9`` of the radius), 0
        elsewhere, and no boundary. On a surface: 1 everywhere (sites may lie anywhere).

        Parameters
        ----------
        points : array_like, shape (m, d)

        Returns
        -------
        winding : ndarray of int32, shape (m,)
            1 inside, 0 outside (0 as well on the boundary).
        on_boundary : ndarray of bool, shape (m,)
        """
        if self.is_surface:
            p = _as_points(points, 3, "points")
            return np.ones(len(p), dtype=np.int32), np.zeros(len(p), dtype=bool)
        if self.is_sphere:
            p = _as_points(points, 3, "points")
            r = np.linalg.norm(p, axis=1)
            on = np.abs(r - self.radius) <= ON_SPHERE_RTOL * self.radius
            if self.is_sphere_region:
                # Inside the region: the core's test of the points' directions.
                unit = p[on] / r[on][:, None]
                winding, edge = self._core.winding_numbers(np.ascontiguousarray(unit))
                inside = np.zeros(len(p), dtype=np.int32)
                on_boundary = np.zeros(len(p), dtype=bool)
                inside[on], on_boundary[on] = winding, edge
                return inside, on_boundary
            return on.astype(np.int32), np.zeros(len(p), dtype=bool)
        pts = self.frame.to_core(_as_points(points, self.dim, "points"), "points")
        return self._core.winding_numbers(pts)

    def contains(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether each point (m, d) lies strictly inside the domain, shape (m,).

        The core's exact winding number, the same test the diagram uses for its sites, for
        every domain (a repaired one too: its repaired surface is the domain).
        """
        winding, on_boundary = self.winding_numbers(points)
        return (winding != 0) & ~on_boundary

    def __reduce__(self) -> tuple[Any, tuple[Any, ...]]:
        if isinstance(self._core, (_core.BoxDomain2, _core.BoxDomain3)):
            lo, hi = self.bounds
            return _unpickle_box, (lo, hi, self.periodic)
        # Pickled as its checked boundary (dask, joblib, multiprocessing); the core rebuilds
        # its index from the same arrays, so diagrams in another process are bitwise equal.
        if self.is_sphere:
            return Domain.sphere, (self.radius, *([self.region] if self.region else []))
        if self.is_surface:
            return Domain.from_surface, (self.vertices, self.faces)
        simplices = self._core.segments if self.dim == 2 else self._core.faces
        return _unpickle, (
            self.dim,
            self.vertices,
            simplices,
            self.geometry,
            self.repair_report,
            self.crs,
        )

    def __repr__(self) -> str:
        if self.is_sphere_region:
            area = f"area={self.volume:.6g}"
            return f"<hcvt.Domain region of a sphere, radius={self.radius:.6g}, {area}>"
        if self.is_sphere:
            return f"<hcvt.Domain sphere, radius={self.radius:.6g}>"
        if isinstance(self._core, (_core.BoxDomain2, _core.BoxDomain3)):
            kind = f"box periodic={self.periodic}"
        elif self.is_surface:
            return f"<hcvt.Domain surface, area={self.volume:.6g}>"
        else:
            kind = "polygon" if self.dim == 2 else "solid"
        crs = ""
        if self.crs is not None:
            authority = self.crs.to_authority()
            crs = f", crs={authority[0]}:{authority[1]}" if authority else f", crs={self.crs.name}"
        return f"<hcvt.Domain {kind}, volume={self.volume:.6g}{crs}>"


def wrapped(
    points: NDArray[np.float64], lo: ArrayLike, hi: ArrayLike, periodic: ArrayLike
) -> NDArray[np.float64]:
    """``points`` (m, d) moved by whole periods into ``[lo, hi)`` along the ``periodic`` axes.

    ``lo + (x − lo) mod (hi − lo)``, and ``lo`` where rounding lands on ``hi``; a copy.
    """
    pts = np.array(points, dtype=np.float64)
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    for k in np.flatnonzero(periodic):
        x = lo[k] + np.mod(pts[:, k] - lo[k], hi[k] - lo[k])
        pts[:, k] = np.where(x < hi[k], x, lo[k])
    return pts


def _surface(dataset: Any) -> Any:
    """The boundary surface of a PyVista volume mesh (``extract_surface``)."""
    try:  # pyvista >= 0.47 picks VTK's filter itself; the default is to change
        return dataset.extract_surface(pass_pointid=False, pass_cellid=False, algorithm=None)
    except TypeError:
        return dataset.extract_surface(pass_pointid=False, pass_cellid=False)


def _unpickle_box(
    lo: NDArray[np.float64], hi: NDArray[np.float64], periodic: tuple[bool, ...]
) -> Domain:
    """A box from the corners and axes :meth:`Domain.__reduce__` saved."""
    return Domain.box(lo, hi, periodic=periodic)


def _as_corner(corner: ArrayLike, name: str) -> NDArray[np.float64]:
    """A box corner as a float64 vector, or an InvalidDomainError."""
    arr = np.asarray(corner)
    if arr.ndim != 1 or arr.dtype.kind not in "iuf":
        raise InvalidDomainError(f"{name} must be a vector of real numbers, got {corner!r}")
    return arr.astype(np.float64)


def _unpickle(
    dim: int,
    vertices: NDArray[np.float64],
    simplices: NDArray[np.intp],
    geometry: Any,
    repair_report: RepairReport | None,
    crs: Any = None,
) -> Domain:
    """A Domain from the arrays :meth:`Domain.__reduce__` saved, checked anew by the core."""
    boundary = _core.PolygonDomain if dim == 2 else _core.SolidDomain
    # Aligned copies: dask hands arrays over as views of its message frames, which may
    # start at any byte.
    frame = Frame.fit(vertices)
    core = boundary(
        np.require(frame.to_core(np.asarray(vertices), "vertices"), np.float64, ["C", "A"]),
        np.require(simplices, np.uint32, ["C", "A"]),
    )
    domain = Domain(core, dim, geometry, repair_report, frame)
    domain.crs = crs
    return domain


def _as_points(points: ArrayLike, dim: int, name: str) -> NDArray[np.float64]:
    """``points`` as a C-contiguous float64 array of shape (m, dim), or a ValueError."""
    arr = np.asarray(points)
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"{name} must be real numbers, got dtype {arr.dtype}")
    arr = np.ascontiguousarray(arr, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != dim:
        raise ValueError(f"{name} must have shape (m, {dim}), got {arr.shape}")
    return arr


def _as_shapely(polygon: Any, holes: Sequence[ArrayLike] | None) -> Polygon | MultiPolygon:
    """Coerce the accepted polygon inputs to a shapely geometry, checking coordinates."""
    if isinstance(polygon, Polygon | MultiPolygon):
        geometry = polygon
    else:
        if (
            isinstance(polygon, tuple)
            and len(polygon) == 2
            and holes is None
            and np.asarray(polygon[0], dtype=object).ndim == 2
        ):
            polygon, holes = polygon
        rings = [("outer ring", polygon)] + [(f"hole {k}", h) for k, h in enumerate(holes or [])]
        checked = [_as_ring(coords, name) for name, coords in rings]
        geometry = Polygon(checked[0], checked[1:])
    if geometry.is_empty:
        raise InvalidDomainError("the polygon is empty")
    for part_index, part in enumerate(_parts(geometry)):
        for name, ring in [("outer ring", part.exterior)] + [
            (f"hole {k}", r) for k, r in enumerate(part.interiors)
        ]:
            coords = np.asarray(ring.coords)
            where = f"{name} of part {part_index}" if len(_parts(geometry)) > 1 else name
            bad = ~np.isfinite(coords).all(axis=1)
            if bad.any():
                raise InvalidDomainError(
                    f"{where} has a non-finite coordinate at vertex {int(np.argmax(bad))}"
                )
            distinct = len(np.unique(coords, axis=0))
            if distinct < 3:
                raise InvalidDomainError(
                    f"{where} has {distinct} distinct vertices; a ring needs at least 3"
                )
    return geometry


def _as_ring(coords: ArrayLike, name: str) -> NDArray[np.float64]:
    arr = np.asarray(coords)
    if arr.dtype.kind not in "iuf":
        raise InvalidDomainError(f"{name}: coordinates must be real numbers, got {arr.dtype}")
    arr = arr.astype(np.float64)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise InvalidDomainError(f"{name} must have shape (k, 2), got {arr.shape}")
    bad = ~np.isfinite(arr).all(axis=1)
    if bad.any():
        raise InvalidDomainError(
            f"{name} has a non-finite coordinate at vertex {int(np.argmax(bad))}"
        )
    if len(np.unique(arr, axis=0)) < 3:
        raise InvalidDomainError(f"{name} has fewer than 3 distinct vertices")
    return arr


def _parts(geometry: Polygon | MultiPolygon) -> list[Polygon]:
    return list(geometry.geoms) if isinstance(geometry, MultiPolygon) else [geometry]


def _check_finite_area(geometry: Polygon | MultiPolygon) -> None:
    """Raise InvalidDomainError when the area overflows (coordinates near 1e160 or more)."""
    if not np.isfinite(geometry.area):
        extent = float(np.max(np.abs(shapely.bounds(geometry))))
        raise InvalidDomainError(
            f"the polygon's area is not representable ({geometry.area}): coordinates up to "
            f"{extent:.3g} overflow when multiplied; scale the polygon down"
        )


def _check_polygon(geometry: Polygon | MultiPolygon) -> None:
    """Raise InvalidDomainError unless the polygon has area and shapely calls it valid."""
    _check_finite_area(geometry)
    # A flat outline is also "self-intersecting", but zero area says more.
    if not geometry.convex_hull.area > 0 or (geometry.is_valid and not geometry.area > 0):
        raise InvalidDomainError(f"the polygon has zero area ({geometry.area})")
    if not geometry.is_valid:
        reason = shapely.is_valid_reason(geometry)
        raise InvalidDomainError(
            f"invalid polygon: {describe_defect(geometry)} (shapely: {reason}); "
            "pass repair=True to fix it with shapely.make_valid"
        )


def _xy(point: Any) -> str:
    x, y = np.asarray(point, dtype=float)[:2]
    return f"({x:.17g}, {y:.17g})"


def describe_defect(geometry: Polygon | MultiPolygon) -> str:
    """What makes a polygon invalid, in words: which ring, what kind, where.

    A ring that crosses itself, a ring that folds back on itself (a zero-width spike), a hole
    that shares part of an edge with another ring or touches it at several points, a hole
    outside its outline; shapely's reason when none of these is found.
    """
    try:
        return _describe(geometry)
    except (ValueError, IndexError, shapely.errors.ShapelyError):
        # Degenerate coordinates (subnormals, 1e300) can defeat the geometry; the
        # reason from shapely still names the defect.
        return shapely.is_valid_reason(geometry)


def _describe(geometry: Polygon | MultiPolygon) -> str:
    parts = _parts(geometry)
    for part_index, part in enumerate(parts):
        prefix = f"part {part_index}: " if len(parts) > 1 else ""
        rings = [("the outer ring", part.exterior)] + [
            (f"hole {k}", r) for k, r in enumerate(part.interiors)
        ]
        for name, ring in rings:
            found = _ring_self_contact(np.asarray(ring.coords)[:, :2])
            if found:
                return prefix + f"{name} {found}"
        for a in range(len(rings)):
            for b in range(a + 1, len(rings)):
                found = _rings_contact(rings[a][1], rings[b][1])
                if found:
                    return prefix + f"{rings[b][0]} {found} {rings[a][0]}"
        shell = Polygon(part.exterior)
        for name, ring in rings[1:]:
            if not shell.covers(Polygon(ring)):
                return prefix + f"{name} lies partly outside the outer ring"
        for a in range(1, len(rings)):
            for b in range(a + 1, len(rings)):
                found = _overlap(Polygon(rings[a][1]), Polygon(rings[b][1]), -1)
                if found:
                    return prefix + f"{rings[a][0]} and {rings[b][0]} overlap: {found}"
    for a in range(len(parts)):
        for b in range(a + 1, len(parts)):
            found = _overlap(parts[a], parts[b], 2)
            if found:
                return f"parts {a} and {b} overlap: {found}"
    return shapely.is_valid_reason(geometry)


def _overlap(first: Polygon, second: Polygon, winding: int) -> str | None:
    """Where two regions share area, which then has winding number ``winding``, or None."""
    common = shapely.intersection(first, second)
    if not common.area > 0:
        return None
    return (
        f"the winding number is {winding} on an area of {common.area:.6g} around "
        f"{_xy(common.representative_point().coords[0])}"
    )


def _ring_self_contact(coords: NDArray[np.float64]) -> str | None:
    """How a closed ring (first point repeated last) meets itself, or None if simple."""
    keep = np.ones(len(coords), dtype=bool)
    keep[1:] = np.any(coords[1:] != coords[:-1], axis=1)  # zero-length edges are harmless
    pts = coords[keep]
    if len(pts) < 4 or shapely.LineString(pts).is_simple:
        return None
    segments = shapely.linestrings(np.stack([pts[:-1], pts[1:]], axis=1))
    m = len(segments)
    tree = shapely.STRtree(segments)
    left, right = tree.query(segments, predicate="intersects")
    crossing = None
    for i, j in zip(left.tolist(), right.tolist(), strict=True):
        if j <= i:
            continue
        meet = shapely.intersection(segments[i], segments[j])
        adjacent = j == i + 1 or (i == 0 and j == m - 1)
        # An overlap explains the point contacts around it (a spike's base): report it first.
        if meet.length > 0:
            a, b = _ends(meet)
            if adjacent:
                return f"folds back on itself between {_xy(a)} and {_xy(b)} (a zero-width spike)"
            return f"overlaps itself between {_xy(a)} and {_xy(b)}"
        if not adjacent and crossing is None and not meet.is_empty:
            crossing = f"crosses itself at {_xy(meet.representative_point().coords[0])}"
    return crossing or "is not simple"


def _ends(lines: Any) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """First and last point of the first line of positive length in ``lines``."""
    for part in shapely.get_parts(lines):
        if part.length > 0:
            coords = np.asarray(part.coords)
            return coords[0], coords[-1]
    point = np.asarray(lines.representative_point().coords[0])
    return point, point


def _rings_contact(first: Any, second: Any) -> str | None:
    """How two rings of one polygon meet (they may touch at one point only), or None."""
    meet = shapely.intersection(shapely.LineString(first.coords), shapely.LineString(second.coords))
    if meet.is_empty:
        return None
    if meet.length > 0:
        a, b = _ends(shapely.line_merge(shapely.unary_union(shapely.get_parts(meet))))
        return f"shares an edge from {_xy(a)} to {_xy(b)} with"
    points = shapely.get_parts(meet)
    if len(points) > 1:
        where = ", ".join(_xy(p.coords[0]) for p in points[:3])
        return f"touches at {len(points)} points ({where}), cutting the domain apart, with"
    if shapely.crosses(shapely.LineString(first.coords), shapely.LineString(second.coords)):
        return f"crosses at {_xy(points[0].coords[0])}"
    return None


def _repair_polygon(
    geometry: Polygon | MultiPolygon,
) -> tuple[Polygon | MultiPolygon, RepairReport]:
    """``shapely.make_valid``, keeping the polygonal parts, with a report of the changes."""
    _check_finite_area(geometry)
    actions = []
    before = float(geometry.area)
    repeated = shapely.get_num_coordinates(geometry) - shapely.get_num_coordinates(
        shapely.remove_repeated_points(geometry)
    )
    if repeated:
        actions.append(f"removed {repeated} repeated consecutive vertices (zero-length edges)")
    fixed = geometry
    if not geometry.is_valid:
        defect = describe_defect(geometry)
        actions.append(f"made valid: {defect} ({shapely.is_valid_reason(geometry)})")
        # "structure": union of the outer rings minus the holes, collapsed parts dropped;
        # unlike "linework" it keeps a hole that touches the outline as a notch.
        fixed = shapely.make_valid(geometry, method="structure", keep_collapsed=False)
    polygons = [g for g in shapely.get_parts(fixed) if isinstance(g, Polygon) and g.area > 0]
    dropped = len(shapely.get_parts(fixed)) - len(polygons)
    if dropped:
        actions.append(f"dropped {dropped} part(s) of zero area (lines, points)")
    if not polygons:
        raise InvalidDomainError("nothing of positive area is left after repair")
    result: Polygon | MultiPolygon = (
        polygons[0] if len(polygons) == 1 else shapely.unary_union(polygons)
    )
    if isinstance(result, MultiPolygon) and len(result.geoms) > 1:
        actions.append(f"the domain now has {len(result.geoms)} separate parts")
    after = float(result.area)
    if abs(after - before) > 1e-12 * max(abs(before), abs(after), 1e-300):
        actions.append(f"area {before:.6g} -> {after:.6g}")
    return result, RepairReport(bool(actions), actions, before, after, _pinches(result))


def _pinches(geometry: Polygon | MultiPolygon) -> list[str]:
    """Rings of a valid polygon that touch at a single point: the interior is pinched there."""
    notes = []
    for part in _parts(geometry):
        rings = [("the outer ring", part.exterior)] + [
            (f"hole {k}", r) for k, r in enumerate(part.interiors)
        ]
        lines = [shapely.LineString(r.coords) for _, r in rings]
        tree = shapely.STRtree(lines)
        left, right = tree.query(lines, predicate="intersects")
        for a, b in zip(left.tolist(), right.tolist(), strict=True):
            if b <= a:
                continue
            meet = shapely.intersection(lines[a], lines[b])
            if isinstance(meet, shapely.Point):
                notes.append(
                    f"{rings[b][0]} touches {rings[a][0]} at {_xy(meet.coords[0])}: kept (valid), "
                    "the domain is pinched there"
                )
    return notes


def _normalise_polygon(geometry: Polygon | MultiPolygon) -> Polygon | MultiPolygon:
    """Outer rings counter-clockwise, holes clockwise, repeated vertices removed."""
    geometry = shapely.remove_repeated_points(geometry)
    parts = [orient(p, sign=1.0) for p in _parts(geometry)]
    return parts[0] if len(parts) == 1 else MultiPolygon(parts)


def polygon_boundary(
    geometry: Polygon | MultiPolygon,
) -> tuple[NDArray[np.float64], NDArray[np.uint32]]:
    """Vertices (V, 2) and segments (S, 2) of every ring, interior on the left."""
    vertices, segments = [], []
    start = 0
    for part in _parts(geometry):
        for ring in [part.exterior, *part.interiors]:
            coords = np.asarray(ring.coords, dtype=np.float64)[:-1]
            k = len(coords)
            idx = np.arange(k, dtype=np.uint32) + start
            vertices.append(coords)
            segments.append(np.column_stack([idx, np.roll(idx, -1)]))
            start += k
    return (
        np.ascontiguousarray(np.concatenate(vertices)),
        np.ascontiguousarray(np.concatenate(segments), dtype=np.uint32),
    )
