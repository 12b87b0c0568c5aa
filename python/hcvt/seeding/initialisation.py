"""Initial sites with exactly ``n`` points strictly inside a domain (DESIGN §1, ALGORITHMS §6).

| method       | what                                                    | seed            |
|--------------|---------------------------------------------------------|-----------------|
| ``random``   | uniform in the domain: rejection in a cover             | the stream      |
| ``halton``   | scrambled Halton in the box, the first ``n`` inside     | the scrambling  |
| ``hammersley`` | centred Hammersley of ``m`` box points, ``m`` searched | unused          |
| ``lattice``  | hexagonal (2D) or BCC (3D) lattice, spacing searched    | the pose        |

Every method is deterministic for a seed and returns an ``(n, d)`` float64 array whose
rows pass :meth:`hcvt.Domain.contains` (strictly inside).

The samplers draw in the bounding box, or, for a domain filling less than 5% of it, in a
tighter cover (:mod:`hcvt.seeding.cover`: the polygon's triangles, a solid's octree boxes):
a thin diagonal triangle of 5e-10 of its box gets 20 sites in milliseconds, not hours.
Every search is bounded and ends with a message: a solid too thin for its octree cover
(:data:`MIN_ACCEPTANCE`), points that cannot lie strictly inside at double precision, a
domain too thin for any lattice of ``n`` sites, a density whose bound keeps rising.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import shapely
from numpy.typing import NDArray
from scipy.spatial.transform import Rotation
from scipy.stats import qmc

from hcvt.density import DensityLike, evaluate, triangle_values
from hcvt.errors import InvalidDensityError, InvalidDomainError, InvalidSitesError
from hcvt.geometry.domain import Domain, polygon_boundary
from hcvt.geometry.surface_points import points_by_area, sample_by_area
from hcvt.seeding.cover import Cover, cover
from hcvt.seeding.sphere import (
    SPHERE_METHODS,
    fibonacci,
    icosahedral,
    point_density,
    random_sphere,
)

METHODS = ("random", "halton", "hammersley", "lattice")
#: ``initialise``'s methods on a triangle surface.
SURFACE_METHODS = ("random", "halton")
# Memory of one site with its diagram, measured order of magnitude (bytes).
BYTES_PER_SITE = {2: 500, 3: 1000}
# Box points drawn per batch by the rejection samplers: bounds the memory for any n.
MAX_BATCH = 1 << 20
# Hammersley: box sizes m tried before falling back to the closest count and a trim: this
# many, or more while the points generated stay under the budget (small n are cheap, and
# their counts jump by several points from one m to the next).
HAMMERSLEY_TRIES = 64
HAMMERSLEY_BUDGET = 200_000
# Lattice: clearance from the boundary, as a fraction of the nearest-neighbour spacing.
# 0.3 removes the boundary slivers seen without it (ALGORITHMS §6: min distance 0.002 h).
LATTICE_MARGIN = 0.3
# Lattice: poses (rotation, offset) tried before falling back to the closest count.
LATTICE_POSES = 8
# Lattice: a count may test at most this many rows per site and boundary piece (measured
# at most 7 on the data set's polygons and meshes, n from 1 to 10025), or this many in all
# (a thin domain needs a lattice far finer than its pieces: a needle tetrahedron of 1.7e-3
# of its box, 20 sites, 3e4 rows; 2^20 rows take about 0.3 s and 150 MB a count in 3D):
# past both the domain is too thin for a lattice of n sites clear of its boundary, and the
# search says so.
LATTICE_ROWS_PER_SITE = 256
LATTICE_MIN_ROWS = 1 << 20
# Lattice: steps of 1.25 in scale tried each way to bracket n (1.25^200 = 4e19).
LATTICE_SCALE_STEPS = 200
# Nearest-neighbour distance of the unit lattices below: hexagonal 1, BCC with cube edge 1.
UNIT_SPACING = {2: 1.0, 3: np.sqrt(3.0) / 2.0}


#: What ``rng=`` takes (SPEC 7): a seed, a generator (used and advanced), or None (fresh).
RandomState = int | np.random.Generator | None


def random_state(seed: int, rng: RandomState) -> int | np.random.Generator | None:
    """``rng`` when given, else the legacy ``seed``: what numpy's and scipy's ``rng=`` take."""
    return seed if rng is None else rng


def initialise(
    domain: Domain,
    n: int,
    method: str = "random",
    seed: int = 0,
    *,
    rng: RandomState = None,
    density: DensityLike = None,
) -> NDArray[np.float64]:
    """Exactly ``n`` sites strictly inside ``domain``.

    Parameters
    ----------
    domain : Domain
        Polygon with holes (d = 2) or closed-mesh solid (d = 3), length unit L.
    n : int
        Number of sites, at least 1 (a Python or numpy integer, not a bool).
    method : {"random", "halton", "hammersley", "lattice", "fibonacci", "icosahedral"}
        ``random``: uniform in the domain, by rejection of uniform points of the bounding
        box (area/volume weighted, whatever the box), or of a tighter cover when the
        domain fills less than 5% of its box (:mod:`hcvt.seeding.cover`; uniform all the
        same). ``halton``: scrambled Halton points of the box or cover
        (``scipy.stats.qmc.Halton(d, scramble=True, rng=seed)``) kept in
        sequence order until ``n`` lie inside; the sequence is extensible, so the count is
        exact. ``hammersley``: see :func:`hammersley`. ``lattice``: see :func:`lattice`.
    seed : int
        Seeds the method (the Hammersley set is fixed and ignores it); kept for
        compatibility, ``rng`` is the numpy way.
    rng : int, numpy.random.Generator or None, optional
        Random state as numpy's ``default_rng`` takes it (SPEC 7); overrides ``seed``.
        ``rng=k`` gives the same sites as ``seed=k``.
    density : Polynomial, SizingField or callable, optional
        A density ρ (:mod:`hcvt.density`): the sites are then distributed with density
        proportional to ``ρ^(d/(d+2))``, the point density of a CVT for ρ (Gersho), so that
        a CVT from them has little to move. Offered for ``random`` and ``halton``: each
        draws one more coordinate ``u`` per point and keeps the point when it is inside
        and ``u < g(x) / g_max`` (``g = ρ^(d/(d+2))``, ``g_max`` 1.25 times the largest
        ``g`` over :data:`DENSITY_PROBES` Halton points of the domain, raised and the
        stream restarted should a larger value turn up). ``hammersley`` and ``lattice``
        are uniform by construction: with a density they raise ValueError.
        On :meth:`hcvt.Domain.sphere` (there only): ``random`` uniform on the sphere
        (normalised normal vectors), ``fibonacci`` the golden-spiral lattice,
        ``icosahedral`` the subdivided icosahedron (``n = 10·4^k + 2`` only), each scaled
        to the radius (:mod:`hcvt.seeding.sphere`).
        On a surface (:meth:`hcvt.Domain.from_surface`): ``random`` points uniform by area
        on its triangles (a triangle drawn by area, then a point uniform in it), ``halton``
        the same map of scrambled 3D Halton points (more even); the box and lattice methods
        have no meaning there and raise ValueError.

    Returns
    -------
    ndarray of float64, shape (n, d)
        Sites in L, each strictly inside (``domain.contains`` is true for every row).

    Raises
    ------
    ValueError
        ``n`` not a positive integer, ``n`` so large that the sites and their diagram
        would not fit in the available memory (the message gives the estimate), or an
        unknown method.
    InvalidDomainError
        The domain cannot take ``n`` sites: a solid so thin that under
        :data:`MIN_ACCEPTANCE` of the draws in its cover would land inside, a domain too
        small for distinct points strictly inside at double precision, or (``lattice``)
        too thin for any lattice of ``n`` sites clear of its boundary.
    InvalidDensityError
        The density is not finite and positive where evaluated, or not bounded.
    InvalidSitesError
        Two sites coincide: ``n`` far above the distinct points of double precision in the
        domain's box (a million sites in a square of side 1e-12 at (1, 1)); checked only
        where that can happen (:data:`COINCIDENCE_CHECK`).

    Examples
    --------
    >>> import hcvt
    >>> square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    >>> hcvt.initialise(square, 4, method="lattice").shape
    (4, 2)
    """
    n = check_count(n, domain.dim)
    if domain.is_sphere:
        return _on_sphere(domain, n, method, random_state(seed, rng), density)
    if domain.is_surface:
        return _on_surface(domain, n, method, random_state(seed, rng), density)
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; expected one of {', '.join(METHODS)}")
    state = random_state(seed, rng)
    if density is not None:
        return _distinct(domain, _graded(domain, n, method, state, density))
    if method == "random":
        generator = np.random.default_rng(state)
        sites = _rejection(domain, n, lambda m: generator.random((m, domain.dim)))
    elif method == "halton":
        engine = qmc.Halton(domain.dim, scramble=True, rng=state)
        sites = _rejection(domain, n, engine.random)
    elif method == "hammersley":
        sites = hammersley(domain, n)
    else:
        sites = lattice(domain, n, seed, rng=rng).sites
    return _distinct(domain, sites)


def _in_sphere_region(
    domain: Domain, n: int, generator: np.random.Generator
) -> NDArray[np.float64]:
    """``n`` points uniform in a region of the sphere, times R.

    Uniform in the cap about the region's centre that holds it (``z`` uniform on the cap's
    axis: Archimedes), kept where :meth:`Domain.contains` says so, until there are ``n``.
    """
    core = domain._core
    c = np.asarray(core.centre, dtype=np.float64)
    cos_reach = min(float(np.min(ring @ c)) for ring in core.rings)
    # An orthonormal frame (e1, e2, c).
    helper = np.eye(3)[int(np.argmin(np.abs(c)))]
    e1 = np.cross(c, helper)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(c, e1)
    kept: list[NDArray[np.float64]] = []
    count = 0
    while count < n:
        m = max(64, 2 * (n - count))
        z = generator.uniform(cos_reach, 1.0, m)
        phi = generator.uniform(0.0, 2.0 * np.pi, m)
        s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
        unit = np.outer(s * np.cos(phi), e1) + np.outer(s * np.sin(phi), e2) + np.outer(z, c)
        unit /= np.linalg.norm(unit, axis=1)[:, None]
        points = unit * domain.radius
        inside = points[domain.contains(points)]
        kept.append(inside[: n - count])
        count += len(kept[-1])
    return np.concatenate(kept)


def _on_sphere(
    domain: Domain,
    n: int,
    method: str,
    state: int | np.random.Generator | None,
    density: DensityLike,
) -> NDArray[np.float64]:
    """``initialise`` on the sphere: unit vectors of :mod:`hcvt.seeding.sphere` times R."""
    if domain.is_sphere_region:
        if method != "random" or density is not None:
            raise NotImplementedError(
                "on a region of the sphere initialise takes method='random' without a "
                f"density (got method={method!r}, density={density!r})"
            )
        return _in_sphere_region(domain, n, np.random.default_rng(state))
    if method not in SPHERE_METHODS:
        raise ValueError(
            f"unknown method {method!r} on the sphere; expected one of {', '.join(SPHERE_METHODS)}"
        )
    if density is not None:
        if method != "random":
            raise ValueError(
                f"method {method!r} places sites uniformly; with a density use 'random' "
                "(a CVT with the density then grades it)"
            )
        return _graded_on_sphere(domain, n, np.random.default_rng(state), density)
    if method == "random":
        unit = random_sphere(n, np.random.default_rng(state))
    elif method == "fibonacci":
        unit = fibonacci(n)
    else:
        unit = icosahedral(n)
    return np.ascontiguousarray(unit * domain.radius)


def _graded_on_sphere(
    domain: Domain, n: int, generator: np.random.Generator, density: DensityLike
) -> NDArray[np.float64]:
    """``n`` random points on the sphere with density ∝ ``ρ^(1/2)``, by rejection.

    ``ρ^(1/2)`` is a CVT's point density on cells of dimension 2 (Gersho). The bound comes
    from 4,096 probes; it is raised and the draws restarted if a value exceeds it.
    """
    probes = fibonacci(DENSITY_PROBES) * domain.radius
    bound = DENSITY_BOUND_FACTOR * float(np.max(point_density(density, probes)))
    for _ in range(DENSITY_RESTARTS):
        found: list[NDArray[np.float64]] = []
        count, peak = 0, 0.0
        while count < n:
            points = random_sphere(int(min(MAX_BATCH, 2 * (n - count) + 64)), generator)
            points = points * domain.radius
            g = point_density(density, points)
            peak = max(peak, float(g.max()))
            points = points[generator.random(len(points)) * bound < g]
            found.append(points)
            count += len(points)
        if peak <= bound:
            return np.ascontiguousarray(np.concatenate(found)[:n])
        bound = DENSITY_BOUND_FACTOR * peak
    raise InvalidDensityError(
        f"the density's ρ^(1/2) kept rising above its bound over {DENSITY_RESTARTS} "
        "restarts of the sampler: it is not bounded on the sphere"
    )


def _on_surface(
    domain: Domain,
    n: int,
    method: str,
    state: int | np.random.Generator | None,
    density: DensityLike,
) -> NDArray[np.float64]:
    """``initialise`` on a surface: ``n`` points spread by area on its triangles.

    ``random``: uniform by area. ``halton``: a scrambled 3D Halton sequence mapped as the
    uniform draws are (:func:`~hcvt.geometry.surface_points.points_by_area`: its first
    coordinate picks the triangle, the others the point in it), so that the points spread
    more evenly than random ones. The other methods need a box or a lattice of the plane
    or space: they have no meaning on a curved surface. With a density, a triangle is
    drawn in proportion to its area times ``ρ^(1/2)`` (Gersho's point density
    ``ρ^(d/(d+2))``, d = 2) at its centroid (a per-vertex field: the mean of its
    vertices' values).
    """
    if method not in SURFACE_METHODS:
        known = "the sphere" if method in SPHERE_METHODS else "planar domains and solids"
        if method not in METHODS and method not in SPHERE_METHODS:
            raise ValueError(
                f"unknown method {method!r} on a surface; expected one of "
                f"{', '.join(SURFACE_METHODS)}"
            )
        raise ValueError(
            f"method {method!r} is for {known}: it has no meaning on a surface; "
            f"expected one of {', '.join(SURFACE_METHODS)}"
        )
    weights = (
        None
        if density is None
        else np.sqrt(triangle_values(density, domain.vertices, domain.faces))
    )
    if method == "random":
        generator = np.random.default_rng(state)
        points, _ = sample_by_area(domain.vertices, domain.faces, n, generator, weights)
    else:
        u = qmc.Halton(3, scramble=True, rng=state).random(n)
        points, _ = points_by_area(domain.vertices, domain.faces, u, weights)
    return _distinct(domain, points)


#: Sites are checked for coincidence when two of ``n`` uniform points would share a
#: double with more than this probability (``n² / 2`` over the doubles in the box).
COINCIDENCE_CHECK = 1e-9


def _distinct(domain: Domain, sites: NDArray[np.float64]) -> NDArray[np.float64]:
    """``sites``, or InvalidSitesError if two coincide (a box holding too few doubles).

    A box of side ``1e-12`` at ``(1, 1)`` holds about 4500 doubles a side: a million sites
    drawn in it coincide. The check (a sort) runs only where that can happen.
    """
    lo, hi = domain.bounds
    ulp = np.spacing(np.maximum(np.abs(lo), np.abs(hi)))
    doubles = float(np.prod(np.maximum((hi - lo) / ulp, 1.0)))
    n = len(sites)
    if 0.5 * n * n <= COINCIDENCE_CHECK * doubles:
        return sites
    order = np.lexsort(sites.T[::-1])
    same = np.flatnonzero((sites[order[1:]] == sites[order[:-1]]).all(axis=1))
    if len(same) == 0:
        return sites
    i, j = sorted((int(order[same[0]]), int(order[same[0] + 1])))
    raise InvalidSitesError(
        f"sites {i} and {j} coincide at {sites[i].tolist()}: the domain's bounding box "
        f"{_box_text(domain)} at {lo.tolist()} holds about {doubles:.3g} distinct points at "
        f"double precision, too few for {n} distinct sites ({len(same)} coincide)"
    )


def check_count(n: object, dim: int) -> int:
    """``n`` as an int, or a ValueError if it is not a positive integer or needs too much memory.

    The memory estimate is ``n`` times :data:`BYTES_PER_SITE` (the sites and their
    diagram), compared with the physical memory available now.
    """
    if isinstance(n, bool) or not isinstance(n, int | np.integer):
        raise ValueError(f"n must be a positive integer, got {n!r} ({type(n).__name__})")
    if n <= 0:
        raise ValueError(f"n must be a positive integer, got {n}")
    need = int(n) * BYTES_PER_SITE[dim]
    available = _available_bytes()
    if available is not None and need > available:
        raise ValueError(
            f"n = {n} sites in {dim}D need about {need / 1e9:.3g} GB for the sites and "
            f"their diagram ({BYTES_PER_SITE[dim]} bytes per site), more than the "
            f"{available / 1e9:.3g} GB of memory available"
        )
    return int(n)


MEMINFO = "/proc/meminfo"


def _available_bytes(meminfo: str = MEMINFO) -> int | None:
    """Memory available for a new allocation now, in bytes, or None where the OS won't say.

    Linux's ``MemAvailable``: free pages plus the page cache and reclaimable slabs the
    kernel would give up. Free pages alone (``SC_AVPHYS_PAGES``) leave out the cache, which
    on a machine that has read a few files is most of its memory: an n that fits would be
    refused.
    """
    try:
        with open(meminfo, encoding="ascii") as lines:
            for line in lines:
                if line.startswith("MemAvailable:"):
                    value, unit = line.split()[1:3]
                    return int(value) * {"kB": 1024}[unit]
    except (OSError, ValueError, KeyError, IndexError):
        pass
    return None


# ---------------------------------------------------------------------- rejection sampling
#: Samplers refuse when fewer than this share of their draws would land inside (the
#: domain's share of its cover, times the density's acceptance): the draws would take
#: minutes. The message says why.
MIN_ACCEPTANCE = 1e-4
#: ... and stop, with a message, after this many times the expected draws (plus this many
#: batches): points that cannot lie strictly inside at double precision.
DRAW_ALLOWANCE = 8


def _cover(domain: Domain, n: int, acceptance: float = 1.0, why: str = "") -> Cover:
    """The domain's cover (:func:`hcvt.seeding.cover.cover`), refused if draws would be wasted.

    ``acceptance`` is the share of the points inside that the caller keeps (a density's
    rejection step), ``why`` its explanation for the message.
    """
    where = cover(domain)
    if where.fraction * acceptance < MIN_ACCEPTANCE:
        raise InvalidDomainError(
            f"cannot draw {n} sites in this {domain.dim}D domain: it fills only "
            f"{where.fraction:.3g} of the {where.kind} it can be sampled in (volume "
            f"{domain.volume:.3g} L^{domain.dim}, bounding box {_box_text(domain)}){why}, "
            f"below the {MIN_ACCEPTANCE:g} the samplers accept; a solid much thinner than "
            "its extent cannot be sampled by rejection: give the sites"
        )
    return where


def _box_text(domain: Domain) -> str:
    lo, hi = domain.bounds
    return "x".join(f"{e:.3g}" for e in hi - lo)


def _too_few(domain: Domain, n: int, count: int, drawn: int, expected: float) -> InvalidDomainError:
    return InvalidDomainError(
        f"only {count} of {n} sites found strictly inside after {drawn} draws "
        f"(expected {expected:.3g} of the draws inside): the domain (volume "
        f"{domain.volume:.3g}, bounding box {_box_text(domain)}) is too small or too thin "
        "to hold distinct points at double precision"
    )


def _rejection(
    domain: Domain, n: int, draw: Callable[[int], NDArray[np.float64]]
) -> NDArray[np.float64]:
    """The first ``n`` points of a stream that lie inside the domain.

    ``draw(m)`` returns the next ``m`` points of the stream in the unit cube, shape (m, d);
    they are mapped to the domain's cover (:func:`hcvt.seeding.cover.cover`: the bounding
    box unless the domain fills less than 5% of it).

    Batches are sized from the inside fraction ``V / V_cover`` so that one or two batches
    usually suffice; the order of the stream is kept, so the result does not depend on
    the batch sizes and is deterministic. The draws are bounded by
    :data:`DRAW_ALLOWANCE` times those expected.
    """
    where = _cover(domain, n)
    fraction = where.fraction
    limit = DRAW_ALLOWANCE * (n / fraction + MAX_BATCH)
    found: list[NDArray[np.float64]] = []
    count = drawn = 0
    while count < n:
        if drawn > limit:
            raise _too_few(domain, n, count, drawn, fraction)
        m = int(min(MAX_BATCH, 1.1 * (n - count) / fraction + 64))
        points = where.place(draw(m))
        points = points[domain.contains(points)]
        found.append(points)
        count += len(points)
        drawn += m
    return np.ascontiguousarray(np.concatenate(found)[:n])


#: Points of the domain at which the bound of a graded initialisation is probed.
DENSITY_PROBES = 4096
#: Safety factor of that bound.
DENSITY_BOUND_FACTOR = 1.25
#: Restarts with a raised bound (each at least 1.25 times the last) before giving up.
DENSITY_RESTARTS = 32


def _graded(
    domain: Domain,
    n: int,
    method: str,
    state: int | np.random.Generator | None,
    density: DensityLike,
) -> NDArray[np.float64]:
    """Exactly ``n`` points inside with density ∝ ``ρ^(d/(d+2))``, by rejection.

    See :func:`initialise`: the stream has one more coordinate, the acceptance level.
    """
    if method not in ("random", "halton"):
        raise ValueError(
            f"method {method!r} places sites uniformly; with a density use 'random' or "
            "'halton' (a CVT with the density then grades any start)"
        )
    dim = domain.dim
    exponent = dim / (dim + 2.0)
    probes = _rejection(domain, DENSITY_PROBES, qmc.Halton(dim, scramble=True, rng=0).random)
    g_probes = evaluate(density, probes) ** exponent
    bound = DENSITY_BOUND_FACTOR * float(np.max(g_probes))
    for _ in range(DENSITY_RESTARTS):
        # Share of the points inside kept by the level test, estimated on the probes.
        keep = float(np.mean(g_probes)) / bound
        where = _cover(
            domain,
            n,
            keep,
            f" and the density keeps about {keep:.3g} of the points inside "
            f"(ρ^(d/(d+2)) peaks at {bound / DENSITY_BOUND_FACTOR:.3g}, "
            f"{1 / keep:.3g} times its mean)",
        )
        fraction = where.fraction
        limit = DRAW_ALLOWANCE * (n / (fraction * keep) + MAX_BATCH)
        draw = _stream(method, state, dim + 1)
        found: list[NDArray[np.float64]] = []
        count, peak, drawn = 0, 0.0, 0
        while count < n:
            if drawn > limit:
                raise _too_few(domain, n, count, drawn, fraction * keep)
            m = int(min(MAX_BATCH, 2.0 * (n - count) / fraction + 64))
            stream = draw(m)
            points = where.place(stream)
            inside = domain.contains(points)
            points, level = points[inside], stream[inside, dim]
            g = evaluate(density, points) ** exponent if len(points) else np.zeros(0)
            peak = max(peak, float(g.max(initial=0.0)))
            points = points[level * bound < g]
            found.append(points)
            count += len(points)
            drawn += m
        if peak <= bound:
            return np.ascontiguousarray(np.concatenate(found)[:n])
        # A value above the bound: the draws were biased. Raise it and start over (a
        # Generator given as the state goes on from where it is: still deterministic).
        bound = DENSITY_BOUND_FACTOR * peak
    raise InvalidDensityError(
        f"the density's ρ^(d/(d+2)) kept rising above its bound over {DENSITY_RESTARTS} "
        f"restarts of the sampler (last peak {bound / DENSITY_BOUND_FACTOR:.3g}): it is "
        "not bounded on the domain"
    )


def _stream(
    method: str, state: int | np.random.Generator | None, dim: int
) -> Callable[[int], NDArray[np.float64]]:
    """``draw(m)``: the next ``m`` points of the method's stream in the unit cube (m, dim)."""
    if method == "halton":
        return qmc.Halton(dim, scramble=True, rng=state).random
    generator = np.random.default_rng(state)
    return lambda m: generator.random((m, dim))


