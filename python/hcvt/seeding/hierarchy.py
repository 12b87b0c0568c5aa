"""The hierarchical method of the paper (§4): regular CVTs by subdivision along Delaunay edges.

A coarse CVT is refined level by level: every restricted Delaunay edge (two cells sharing a
face inside the domain) gets a new site at its midpoint, which turns a hexagonal (BCC)
lattice into the lattice of half the spacing, four (eight) times as dense. Where the count
falls short of the schedule, random sites go into distinct boundary cells; then L-BFGS
brings the sites back to a CVT.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import Delaunay, cKDTree

from hcvt.density import DEFAULT_QUADRATURE_DEGREE, DensityLike
from hcvt.diagram import Diagram, voronoi
from hcvt.draw import Shows
from hcvt.geometry.domain import Domain
from hcvt.optimise import check_rule, cvt
from hcvt.seeding.initialisation import RandomState, initialise, random_state
from hcvt.seeding.sphere import rebalance

# Sites per subdivision in the ideal lattice: hexagonal 1 + 6/2, BCC 1 + 14/2 (paper §4.1.1).
GROWTH = {2: 4, 3: 8}


@dataclass(frozen=True)
class Schedule:
    """Site counts of the paper's §4.1.1 for target ``n`` and ``s`` subdivisions.

    Attributes
    ----------
    k0 : int
        Sites of the initial CVT, ``⌊b_1 / a⌋`` (``n`` when ``s = 0``).
    targets : tuple of int
        ``b_1 .. b_s`` with ``b_s = n`` and ``b_i = ⌊b_{i+1} / a⌋``.
    subdivisions : int
        ``s`` after capping.
    """

    k0: int
    targets: tuple[int, ...]
    subdivisions: int


def max_subdivisions(n: int, dim: int) -> int:
    """Default ``s``: ``⌊log_a n⌋ - 1``, what every "maximum" run of the paper used.

    The text caps ``s`` at ``⌊log_a n⌋``, but its experiments (1033 → 4, 10025 → 5, ball
    1000 → 2, 5000 → 3) took one less, which keeps ``k_0 ≥ a`` (DESIGN §5).
    """
    return max(_floor_log(n, GROWTH[dim]) - 1, 0)


def schedule(n: int, subdivisions: int, dim: int) -> Schedule:
    """The level schedule of §4.1.1, ``s`` capped at ``⌊log_a n⌋``.

    Examples
    --------
    >>> schedule(1033, 4, 2)
    Schedule(k0=4, targets=(16, 64, 258, 1033), subdivisions=4)
    >>> schedule(1033, 9, 2).subdivisions
    5
    """
    if isinstance(n, bool) or not isinstance(n, int | np.integer) or n < 1:
        raise ValueError(f"n must be a positive integer, got {n!r}")
    if subdivisions < 0:
        raise ValueError(f"subdivisions must be >= 0, got {subdivisions}")
    a = GROWTH[dim]
    s = min(int(subdivisions), _floor_log(n, a))
    targets = [int(n)]
    for _ in range(s - 1):
        targets.append(targets[-1] // a)
    targets.reverse()
    k0 = targets[0] // a if s > 0 else int(n)
    return Schedule(k0, tuple(targets) if s > 0 else (), s)


def _floor_log(n: int, a: int) -> int:
    """``⌊log_a n⌋`` in integers (no floating-point edge cases at exact powers)."""
    s, power = 0, a
    while power <= n:
        s, power = s + 1, power * a
    return s


EDGE_KINDS = ("restricted", "delaunay")


def subdivide(
    diagram: Diagram, edges: str = "restricted"
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Midpoints of the Delaunay edges that lie inside the domain.

    ``edges="restricted"``: pairs of cells sharing a face inside the domain (the paper's
    scheme as DESIGN §3.5 reads it). ``edges="delaunay"``: every edge of the Delaunay
    triangulation of the sites (scipy/Qhull), as a CGAL implementation would take it;
    near a straight boundary it also joins boundary sites whose cells meet only outside
    the domain, which puts midpoints where the restricted scheme leaves room for random
    top-up sites (measured on the 20 x 20 square, n = 1033, s = 4, 12 seeds: median mean G
    0.08088 against 0.08093).

    Returns
    -------
    midpoints : ndarray, shape (m, d)
    edges : ndarray of int, shape (m, 2)
        The pair of sites each midpoint came from.

    Notes
    -----
    A midpoint can fall outside a non-convex domain even though the two cells share a face
    inside it; such midpoints are left out (and the top-up fills the count).

    Symmetric CVTs have co-circular (co-spherical) sites, whose Voronoi cells meet in a
    face of round-off size across both diagonals of a planar quad: two "edges" then share a
    midpoint. Only the first of midpoints closer than ``1e-9 h`` (``h`` the mean cell
    size) is kept, so that no two sites coincide.
    """
    if edges not in EDGE_KINDS:
        raise ValueError(f"edges must be one of {EDGE_KINDS}, got {edges!r}")
    pairs = diagram.neighbors if edges == "restricted" else delaunay_edges(diagram.sites)
    domain = diagram.domain
    midpoints = onto_domain(domain, 0.5 * (diagram.sites[pairs[:, 0]] + diagram.sites[pairs[:, 1]]))
    keep = domain.contains(midpoints)
    h = (domain.volume / diagram.n) ** (1.0 / domain.cell_dim)
    for i, j in sorted(cKDTree(midpoints).query_pairs(1e-9 * h)):
        if keep[i]:
            keep[j] = False
    if domain.cell_dim < domain.dim:
        # Projected, a midpoint can land on a site (the two sides of a thin sheet).
        keep &= cKDTree(diagram.sites).query(midpoints)[0] > 1e-9 * h
    return midpoints[keep], pairs[keep]


