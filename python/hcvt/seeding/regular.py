"""Regular CVTs beyond the paper: defect counts, best-posed lattices, defect relaxation.

The paper's most regular 2D result is a hand-posed clipped hexagonal lattice optimised by
L-BFGS (square 20 x 20, n = 1,033: mean G 0.08066, E 25.002). Its regularity comes from the
pose (orientation, offset, spacing) and from the absence of *defects*: interior cells whose
number of neighbours is not the lattice's (6 in 2D, 14 in 3D; 5-7 pairs in 2D). This
module finds the pose automatically and then lowers the energy below the lattice's local
minimum by moves aimed at defects and at the most irregular cells.

| step | function | what |
|---|---|---|
| defect measure | :func:`defects` | interior cells whose neighbour count is not 6 / 14 |
| pose search | :func:`posed_lattice` | exact-count lattice poses, by clipped energy |
| relaxation | :func:`relax_defects` | moves at defects, Newton, kept if E drops |
| entry point | :func:`regular_cvt` | pose search, CVT of the best poses, relaxation |

**What is taken from Lu et al. (2012) and what is new.** :func:`hcvt.global_monte_carlo`
(Lu et al.'s Monte-Carlo with minimisation) perturbs the sites around a *random* site,
minimises, and keeps the result if the energy dropped. :func:`relax_defects` keeps that
skeleton (perturb, minimise, accept on a drop at zero temperature) and changes three things:
the perturbation is *centred on a defect* or on one of the highest-G cells (where the energy
can fall; a random centre in a defect-free lattice interior is wasted work); a second kind
of move, the *transfer*, takes the site of one such cell out and puts it in at the midpoint
of a restricted Delaunay edge of another, which changes the local site count and so the
topology (a perturbation of a converged lattice falls back into the same basin); and the
minimisation is Newton's (:func:`hcvt.cvt`, ``method="newton"``) from the warm start,
a handful of diagrams per move instead of an L-BFGS run. The core has no fixed sites, so the
"patch" is re-optimised together with the whole; Newton's quadratic end game makes that
cheap: the sites far from the move are already converged.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from hcvt.diagram import Diagram, as_sites, voronoi
from hcvt.draw import Shows
from hcvt.errors import InvalidSitesError
from hcvt.geometry.domain import Domain
from hcvt.optimise import check_rule, cvt
from hcvt.seeding.hierarchy import hierarchical_cvt
from hcvt.seeding.initialisation import (
    RandomState,
    boundary_pieces,
    check_count,
    lattice_at,
    random_state,
)

#: Neighbours of an interior cell of the regular lattice: hexagon (2D), truncated octahedron (3D).
IDEAL_NEIGHBORS = {2: 6, 3: 14}
#: Hexagonal lattice basis (columns), nearest-neighbour distance 1: offsets are fractions of it.
HEX_BASIS = np.array([[1.0, 0.5], [0.0, np.sqrt(3.0) / 2.0]])
#: The hexagonal lattice repeats every 60 degrees.
HEX_PERIOD = np.pi / 3.0
#: A move is kept when it lowers E by more than this fraction of E (E's round-off is ~1e-15).
ACCEPT_REL = 1e-11
#: Default size of the pose search (:func:`posed_lattice`) and finalists, by dimension.
SEARCH = {
    2: {"orientations": 12, "offsets": 4, "refine": 4, "finalists": 3},
    3: {"orientations": 6, "offsets": 2, "refine": 2, "finalists": 2},
}
#: Stages of :attr:`RegularResult.history`.
STAGES = ("pose", "cvt", "move")
#: Starts of :func:`regular_cvt`: the best-posed lattice, or the paper's hierarchical method
#: from random sites (s maximal) or from a lattice (s = 1, its best in Tables 4-6).
STARTS = ("lattice", "hierarchical", "hierarchical-lattice")


# ----------------------------------------------------------------------------- defects
@dataclass(frozen=True)
class Defects:
    """Interior cells whose neighbour count differs from the regular lattice's.

    Attributes
    ----------
    counts : ndarray of intp, shape (n,)
        Neighbours of each cell (restricted Delaunay edges, :attr:`Diagram.neighbors`).
    interior : ndarray of bool, shape (n,)
        Cells with no part of the domain boundary (``boundary_measure == 0``).
    defective : ndarray of bool, shape (n,)
        Interior cells with ``counts != ideal``.
    deep : ndarray of bool, shape (n,)
        Interior cells whose neighbours are all interior too (a layer away from the
        boundary): defects there are dislocations of the bulk, not the boundary layer's
        reconstruction (the moves of :func:`relax_defects` often trade a few of the latter
        for lower energy).
    ideal : int
        6 (2D) or 14 (3D).
    """

    counts: NDArray[np.intp]
    interior: NDArray[np.bool_]
    defective: NDArray[np.bool_]
    deep: NDArray[np.bool_]
    ideal: int

    @property
    def number(self) -> int:
        """Number of defective interior cells."""
        return int(self.defective.sum())

    @property
    def interior_cells(self) -> int:
        """Number of interior cells."""
        return int(self.interior.sum())

    @property
    def fraction(self) -> float:
        """Defective interior cells over interior cells (0 when there are none)."""
        return self.number / self.interior_cells if self.interior_cells else 0.0

    @property
    def deep_number(self) -> int:
        """Number of defective cells among the deep ones (no boundary cell as neighbour)."""
        return int((self.defective & self.deep).sum())

    def summary(self) -> dict[str, float | int]:
        """``defects``, ``interior_cells``, ``defect_fraction`` and ``deep_defects``."""
        return {
            "defects": self.number,
            "interior_cells": self.interior_cells,
            "defect_fraction": self.fraction,
            "deep_defects": self.deep_number,
        }


def neighbor_counts(diagram: Diagram) -> NDArray[np.intp]:
    """Neighbours of each cell, shape (n,): its restricted Delaunay degree."""
    return np.bincount(diagram.neighbors.ravel(), minlength=diagram.n).astype(np.intp)


def defects(diagram: Diagram) -> Defects:
    """The defect measure of a diagram: interior cells without 6 (2D) / 14 (3D) neighbours.

    An interior cell is one with ``boundary_measure == 0``; boundary cells are left out,
    since no count is right for them. Cells of dimension 2 on the sphere are all interior
    and ideal with 6 neighbours (an icosahedral CVT has exactly 12 defects, its pentagons).
    """
    counts = neighbor_counts(diagram)
    ideal = IDEAL_NEIGHBORS[diagram.domain.cell_dim]
    interior = diagram.boundary_measure == 0
    # A cell is deep when no edge joins it to a boundary cell.
    i, j = diagram.neighbors.T
    touches = np.zeros(diagram.n, dtype=bool)
    touches[i[~interior[j]]] = True
    touches[j[~interior[i]]] = True
    return Defects(counts, interior, interior & (counts != ideal), interior & ~touches, ideal)


# --------------------------------------------------------------------------- pose search
@dataclass(frozen=True)
class Pose:
    """One exact-count lattice pose and its score.

    Attributes
    ----------
    sites : ndarray of float64, shape (n, d)
        The lattice points inside, L.
    rotation : ndarray, shape (d, d)
        Lattice axes as columns.
    offset : ndarray, shape (d,)
        A lattice point, L.
    spacing : float
        Nearest-neighbour distance, L.
    energy : float
        CVT energy of the clipped lattice (its diagram before any optimisation), L^(d+2).
    """

    sites: NDArray[np.float64]
    rotation: NDArray[np.float64]
    offset: NDArray[np.float64]
    spacing: float
    energy: float


def posed_lattice(
    domain: Domain,
    n: int,
    *,
    seed: int = 0,
    rng: RandomState = None,
    orientations: int | None = None,
    offsets: int | None = None,
    refine: int | None = None,
) -> list[Pose]:
    """Hexagonal (2D) or BCC (3D) lattices with exactly ``n`` sites, best first.

    Candidates are poses (orientation, offset); for each, the spacing giving exactly ``n``
    sites inside is found by bisection on the count (:func:`hcvt.seeding.initialisation.lattice_at`)
    and the pose is scored by the energy of its clipped lattice (one diagram, a few
    milliseconds per thousand sites). Coarse to fine:

    1. Orientations: 2D, ``orientations`` angles evenly over the 60 degrees of the lattice's
       symmetry with a phase from the seed, plus the angles that align lattice rows with
       the longest boundary edges (rows along an edge, or across it: ``+30°``); 3D,
       ``orientations`` random rotations from the seed plus the identity.
       Offsets: an ``offsets^d`` grid over the unit cell, phase from the seed.
    2. Around each of the ``refine`` best poses: the angle and half a grid step either
       side of it (3D: a turn of 0.05 rad about a random axis), each with the offset moved
       a quarter of a grid step either way along every axis (``3 · 2^d`` poses).

    Poses whose count jumps over ``n`` (a row reaching a straight edge all at once) drop out.

    Parameters
    ----------
    domain : Domain
    n : int
        Sites, at least 1.
    seed, rng
        Choose the candidate set (phases and 3D rotations); ``rng`` as in
        :func:`hcvt.initialise`.
    orientations, offsets, refine : int, optional
        Sizes of the search above; defaults :data:`SEARCH` of the dimension (2D 12, 4, 4:
        250 to 450 poses with the aligned angles; 3D 6, 2, 2: about 100, a 3D pose costing
        ten 2D ones).

    Returns
    -------
    list of Pose
        Every exact-count pose tried, lowest clipped energy first (ties by order tried).

    Raises
    ------
    ValueError
        Bad ``n`` or sizes, or no pose with exactly ``n`` sites.
    """
    n = check_count(n, domain.dim)
    orientations, offsets, refine = (
        SEARCH[domain.dim][k] if v is None else v
        for k, v in (("orientations", orientations), ("offsets", offsets), ("refine", refine))
    )
    if min(orientations, offsets) < 1 or refine < 0:
        raise ValueError(
            f"need orientations, offsets >= 1 and refine >= 0, got {orientations}, {offsets}, "
            f"{refine}"
        )
    generator = np.random.default_rng(random_state(seed, rng))
    search = _PoseSearch(domain, n)
    rotations, angle_step = _orientations(domain, orientations, generator)
    grid = _offset_grid(domain.dim, offsets, generator.random(domain.dim))
    for rotation in rotations:
        for fraction in grid:
            search.try_pose(rotation, fraction)
    # Refinement: halfway towards the grid neighbours of the best poses.
    for rotation, fraction, _ in search.best(refine):
        for turn in (-0.5, 0.0, 0.5):
            turned = _turn(rotation, turn * angle_step, domain.dim, generator)
            for shift in _offset_grid(domain.dim, 2, np.zeros(domain.dim)):
                search.try_pose(turned, fraction + (shift - 0.25) / offsets)
    if not search.poses:
        raise ValueError(f"no lattice pose has exactly {n} sites inside; try more orientations")
    return [pose for pose, _, _ in sorted(search.poses, key=lambda p: (p[0].energy, p[1]))]


class _PoseSearch:
    """Poses tried so far: (Pose, order tried, (rotation, fraction)) with exactly n sites."""

    def __init__(self, domain: Domain, n: int) -> None:
        self.domain, self.n = domain, n
        self.pieces = boundary_pieces(domain)
        cell_volume = {2: np.sqrt(3.0) / 2.0, 3: 0.5}[domain.dim]
        self.scale0 = float((domain.volume / n / cell_volume) ** (1.0 / domain.dim))
        self.poses: list[tuple[Pose, int, tuple[NDArray[np.float64], NDArray[np.float64]]]] = []
        self.tried = 0

    def try_pose(self, rotation: NDArray[np.float64], fraction: NDArray[np.float64]) -> None:
        """Score the pose whose offset is ``fraction`` of the unit cell from the centroid."""
        fraction = np.mod(fraction, 1.0)
        basis = HEX_BASIS if self.domain.dim == 2 else np.eye(3)
        offset = self.domain.centroid + self.scale0 * rotation @ (basis @ fraction)
        self.tried += 1
        found = lattice_at(self.domain, self.n, offset, rotation, pieces=self.pieces)
        if found is None:
            return
        energy = voronoi(self.domain, found.sites).energy
        pose = Pose(found.sites, rotation, offset, found.spacing, energy)
        self.poses.append((pose, self.tried, (rotation, fraction)))

    def best(self, k: int) -> list[tuple[NDArray[np.float64], NDArray[np.float64], float]]:
        ranked = sorted(self.poses, key=lambda p: (p[0].energy, p[1]))[:k]
        return [(rot, frac, pose.energy) for pose, _, (rot, frac) in ranked]


def _orientations(
    domain: Domain, count: int, rng: np.random.Generator
) -> tuple[list[NDArray[np.float64]], float]:
    """Rotation matrices to try and the angular step of the 2D grid (radians; 3D: 0.1)."""
    if domain.dim == 3:
        rotations = [np.eye(3)] + list(Rotation.random(count, rng=rng).as_matrix())
        return rotations, 0.1
    step = HEX_PERIOD / count
    angles = list((np.arange(count) + rng.random()) * step)
    angles += _aligned_angles(domain)
    unique: list[float] = []
    for angle in angles:  # drop repeats within 0.1 degree (modulo 60)
        if all(abs(_wrap(angle - a)) > np.radians(0.1) for a in unique):
            unique.append(angle)
    return [_rotation_2d(a) for a in unique], step


ALIGNED_EDGES = 6  # boundary directions, by total length, that lattice rows are aligned with


def _aligned_angles(domain: Domain) -> list[float]:
    """Angles (mod 60°) putting lattice rows along, or across, the longest edge directions."""
    segments = boundary_pieces(domain)
    vectors = segments[:, 1] - segments[:, 0]
    lengths = np.linalg.norm(vectors, axis=1)
    angles = np.mod(np.arctan2(vectors[:, 1], vectors[:, 0]), HEX_PERIOD)
    # Total length per direction, to 0.1 degree.
    keys = np.round(np.degrees(angles), 1)
    unique, inverse = np.unique(keys, return_inverse=True)
    totals = np.bincount(inverse, weights=lengths)
    top = unique[np.argsort(-totals, kind="stable")[:ALIGNED_EDGES]]
    return [float(np.radians(a + t)) % HEX_PERIOD for a in top for t in (0.0, 30.0)]


def _wrap(angle: float) -> float:
    """Angle difference modulo the hexagonal period, in (-30°, 30°]."""
    return float((angle + HEX_PERIOD / 2) % HEX_PERIOD - HEX_PERIOD / 2)


def _rotation_2d(angle: float) -> NDArray[np.float64]:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s], [s, c]])


def _turn(
    rotation: NDArray[np.float64], angle: float, dim: int, rng: np.random.Generator
) -> NDArray[np.float64]:
    """``rotation`` turned by ``angle``: about the normal (2D) or a random axis (3D)."""
    if angle == 0.0:
        return rotation
    if dim == 2:
        return _rotation_2d(angle) @ rotation
    axis = rng.normal(size=3)
    turn = Rotation.from_rotvec(angle * axis / np.linalg.norm(axis)).as_matrix()
    return turn @ rotation


def _offset_grid(dim: int, k: int, phase: NDArray[np.float64]) -> NDArray[np.float64]:
    """``k^dim`` fractions of the unit cell, ``(i + phase) / k`` per axis, shape (k^dim, dim)."""
    axes = [(np.arange(k) + phase[a]) / k for a in range(dim)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, dim)


# ----------------------------------------------------------------------- relaxation
@dataclass
class Relaxation:
    """Outcome of :func:`relax_defects`.

    Attributes
    ----------
    sites : ndarray, shape (n, d)
        The lowest-energy CVT found, L.
    diagram : Diagram
        Its diagram.
    history : dict of str to ndarray
        One entry per move (index 0: the start): ``energy`` (of the CVT the move reached),
        ``best_energy`` (non-increasing), ``mean_G`` and ``defects`` (of the best so far),
        ``kind`` (``"start"``, ``"shake"``, ``"transfer"``), ``accepted``, ``seconds``.
    moves : int
        Moves tried.
    accepted : int
        Moves kept.
    stop_reason : str
        ``"budget"`` (``moves`` spent) or ``"patience"`` (that many moves in a row failed).
    """

    sites: NDArray[np.float64]
    diagram: Diagram
    history: dict[str, NDArray[Any]] = field(repr=False)
    moves: int
    accepted: int
    stop_reason: str


MOVE_KINDS = ("shake", "transfer")
# Shake: sites within SHAKE_RADIUS h (a uniform draw in this range) of the target move by up
# to SHAKE_STEP h per axis; Lu et al.'s scheme uses radius 2 h and step 0.5 h (baselines.py).
SHAKE_RADIUS = (1.5, 3.0)
SHAKE_STEP = 0.4


def relax_defects(
    domain: Domain,
    sites: ArrayLike,
    *,
    moves: int = 60,
    patience: int | None = None,
    worst: int = 40,
    seed: int = 0,
    rng: RandomState = None,
    method: str = "newton",
    rule: str = "gap",
    tol: float | None = None,
    max_iter: int = 200,
) -> Relaxation:
    """Lower the CVT energy by moves aimed at defects and irregular cells (module docs).

    Each move picks a target at random (seeded) among the defective interior cells
    (:func:`defects`) and the ``worst`` cells of highest G, then either

    - *shakes*: moves every site within ``r h`` of the target (``r`` uniform in
      :data:`SHAKE_RADIUS`) by up to :data:`SHAKE_STEP` ``h`` per axis (moves that would
      leave the domain are not made), or
    - *transfers*: puts the target's site at the midpoint of a restricted Delaunay edge of
      another target (skipped when that midpoint is outside the domain),

    re-optimises all sites from there (``method``, default Newton) and keeps the result if
    its energy is lower by more than :data:`ACCEPT_REL` of E. Stops after ``moves`` moves or
    ``patience`` failed moves in a row. ``h = (V / n)^(1/d)``.

    Parameters
    ----------
    domain : Domain
    sites : array_like, shape (n, d)
        Start; re-optimised first (a converged CVT costs one or two diagrams).
    moves : int
        Budget of moves.
    patience : int, optional
        Failed moves in a row that end the search; default no limit.
    worst : int
        Highest-G cells added to the targets.
    seed, rng
        Seed the moves; ``rng`` as in :func:`hcvt.initialise`.
    method, rule, tol, max_iter
        The minimisation of each move (:func:`hcvt.cvt`).

    Returns
    -------
    Relaxation
    """
    if moves < 0 or worst < 0 or (patience is not None and patience < 1):
        raise ValueError(
            f"need moves >= 0, worst >= 0, patience >= 1; got {moves}, {worst}, {patience}"
        )
    generator = np.random.default_rng(random_state(seed, rng))
    start = time.perf_counter()
    points = as_sites(sites, domain.dim)
    best = cvt(domain, points, method, rule=rule, tol=tol, max_iter=max_iter)
    n, dim = best.sites.shape
    h = (domain.volume / n) ** (1.0 / dim)
    records: list[tuple[float, float, float, int, str, bool, float]] = []

    def record(energy: float, kind: str, accepted: bool) -> None:
        count = defects(best.diagram).number
        seconds = time.perf_counter() - start
        records.append((energy, best.energy, best.mean_G, count, kind, accepted, seconds))

    record(best.energy, "start", True)
    failed, stop_reason = 0, "budget"
    for _ in range(moves):
        if patience is not None and failed >= patience:
            stop_reason = "patience"
            break
        kind = MOVE_KINDS[int(generator.integers(len(MOVE_KINDS)))]
        trial_sites = _move(domain, best.diagram, kind, worst, h, generator)
        trial = None
        if trial_sites is not None:
            try:
                trial = cvt(domain, trial_sites, method, rule=rule, tol=tol, max_iter=max_iter)
            except InvalidSitesError:  # two sites made to coincide: not a move
                trial = None
        energy = np.inf if trial is None else trial.energy
        accepted = trial is not None and energy < best.energy * (1.0 - ACCEPT_REL)
        if accepted and trial is not None:
            best, failed = trial, 0
        else:
            failed += 1
        record(energy, kind, accepted)
    columns = list(zip(*records, strict=True))
    history = {
        "energy": np.asarray(columns[0], dtype=np.float64),
        "best_energy": np.asarray(columns[1], dtype=np.float64),
        "mean_G": np.asarray(columns[2], dtype=np.float64),
        "defects": np.asarray(columns[3], dtype=np.int64),
        "kind": np.asarray(columns[4]),
        "accepted": np.asarray(columns[5], dtype=bool),
        "seconds": np.asarray(columns[6], dtype=np.float64),
    }
    return Relaxation(
        sites=best.sites,
        diagram=best.diagram,
        history=history,
        moves=len(records) - 1,
        accepted=int(history["accepted"][1:].sum()),
        stop_reason=stop_reason,
    )


def targets(diagram: Diagram, worst: int) -> NDArray[np.intp]:
    """Cells moves aim at, sorted: defective interior cells and the ``worst`` highest-G cells."""
    g = np.nan_to_num(diagram.G, nan=-np.inf)
    highest = np.argsort(-g, kind="stable")[:worst]
    return np.union1d(np.flatnonzero(defects(diagram).defective), highest).astype(np.intp)


def _move(
    domain: Domain,
    diagram: Diagram,
    kind: str,
    worst: int,
    h: float,
    rng: np.random.Generator,
) -> NDArray[np.float64] | None:
    """Sites after one move of ``kind`` (module docs), or None when it cannot be made."""
    aims = targets(diagram, worst)
    if len(aims) == 0:
        return None
    sites = diagram.sites.copy()
    target = int(aims[rng.integers(len(aims))])
    if kind == "shake":
        radius = rng.uniform(*SHAKE_RADIUS) * h
        near = np.flatnonzero(np.sum((sites - sites[target]) ** 2, axis=1) <= radius**2)
        moved = sites[near] + rng.uniform(
            -SHAKE_STEP * h, SHAKE_STEP * h, (len(near), sites.shape[1])
        )
        inside = domain.contains(moved)
        sites[near[inside]] = moved[inside]
        return sites
    other = int(aims[rng.integers(len(aims))])
    across, _ = diagram.cell_neighbors(other)
    across = across[across != target]
    if other == target or len(across) == 0:
        return None
    midpoint = 0.5 * (sites[other] + sites[int(across[rng.integers(len(across))])])
    if not domain.contains(midpoint[None])[0]:
        return None
    sites[target] = midpoint
    return sites


# ---------------------------------------------------------------------- entry point
@dataclass(repr=False)
class RegularResult(Shows):
    """Outcome of :func:`regular_cvt`; shows its diagram in Jupyter.

    Attributes
    ----------
    sites : ndarray, shape (n, d)
        Final sites, L.
    diagram : Diagram
        Their diagram.
    history : dict of str to ndarray
        One entry per step, in order: ``stage`` (``"pose"`` for each lattice pose scored,
        ``"cvt"`` for each finalist's CVT, ``"move"`` for each relaxation move), ``energy``
        (the clipped lattice's, the CVT's, the move's CVT), ``best_energy`` (lowest CVT energy
        so far; NaN during the pose search), ``defects`` (interior defects of that best),
        ``accepted`` and ``seconds`` (since the start).
    pose : Pose or None
        The pose whose CVT was kept (None when ``start="hierarchical"``).
    start_energy : float
        Energy of the CVT the relaxation started from (best posed lattice or hierarchical).
    start_mean_G : float
        Its mean G.
    start_defects : int
        Its interior defects.
    relaxation : Relaxation
        The relaxation's own record.
    seconds : float
        Wall time.
    """

    sites: NDArray[np.float64]
    diagram: Diagram
    history: dict[str, NDArray[Any]] = field(repr=False)
    pose: Pose | None
    start_energy: float
    start_mean_G: float  # noqa: N815 (the paper's G)
    start_defects: int
    relaxation: Relaxation = field(repr=False)
    seconds: float

    @property
    def mean_G(self) -> float:  # noqa: N802 (the paper's G)
        """Mean G of the final diagram."""
        return self.diagram.mean_G

    @property
    def energy(self) -> float:
        """CVT energy of the final sites, L^(d+2)."""
        return self.diagram.energy

    @property
    def defects(self) -> Defects:
        """Interior defects of the final diagram."""
        return defects(self.diagram)

    def __repr__(self) -> str:
        start = "lattice" if self.pose is not None else "hierarchical"
        return (
            f"<hcvt.RegularResult n={len(self.sites)} d={self.sites.shape[1]} from a {start} "
            f"start with {self.start_defects} defects, now {self.defects.number}, "
            f"{self.seconds:.3g} s; mean G={self.mean_G:.6f}>"
        )


def regular_cvt(
    domain: Domain,
    n: int,
    *,
    seed: int = 0,
    rng: RandomState = None,
    start: str = "lattice",
    orientations: int | None = None,
    offsets: int | None = None,
    refine: int | None = None,
    finalists: int | None = None,
    moves: int = 60,
    patience: int | None = None,
    method: str = "newton",
    rule: str = "gap",
    tol: float | None = None,
    max_iter: int = 10_000,
) -> RegularResult:
    """A CVT of exactly ``n`` sites more regular than the paper's methods reach (module docs).

    1. ``start="lattice"`` (default): :func:`posed_lattice` ranks exact-count hexagonal/BCC
       poses by their clipped energy; the ``finalists`` best are optimised by ``method``
       (Newton by default) and the lowest energy is kept. ``start="hierarchical"``:
       :func:`hcvt.hierarchical_cvt` from random sites (maximal s) with ``method`` instead;
       ``"hierarchical-lattice"``: from a lattice with s = 1 (the paper's best rows).
    2. :func:`relax_defects` with ``moves`` moves lowers the energy further.

    Parameters
    ----------
    domain : Domain
    n : int
        Sites, at least 1.
    seed, rng
        Choose the pose candidates, the hierarchy's random sites and the moves; ``rng``
        as in :func:`hcvt.initialise`. Deterministic for a seed.
    start : {"lattice", "hierarchical", "hierarchical-lattice"}
    orientations, offsets, refine
        Size of the pose search (:func:`posed_lattice`); defaults by dimension (:data:`SEARCH`).
    finalists : int, optional
        Best poses optimised to a CVT: 3 (2D) or 2 (3D) by default.
    moves, patience
        Relaxation budget (:func:`relax_defects`); ``moves=0`` stops after step 1.
    method, rule, tol, max_iter
        Every CVT (:func:`hcvt.cvt`): Newton under the scale-free gap rule by default; pass
        ``rule="paper"`` for figures set beside the paper's.

    Returns
    -------
    RegularResult
        ``sites``, ``diagram``, ``history``, ``pose``, ``defects``, the start's energy and
        defects, and the relaxation's record.
    """
    check_rule(rule)
    n = check_count(n, domain.dim)
    if start not in STARTS:
        raise ValueError(f"start must be one of {STARTS}, got {start!r}")
    if finalists is None:
        finalists = SEARCH[domain.dim]["finalists"]
    if finalists < 1:
        raise ValueError(f"finalists must be at least 1, got {finalists}")
    if moves < 0:
        raise ValueError(f"need moves >= 0, got {moves}")
    clock = time.perf_counter()
    generator = np.random.default_rng(random_state(seed, rng))
    rows: list[tuple[str, float, float, int, bool, float]] = []
    pose: Pose | None = None
    if start == "lattice":
        poses = posed_lattice(
            domain,
            n,
            rng=generator,
            orientations=orientations,
            offsets=offsets,
            refine=refine,
        )
        seconds = time.perf_counter() - clock
        rows += [("pose", p.energy, np.nan, -1, False, seconds) for p in poses]
        best = None
        for candidate in poses[:finalists]:
            run = cvt(domain, candidate.sites, method, rule=rule, tol=tol, max_iter=max_iter)
            better = best is None or run.energy < best.energy
            if better:
                best, pose = run, candidate
            assert best is not None
            rows.append(
                (
                    "cvt",
                    run.energy,
                    best.energy,
                    defects(best.diagram).number,
                    better,
                    time.perf_counter() - clock,
                )
            )
        assert best is not None
        sites, start_diagram = best.sites, best.diagram
    else:
        from_lattice = start == "hierarchical-lattice"
        hier = hierarchical_cvt(
            domain,
            n,
            1 if from_lattice else None,
            init="lattice" if from_lattice else "random",
            rng=generator,
            rule=rule,
            tol=tol,
            max_iter=max_iter,
            method=method,
        )
        sites, start_diagram = hier.sites, hier.diagram
        rows.append(
            (
                "cvt",
                hier.diagram.energy,
                hier.diagram.energy,
                defects(hier.diagram).number,
                True,
                time.perf_counter() - clock,
            )
        )
    offset = time.perf_counter() - clock
    relaxed = relax_defects(
        domain,
        sites,
        moves=moves,
        patience=patience,
        rng=generator,
        method=method,
        rule=rule,
        tol=tol,
        max_iter=max_iter,
    )
    h = relaxed.history
    rows += [
        ("move", e, b, int(d), bool(a), s + offset)
        for e, b, d, a, s in zip(
            h["energy"][1:],
            h["best_energy"][1:],
            h["defects"][1:],
            h["accepted"][1:],
            h["seconds"][1:],
            strict=True,
        )
    ]
    columns = list(zip(*rows, strict=True))
    history = {
        "stage": np.asarray(columns[0]),
        "energy": np.asarray(columns[1], dtype=np.float64),
        "best_energy": np.asarray(columns[2], dtype=np.float64),
        "defects": np.asarray(columns[3], dtype=np.int64),
        "accepted": np.asarray(columns[4], dtype=bool),
        "seconds": np.asarray(columns[5], dtype=np.float64),
    }
    return RegularResult(
        sites=relaxed.sites,
        diagram=relaxed.diagram,
        history=history,
        pose=pose,
        start_energy=float(start_diagram.energy),
        start_mean_G=float(start_diagram.mean_G),
        start_defects=defects(start_diagram).number,
        relaxation=relaxed,
        seconds=time.perf_counter() - clock,
    )


__all__ = [
    "IDEAL_NEIGHBORS",
    "Defects",
    "Pose",
    "RegularResult",
    "Relaxation",
    "defects",
    "neighbor_counts",
    "posed_lattice",
    "regular_cvt",
    "relax_defects",
]