# ---------------------------------------------------------------------- Hammersley
def hammersley(domain: Domain, n: int) -> NDArray[np.float64]:
    """Exactly ``n`` points of a Hammersley set of the domain's cover that lie inside.

    The cover is the bounding box, or for a domain filling less than 5% of it the
    polygon's triangles or an octree's boxes (:mod:`hcvt.seeding.cover`), the set mapped
    into them by :meth:`~hcvt.seeding.cover.Cover.place`.

    The set of ``m`` points is ``((i + 1/2) / m, φ_2(i)[, φ_3(i)])`` for ``i < m``, with
    ``φ_b`` the radical inverse in base ``b`` (Quinn et al. 2012; centred so that no
    point sits on the box). Its inside count is not monotone in ``m`` (the paper, §5.3),
    so ``m`` is searched: secant steps from ``m = n V_cover / V`` to the trend, then a scan
    ``m ± 1, ± 2, ...`` around it, :data:`HAMMERSLEY_TRIES` sets in all (more for small
    ``m``, up to :data:`HAMMERSLEY_BUDGET` points). If no set
    has exactly ``n`` inside, the tried set with the fewest surplus points inside is
    taken and its surplus dropped at evenly spaced ranks of the inside points (the first
    coordinate is the rank, so the drops are spread across the box). Deterministic.

    Returns
    -------
    ndarray of float64, shape (n, d)
    """
    return _hammersley(domain, check_count(n, domain.dim))[0]