def onto_domain(domain: Domain, points: NDArray[np.float64]) -> NDArray[np.float64]:
    """``points`` (m, 3) moved onto the sphere or a surface; other domains' as they are.

    A chord's midpoint, or a point drawn in a ball, lies off the sphere or surface, where
    its cell would be empty (a surface) or ``contains`` is false (the sphere). The sphere
    pushes it radially (a chord's midpoint becomes the midpoint of its arc, the spherical
    Delaunay edge; a point at the centre stays there and is then not contained); a surface
    takes its closest point, through the surface's own BVH.
    """
    if domain.is_sphere:
        norm = np.linalg.norm(points, axis=1)[:, None]
        safe = np.where(norm > 0, norm, 1.0)
        return np.where(norm > 0, points * (domain.radius / safe), points)
    if domain.is_surface:
        frame = domain.frame
        nearest, _ = domain._core.closest(frame.to_core(points, "points"))
        return np.asarray(frame.to_input("sites", nearest), dtype=np.float64)
    return points


def delaunay_edges(sites: NDArray[np.float64]) -> NDArray[np.int64]:
    """Edges ``(i, j)``, ``i < j``, of the Delaunay triangulation of ``sites``, sorted."""
    simplices = Delaunay(sites).simplices
    d = sites.shape[1]
    pairs = [simplices[:, [a, b]] for a in range(d + 1) for b in range(a + 1, d + 1)]
    return np.unique(np.sort(np.vstack(pairs), axis=1), axis=0).astype(np.int64)


def boundary_cells(diagram: Diagram) -> NDArray[np.int64]:
    """Indices of the cells touching the domain boundary."""
    return np.flatnonzero(diagram.boundary_measure > 0)


def sample_in_cells(
    diagram: Diagram, cells: NDArray[np.int64], rng: np.random.Generator
) -> NDArray[np.float64]:
    """One random point in each listed cell (rejection sampling), shape (m, d).

    Candidates are drawn uniformly in a ball around the site of radius twice the cell's
    size ``volume^(1/d)`` and kept when they are inside the domain and nearest to that
    cell's site: uniform in the part of the cell within the ball. A cell that rejects a
    batch shrinks its ball (a site near the boundary has most of the ball outside), which
    always ends, as the site is inside the domain and its own cell; the result is then
    biased towards the site, still inside the cell and never on an existing site. On the
    sphere and on a surface the candidates are moved onto it (:func:`onto_domain`) and the
    cells (areas) have dimension 2.
    """
    dim = diagram.domain.dim
    tree = cKDTree(diagram.sites)
    out = np.empty((len(cells), dim))
    todo = np.arange(len(cells))
    radius = 2.0 * diagram.volume[cells] ** (1.0 / diagram.domain.cell_dim)
    batch = 32
    while len(todo):
        owner = np.repeat(todo, batch)
        direction = rng.normal(size=(len(owner), dim))
        direction /= np.linalg.norm(direction, axis=1, keepdims=True)
        r = radius[owner] * rng.random(len(owner)) ** (1.0 / dim)
        candidates = diagram.sites[cells[owner]] + direction * r[:, None]
        candidates = onto_domain(diagram.domain, candidates)
        moved = (candidates != diagram.sites[cells[owner]]).any(axis=1)
        ok = (r > 0) & moved & diagram.domain.contains(candidates)
        ok[ok] &= tree.query(candidates[ok])[1] == cells[owner[ok]]
        hit = np.zeros(len(cells), dtype=bool)
        first: dict[np.intp, np.intp] = {}
        for k in np.flatnonzero(ok):
            first.setdefault(owner[k], k)
        for j, k in first.items():
            out[j] = candidates[k]
            hit[j] = True
        todo = todo[~hit[todo]]
        radius[todo] *= 0.7
    return out


