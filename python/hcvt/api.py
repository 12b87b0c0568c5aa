"""The two entry points that may run on many machines: :func:`voronoi` and :func:`cvt`.

Each runs in this process (:mod:`hcvt.diagram`, :mod:`hcvt.optimise`) or, given a dask
``client``, partitioned over its workers (:mod:`hcvt.distributed`): the dispatch is here, at
the top, so that the one-process layers never import the scale-out above them.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from numpy.typing import ArrayLike

from hcvt import diagram, optimise
from hcvt.density import DEFAULT_QUADRATURE_DEGREE, DensityLike
from hcvt.diagram import Diagram
from hcvt.distributed import DEFAULT_SITES_PER_PARTITION, partitioned_cvt, partitioned_voronoi
from hcvt.geometry.domain import Domain
from hcvt.optimise import CVTResult


def voronoi(
    domain: Domain,
    sites: ArrayLike,
    *,
    allow_outside: bool = False,
    client: Any = None,
    sites_per_partition: int | None = None,
    density: DensityLike = None,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
    weights: ArrayLike | None = None,
) -> Diagram:
    """Clipped Voronoi diagram of ``sites`` inside ``domain``, exact to round-off.

    Parameters
    ----------
    domain : Domain
        Polygon with holes (d = 2), closed-mesh solid (d = 3) or box, periodic along some
        axes or all (:meth:`Domain.box`: sites may then lie anywhere along a periodic axis,
        and the diagram gives each neighbour's image shift), or a triangle surface
        (:meth:`Domain.from_surface`: the restricted Voronoi diagram, cells the parts of
        the surface nearer their site, sites anywhere in space); length unit L.
    sites : array_like of float, shape (n, d)
        Generator positions in L: finite, distinct, inside the domain (points on the
        boundary count as inside). Copied to C-contiguous float64.
    allow_outside : bool, default False
        Accept sites outside the domain. The cell of such a site is the part of its Voronoi
        cell inside the domain: possibly empty (volume 0, centroid = site, G = NaN) and
        not containing the site. Such a site must lie within 64 times the smallest side of
        the domain's bounding box: farther, its cell cannot be cut accurately (the error
        grows as the distance squared).
    client : dask.distributed.Client, optional
        Compute the cells on its workers, the sites split into spatial parts of at most
        ``sites_per_partition`` sites (default 200,000), each with a halo of nearby sites
        grown until every cell is certified (:mod:`hcvt.distributed`); the cells are then
        gathered here. Per-cell arrays are bitwise those of one process (with a
        ``density`` too); ``energy`` is summed per part and agrees to round-off. For cells
        that stay on the workers use :func:`hcvt.distributed.partitioned_voronoi`.
    sites_per_partition : int, optional
        With ``client``: the most sites one part holds (fixed by the data, not by the
        number of workers).
    density : Polynomial, SizingField or callable, optional
        A density ρ > 0 (:mod:`hcvt.density`): ``mass``, ``centroid``, ``energy_terms``,
        ``energy`` and ``gradient`` are then ρ-weighted, exactly for a polynomial of degree
        ≤ 2; ``volume``, ``second_moment`` and ``G`` stay geometric. A constant density
        gives the uniform diagram (``Polynomial(1.0)`` bitwise).
    quadrature_degree : int, default 4
        Degree (1 to 5) of the simplex rule that samples a callable density.
    weights : array_like of float, shape (n,), optional
        The power (Laguerre) diagram of these weights, L²: cell ``i`` is ``{x : |x - z_i|²
        - w_i <= |x - z_j|² - w_j}`` inside the domain, on every flat domain kind (not on
        the sphere; with ``client`` bitwise too). A cell may be empty (volume 0, no
        neighbours, G NaN) and need not hold its site; ``weights=0`` is the Voronoi
        diagram bit for bit. :func:`hcvt.optimal_transport` finds the weights that give
        each cell a prescribed mass. ``Diagram.mesh()`` of a power diagram is not
        implemented yet.

    Returns
    -------
    Diagram
        ``volume`` (n,), ``centroid`` (n, d), ``second_moment`` (n,), ``G`` (n,),
        ``energy``, ``neighbors`` (k, 2), ``face_measures`` (k,), ``cells()``.

    Raises
    ------
    ValueError
        Bad shape or dtype, or n = 0.
    InvalidDensityError
        The density is not finite and positive where evaluated; the message names the point.
    InvalidSitesError
        Non-finite coordinates, coinciding sites, a site outside the domain (or, with
        ``allow_outside``, too far outside it); the message names the first offending row.

    Examples
    --------
    A 2 x 2 grid in the unit square: four squares of area 1/4, G = 1/12.

    >>> import hcvt
    >>> square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    >>> sites = [[0.25, 0.25], [0.75, 0.25], [0.25, 0.75], [0.75, 0.75]]
    >>> diagram = hcvt.voronoi(square, sites)
    >>> diagram.volume
    array([0.25, 0.25, 0.25, 0.25])
    >>> diagram.G.round(6)
    array([0.083333, 0.083333, 0.083333, 0.083333])
    """
    if client is not None and domain.is_surface:
        raise NotImplementedError("partitioned diagrams on a surface are not implemented yet")
    if client is None:
        return diagram.voronoi(
            domain,
            sites,
            allow_outside=allow_outside,
            density=density,
            quadrature_degree=quadrature_degree,
            weights=weights,
        )
    return partitioned_voronoi(
        domain,
        sites,
        client,
        sites_per_partition=sites_per_partition or DEFAULT_SITES_PER_PARTITION,
        allow_outside=allow_outside,
        density=density,
        quadrature_degree=quadrature_degree,
        weights=weights,
    ).gather()


def cvt(
    domain: Domain,
    sites: ArrayLike,
    method: str | None = None,
    *,
    rule: str = "gap",
    tol: float | None = None,
    max_iter: int = 10_000,
    memory: int = 7,
    callback: Callable[[dict[str, Any]], Any] | None = None,
    progress: bool = False,
    client: Any = None,
    sites_per_partition: int | None = None,
    density: DensityLike = None,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
    volumes: ArrayLike | None = None,
    normalise: bool = False,
    volume_tol: float = optimise.VOLUME_TOL,
    fixed: ArrayLike | None = None,
) -> CVTResult:
    """Move ``sites`` to a centroidal Voronoi tessellation of ``domain``.

    Parameters
    ----------
    domain : Domain
        Polygon (d = 2), solid (d = 3) or box (:meth:`Domain.box`; along its periodic axes
        sites move across the sides and come back wrapped), or a triangle surface
        (:meth:`Domain.from_surface`: the energy ``Σ ∫_cell |x - x_i|² dA`` of the
        restricted diagram, minimised with the sites free in space, which are projected
        onto the surface at the end, as in Yan et al. 2009; ``sites`` and ``diagram`` are
        those projected sites and their diagram, ``history`` the free run's); length unit L.
    sites : array_like of float, shape (n, d)
        Initial sites: finite, distinct, inside the domain. Not modified.
    method : {"newton", "lbfgs", "lloyd"}, optional
        Newton (the exact Hessian from the same diagram, truncated conjugate gradients in
        a trust region; 3-5x fewer diagrams than L-BFGS from random sites, see
        ``hcvt-core/src/optimise/newton.rs``; the Hessian takes about 0.2 kB per site in
        2D and 1.2 kB in 3D on top of the diagram; on the sphere the Riemannian Hessian:
        5 diagrams from icosahedral sites), L-BFGS (memory ``memory``, strong-Wolfe line
        search, preconditioned so that its first step is a Lloyd step; the paper's method)
        or Lloyd's ``x_i <- c_i``. Default: the fastest the domain takes
        (:func:`hcvt.optimise.fastest_method`): Newton on polygons, solids and plain
        boxes without a density or with a polynomial one, on the sphere with any
        density, and on triangle surfaces (the arcs' Hessian terms weighted by the
        bisectors' slopes against the triangles), in one process; L-BFGS elsewhere
        (periodic boxes, a sampled density in a flat domain, ``client=``) and with
        ``volumes``.
    rule : {"gap", "paper"}
        Stop when the RMS over the sites of ``|x_i - c_i| / V_i^(1/d)`` is below ``tol``
        (``"gap"``, scale-free), or when ``‖g‖/‖X‖ < tol`` in the input coordinates
        (``"paper"``, the paper's rule to the letter); module docs.
    tol : float, optional
        The rule's tolerance; default 1e-7 for ``"gap"``, the paper's 1e-10 for ``"paper"``.
    max_iter : int
        Stop after this many iterations.
    memory : int
        L-BFGS correction pairs kept.
    callback : callable, optional
        ``callback(info)`` after every iterate (the initial sites first), ``info`` a dict
        with the history fields of that iterate and ``sites`` (n, d). Returning a true
        value, or raising ``StopIteration`` as with scipy.optimize, stops the run
        (``stop_reason == "interrupted"``). Sites and energy are in the input's unit
        (the energy NaN where float64 cannot hold it, :mod:`hcvt.geometry.frame`).
    progress : bool
        Show a progress bar (rich) of the rule's value towards ``tol``.
    client : dask.distributed.Client, optional
        Run on its workers, the sites and their state split into spatial parts of at most
        ``sites_per_partition`` sites (default 200,000) that stay there between iterations
        (:mod:`hcvt.distributed`; ``"lbfgs"`` and ``"lloyd"`` only; the callback's info
        then has no ``sites``). Lloyd is bitwise the single-process run; L-BFGS is bitwise
        the same for any number of workers, not the single-process iterates; with a
        ``density`` too.
    sites_per_partition : int, optional
        With ``client``: the most sites one part holds.
    density : Polynomial, SizingField or callable, optional
        A density ρ > 0 (:mod:`hcvt.density`): the energy becomes ``Σ ∫ ρ |x - x_i|²``,
        Lloyd moves each site to its ρ-weighted centroid and L-BFGS follows the ρ-weighted
        gradient; both rules apply unchanged (``h_i`` stays the geometric ``V_i^(1/d)``).
        Newton's Hessian weighs its face terms by ρ on each face, exactly for a
        :class:`~hcvt.density.Polynomial`; with a callable Newton is not offered in a flat
        domain (InvalidDensityError); on the sphere it is, its arcs sampled at 3
        Gauss–Legendre nodes in the same call as the cells. A callable is called once per
        diagram, with the GIL.
    quadrature_degree : int, default 4
        Degree (1 to 5) of the simplex rule that samples a callable density.
    volumes : array_like of float, shape (n,), optional
        Prescribed cell volumes (masses ``∫ρ`` with a ``density``), positive, L^d: a
        capacity-constrained CVT, the sites at the centroids of the cells of a *power*
        diagram whose cell ``i`` has volume ``volumes[i]``
        (``hcvt-core/src/optimise/capacity.rs``). ``method``: ``"lbfgs"`` (the default
        here; :func:`hcvt.optimise.fastest_method` does not apply) runs L-BFGS on the
        transport cost, whose gradient is ``2 v_i (x_i - c_i)``, every trial point a
        warm-started optimal transport; ``"lloyd"`` is Bourne, Kok, Roper and Spanjer
        2020's alternation (optimal-transport weights for the present sites, warm-started,
        then sites to their power cells' centroids, repeated), 13-15x more outer
        iterations; ``"newton"`` is Newton in a trust region on the transport cost with
        its exact Hessian in the sites, the weights eliminated (``H_zz + B L^-1 B^T``;
        about 3-13x fewer outer iterations and 2-8x fewer diagrams than ``"lbfgs"`` on
        1,000 grains in a periodic cube; no ``density``). They must sum to the domain's
        volume (to 1e-9 relative) unless ``normalise``. On polygons, solids and boxes,
        periodic or not; not with ``client`` (NotImplementedError), the sphere or a surface.
        The result's ``diagram`` is the power diagram, ``weights`` its weights; the
        history has one record per outer iteration with ``max_volume_error`` and
        ``newton_steps`` (the transport's) besides the gaps; it stops when every cell is
        within ``volume_tol`` of its volume *and* the rule holds, both for that diagram.
    normalise : bool, default False
        With ``volumes``: treat them as relative sizes, scaled to the domain's volume (as
        :func:`hcvt.optimal_transport`'s ``normalise``).
    volume_tol : float, default 1e-8
        With ``volumes``: every cell's ``|V_i - v_i| / v_i`` at most this.
    fixed : array_like of bool, shape (n,), optional
        Sites held where they are: ``sites[i]`` with ``fixed[i]`` true never moves (its
        row of the result is the input's, bit for bit) while the others are optimised,
        their cells meeting the fixed ones'. In the core's Lloyd and L-BFGS (the fixed
        rows of the gradient are zero, so L-BFGS's direction, line search and memory
        leave them out; the stopping rules count the free sites only); ``method=None``
        then means ``"lbfgs"``; not with Newton, ``volumes`` or ``client``. On a surface
        the fixed sites should lie on it (they are not projected). Used by
        :func:`hcvt.remesh`'s ``features=`` to hold corners and feature curves.

    Returns
    -------
    CVTResult
        ``sites``, ``diagram``, ``history``, ``rule``, ``tol``, ``converged``,
        ``stop_reason``, ``iterations``, ``evaluations``, ``seconds``. The iteration runs
        in the domain's frame (``domain.frame``, :mod:`hcvt.geometry.frame`) and every
        result is mapped back; a history column float64 cannot hold in the input's unit
        (the energy of a domain 1e100 wide) raises UnrepresentableError when read.

    Raises
    ------
    ValueError
        Unknown method or rule, negative tol, bad shape; ``fixed`` not bool or not of
        shape (n,); ``fixed`` with Newton or ``volumes``.
    InvalidSitesError
        Sites outside the domain, coinciding or non-finite; the message names the row.

    Examples
    --------
    Four sites in the unit square converge to the 2 x 2 grid of squares, G = 1/12.

    >>> import hcvt
    >>> square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    >>> res = hcvt.cvt(square, [[0.2, 0.3], [0.7, 0.2], [0.3, 0.6], [0.8, 0.9]])
    >>> res.converged, res.stop_reason
    (True, 'converged')
    >>> res.sites.round(6)
    array([[0.25, 0.25],
           [0.75, 0.25],
           [0.25, 0.75],
           [0.75, 0.75]])
    >>> round(res.mean_G, 6)
    0.083333
    """
    options: dict[str, Any] = {
        "rule": rule,
        "tol": tol,
        "max_iter": max_iter,
        "memory": memory,
        "callback": callback,
        "progress": progress,
        "density": density,
        "quadrature_degree": quadrature_degree,
    }
    if fixed is not None:
        if client is not None:
            raise NotImplementedError(
                "fixed= is not implemented on dask partitions (client=): run without client"
            )
        options["fixed"] = fixed
    if volumes is not None:
        if client is not None:
            raise NotImplementedError(
                "volumes= (capacity-constrained CVTs) is not implemented on dask partitions "
                "(client=): run without client"
            )
        options |= {"volumes": volumes, "normalise": normalise, "volume_tol": volume_tol}
    if client is not None and domain.is_surface:
        raise NotImplementedError("partitioned CVTs on a surface are not implemented yet")
    if client is None:
        return optimise.cvt(domain, sites, method, **options)
    method = method or optimise.fastest_method(domain, density, partitioned=True)
    per_part = sites_per_partition or DEFAULT_SITES_PER_PARTITION
    return partitioned_cvt(
        domain, sites, method, client, sites_per_partition=per_part, **options
    ).gather()