def _hammersley(domain: Domain, n: int) -> tuple[NDArray[np.float64], int, int]:
    """Sites (n, d), the box count ``m`` taken, and how many inside points were dropped."""
    where = _cover(domain, n)
    ratio = 1.0 / where.fraction
    counts: dict[int, int] = {}

    def inside(m: int) -> NDArray[np.float64]:
        points = where.place(_hammersley_unit(m, domain.dim))
        points = points[domain.contains(points)]
        counts[m] = len(points)
        return points

    m = max(int(round(n * ratio)), n)
    for _ in range(8):  # secant steps on the trend, count ≈ m / ratio
        step = int(round((n - len(inside(m))) * ratio))
        if step == 0 or m + step < n or m + step in counts:
            break
        m += step
    offsets = (o for k in itertools.count(1) for o in (k, -k))
    centre = m
    while n not in counts.values() and (
        len(counts) < HAMMERSLEY_TRIES or sum(counts) < HAMMERSLEY_BUDGET
    ):
        m = centre + next(offsets)
        if m >= n and m not in counts:
            inside(m)
    hits = [k for k, c in counts.items() if c == n]
    above = [k for k, c in counts.items() if c > n]
    if hits:
        m = hits[0]
    elif above:
        m = min(above, key=lambda k: (counts[k] - n, k))
    else:
        m = _grow(domain, inside, n, m, ratio)
    points = inside(m)
    surplus = len(points) - n
    if surplus:
        keep = np.ones(len(points), dtype=bool)
        keep[((np.arange(surplus) + 0.5) * len(points) / surplus).astype(np.int64)] = False
        points = points[keep]
    return np.ascontiguousarray(points), m, surplus


