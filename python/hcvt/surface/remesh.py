"""Isotropic remeshing with exactly ``n`` vertices: a restricted CVT, then its triangulation.

Yan, Lévy, Liu, Sun, Wang, "Isotropic remeshing with fast and exact computation of
restricted Voronoi diagram", SGP 2009; DESIGN §12.

``n`` sites random by area on the surface, spread by a few Lloyd steps over points sampled
on it (a cheap CVT of the samples, :data:`START_STEPS`); a CVT of the restricted Voronoi diagram
(:func:`hcvt.cvt`, sites free in space, projected onto the surface at the end, to a
loose tolerance, tightened while the triangulation has defects); then a
triangle for each point where three cells meet on the surface, oriented by the surface's
normal there (the core's ``restricted_delaunay``); unless ``tighten=False``, then a few
vertices moved along the surface where the mesh is farthest from it
(:mod:`hcvt.surface.tighten`), the connectivity kept and the least angle not taken below
30° (:data:`TIGHTEN_MIN_ANGLE`). Where every cell is a topological disc meeting its
neighbours along single arcs (the closed-ball property, Edelsbrunner and Shah 1997) the
triangulation is a manifold homeomorphic to the surface. Where not (too few vertices for
a thin part or a tight fold), :attr:`RemeshResult.defects` names the cells; with
``check=True`` :class:`RemeshError` is raised instead. Nothing is repaired silently.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from typing import Any, overload

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

import hcvt._core as _core
from hcvt.density import DensityLike, triangle_values
from hcvt.geometry.domain import Domain
from hcvt.geometry.surface_points import sample_by_area
from hcvt.optimise import CVTResult, cvt
from hcvt.seeding.initialisation import initialise
from hcvt.surface.curvature import curvature_density
from hcvt.surface.features import (
    FeatureSites,
    constrained_cvt,
    intruding_sites,
    move_intruders,
    move_to_gaps,
    plan_feature_sites,
    release_sites,
    restore_segments,
    segment_defects,
)
from hcvt.surface.quality import (
    SurfaceQuality,
    edge_counts,
    edge_topology,
    surface_quality,
    triangle_angles,
)
from hcvt.surface.tighten import check_min_angle
from hcvt.surface.tighten import tighten as tighten_vertices


class RemeshError(ValueError):
    """The restricted Delaunay triangulation is not a manifold mesh of the surface."""


class _Lazy:
    """:attr:`RemeshResult.quality`: a :class:`SurfaceQuality`, or a callable giving one.

    A callable is called on first reading, once (the exact Hausdorff distance to the input
    costs a fifth to a quarter of the remeshing's CPU: fandisk, n = 5,000, one thread,
    0.33-0.57 s against 1.6-2.4 s), and its value kept; :func:`remesh` gives
    :func:`hcvt.surface_quality` of its result that way (a :func:`functools.partial`, so
    the result still pickles).
    """

    def __init__(self, name: str) -> None:
        self.slot = "_" + name

    @overload
    def __get__(self, obj: None, owner: type | None = None) -> _Lazy: ...
    @overload
    def __get__(self, obj: object, owner: type | None = None) -> SurfaceQuality: ...
    def __get__(self, obj: object | None, owner: type | None = None) -> _Lazy | SurfaceQuality:
        if obj is None:
            # Read on the class (as dataclass looks for a default): no default.
            raise AttributeError(self.slot[1:])
        value = obj.__dict__[self.slot]
        if not isinstance(value, SurfaceQuality):
            value = obj.__dict__[self.slot] = value()
        return value

    def __set__(self, obj: object, value: SurfaceQuality | Callable[[], SurfaceQuality]) -> None:
        obj.__dict__[self.slot] = value


@dataclass
class RemeshResult:
    """What :func:`remesh` returns.

    Attributes
    ----------
    vertices : ndarray, shape (n, 3)
        The CVT's sites projected onto the surface, L: exactly ``n`` (with ``tighten``,
        the few moved along it where the mesh was farthest from it).
    faces : ndarray of intp, shape (m, 3)
        The restricted Delaunay triangles, counter-clockwise about the surface's normal.
    quality : SurfaceQuality
        :func:`hcvt.surface_quality` of the result against the input surface, computed
        when first read (its exact Hausdorff distance costs a fifth to a quarter of the
        remeshing's CPU; ``seconds`` leaves it out). A SurfaceQuality, or a callable giving
        one, may be passed.
    cvt : CVTResult
        The CVT run (history, stop reason, the final diagram of the projected sites).
    defects : list of str
        Where the triangulation is not a manifold mesh of the surface, naming the cells
        (site indices): cells meeting at more than one point, vertices in no triangle,
        edges in more than two triangles, a genus other than the input's. Empty when sound.
    seconds : float
        Wall time of the whole remeshing (CVT and triangulation; not the quality).
    iterations : int
        CVT iterations in all, over the rounds (``cvt`` is the last round's run).
    moves : int
        Vertices moved by ``tighten`` (:func:`hcvt.surface.tighten.tighten`).
    freed : int
        With ``features``: the feature sites freed (cells that were not discs around
        them, or parting a feature segment): the features are not kept there.
    """

    vertices: NDArray[np.float64]
    faces: NDArray[np.intp]
    quality: SurfaceQuality  # read through _Lazy (set below, after the dataclass is made)
    cvt: CVTResult
    defects: list[str] = field(default_factory=list)
    seconds: float = 0.0
    iterations: int = 0
    moves: int = 0
    freed: int = 0


# After the dataclass is made, which takes the field as having no default; its __init__,
# repr and comparison then go through the descriptor.
RemeshResult.quality = _Lazy("quality")  # type: ignore[assignment]


#: The CVT's default tolerance on the gap rule in :func:`remesh`: the least angle has
#: saturated there, the rest nearly. Bunny, n = 5,000, L-BFGS from random sites: 11
#: iterations, Q min 0.596, least angle 32.4°, Hausdorff 0.499%, against 18 iterations at
#: 5e-3 (0.641, 32.9°, 0.466%) and 100 at 7e-4 (0.656, 39.4°, 0.454%); at n = 20,000
#: 11 iterations against 19 (Q min 0.532 against 0.628, 32.2° against 35.0°, Hausdorff
#: 0.302% against 0.293%). pyacvd's and MeshLab's least angles there are 3-24°.
REMESH_TOL = 1e-2
#: Rounds, each at a tolerance ``TIGHTER`` times the last, while the triangulation of an
#: early stop has defects (a cell not yet a disc).
TIGHTER_ROUNDS, TIGHTER = 3, 0.25
#: The most rounds in all, those freeing held sites (features) among them.
_MOST_ROUNDS = 12
#: The least angle (degrees) ``tighten`` may leave by default: its moves lower the mesh's
#: least angle to this, not below (nor below the CVT mesh's own where that is lower). The
#: peers' least angles are 1-26° (pyacvd, MeshLab; ``benchmarks/remesh.py``). Kitten, n =
#: 5,000, the Hausdorff distance (% of the diagonal) after tightening at the CVT mesh's
#: own least angle, 33.5°, is 0.383%; at 30° 0.284% (MeshLab's 0.366%).
TIGHTEN_MIN_ANGLE = 30.0
#: An open surface's border (``border=True``) has a corner (a held site) only where it turns
#: by more than this many degrees (a slit's end). A scan's border turns sharply every few
#: edges: the Stanford scan's five holes, n = 1,500, seeds 0-2, with corners above 30°, 60°
#: or 120° held sites as close as welding allows and gave least angles of 2.1-3.0° (Q min
#: 0.06-0.09); above 150°: 21.6-27.3°, Q min 0.51-0.54, Hausdorff 0.56-0.72%. So a CAD
#: border's right-angled corners are not held (the mesh cuts them, by up to a spacing):
#: ``features=30`` holds them.
BORDER_CORNER_ANGLE = 150.0
#: Points sampled on the input per vertex of the mesh for ``tighten`` (at least
#: 30,000): its worst places are those of the samples, and too few miss them. Bunny,
#: n = 20,000, floor 30°: 30,000 samples stop at 0.178% of the diagonal, 200,000 at 0.160%
#: (uniform, before tighten searched finer near its worst places). With that search and
#: the curvature density, n = 20,000, seeds 0-3: bunny 0.120-0.142% at 5 per vertex
#: (0.114-0.138% at 10), kitten 0.097-0.110% (0.089-0.116%); tighten's seconds 20-30%
#: fewer.
TIGHTEN_SAMPLES_PER_VERTEX = 5
#: The CVT's start (:func:`_spread`): this many Lloyd steps of the random sites over
#: ``START_SAMPLES`` points per site drawn on the surface. Random sites' cells differ in
#: size by an order of magnitude, which the exact CVT spent its first iterations evening
#: out; the four sampled steps cost about one exact diagram (fandisk, n = 5,000, one
#: thread: 0.12-0.13 s of CPU against 0.135 s, the k-d tree queries most of it). L-BFGS
#: iterations from random sites / spread ones, seed 0, one thread, tighten=False: fandisk
#: 5,000 11 / 9, bunny 11 / 9; 4 points per site or 2 steps gave 9-10.
#: Not with ``features``, whose constrained CVT keeps its exact Lloyd steps
#: (:data:`hcvt.surface.features.PRESMOOTH`): from spread sites, with or without them, the
#: bunny at n = 600, 30°, kept cells that are not discs near its ears on seeds 0, 1 and 2
#: (from random ones on seed 1 only); and L-BFGS from spread sites a few hundredths of a
#: spacing from held ones (bunny, n = 5,000, 30°) took 59 evaluations for 16 iterations.
START_SAMPLES, START_STEPS = 8, 4


#: The power of :func:`hcvt.surface.curvature_density` for ``density="curvature"`` (an
#: option; the default is uniform): the spacing ``∝ (1 + κ/κ̄)^(-1/4)``. n = 20,000, seeds
#: 0-3, spread start, the exact Hausdorff distance (% of the diagonal) after ``tighten``,
#: graded against uniform: bunny 0.144, 0.171, 0.121, 0.140 against 0.158, 0.215, 0.187,
#: 0.159 (MeshLab 0.148); kitten 0.094, 0.096, 0.095, 0.091 against 0.126, 0.143, 0.165,
#: 0.142 (MeshLab 0.141); but 16-66% more CPU on the 8 benchmark cases (tighten works
#: longer on the graded mesh; the density's integrals 4-18% of the CVT), and the bunny's
#: seed 1 still above MeshLab's: not the default (docs/results/remesh.txt, shaus2).
REMESH_DENSITY_POWER = 1.0


def _density(surface: Domain, density: DensityLike | str, held: bool) -> DensityLike:
    """:func:`remesh`'s ``density``, "curvature" made a field on the surface's vertices.

    Uniform (None) with ``held`` sites (features, the border): they are spaced for a
    uniform density (bunny, n = 600, creases above 30°, graded: cells that are not discs).
    """
    if isinstance(density, str):
        if density != "curvature":
            raise ValueError(
                f'density must be "curvature", a density (hcvt.density) or None, not {density!r}'
            )
        return None if held else curvature_density(surface, REMESH_DENSITY_POWER)
    return density


def _defects(
    faces: NDArray[np.intp], n: int, repeated: NDArray[np.intp], input_topology: dict[str, int]
) -> list[str]:
    """The defects of :attr:`RemeshResult.defects`."""
    out = []
    if len(repeated):
        out.append(
            f"{len(repeated)} triple(s) of cells meet at more than one point (cells that are "
            f"not discs), first cells {repeated[0].tolist()}"
        )
    unused = np.setdiff1d(np.arange(n), faces)
    if len(unused):
        out.append(f"{len(unused)} site(s) in no triangle, first site {int(unused[0])}")
    topology = edge_topology(faces, n)
    if topology["nonmanifold_edges"] or topology["border_edges"]:
        # The edges' counts, to name the first offender (only when there is one).
        pairs, counts = edge_counts(faces)
    if topology["nonmanifold_edges"]:
        first = pairs[counts >= 3][0].tolist()
        out.append(
            f"{topology['nonmanifold_edges']} edge(s) in three or more triangles, first "
            f"between sites {first}"
        )
    if not topology["manifold"] and not topology["nonmanifold_edges"]:
        out.append("triangles disagree in orientation (some edge run twice the same way)")
    if topology["border_edges"] and not input_topology["border_edges"]:
        first = pairs[counts == 1][0].tolist()
        out.append(
            f"{topology['border_edges']} border edge(s) on a closed surface (holes), first "
            f"between sites {first}"
        )
    for key in ("components", "genus"):
        if topology[key] != input_topology[key]:
            out.append(f"{key} {topology[key]}, the surface's {input_topology[key]}")
    return out


def _stuck_held(
    repeated: NDArray[np.intp], faces: NDArray[np.intp], n: int, held: int
) -> NDArray[np.intp]:
    """The held sites (the last ``held`` of ``n``) in triples of cells meeting twice.

    Also those at an end of an edge of ``faces`` in three or more triangles.
    """
    pairs, counts = edge_counts(faces)
    sites = np.union1d(np.asarray(repeated, dtype=np.intp).ravel(), pairs[counts >= 3].ravel())
    return sites[sites >= n - held].astype(np.intp)


def _spread(
    surface: Domain, sites: NDArray[np.float64], seed: int, density: DensityLike = None
) -> NDArray[np.float64]:
    """``sites`` (n, 3) spread evenly over ``surface``: a cheap, sampled CVT.

    :data:`START_STEPS` steps of Lloyd's method on ``START_SAMPLES * n`` points drawn by
    area (times the density) on the surface: each point goes to its nearest site, each
    site to the mean of its points (a site with no point stays), then onto the surface.
    The exact CVT then starts from cells of about the size it will give them.
    """
    n = len(sites)
    weights = None if density is None else triangle_values(density, surface.vertices, surface.faces)
    # A stream apart from the random sites' (``initialise`` draws from ``seed``).
    rng = np.random.default_rng([seed, 1])
    points, _ = sample_by_area(surface.vertices, surface.faces, START_SAMPLES * n, rng, weights)
    frame = surface.frame
    out = np.array(sites, dtype=np.float64)
    for _ in range(START_STEPS):
        _, owner = cKDTree(out).query(points)
        count = np.bincount(owner, minlength=n)
        sums = np.column_stack([np.bincount(owner, points[:, k], minlength=n) for k in range(3)])
        some = count > 0
        out[some] = sums[some] / count[some, None]
        # Onto the surface: a mean of points on both sides of a thin part lies between
        # them, where the CVT could keep one cell round both.
        nearest, _ = surface._core.closest(frame.to_core(np.ascontiguousarray(out)))
        out = frame.points_to_input(np.asarray(nearest))
    return out


def _cvt(
    surface: Domain,
    sites: NDArray[np.float64],
    plan: FeatureSites | None,
    method: str,
    tol: float | None,
    max_iter: int,
    density: DensityLike = None,
) -> CVTResult:
    """The CVT of :func:`remesh`: :func:`hcvt.cvt`, or one holding the features' sites.

    With ``plan``, the last ``len(plan.points)`` sites do not move
    (:func:`hcvt.surface.features.constrained_cvt`).
    """
    if plan is None:
        return cvt(surface, sites, method, tol=tol, max_iter=max_iter, density=density)
    tol = _core.check_settings(method, "gap", tol, max_iter, 7)
    held = len(plan.points)
    return constrained_cvt(
        surface, sites, held, method, tol=tol, max_iter=max_iter, density=density
    )


def remesh(
    surface: Domain,
    n: int,
    *,
    seed: int = 0,
    method: str = "lbfgs",
    tol: float | None = REMESH_TOL,
    max_iter: int = 200,
    check: bool = False,
    features: float | None = None,
    tighten: bool = True,
    min_angle: float | None = None,
    density: DensityLike | str = None,
    border: bool = True,
) -> RemeshResult:
    """Remesh ``surface`` isotropically with exactly ``n`` vertices.

    Parameters
    ----------
    surface : Domain
        A triangle surface (:meth:`hcvt.Domain.from_surface`,
        ``hcvt.load_domain(path, surface=True)``).
    n : int
        The number of vertices, exactly.
    seed : int
        Seeds the initial sites (random by area, then spread by a few Lloyd steps over
        points sampled on the surface: :data:`START_STEPS`) and ``tighten``'s samples of
        the input.
    method : {"lbfgs", "lloyd"}
        The CVT's optimiser (:func:`hcvt.cvt`).
    tol : float or None
        The CVT's tolerance on the scale-free gap rule (default :data:`REMESH_TOL`, 1e-2:
        the least angle has saturated there); None for the rule's default. While
        the triangulation then has defects, the CVT goes on from the projected sites at
        a tolerance 4 times tighter, up to three times, within ``max_iter`` in all.
    max_iter : int
        The CVT's most iterations.
    check : bool
        Raise :class:`RemeshError` naming the cells where the triangulation is not a
        manifold mesh of the surface, instead of listing them in ``defects``.
    features : float or None
        Keep the sharp features: edges whose triangles' normals differ by more than this
        many degrees (in (0, 180)), and the border of an open surface, chained into curves.
        Curves shorter than one site spacing are dropped (a scanned mesh's short creases;
        a border loop that short too, so a hole that small is not kept).
        Their corners and sites about 0.7 spacings apart along them are held fixed through
        the CVT, so the triangulation runs along them (:mod:`hcvt.surface.features`; a
        segment of a curve missing from the triangles is a defect: where free sites that
        settled on the curve cause it, they are moved to the widest gaps and the CVT goes
        on at the same tolerance, :func:`hcvt.surface.features.move_intruders`). Held
        sites closer than 0.4 spacings to another are welded into it (at corners, and
        between curves within 15° of parallel: :func:`hcvt.surface.features.weld_sites`);
        held sites among cells that are not discs, or parting a segment's ends, are freed
        and moved to the widest gaps, their segments no longer required
        (:func:`hcvt.surface.features.release_sites`). None: no features (an open
        surface's border is still kept: ``border``).
    tighten : bool
        Then lower the Hausdorff distance to the surface (bunny, n = 5,000: 0.485% ->
        0.359% of the diagonal, for 17% of the remeshing's time; False to skip it):
        where the mesh is farthest from it (a crease, a tip), move a vertex along it, worst
        place first, while every moved triangle keeps its least angle and Q at or above
        ``min_angle`` and the mesh's least Q (:func:`hcvt.surface.tighten.tighten`; the
        faces are not changed; skipped while there are defects; feature and border
        vertices stay).
    min_angle : float or None
        The least angle (degrees, in [0, 60]) ``tighten`` may leave; None: the smaller of
        :data:`TIGHTEN_MIN_ANGLE` (30°) and the CVT mesh's own least angle (which then
        falls to 30° at most). Only with ``tighten``.
    density : "curvature", callable, Polynomial, array or None
        A density ρ > 0 on the surface for the CVT (:mod:`hcvt.density`): a callable of
        position, a :class:`hcvt.density.Polynomial`, or one value per vertex of the
        surface (linear on each triangle), e.g. :func:`hcvt.surface.curvature_density`.
        ``"curvature"``: that function's mild grading (:data:`REMESH_DENSITY_POWER`), the
        spacing smaller where the surface bends, where the chords leave it farthest (a
        lower Hausdorff distance for more time); uniform with ``features`` or an open
        surface's ``border`` (the held sites are spaced evenly).
        The spacing of the vertices follows ``ρ^(-1/4)`` (cells of dimension 2): for a
        spacing ``h(x)`` give ``ρ = h^-4``. The initial sites are drawn by area times
        ``ρ^(1/2)``. Still exactly ``n`` vertices. None: uniform.
    border : bool
        Keep an open surface's border (with ``features=None``; ``features`` keeps it
        anyway): its loops are held as feature curves are, corners where a loop turns by
        more than :data:`BORDER_CORNER_ANGLE`, sites about 0.7 spacings apart along it, so
        every loop longer than one spacing stays a border loop of the mesh with its
        vertices on it (the Stanford scan's five holes, n = 1,500: Hausdorff 0.61-0.72% of
        the diagonal against 2.8-3.0% free). False: the border is free, as the CVT leaves
        it: its cells are not a 1D diagram of the border, so a loop can close and a border
        cell meeting only two cells be in no triangle (named in ``defects``). No effect on
        a closed surface.

    Returns
    -------
    RemeshResult

    Raises
    ------
    ValueError
        ``surface`` is not a surface; ``features`` is not an angle in (0, 180) degrees, or
        the features take all ``n`` sites; ``min_angle`` is not in [0, 60] degrees, or is
        given with ``tighten=False``.
    RemeshError
        With ``check=True``: the triangulation has defects (module docs).

    Examples
    --------
    >>> import hcvt, trimesh
    >>> ball = trimesh.creation.icosphere(3)
    >>> out = hcvt.remesh(hcvt.Domain.from_surface(ball.vertices, ball.faces), 200)
    >>> len(out.vertices), out.quality.closed, out.quality.genus, out.defects
    (200, True, 0, [])
    """
    if not surface.is_surface:
        raise ValueError("remesh takes a surface (hcvt.Domain.from_surface)")
    check_min_angle(min_angle)
    if min_angle is not None and not tighten:
        raise ValueError(
            "min_angle is the least angle of tighten's moves; it was given with tighten=False"
        )
    start = time.perf_counter()
    input_topology = edge_topology(surface.faces, len(surface.vertices))
    plan = None if features is None else plan_feature_sites(surface, n, features)
    if plan is None and border and input_topology["border_loops"] > 0:
        plan = plan_feature_sites(surface, n, BORDER_CORNER_ANGLE, creases=False)
    density = _density(surface, density, plan is not None)
    held = 0 if plan is None else len(plan.points)
    sites = initialise(surface, n - held, method="random", seed=seed, density=density)
    if plan is not None:  # the free sites first, then the fixed ones on the features
        sites = np.vstack([sites, plan.points])
    if plan is None:  # (with features: their constrained CVT's exact Lloyd steps)
        sites = _spread(surface, sites, seed, density)
    run = _cvt(surface, sites, plan, method, tol, max_iter, density)
    iterations = run.iterations
    # Rounds after the first run: at most TIGHTER_ROUNDS that tighten the tol or move
    # intruders, and those that free held sites (each frees at least one) besides.
    rounds = freed = 0
    for round_ in range(_MOST_ROUNDS):
        # The CVT's own, computed with its final diagram (else afresh).
        rdt = run._triangulation or _core.restricted_delaunay(
            surface._core, surface.frame.to_core(run.sites)
        )
        faces = np.asarray(rdt["triangles"], dtype=np.intp)
        if plan is not None:
            faces = restore_segments(faces, run.sites, plan)
        defects = _defects(faces, n, np.asarray(rdt["repeated"]), input_topology)
        if plan is not None:
            defects += segment_defects(faces, plan, n)
        last = rounds == TIGHTER_ROUNDS or round_ == _MOST_ROUNDS - 1
        if not defects or tol is None or iterations >= max_iter or last:
            break
        # Held sites among cells that are not discs (or on an edge of three triangles),
        # or parting a feature segment's ends: free them (the CVT cannot move them) and
        # move them to the widest gaps (where they are the CVT has converged), same tol.
        stuck = _stuck_held(np.asarray(rdt["repeated"]), faces, n, held)
        if plan is not None:
            parting = intruding_sites(run.sites, faces, plan)
            stuck = np.union1d(stuck, parting[parting >= n - held])
        if plan is not None and len(stuck):
            plan = release_sites(plan, stuck - (n - held))
            # The free sites, the freed ones, then those still held (last, as before).
            still = np.setdiff1d(np.arange(n - held, n), stuck)
            order = np.concatenate([np.arange(n - held), stuck, still])
            again, _ = move_to_gaps(run.sites, faces, n - held, stuck.tolist())
            held, freed = len(plan.points), freed + len(stuck)
            run = _cvt(surface, again[order], plan, method, tol, max_iter - iterations, density)
            iterations += run.iterations
            continue
        # The only defect free sites cutting feature segments: move them, same tol.
        alone = plan is not None and len(defects) == 1
        moved = move_intruders(run.sites, faces, plan) if alone and plan else None
        if moved is None:
            # Cells that are not yet discs (the closed-ball property fails) in an early
            # stop: iterate on from the projected sites to a tighter gap.
            tol *= TIGHTER
        rounds += 1
        again = run.sites if moved is None else moved
        run = _cvt(surface, again, plan, method, tol, max_iter - iterations, density)
        iterations += run.iterations
    reference = (surface.vertices, surface.faces)
    vertices, moves = run.sites, 0
    if tighten and not defects:
        held_mask = np.arange(n) >= n - held  # the features' sites, last
        floor = min_angle
        if floor is None:
            floor = min(TIGHTEN_MIN_ANGLE, float(triangle_angles(vertices, faces).min()))
        tightened = tighten_vertices(
            vertices,
            faces,
            surface,
            fixed=held_mask,
            samples=max(30_000, TIGHTEN_SAMPLES_PER_VERTEX * n),
            seed=seed,
            min_angle=floor,
        )
        vertices, moves = tightened.vertices, tightened.moves
    seconds = time.perf_counter() - start
    if check and defects:
        raise RemeshError("restricted Delaunay triangulation: " + "; ".join(defects))
    # Computed when first read (_Lazy).
    quality: Any = partial(surface_quality, vertices, faces, reference)
    return RemeshResult(vertices, faces, quality, run, defects, seconds, iterations, moves, freed)


__all__ = ["RemeshError", "RemeshResult", "remesh"]