# Uniform draws per top-up site, of which the farthest from the cell's site is kept.
TOP_UP_DRAWS = 4


def top_up(
    domain: Domain,
    sites: NDArray[np.float64],
    target: int,
    rng: np.random.Generator,
    density: DensityLike = None,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
) -> NDArray[np.float64]:
    """Add ``target - len(sites)`` random sites, each in a different boundary cell.

    The cells are those of ``sites`` (the subdivided level), where the gaps are: after a
    subdivision the new boundary row sits as far from the boundary as the old one, so
    the boundary cells are the strips the finer lattice has not filled. The paper picks
    them at random; we take the boundary cells of largest energy ``∫|x - x_i|²`` first,
    as a site added there lowers the energy most, and place it at the farthest from the
    cell's site of ``TOP_UP_DRAWS`` uniform draws in the cell, so that it splits the cell
    rather than crowding its site. On the 20 x 20 square, n = 1033, s = 4 (24 seeds),
    the median mean G drops from 0.08095 (random cells of the coarser level) to 0.08080,
    the paper's 0.08086. When more sites are needed than there are boundary
    cells, the list is used again in random order (Table 1 has ``b_1 - k_1 = 11`` with
    few boundary cells). With a density the energy is the ρ-weighted one.

    On the sphere and on a surface (cells of dimension 2 in 3D) the cells of largest
    energy are taken from all cells, also on an open surface with border loops: on the
    open Stanford bunny scan (n = 500, tol 1e-3, seeds 0-2) the border cells gave final
    energies 0.4-0.8% above those of all cells and 28-41% more diagrams
    (docs/results/surface_hierarchy.txt).
    """
    missing = target - len(sites)
    if missing <= 0:
        return sites
    diagram = voronoi(domain, sites, density=density, quadrature_degree=quadrature_degree)
    # On the sphere and on a surface every cell is a candidate (the gaps are where
    # curvature breaks the lattice, not along a border: below).
    candidates = boundary_cells(diagram) if domain.cell_dim == domain.dim else None
    if candidates is None or len(candidates) == 0:
        candidates = np.arange(diagram.n)
    order = np.argsort(-diagram.energy_terms[candidates], kind="stable")
    chosen = [candidates[order[:missing]]]
    missing -= len(chosen[0])
    while missing > 0:
        take = rng.permutation(candidates)[:missing]
        chosen.append(take)
        missing -= len(take)
    cells = np.concatenate(chosen)
    draws = np.stack([sample_in_cells(diagram, cells, rng) for _ in range(TOP_UP_DRAWS)])
    distance = np.linalg.norm(draws - diagram.sites[cells], axis=2)
    return np.vstack([sites, draws[distance.argmax(axis=0), np.arange(len(cells))]])


def trim(
    diagram: Diagram,
    midpoints: NDArray[np.float64],
    edges: NDArray[np.int64],
    surplus: int,
) -> NDArray[np.float64]:
    """Drop ``surplus`` midpoints, those of edges touching boundary cells first.

    In 3D an irregular region has mean Delaunay degree above 14 (15.5 for Poisson points),
    so subdividing can overshoot the schedule; boundary cells are the least regular, so
    their midpoints go first, in a fixed order (DESIGN §5).
    """
    touches = (diagram.boundary_measure[edges] > 0).any(axis=1)
    # Boundary-touching edges first, the latest edges first within each group.
    order = np.lexsort((-np.arange(len(edges)), ~touches))
    drop = np.zeros(len(edges), dtype=bool)
    drop[order[:surplus]] = True
    return midpoints[~drop]