def _grow(
    domain: Domain, inside: Callable[[int], NDArray[np.float64]], n: int, m: int, ratio: float
) -> int:
    """Smallest of ``m * 1.1^k`` whose set has at least ``n`` points inside.

    Up to :data:`DRAW_ALLOWANCE` times the expected ``n * ratio`` points, then an error.
    """
    limit = DRAW_ALLOWANCE * (n * ratio + MAX_BATCH)
    while (count := len(inside(m))) < n:
        if m > limit:
            raise _too_few(domain, n, count, m, 1.0 / ratio)
        m = int(m * 1.1) + 1
    return m


def _hammersley_unit(m: int, dim: int) -> NDArray[np.float64]:
    """Centred Hammersley set in the unit cube, shape (m, dim)."""
    i = np.arange(m, dtype=np.int64)
    columns = [(i + 0.5) / m] + [_radical_inverse(i, base) for base in (2, 3)[: dim - 1]]
    return np.column_stack(columns)


def _radical_inverse(i: NDArray[np.int64], base: int) -> NDArray[np.float64]:
    """Van der Corput radical inverse of each integer in ``base``, shape like ``i``."""
    result = np.zeros(i.shape, dtype=np.float64)
    scale = 1.0 / base
    i = i.copy()
    while i.any():
        result += (i % base) * scale
        i //= base
        scale /= base
    return result


# ---------------------------------------------------------------------- lattice
@dataclass(frozen=True)
class LatticeResult:
    """A hexagonal (2D) or BCC (3D) lattice clipped to a domain, from :func:`lattice`.

    Attributes
    ----------
    sites : ndarray of float64, shape (n, d)
        The lattice points kept, in L.
    spacing : float
        Nearest-neighbour distance, L (BCC: cube edge ``2 spacing / √3``).
    offset : ndarray of float64, shape (d,)
        A lattice point, the centre about which the spacing was scaled, L.
    rotation : ndarray of float64, shape (d, d)
        Orthogonal; column ``k`` is lattice axis ``k``: with ``u`` the unit lattice
        (hexagonal ``(i + j/2, j √3/2)``; BCC ``(i, j, k)`` and ``(i, j, k) + 1/2``) the
        sites are ``offset + (spacing / s_1) * u @ rotation.T``, ``s_1`` the unit lattice's
        nearest-neighbour distance (1 or √3/2).
    trimmed : int
        Sites dropped because no pose hit ``n`` exactly (the closest lattice above ``n``
        was trimmed, sites nearest the boundary first); 0 on an exact hit.
    added : int
        Sites added to a lattice below ``n``. Always 0 here: the search keeps a lattice
        with at least ``n`` sites as its fallback, which only ever needs a trim.
    """

    sites: NDArray[np.float64]
    spacing: float
    offset: NDArray[np.float64]
    rotation: NDArray[np.float64]
    trimmed: int = 0
    added: int = 0


@dataclass(frozen=True)
class _Gaps:
    """Runs of lattice rows inside the domain, clear of its boundary, in unit coordinates.

    Row ``r`` is the line ``(t, *transverse[r])`` with lattice points at ``t = i + shift[r]``;
    the points kept are those with ``lo[r] < t < hi[r]``, ``count[r]`` of them.
    """

    lo: NDArray[np.float64]
    hi: NDArray[np.float64]
    shift: NDArray[np.float64]
    transverse: NDArray[np.float64]
    count: NDArray[np.int64]