@dataclass
class Level:
    """One level of the hierarchy, the content of a row of the paper's Table 1 and more."""

    sites: NDArray[np.float64]
    diagram: Diagram
    subdivided: int  # k_i: sites after subdividing (the initial count at level 0)
    added: int  # b_i - k_i: random sites put into boundary cells (negative: trimmed)
    iterations: int
    seconds: float
    history: Any = None  # the level's L-BFGS history (hcvt.optimise), per iteration

    @property
    def n(self) -> int:
        """Sites at this level (``b_i``)."""
        return len(self.sites)

    @property
    def mean_G(self) -> float:  # noqa: N802 (the paper's G)
        """Average G over the cells of the level's CVT."""
        return self.diagram.mean_G

    @property
    def energy(self) -> float:
        """CVT energy of the level."""
        return self.diagram.energy


@dataclass(repr=False)
class HierarchicalResult(Shows):
    """Result of :func:`hierarchical_cvt`: the final CVT and every level.

    Shows the final diagram in Jupyter, with the site count of every level.
    """

    levels: list[Level] = field(default_factory=list)
    schedule: Schedule | None = None

    @property
    def sites(self) -> NDArray[np.float64]:
        """Final sites, shape (n, d)."""
        return self.levels[-1].sites

    @property
    def diagram(self) -> Diagram:
        """Diagram of the final sites."""
        return self.levels[-1].diagram

    @property
    def seconds(self) -> float:
        """Total seconds over all levels."""
        return sum(level.seconds for level in self.levels)

    def __repr__(self) -> str:
        if not self.levels:
            return "<hcvt.HierarchicalResult (no levels)>"
        counts = " -> ".join(str(level.n) for level in self.levels)
        return (
            f"<hcvt.HierarchicalResult n={len(self.sites)} d={self.sites.shape[1]} "
            f"levels {counts}, {sum(lv.iterations for lv in self.levels)} iterations, "
            f"{self.seconds:.3g} s; mean G={self.diagram.mean_G:.6f}>"
        )

    @property
    def history(self) -> dict[str, NDArray[Any]]:
        """Every level's CVT history end to end, as :attr:`hcvt.CVTResult.history`.

        Arrays per field, one entry per iterate of every level (each level's initial sites
        first), with ``level`` (int) saying which; ``seconds`` and ``evaluations`` run on
        across levels.
        """
        parts = [lv.history for lv in self.levels]
        out: dict[str, NDArray[Any]] = {
            key: np.concatenate([np.asarray(h[key]) for h in parts]) for key in parts[0]
        }
        out["level"] = np.repeat(np.arange(len(parts)), [len(h["energy"]) for h in parts])
        for key in ("seconds", "evaluations"):
            ends = np.cumsum([0] + [h[key][-1] for h in parts[:-1]])
            out[key] = np.concatenate(
                [np.asarray(h[key]) + end for h, end in zip(parts, ends, strict=True)]
            )
        return out

    def table(self) -> list[dict[str, Any]]:
        """The paper's Table 1 (k_i, b_i - k_i per level) with mean G and energy."""
        return [
            {
                "level": i,
                "k": lv.subdivided,
                "added": lv.added,
                "n": lv.n,
                "mean_G": lv.mean_G,
                "energy": lv.energy,
                "iterations": lv.iterations,
                "seconds": lv.seconds,
            }
            for i, lv in enumerate(self.levels)
        ]