def lattice(domain: Domain, n: int, seed: int = 0, *, rng: RandomState = None) -> LatticeResult:
    """Hexagonal (2D) or BCC (3D) lattice with exactly ``n`` sites inside ``domain``.

    The lattice is posed once per attempt (a random rotation and a random offset from
    ``seed``) and scaled about the offset. A lattice point counts when it lies inside and
    at least ``LATTICE_MARGIN × spacing`` from the boundary, which keeps slivers out of the
    first diagram. For a generic pose the count changes by ±1 as the spacing passes each
    point's event, so a bisection between a spacing with at least ``n`` and one with fewer
    ends on exactly ``n`` (ALGORITHMS §6). Counting is by lattice rows: each boundary
    segment (triangle), grown to a convex superset of its margin neighbourhood, blocks an
    interval of every row it meets; the free runs between blocked intervals lie wholly
    inside or wholly outside, one exact inside test each. The cost per count is about the
    number of rows that meet the boundary, not the number of sites.

    If :data:`LATTICE_POSES` poses all fail (two events closer than round-off), the pose
    whose lattice exceeds ``n`` by the least is trimmed: the surplus sites nearest the
    boundary go (2D: exact distance to the polygon's boundary; 3D: clearance along the
    lattice row), ties by index. ``LatticeResult.trimmed`` says how many.

    Parameters
    ----------
    domain : Domain
    n : int
        Number of sites, at least 1.
    seed : int
        Seeds the poses.
    rng : int, numpy.random.Generator or None, optional
        As for :func:`initialise`; overrides ``seed``.

    Returns
    -------
    LatticeResult
        ``sites`` (n, d), with ``spacing``, ``offset``, ``rotation`` and the trim count.
    """
    n = check_count(n, domain.dim)
    dim = domain.dim
    generator = np.random.default_rng(random_state(seed, rng))
    pieces = _boundary_pieces(domain)
    # Unit-lattice scale with the lattice's Voronoi cell volume V / n.
    cell_volume = {2: np.sqrt(3.0) / 2.0, 3: 0.5}[dim]
    scale0 = float((domain.volume / n / cell_volume) ** (1.0 / dim))
    max_rows = max(LATTICE_MIN_ROWS, LATTICE_ROWS_PER_SITE * (n + len(pieces)))
    closest: tuple[int, _Pose, float] | None = None
    for _ in range(LATTICE_POSES):
        pose = _Pose.of(pieces, *_random_pose(domain, scale0, generator))

        def count(scale: float, pose: _Pose = pose) -> int:
            return int(_gaps(domain, pose, scale, max_rows).count.sum())

        scale, found = _search_scale(count, n, scale0)
        if found == n:
            return _lattice_result(domain, pose, scale, n)
        if closest is None or found < closest[0]:
            closest = (found, pose, scale)
    assert closest is not None
    return _lattice_result(domain, closest[1], closest[2], n)


def lattice_at(
    domain: Domain,
    n: int,
    offset: NDArray[np.float64],
    rotation: NDArray[np.float64],
    *,
    pieces: NDArray[np.float64] | None = None,
) -> LatticeResult | None:
    """The lattice of one pose with exactly ``n`` sites inside, or None if the pose misses ``n``.

    The pose is fixed (``offset`` (d,) a lattice point in L, ``rotation`` (d, d) with the
    lattice axes as columns, as in :class:`LatticeResult`); only the spacing is searched,
    scaling about ``offset``, by the bisection of :func:`lattice`. A pose misses ``n`` when
    the count jumps over it (a lattice row reaching a straight boundary all at once).
    ``pieces`` (the domain's boundary segments or triangles) saves recomputing them per pose.
    """
    n = check_count(n, domain.dim)
    cell_volume = {2: np.sqrt(3.0) / 2.0, 3: 0.5}[domain.dim]
    scale0 = float((domain.volume / n / cell_volume) ** (1.0 / domain.dim))
    pose = _Pose.of(_boundary_pieces(domain) if pieces is None else pieces, offset, rotation)
    max_rows = max(LATTICE_MIN_ROWS, LATTICE_ROWS_PER_SITE * (n + len(pose.frame)))

    def count(scale: float) -> int:
        return int(_gaps(domain, pose, scale, max_rows).count.sum())

    scale, found = _search_scale(count, n, scale0)
    return _lattice_result(domain, pose, scale, n) if found == n else None


def _search_scale(count: Callable[[float], int], n: int, scale0: float) -> tuple[float, int]:
    """A scale whose count is ``n``, or the closest found with more; and its count.

    Brackets ``count(lo) ≥ n > count(hi)``, then narrows the bracket alternating a step
    interpolated on the trend ``count ∝ scale^-d`` (taken as linear in ``1/scale²``,
    good enough to aim) with a bisection, which halves it at least every other step.

    The bracket grows by 1.25 at most :data:`LATTICE_SCALE_STEPS` times each way. A domain
    too thin for a lattice of ``n`` sites clear of its boundary keeps fewer than ``n`` as
    the scale shrinks until ``count`` refuses the rows it would need
    (:data:`LATTICE_ROWS_PER_SITE`): InvalidDomainError, with the finest scale tried.
    """
    lo = hi = scale0
    try:
        n_lo = n_hi = count(scale0)
    except _TooManyRowsError as err:
        raise _too_thin(n, 1.0, None, err) from None
    for _ in range(LATTICE_SCALE_STEPS):
        if n_hi < n:
            break
        lo, n_lo = hi, n_hi
        hi *= 1.25
        n_hi = count(hi)
    else:
        raise InvalidDomainError(
            f"a lattice {1.25**LATTICE_SCALE_STEPS:.3g} times coarser than the domain's "
            f"mean spacing still has {n_hi} >= n = {n} sites inside: the domain is unbounded "
            "or degenerate"
        )
    for _ in range(LATTICE_SCALE_STEPS):
        if n_lo >= n:
            break
        hi, n_hi = lo, n_lo
        try:
            n_lo = count(lo / 1.25)
        except _TooManyRowsError as err:
            raise _too_thin(n, scale0 / lo, n_lo, err) from None
        lo /= 1.25
    else:
        raise InvalidDomainError(
            f"a lattice {1.25**LATTICE_SCALE_STEPS:.3g} times finer than the domain's mean "
            f"spacing still has only {n_lo} < n = {n} sites inside"
        )
    step = 0
    while n_lo != n and hi - lo > 4 * np.spacing(hi):
        if step % 2 == 0 and n_lo > n_hi:
            w = (n_lo - n) / (n_lo - n_hi)
            x = (1 - w) / lo**2 + w / hi**2
            mid = float(np.clip(1.0 / np.sqrt(x), lo + (hi - lo) / 64, hi - (hi - lo) / 64))
        else:
            mid = 0.5 * (lo + hi)
        step += 1
        n_mid = count(mid)
        if n_mid >= n:
            lo, n_lo = mid, n_mid
        else:
            hi, n_hi = mid, n_mid
    return lo, n_lo


def _too_thin(n: int, finer: float, held: int | None, err: _TooManyRowsError) -> InvalidDomainError:
    tried = "" if held is None else f"{finer:.3g} times finer it holds {held}, and "
    return InvalidDomainError(
        f"no lattice of n = {n} sites fits in the domain clear of its boundary (by "
        f"{LATTICE_MARGIN} spacings, from the mean spacing (V/n)^(1/d) down): {tried}"
        f"counting needs {err.rows} lattice rows, more than the {err.limit} allowed "
        f"(the larger of {LATTICE_MIN_ROWS} and {LATTICE_ROWS_PER_SITE} per site and "
        "boundary piece); the domain is too thin "
        "for 'lattice': use method='random' or 'halton'"
    )


def _random_pose(
    domain: Domain, scale: float, rng: np.random.Generator
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Offset (d,) near the centroid and rotation (d, d), random so the pose is generic."""
    if domain.dim == 2:
        angle = rng.uniform(0.0, np.pi / 3.0)  # the hexagonal lattice repeats every 60°
        c, s = np.cos(angle), np.sin(angle)
        rotation = np.array([[c, -s], [s, c]])
    else:
        rotation = Rotation.random(rng=rng).as_matrix()
    offset = domain.centroid + scale * rotation @ rng.random(domain.dim)
    return offset, rotation


def boundary_pieces(domain: Domain) -> NDArray[np.float64]:
    """Boundary segments (P, 2, 2) or triangles (P, 3, 3), world coordinates (L)."""
    return _boundary_pieces(domain)


def _boundary_pieces(domain: Domain) -> NDArray[np.float64]:
    """Boundary segments (P, 2, 2) or triangles (P, 3, 3), world coordinates."""
    if domain.dim == 2:
        vertices, segments = polygon_boundary(domain.geometry)
        return vertices[segments]
    return domain.vertices[domain.faces]


# Rows of the unit lattice along its first axis come in two families f = 0, 1: the rows
# at transverse position (index + f/2) * ROW_STEP (each transverse axis), with lattice
# points at t = i + f/2. Hexagonal: rows j√3/2 with the odd ones shifted by 1/2; BCC: the
# cube corners and the cube centres.
ROW_STEP = {2: np.sqrt(3.0), 3: 1.0}


def _gaps(domain: Domain, pose: _Pose, scale: float, max_rows: float = np.inf) -> _Gaps:
    """Free runs of lattice rows inside the domain for one pose and scale (unit coordinates).

    Raises :class:`_TooManyRowsError` rather than test more than ``max_rows`` rows.
    """
    dim = domain.dim
    margin = LATTICE_MARGIN * UNIT_SPACING[dim]
    lo = pose.frame[:, :, 1:].min(axis=1) / scale - margin
    hi = pose.frame[:, :, 1:].max(axis=1) / scale + margin
    piece, family, index = _candidate_rows(lo, hi, dim, max_rows)
    transverse = (index + 0.5 * family[:, None]) * ROW_STEP[dim]
    # Clip the row (t, transverse) by the piece's half-spaces a . x <= bounds.
    a = pose.normals[piece]  # (K, C, d)
    bounds = pose.heights[piece] / scale + np.where(pose.active[piece], margin, 1.0)
    rhs = bounds - np.einsum("kcj,kj->kc", a[:, :, 1:], transverse)
    ax = a[:, :, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = rhs / ax
    t_hi = np.where(ax > 0, ratio, np.inf).min(axis=1)
    t_lo = np.where(ax < 0, ratio, -np.inf).max(axis=1)
    ok = (t_lo < t_hi) & ((ax != 0) | (rhs >= 0)).all(axis=1)
    t_lo, t_hi, family, index, transverse = (
        t_lo[ok],
        t_hi[ok],
        family[ok],
        index[ok],
        transverse[ok],
    )
    # Sort the blocked intervals by row, then start; merge within a row with a running
    # maximum, offsetting each row by more than the span of t so rows do not mix.
    key = _row_key(family, index)
    order = np.lexsort((t_lo, key))
    key, t_lo, t_hi, family, transverse = (
        key[order],
        t_lo[order],
        t_hi[order],
        family[order],
        transverse[order],
    )
    if len(key) < 2:
        return _empty_gaps(dim)
    rank = np.concatenate([[0], np.cumsum(key[1:] != key[:-1])])
    t0 = t_lo.min()
    span = t_hi.max() - t0 + 1.0
    reach = np.maximum.accumulate(t_hi - t0 + rank * span) - rank * span + t0
    between = (rank[1:] == rank[:-1]) & (t_lo[1:] > reach[:-1])
    lo, hi = reach[:-1][between], t_lo[1:][between]
    shift = 0.5 * family[1:][between]
    transverse = transverse[1:][between]
    count = (np.ceil(hi - shift) - np.floor(lo - shift) - 1).astype(np.int64)
    has = count > 0
    lo, hi, shift, transverse, count = lo[has], hi[has], shift[has], transverse[has], count[has]
    # Each free run lies wholly inside or outside (the blockers cover the boundary):
    # one exact test at its middle, well clear of the boundary.
    middle = np.column_stack([0.5 * (lo + hi), transverse])
    inside = domain.contains(pose.offset + scale * middle @ pose.rotation.T)
    return _Gaps(lo[inside], hi[inside], shift[inside], transverse[inside], count[inside])


def _empty_gaps(dim: int) -> _Gaps:
    empty = np.zeros(0)
    return _Gaps(empty, empty, empty, np.zeros((0, dim - 1)), np.zeros(0, dtype=np.int64))


def _row_key(family: NDArray[np.int64], index: NDArray[np.int64]) -> NDArray[np.int64]:
    """One integer per row: family and transverse indices, (K,) and (K, d-1)."""
    key = np.zeros(len(family), dtype=np.int64)
    for axis in range(index.shape[1]):
        column = index[:, axis] - index[:, axis].min(initial=0)
        key = key * (column.max(initial=0) + 1) + column
    return 2 * key + family


@dataclass(frozen=True)
class _Pose:
    """A lattice pose and the boundary's blockers seen from it, computed once per pose.

    ``frame`` holds the boundary pieces in the lattice frame about ``offset``, (P, d, d),
    in L. At scale ``s`` (unit coordinates ``x / s``) piece ``p`` blocks the convex set
    ``normals[p] . x <= heights[p] / s + margin`` over its ``active`` rows; inactive rows
    (zero normal) always hold. It contains every point within ``margin`` of the piece.
    """

    offset: NDArray[np.float64]
    rotation: NDArray[np.float64]
    frame: NDArray[np.float64]
    normals: NDArray[np.float64]
    heights: NDArray[np.float64]
    active: NDArray[np.bool_]

    @classmethod
    def of(
        cls,
        pieces: NDArray[np.float64],
        offset: NDArray[np.float64],
        rotation: NDArray[np.float64],
    ) -> _Pose:
        frame = (pieces - offset) @ rotation
        normals = _segment_normals(frame) if frame.shape[2] == 2 else _triangle_normals(frame)
        active = (normals != 0).any(axis=2)
        # Each half-space touches its piece at the vertex farthest along its normal.
        heights = np.einsum("pcj,pvj->pcv", normals, frame).max(axis=2)
        return cls(offset, rotation, frame, normals, heights, active)


def _segment_normals(frame: NDArray[np.float64]) -> NDArray[np.float64]:
    """Slab and end half-space normals of segments (P, 2, 2): (P, 4, 2), a rectangle."""
    p, q = frame[:, 0], frame[:, 1]
    along = (q - p) / np.linalg.norm(q - p, axis=1, keepdims=True)
    across = np.column_stack([-along[:, 1], along[:, 0]])
    return np.stack([across, -across, along, -along], axis=1)


def _triangle_normals(frame: NDArray[np.float64]) -> NDArray[np.float64]:
    """Slab and edge half-space normals of triangles (P, 3, 3): (P, 6, 3), a prism.

    Regular triangles: both sides of the plane and the three edges, outward in the plane
    (the sixth row inactive). Near-degenerate ones, whose plane is ill-defined: the six
    faces of their bounding box instead.
    """
    a, b, c = frame[:, 0], frame[:, 1], frame[:, 2]
    normal = np.cross(b - a, c - a)
    length = np.linalg.norm(normal, axis=1)
    longest = np.max([_dot(e, e) for e in (b - a, c - b, a - c)], axis=0)
    flat = length <= 1e-10 * longest
    normal = normal / np.where(flat, 1.0, length)[:, None]
    rows = [normal, -normal]
    for v0, v1, w in ((a, b, c), (b, c, a), (c, a, b)):
        out = np.cross(v1 - v0, normal)
        out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)
        out *= np.where(_dot(out, w - v0) > 0, -1.0, 1.0)[:, None]
        rows.append(out)
    rows.append(np.zeros_like(normal))
    normals = np.stack(rows, axis=1)
    normals[flat] = np.concatenate([np.eye(3), -np.eye(3)])
    return normals


def _dot(u: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    return np.einsum("ij,ij->i", u, v)


class _TooManyRowsError(Exception):
    """A lattice count would test more rows than allowed (a domain too thin for it)."""

    def __init__(self, rows: float, limit: float) -> None:
        super().__init__(f"{rows:.3g} rows, more than {limit:.3g}")
        self.rows, self.limit = f"{rows:.3g}", f"{limit:.3g}"


def _candidate_rows(
    lo: NDArray[np.float64], hi: NDArray[np.float64], dim: int, max_rows: float = np.inf
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
    """(piece, family, transverse index (K, d-1)) of every row through a piece's box.

    ``lo``, ``hi`` (P, d-1): transverse extent of each piece's grown box, unit coordinates.
    More than ``max_rows`` rows in all: :class:`_TooManyRowsError`, before any is made (counted
    in floating point, which does not overflow).
    """
    rows = 2.0 * np.prod(np.maximum((hi - lo) / ROW_STEP[dim] + 1.0, 0.0), axis=1).sum()
    if rows > max_rows:
        raise _TooManyRowsError(rows, max_rows)
    pieces, families, indices = [], [], []
    for family in (0, 1):
        first = np.ceil(lo / ROW_STEP[dim] - 0.5 * family).astype(np.int64)
        last = np.floor(hi / ROW_STEP[dim] - 0.5 * family).astype(np.int64)
        sizes = np.maximum(last - first + 1, 0)  # (P, d-1)
        total = sizes.prod(axis=1)
        piece = np.repeat(np.arange(len(lo)), total)
        local = np.arange(total.sum()) - np.repeat(np.cumsum(total) - total, total)
        index = np.empty((len(piece), dim - 1), dtype=np.int64)
        for axis in range(dim - 2, -1, -1):  # last axis fastest
            size = sizes[piece, axis]
            index[:, axis] = first[piece, axis] + local % size
            local //= size
        pieces.append(piece)
        families.append(np.full(len(piece), family, dtype=np.int64))
        indices.append(index)
    return np.concatenate(pieces), np.concatenate(families), np.concatenate(indices)


def _lattice_result(domain: Domain, pose: _Pose, scale: float, n: int) -> LatticeResult:
    """The sites of one pose and scale, trimmed to ``n`` nearest the boundary first."""
    gaps = _gaps(domain, pose, scale)
    offset, rotation = pose.offset, pose.rotation
    run = np.repeat(np.arange(len(gaps.count)), gaps.count)
    first = np.floor(gaps.lo - gaps.shift) + 1
    local = np.arange(len(run)) - np.repeat(np.cumsum(gaps.count) - gaps.count, gaps.count)
    t = first[run] + local + gaps.shift[run]
    unit = np.column_stack([t, gaps.transverse[run]])
    sites = offset + scale * unit @ rotation.T
    surplus = len(sites) - n
    if surplus > 0:
        if domain.dim == 2:
            clearance = shapely.distance(domain.geometry.boundary, shapely.points(sites))
        else:
            clearance = np.minimum(t - gaps.lo[run], gaps.hi[run] - t)
        drop = np.argsort(clearance, kind="stable")[:surplus]
        sites = np.delete(sites, drop, axis=0)
    spacing = scale * UNIT_SPACING[domain.dim]
    return LatticeResult(np.ascontiguousarray(sites), spacing, offset, rotation, max(surplus, 0))