def hierarchical_cvt(
    domain: Domain,
    n: int,
    subdivisions: int | None = None,
    *,
    init: str = "random",
    seed: int = 0,
    rng: RandomState = None,
    rule: str = "gap",
    tol: float | None = None,
    max_iter: int = 10_000,
    edges: str = "restricted",
    method: str | None = None,
    callback: Any = None,
    density: DensityLike = None,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
    level_tol: float | None = None,
    level_max_iter: int | None = None,
    iteration_callback: Any = None,
) -> HierarchicalResult:
    """Regular CVT of exactly ``n`` sites by the hierarchical method of the paper (§4).

    Parameters
    ----------
    domain : Domain
        A polygon, solid, box, the sphere or a triangle surface. On the sphere and on a
        surface the cells have dimension 2 (four sites per site per subdivision) and the
        midpoints and top-up sites are moved onto it (:func:`onto_domain`).
    n : int
        Final number of sites.
    subdivisions : int, optional
        ``s``; default :func:`max_subdivisions` (``⌊log_a n⌋ - 1``); capped at
        ``⌊log_a n⌋``.
    init : {"random", "halton", "lattice"}
        Level 0's sites (:func:`hcvt.initialise`'s method): random, scrambled Halton
        (low discrepancy, on a surface too), or an exact-count hexagonal/BCC lattice;
        then the level's CVT.
    seed : int
        Seeds the initialisation and every top-up.
    rng : int, numpy.random.Generator or None, optional
        Random state as numpy takes it (SPEC 7); overrides ``seed`` (``rng=k`` is
        ``seed=k``).
    rule : {"gap", "paper"}
        The stopping rule of every level (:func:`hcvt.cvt`): the scale-free RMS gap
        (default) or the paper's ``‖g‖/‖X‖`` in input coordinates.
    tol : float, optional
        Its tolerance; default 1e-7 (gap) or the paper's 1e-10.
    max_iter : int
        Iterations per level at most.
    edges : {"restricted", "delaunay"}
        Which Delaunay edges are subdivided (see :func:`subdivide`).
    method : {"newton", "lbfgs", "lloyd"}, optional
        The optimiser of every level (:func:`hcvt.cvt`); the paper's is L-BFGS. Default:
        the fastest the domain takes (:func:`hcvt.optimise.fastest_method`).
    callback : callable, optional
        Called with each finished :class:`Level`; a true return value or ``StopIteration``
        ends the run after that level (the result then holds the levels made).
    density : Polynomial, SizingField or callable, optional
        A density ρ (:mod:`hcvt.density`) for every level's CVT. Level 0 starts from
        sites distributed ∝ ``ρ^(d/(d+2))`` (``init="random"`` or ``"halton"``; a
        lattice start is uniform and the level's CVT grades it); subdividing the
        restricted Delaunay edges keeps the grading, and the top-up fills the boundary
        cells of most ρ-weighted energy.
        Every level still has exactly its scheduled count.
    quadrature_degree : int, default 4
        Degree of the simplex rule that samples a callable density.
    iteration_callback : callable, optional
        Passed to every level's :func:`hcvt.cvt` as its ``callback``: called with each
        iterate's info dict (the history fields and ``sites``); a true return value stops
        that level (progress of a long last level, ``benchmarks/sphere.py``).
    level_tol, level_max_iter : float and int, optional
        Tolerance and iteration cap of the levels before the last, which only place the
        next level's sites; default ``tol`` and ``max_iter``, but with a density on the
        sphere ``SPHERE_DENSITY_LEVELS`` (1e-2, 100): there the coarse levels' cells are
        wider than the density's features and L-BFGS stalls in its line search (on the
        2,584-cell 4:1 band, levels of 10-161 sites ran 100 iterations and ~1,700 diagrams
        each to RMS gap 3-5e-3; to 1e-2 they take 22-49 diagrams). On a surface with
        the gap rule the coarse levels stop at ``SURFACE_LEVEL_TOL`` (1e-2, or ``tol``
        if looser): converged to 1e-7 they cost 827 diagrams and the last level then
        needed more (bunny, n = 5,000: 688 diagrams, 68 CPU s in all, against 467 and 41
        s, and 578 and 50 s from random sites; energy 0.06% lower than from random sites;
        at n = 20,000 the hierarchy took 507 CPU s against 286 from random sites (kitten
        574 against 522), docs/results/surface_hierarchy.txt).

    Returns
    -------
    HierarchicalResult
        ``sites`` (n, d), ``diagram``, and ``levels`` (the paper's Table 1 in ``table()``).
    """
    if domain.is_sphere_region:
        raise NotImplementedError(
            "hierarchical_cvt on a region of the sphere is not implemented yet: use hcvt.cvt"
        )
    check_rule(rule)
    if init not in HIERARCHY_INITS:
        raise ValueError(f"init must be one of {HIERARCHY_INITS}, got {init!r}")
    if edges not in EDGE_KINDS:
        raise ValueError(f"edges must be one of {EDGE_KINDS}, got {edges!r}")
    if subdivisions is None:
        subdivisions = max_subdivisions(int(n), domain.cell_dim)
    plan = schedule(n, subdivisions, domain.cell_dim)
    generator = np.random.default_rng(random_state(seed, rng))
    result = HierarchicalResult(schedule=plan)

    start = time.perf_counter()
    # An int seeds the initialisation and the top-ups apart (as ``seed`` always has); a
    # Generator serves both, in that order.
    graded = density if init in ("random", "halton") else None
    sites = initialise(domain, plan.k0, method=init, rng=random_state(seed, rng), density=graded)
    optimise = partial(
        cvt,
        method=method,
        rule=rule,
        tol=tol,
        max_iter=max_iter,
        density=density,
        quadrature_degree=quadrature_degree,
        callback=iteration_callback,
    )
    coarse = _coarse_levels(domain, density, level_tol, level_max_iter, rule, tol)
    optimise_coarse = partial(optimise, **coarse) if plan.targets else optimise
    level = _optimise_level(optimise_coarse, domain, sites, len(sites), 0, start)
    result.levels.append(level)
    if _stop_asked(callback, level):
        return result
    for index, target in enumerate(plan.targets):
        start = time.perf_counter()
        previous = result.levels[-1]
        midpoints, pairs = subdivide(previous.diagram, edges)
        k = previous.n + len(midpoints)
        if k > target:
            midpoints = trim(previous.diagram, midpoints, pairs, k - target)
        sites = np.vstack([previous.sites, midpoints])
        sites = top_up(domain, sites, target, generator, density, quadrature_degree)
        if domain.is_sphere and density is not None:
            sites = rebalance(previous.sites, sites, density)
        last = index == len(plan.targets) - 1
        level = _optimise_level(
            optimise if last else optimise_coarse, domain, sites, k, target - k, start
        )
        result.levels.append(level)
        if _stop_asked(callback, level):
            break
    return result


#: Level 0's initialisations (:func:`hcvt.initialise` methods) that :func:`hierarchical_cvt` offers.
HIERARCHY_INITS = ("random", "halton", "lattice")
# The coarse levels' tolerance and iteration cap with a density on the sphere.
SPHERE_DENSITY_LEVELS = (1e-2, 100)
# The coarse levels' tolerance on a surface (gap rule), unless the last level's is looser.
SURFACE_LEVEL_TOL = 1e-2


def _coarse_levels(
    domain: Domain,
    density: DensityLike,
    tol: float | None,
    max_iter: int | None,
    rule: str,
    final_tol: float | None,
) -> dict[str, Any]:
    """``tol`` / ``max_iter`` overrides of the levels before the last (none: as the last)."""
    if domain.is_sphere and density is not None:
        tol = SPHERE_DENSITY_LEVELS[0] if tol is None else tol
        max_iter = SPHERE_DENSITY_LEVELS[1] if max_iter is None else max_iter
    if domain.is_surface and rule == "gap" and tol is None:
        tol = max(SURFACE_LEVEL_TOL, final_tol or 0.0)
    out: dict[str, Any] = {}
    if tol is not None:
        out["tol"] = tol
    if max_iter is not None:
        out["max_iter"] = max_iter
    return out


def _stop_asked(callback: Any, level: Level) -> bool:
    """Call ``callback(level)``; a true return value or ``StopIteration`` asks to stop."""
    if callback is None:
        return False
    try:
        return bool(callback(level))
    except StopIteration:
        return True


def _optimise_level(
    optimise: Any,
    domain: Domain,
    sites: NDArray[np.float64],
    subdivided: int,
    added: int,
    start: float,
) -> Level:
    res = optimise(domain, sites)
    return Level(
        sites=res.sites,
        diagram=res.diagram,
        subdivided=subdivided,
        added=added,
        iterations=int(res.iterations),
        seconds=time.perf_counter() - start,
        history=res.history,
    )


__all__ = [
    "HierarchicalResult",
    "Level",
    "Schedule",
    "hierarchical_cvt",
    "max_subdivisions",
    "schedule",
    "subdivide",
]
