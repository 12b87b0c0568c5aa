"""Sites in spatial partitions with halos: the work of one partition, on any process.

Everything here is a plain function of numpy arrays (and a :class:`~hcvt.geometry.domain.Domain`),
run by :mod:`hcvt.distributed` as dask tasks; nothing imports dask. DESIGN §10:

- :func:`kd_split` cuts space by median planes until every part holds at most a target
  number of sites. The planes depend on the sites and the target only, never on the
  number of workers, and :meth:`KdSplit.locate` assigns any point to a part by position.
- A :class:`Part` holds its sites with their rows in the whole problem, in increasing row
  order (or along a Morton curve, :func:`along_curve`), and per-row arrays (gradient,
  L-BFGS pairs, ...) that travel with the sites.
- :func:`part_cells` computes a part's cells among its own sites and a halo of other
  parts' sites (:func:`halo_slice`) within a distance ``rho`` of its sites' box. The core
  reports each cell's *reach*: the cell is the single-process cell, bit for bit, whenever
  every site within that distance of its site is present (``clipped_cells`` in
  ``hcvt-core/src/diagram/mod.rs``). Cells whose reach the halo does not cover are
  computed again with a wider halo; none is assumed right.
- Sums are taken per part with :func:`math.fsum` (correctly rounded, so in any order),
  then over the parts in part order (:mod:`hcvt.distributed`), so they do not depend on
  which worker did what.
"""

from __future__ import annotations

import math
import resource
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

import hcvt._core as _core
from hcvt.density import DEFAULT_QUADRATURE_DEGREE, DensityLike, core_arguments
from hcvt.geometry.domain import Domain, wrapped

#: A halo covers a cell when the cell's reach is below this fraction of the halo width:
#: the halo is selected by comparing coordinates with the part's box widened by ``rho``,
#: and this margin absorbs the rounding of that comparison.
COVER_FRACTION = 1.0 - 1e-9
#: A cell not certified is computed again among the sites within this multiple of its
#: reach: a missing site usually leaves a cell larger, and its reach with it, so the
#: second try rarely needs a third.
BALL_FACTOR = 1.5


@dataclass(frozen=True)
class KdSplit:
    """Median planes cutting space into ``parts`` boxes; part numbers follow the tree.

    Attributes
    ----------
    axis : ndarray of intp, shape (m,)
        Axis of each inner node's plane.
    value : ndarray of float64, shape (m,)
        Its position: points with ``x[axis] < value`` go left, the others right.
    children : ndarray of intp, shape (m, 2)
        Left and right child: an inner node ``>= 0``, or part ``p`` as ``-1 - p``.
    parts : int
        Number of parts (leaves), numbered left to right.
    """

    axis: NDArray[np.intp]
    value: NDArray[np.float64]
    children: NDArray[np.intp]
    parts: int

    def locate(self, points: NDArray[np.float64]) -> NDArray[np.intp]:
        """The part of each point (m, d), shape (m,), by position alone."""
        out = np.zeros(len(points), dtype=np.intp)
        if len(self.axis) == 0:
            return out
        active = np.arange(len(points))
        node = np.zeros(len(points), dtype=np.intp)
        while active.size:
            right = points[active, self.axis[node]] >= self.value[node]
            nxt = self.children[node, right.astype(np.intp)]
            leaf = nxt < 0
            out[active[leaf]] = -1 - nxt[leaf]
            active, node = active[~leaf], nxt[~leaf]
        return out


def kd_split(sites: NDArray[np.float64], target: int) -> KdSplit:
    """Median planes along the longest side until each part holds at most ``target`` sites.

    The plane of a node is the median coordinate of its sites along the longest side of
    their box (the next longer side when all share one coordinate there); the sites below
    it go left. Depends on the sites and ``target`` only.
    """
    return _kd_build(sites, target)[0]


def split_parts(sites: NDArray[np.float64], target: int) -> tuple[KdSplit, list[Part]]:
    """:func:`kd_split` of ``sites`` and :func:`make_parts` under it, in one pass.

    The rows of each part are those the split's recursion sent to its leaf (the same test
    as :meth:`KdSplit.locate`), so no point is located again (on 4M sites the locating
    and sorting took 0.5 of the client's 1.5 s of CPU).
    """
    split, leaves = _kd_build(sites, target)
    return split, [Part(p, rows.astype(np.int64), sites[rows]) for p, rows in enumerate(leaves)]


def _kd_build(sites: NDArray[np.float64], target: int) -> tuple[KdSplit, list[NDArray[np.intp]]]:
    """:func:`kd_split` and the rows of each part, increasing."""
    if target < 1:
        raise ValueError(f"sites_per_partition must be >= 1, got {target}")
    axes: list[int] = []
    values: list[float] = []
    children: list[list[int]] = []
    leaves: list[NDArray[np.intp]] = []

    def build(rows: NDArray[np.intp]) -> int:
        points = sites[rows] if len(rows) > target else None
        plane = _median_plane(points) if points is not None else None
        if plane is None:
            leaves.append(rows)
            return -len(leaves)  # part len(leaves) - 1, as -1 - p
        assert points is not None
        axis, value = plane
        node = len(axes)
        axes.append(axis)
        values.append(value)
        children.append([0, 0])
        below = points[:, axis] < value
        del points
        children[node][0] = build(rows[below])
        children[node][1] = build(rows[~below])
        return node

    build(np.arange(len(sites), dtype=np.intp))
    split = KdSplit(
        axis=np.asarray(axes, dtype=np.intp),
        value=np.asarray(values, dtype=np.float64),
        children=np.asarray(children, dtype=np.intp).reshape(-1, 2),
        parts=len(leaves),
    )
    return split, leaves


def bounds(points: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(lo, hi)`` of ``points`` (m >= 1, d), each shape (d,): ``min``/``max`` over axis 0.

    Column by column: numpy reduces a strided column of an (m, d) array with its
    vectorised loop, 20x faster than ``points.min(axis=0)`` (4M 2D sites: 5 ms against
    115 ms); the values are the same.
    """
    lo = np.array([points[:, k].min() for k in range(points.shape[1])])
    hi = np.array([points[:, k].max() for k in range(points.shape[1])])
    return lo, hi


def _median_plane(points: NDArray[np.float64]) -> tuple[int, float] | None:
    """``(axis, value)`` splitting ``points`` in two non-empty halves, or None."""
    lo, hi = bounds(points)
    extent = hi - lo
    for axis in np.argsort(-extent, kind="stable"):
        coords = points[:, axis]
        # The element a sort would put in the middle, found in linear time.
        middle = len(coords) // 2
        value = np.partition(coords, middle)[middle]
        if value == coords.min():
            above = coords[coords > value]
            if above.size == 0:
                continue
            value = above.min()
        return int(axis), float(value)
    return None


@dataclass(frozen=True)
class Torus:
    """The periodic axes of a box (DESIGN §14): halos that wrap across its sides.

    A site stands for all its images ``x + k∘L``. The halos are selected on the sites
    wrapped into ``[lo, hi)`` (:meth:`wrap`, as the core wraps them), where the images
    with ``k`` in ``{-1, 0, 1}`` along the periodic axes hold the nearest image of every
    site to any point of the box and every image inside a box that overlaps it and is
    shorter than a period (a longer one takes every site along that axis).

    Attributes
    ----------
    lo, hi : ndarray, shape (d,)
        The box, L.
    periodic : ndarray of bool, shape (d,)
        Which axes are periodic.
    """

    lo: NDArray[np.float64]
    hi: NDArray[np.float64]
    periodic: NDArray[np.bool_]

    @classmethod
    def of(cls, domain: Domain) -> Torus | None:
        """The torus of a box periodic along some axis, else None."""
        if not any(domain.periodic):
            return None
        lo, hi = domain.bounds
        return cls(lo, hi, np.asarray(domain.periodic, dtype=bool))

    @property
    def periods(self) -> NDArray[np.float64]:
        """``hi - lo`` along the periodic axes, 0 along the others, shape (d,)."""
        return np.where(self.periodic, self.hi - self.lo, 0.0)

    def wrap(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """``points`` (m, d) moved by whole periods into ``[lo, hi)`` (``Domain.wrap``)."""
        return wrapped(points, self.lo, self.hi, self.periodic)

    def shifts(self) -> NDArray[np.float64]:
        """``k∘L`` for every ``k`` in ``{-1, 0, 1}`` along the periodic axes, (s, d)."""
        steps = [np.array([-1.0, 0.0, 1.0]) if p else np.zeros(1) for p in self.periodic]
        grid = np.stack(np.meshgrid(*steps, indexing="ij"), axis=-1).reshape(-1, len(steps))
        return np.asarray(grid * self.periods)

    def in_box(
        self, points: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64]
    ) -> NDArray[np.bool_]:
        """Whether an image of each of ``points`` (m, d) lies in ``[lo, hi]``, shape (m,).

        The box is a product: along each axis separately, some image in its interval.
        """
        w = self.wrap(points)
        inside = np.ones(len(w), dtype=bool)
        for k in range(w.shape[1]):
            period = self.hi[k] - self.lo[k]
            if self.periodic[k] and hi[k] - lo[k] >= period:
                continue
            steps = (-period, 0.0, period) if self.periodic[k] else (0.0,)
            inside &= np.any([(w[:, k] + s >= lo[k]) & (w[:, k] + s <= hi[k]) for s in steps], 0)
        return inside

    def overlaps(
        self,
        box: tuple[NDArray[np.float64], NDArray[np.float64]],
        lo: NDArray[np.float64],
        hi: NDArray[np.float64],
    ) -> bool:
        """Whether an image of ``box`` (of wrapped sites) meets ``[lo, hi]``."""
        return any(
            bool(np.all(box[0] + s <= hi) and np.all(box[1] + s >= lo)) for s in self.shifts()
        )


def box_of(part: Part, torus: Torus | None) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(lo, hi)`` of ``part``'s sites, wrapped into a periodic box's ``torus``."""
    if torus is None or len(part.sites) == 0:
        return part.box()
    wrapped = torus.wrap(part.sites)
    return bounds(wrapped)


@dataclass
class Part:
    """One partition's sites and the per-row arrays that travel with them.

    Attributes
    ----------
    index : int
        Part number in the :class:`KdSplit`.
    rows : ndarray of int64, shape (k,)
        Row of each site in the whole problem, increasing unless ``along_curve``.
    sites : ndarray of float64, shape (k, d)
        The sites, L.
    fields : dict of str to ndarray
        Per-row arrays, first axis ``k`` (or, for L-BFGS pairs, shape (m, k, d)).
    along_curve : bool
        The rows are in :func:`spatial_order` of the sites (:func:`along_curve`): the
        core's visiting order, so a part's cells come back in the part's order as they are.
    """

    index: int
    rows: NDArray[np.int64]
    sites: NDArray[np.float64]
    fields: dict[str, NDArray[Any]] = field(default_factory=dict)
    along_curve: bool = False

    def box(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(lo, hi)`` of the sites, each shape (d,); empty part: an inverted box."""
        if len(self.sites) == 0:
            d = self.sites.shape[1]
            return np.full(d, np.inf), np.full(d, -np.inf)
        return bounds(self.sites)


def make_parts(sites: NDArray[np.float64], split: KdSplit) -> list[Part]:
    """The parts of ``sites`` (n, d) under ``split``, rows in increasing order."""
    where = split.locate(sites)
    order = np.argsort(where, kind="stable")
    ends = np.searchsorted(where[order], np.arange(split.parts + 1))
    return [
        Part(p, order[a:b].astype(np.int64), sites[order[a:b]])
        for p, (a, b) in enumerate(zip(ends[:-1], ends[1:], strict=True))
    ]


def along_curve(part: Part) -> Part:
    """``part`` with its rows (sites, fields) in :func:`spatial_order`, the core's visit.

    A diagram's parts are put so once, on their workers: the first round's cells then come
    back from the core in the part's order, instead of being moved back into row order
    (0.8 s of CPU per 1M cells, a fifth of a part's work, measured in-process).
    """
    order = spatial_order(part.sites)
    fields = {k: (v[:, order] if k in ("s", "y") else v[order]) for k, v in part.fields.items()}
    return Part(part.index, part.rows[order], part.sites[order], fields, along_curve=True)


def halo_slice(
    part: Part, lo: NDArray[np.float64], hi: NDArray[np.float64], torus: Torus | None = None
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Rows and sites of ``part`` inside the closed box ``[lo, hi]``.

    In a periodic box's ``torus``: an image of them inside (the sites as the part holds them).
    """
    if torus is not None:
        inside = torus.in_box(part.sites, lo, hi)
    else:
        inside = np.all((part.sites >= lo) & (part.sites <= hi), axis=1)
    return part.rows[inside], part.sites[inside]


@dataclass
class PartCells:
    """A part's cells, one row per own site (in the order of :attr:`Part.rows`).

    Attributes
    ----------
    arrays : dict of str to ndarray
        ``moments`` (k, d + 2) (and ``weighted``, with a density) as the core returned
        them, in its frame, about the sites; in L, made from them (:func:`cell_fields`):
        ``volume``, ``mass``, ``centroid``, ``second_moment``, ``G``, ``energy_terms``,
        ``first`` (moments about the sites, ρ-weighted with a density as ``mass``,
        ``centroid`` and ``energy_terms``; the gradient is ``-2 first``, exactly, but on
        the sphere, where ``gradient`` is kept), ``boundary_measure``, and the faces in
        CSR layout ``neighbor_offsets`` (k + 1,), ``neighbor_sites`` (problem rows),
        ``neighbor_measures``.
    reach : ndarray, shape (k,)
        Distance from each site within which its cell read the sites, L.
    certified : ndarray of bool, shape (k,)
        Whether the halo held every site within the reach (the cell is then exact).
    halo : int
        Sites of other parts in the last halo.
    computed : int
        Cells computed in the last round.
    sites : ndarray, shape (k, d)
        The own sites (for the box of the cells not certified).
    """

    arrays: dict[str, NDArray[Any]]
    reach: NDArray[np.float64]
    certified: NDArray[np.bool_]
    halo: int = 0
    computed: int = 0
    sites: NDArray[np.float64] | None = None

    def balls(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Centre (k, d) and radius (k,) of the next halo of each cell not certified."""
        bad = ~self.certified
        assert self.sites is not None
        return self.sites[bad], BALL_FACTOR * self.reach[bad]

    def status(self) -> Status:
        """What the client needs to grow the halo of the cells not certified."""
        bad = ~self.certified
        if not bad.any() or self.sites is None:
            return Status(0, self.computed, self.halo, None, None)
        centres, radii = self.balls()
        return Status(
            int(bad.sum()),
            self.computed,
            self.halo,
            (centres - radii[:, None]).min(axis=0),
            (centres + radii[:, None]).max(axis=0),
        )


@dataclass
class Status:
    """A part's round: cells not certified and the box of their next halo; work done."""

    uncertified: int
    computed: int
    halo: int
    lo: NDArray[np.float64] | None
    hi: NDArray[np.float64] | None
    #: Energy, sum of G and non-empty cells, once every cell is certified (if asked).
    partial: tuple[float, float, int] | None = None


def empty_cells(d: int) -> PartCells:
    """The cells of a part of no sites."""
    arrays = {
        key: np.zeros((0, d) if key in ("centroid", "first") else 0)
        for key in (*CELL_FIELDS, "first", "boundary_measure", "neighbor_measures")
    }
    arrays["moments"] = np.zeros((0, d + 2))
    arrays["neighbor_offsets"] = np.zeros(1, dtype=np.intp)
    arrays["neighbor_sites"] = np.zeros(0, dtype=np.intp)
    return PartCells(arrays, np.zeros(0), np.zeros(0, dtype=bool))


def ball_slice(
    part: Part,
    centres: NDArray[np.float64],
    radii: NDArray[np.float64],
    torus: Torus | None = None,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Rows and sites of ``part`` within ``radii`` of any of ``centres``, and maybe more.

    In a periodic box's ``torus``: an image of them, ``centres`` wrapped.
    """
    near = _in_torus_balls(part.sites, centres, radii, torus)
    return part.rows[near], part.sites[near]


def _in_torus_balls(
    points: NDArray[np.float64],
    centres: NDArray[np.float64],
    radii: NDArray[np.float64],
    torus: Torus | None,
) -> NDArray[np.intp]:
    """:func:`_in_balls`, in a periodic box's ``torus`` by the images of ``centres``.

    The images of the (wrapped) centres next to the box hold the nearest image of every
    wrapped point.
    """
    if torus is None:
        return _in_balls(points, centres, radii)
    wrapped = torus.wrap(points)
    found = [_in_balls(wrapped, centres + s, radii) for s in torus.shifts()]
    return np.unique(np.concatenate(found)).astype(np.intp)


def _in_balls(
    points: NDArray[np.float64], centres: NDArray[np.float64], radii: NDArray[np.float64]
) -> NDArray[np.intp]:
    """Indices of ``points`` (m, d) within ``radii`` (c,) of any of ``centres`` (c, d), or more.

    Increasing.

    The balls are grouped by radius into powers of two; each group answers one
    nearest-centre query per point within its largest radius: a superset of the points in
    the balls (which is all a halo needs), in memory linear in the points. (Listing each
    ball's points took more than 2 GB on a 10M-site run: the balls overlap.)
    """
    if len(points) == 0 or len(centres) == 0:
        return np.zeros(0, dtype=np.intp)
    near = _near_balls(points, centres, radii)
    take = np.zeros(len(near), dtype=bool)
    group = np.ceil(np.log2(radii)).astype(int)
    for g in np.unique(group):
        members = group == g
        bound = float(radii[members].max())
        distance, _ = cKDTree(centres[members]).query(
            points[near], distance_upper_bound=bound * (1 + 1e-12)
        )
        take |= distance <= bound * (1 + 1e-12)
    return near[take]


def _near_balls(
    points: NDArray[np.float64], centres: NDArray[np.float64], radii: NDArray[np.float64]
) -> NDArray[np.intp]:
    """Indices of the ``points`` in the grid cells that the balls' boxes touch, increasing.

    A coarse filter before the distance test: the balls of the cells left over from a
    first round lie along a part's faces, so their common box is most of the part, while
    the grid cells they touch hold a few of its sites. The grid's side is at least the
    largest radius, so a ball's box spans at most three cells along each axis, and at
    least the points' mean spacing, so the grid has about as many cells as points at most.
    """
    lo = (centres - radii[:, None]).min(axis=0)
    hi = (centres + radii[:, None]).max(axis=0)
    inside = np.flatnonzero(np.all((points >= lo) & (points <= hi), axis=1))
    d = points.shape[1]
    extent = np.maximum(hi - lo, np.finfo(np.float64).tiny)
    side = max(float(radii.max()), float(np.prod(extent) / max(len(inside), 1)) ** (1.0 / d))
    shape = np.maximum(np.ceil(extent / side).astype(np.intp), 1)

    def cell_of(x: NDArray[np.float64]) -> NDArray[np.intp]:
        return np.clip(np.floor((x - lo) / side).astype(np.intp), 0, shape - 1)

    touched = np.zeros(shape, dtype=bool)
    first, last = cell_of(centres - radii[:, None]), cell_of(centres + radii[:, None])
    # Every cell of each ball's span (at most 3 per axis), as offsets from its first.
    for corner in np.ndindex(*(3,) * d):
        at = np.minimum(first + np.asarray(corner), last)
        touched[tuple(at.T)] = True
    return inside[touched[tuple(cell_of(points[inside]).T)]]


def spatial_order(points: NDArray[np.float64]) -> NDArray[np.intp]:
    """A permutation of ``points`` (m, d) along a Morton curve over their box, shape (m,).

    The core computes the cells it is given in the order given; visiting them along the
    curve keeps neighbouring cells' index buckets in cache (as ``morton_order`` does for a
    whole diagram). Measured on 1M uniform random sites in the unit square, one thread:
    ``partition_cells`` took 7.0 s of CPU in row order, 4.0 s along the curve.
    """
    m, d = points.shape
    if m < 2:
        return np.arange(m, dtype=np.intp)
    lo, hi = bounds(points)
    bits = min(int(math.log2(m)) // d + 3, 63 // d)
    extent = np.maximum(hi - lo, np.finfo(np.float64).tiny)
    cell = ((points - lo) / extent * ((1 << bits) - 1)).astype(np.uint64)
    key = np.zeros(m, dtype=np.uint64)
    for k in range(d):
        key |= _spread_bits(cell[:, k], d) << np.uint64(k)
    return np.argsort(key, kind="stable")


#: Shifts and masks that move bit ``b`` of a value to bit ``d·b``, by dimension ``d``.
_SPREAD = {
    1: [],
    2: [
        (16, 0x0000FFFF0000FFFF),
        (8, 0x00FF00FF00FF00FF),
        (4, 0x0F0F0F0F0F0F0F0F),
        (2, 0x3333333333333333),
        (1, 0x5555555555555555),
    ],
    3: [
        (32, 0x001F00000000FFFF),
        (16, 0x001F0000FF0000FF),
        (8, 0x100F00F00F00F00F),
        (4, 0x10C30C30C30C30C3),
        (2, 0x1249249249249249),
    ],
}


def _spread_bits(values: NDArray[np.uint64], d: int) -> NDArray[np.uint64]:
    """``values`` (each below ``2^(63 // d)``) with bit ``b`` moved to bit ``d·b``.

    The Morton interleave of one coordinate, in five shift-and-mask steps instead of one
    per bit.
    """
    out = values.copy()
    for shift, mask in _SPREAD[d]:
        out = (out | (out << np.uint64(shift))) & np.uint64(mask)
    return out


#: The per-face arrays of a part's cells (CSR rows by `neighbor_offsets`); the image shift
#: of each neighbour only in a periodic box.
FACE_ARRAYS = ("neighbor_sites", "neighbor_measures", "neighbor_images")


def part_cells(
    domain: Domain,
    part: Part,
    cover: float | NDArray[np.float64],
    total_sites: int,
    previous: PartCells | None,
    allow_outside: bool,
    *slices: tuple[NDArray[np.int64], NDArray[np.float64]],
    density: DensityLike = None,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
    weights: NDArray[np.float64] | None = None,
    power_whole: tuple[list[float], list[float], float] | None = None,
    sites_box: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
) -> PartCells:
    """The cells of ``part`` among its sites and ``slices`` of its neighbours' sites.

    Only the cells not yet certified in ``previous`` are computed (all without it).
    ``slices`` hold every site of the problem within ``cover`` of each of these cells'
    sites: a float (the slices are then the sites of other parts in ``part``'s box widened
    by ``cover``), or one radius per cell computed (the balls of ``previous.balls()``).
    A cell is certified when its reach stays inside that box (first round) or below its
    radius (later rounds), or when every site of the problem is present. ``sites_box``,
    the box ``(lo, hi)`` of every site of the problem (not in a periodic box), frees the
    first round's box of its sides beyond it: no site lies there to be missed (a cell at
    the domain's side may read far along it).

    Later rounds read only the part's own sites within the balls: every site within a
    cell's radius is then still present, and the core indexes a few thousand sites instead
    of the whole part.

    With a ``density`` (as :func:`hcvt.voronoi` takes it) ``mass``, ``centroid``,
    ``energy_terms`` and ``first`` are ρ-weighted as in one process; a callable is called
    once per part and round, on the quadrature nodes of the cells computed. The reach,
    and so the halo, does not depend on ρ.

    A power diagram's part takes ``weights`` (n,), the whole problem's in the core's frame
    (indexed by row), and ``power_whole``, the whole problem's ``(lo, hi, largest weight)``
    in that frame: its cells then bound the reach of heavier sites by the largest weight
    of all (DESIGN §14), and are the whole power diagram's cells, bit for bit, once
    certified.
    """
    if len(part.rows) == 0:
        return empty_cells(part.sites.shape[1])
    torus = Torus.of(domain)
    if previous is None:
        todo = np.arange(len(part.rows))
        present = todo
    else:
        todo = np.flatnonzero(~previous.certified)
        present = np.union1d(_in_torus_balls(part.sites, *previous.balls(), torus), todo)
    rows = np.concatenate([part.rows[present]] + [r for r, _ in slices])
    sites = np.concatenate([part.sites[present]] + [s for _, s in slices])
    order = np.argsort(rows, kind="stable")
    rows, sites = np.ascontiguousarray(rows[order]), np.ascontiguousarray(sites[order])
    # Computed along a curve through space (cache), stored in the part's order: a part
    # already along the curve is visited in its own order (nothing to put back).
    in_place = part.along_curve and previous is None
    visit = np.arange(len(todo)) if in_place else spatial_order(part.sites[todo])
    if previous is None:
        # Where each own site went in the sorted rows: it came first, in the part's order.
        position = np.empty(len(order), dtype=np.intp)
        position[order] = np.arange(len(order))
        own = position[: len(todo)][visit]
    else:
        own = np.searchsorted(rows, part.rows[todo])[visit]
    # The core works in the domain's frame; a part's cells are kept in L.
    frame = domain.frame
    core_sites = frame.steps_to_core(sites)
    with frame.input_errors():
        out = _core.partition_cells(
            domain._core,
            core_sites,
            rows,
            own.astype(np.uint32),
            int(total_sites),
            allow_outside=allow_outside,
            weights=None if weights is None else np.ascontiguousarray(weights[rows]),
            power_whole=power_whole,
            **core_arguments(frame.density_to_core(density), domain.dim, quadrature_degree),
        )
    reach = np.sqrt(frame.to_input("reach2", out["reach2"]))
    moments, weighted = out["moments"], out.get("weighted")
    fields = cell_fields(domain, core_sites[own], moments, weighted)
    # The energy is summed by the client; the moments stay in the core's frame (a
    # gathered diagram is made from them), the rest is kept in L.
    kept = {k: v for k, v in out.items() if k not in ("reach2", "energy", "moments", "weighted")}
    cells = {key: frame.to_input(key, value) for key, value in {**kept, **fields}.items()}
    cells["moments"] = moments
    if weighted is not None:
        cells["weighted"] = weighted
    if not in_place:
        reach[visit] = reach.copy()
        cells = _in_row_order(cells, visit)
    # Halos and balls are about the sites wrapped into a periodic box (the core's reach is
    # about its site wrapped, among the images of the sites given).
    own_sites = part.sites if torus is None else torus.wrap(part.sites)
    if len(rows) == total_sites:
        certified = np.full(len(todo), True)
    elif previous is None:
        lo, hi = box_of(part, torus)
        lo, hi = lo - cover, hi + cover  # as the halo was selected: the same floats
        if sites_box is not None and torus is None:
            # A side at or beyond every site excludes none of them.
            lo = np.where(lo <= sites_box[0], -np.inf, lo)
            hi = np.where(hi >= sites_box[1], np.inf, hi)
        room = room_in_box(own_sites[todo], lo, hi)
        certified = reach < COVER_FRACTION * room
    else:
        certified = reach < COVER_FRACTION * cover
    halo = len(rows) - len(present)
    if previous is None:
        return PartCells(cells, reach, certified, halo, len(todo), own_sites)
    # In place: the earlier round is superseded, and a part's cells are held once (twice
    # for all parts at a time was the peak of a 20M-site run). Running this again on the
    # updated object finds nothing to do, so a retried task gives the same cells.
    previous.arrays = _replace_rows(previous.arrays, todo, cells)
    previous.reach[todo] = reach
    previous.certified[todo] = certified
    previous.halo, previous.computed = halo, len(todo)
    return previous


#: A part's quantities of each cell, made from the core's moments (``_core.diagram_field``)
#: as :class:`hcvt.Diagram` makes them; ``gradient`` too on the sphere (the core's
#: projection onto the tangent plane; ``-2 first`` exactly elsewhere).
CELL_FIELDS = ("volume", "mass", "centroid", "second_moment", "G", "energy_terms")


def cell_fields(
    domain: Domain,
    core_sites: NDArray[np.float64],
    moments: NDArray[np.float64],
    weighted: NDArray[np.float64] | None,
) -> dict[str, NDArray[np.float64]]:
    """:data:`CELL_FIELDS` and ``first`` of cells whose ``moments`` are about ``core_sites``.

    In the core's frame; ``first`` (k, d) is the first moment about the site, ρ-weighted
    with a density (``weighted``), as ``mass``, ``centroid`` and ``energy_terms``.
    """
    names = CELL_FIELDS + (("gradient",) if domain.is_sphere else ())
    core_sites = np.ascontiguousarray(core_sites)
    out = {
        name: _core.diagram_field(domain._core, core_sites, moments, weighted, name)
        for name in names
    }
    d = core_sites.shape[1]
    out["first"] = np.ascontiguousarray((moments if weighted is None else weighted)[:, 1 : d + 1])
    return out


def room_in_box(
    points: NDArray[np.float64], lo: NDArray[np.float64], hi: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Distance from each of ``points`` (m, d) to the nearest side of the box, shape (m,).

    A cell whose reach is below it read only sites inside the box, L.
    """
    return np.asarray(np.minimum(points - lo, hi - points).min(axis=1))


def _in_row_order(
    cells: dict[str, NDArray[Any]], visit: NDArray[np.intp]
) -> dict[str, NDArray[Any]]:
    """The core's per-cell arrays, computed in the order ``visit``, in the part's order again.

    Row ``j`` of ``cells`` is the cell ``visit[j]``; faces (CSR) move with their cell.
    """
    out = {}
    for key, value in cells.items():
        if key == "neighbor_offsets" or key in FACE_ARRAYS:
            continue
        placed = np.empty_like(value)
        placed[visit] = value
        out[key] = placed
    offsets = cells["neighbor_offsets"]
    counts = np.empty(len(visit), dtype=np.intp)
    counts[visit] = np.diff(offsets)
    new_offsets = np.zeros(len(visit) + 1, dtype=np.intp)
    np.cumsum(counts, out=new_offsets[1:])
    # Face e of cell i (row order) is entry offsets[where[i]] + e of the core's arrays.
    where = np.empty(len(visit), dtype=np.intp)
    where[visit] = np.arange(len(visit))
    take = np.repeat(offsets[where] - new_offsets[:-1], counts) + np.arange(new_offsets[-1])
    for key in FACE_ARRAYS:
        if key in cells:
            out[key] = cells[key][take]
    out["neighbor_offsets"] = new_offsets
    return out


def _replace_rows(
    old: dict[str, NDArray[Any]], todo: NDArray[np.intp], new: dict[str, NDArray[Any]]
) -> dict[str, NDArray[Any]]:
    """``old`` with rows ``todo`` replaced by the rows of ``new`` (faces in CSR too).

    Per-cell arrays are written in place; the face arrays are built anew.
    """
    out = {}
    for key, value in old.items():
        if key == "neighbor_offsets" or key in FACE_ARRAYS:
            continue
        value[todo] = new[key]
        out[key] = value
    counts = np.diff(old["neighbor_offsets"])
    new_counts = np.diff(new["neighbor_offsets"])
    counts[todo] = new_counts
    offsets = np.zeros(len(counts) + 1, dtype=np.intp)
    np.cumsum(counts, out=offsets[1:])
    replaced = np.zeros(len(counts), dtype=bool)
    replaced[todo] = True
    for key in FACE_ARRAYS:
        if key not in old:
            continue
        values = np.empty((offsets[-1], *old[key].shape[1:]), dtype=old[key].dtype)
        keep = np.repeat(~replaced, counts)
        old_keep = np.repeat(~replaced, np.diff(old["neighbor_offsets"]))
        values[keep] = old[key][old_keep]
        # The new rows' faces, in row order of todo (todo is increasing).
        values[~keep] = new[key]
        out[key] = values
    out["neighbor_offsets"] = offsets
    return out


def gradient_of(cells: PartCells) -> NDArray[np.float64]:
    """``∂E/∂x_i = -2 ∫ρ(x - x_i)`` of each cell, (k, d): the core's, bit for bit.

    On the sphere the core's projection of it onto each site's tangent plane, kept with
    the cells.
    """
    if "gradient" in cells.arrays:
        return cells.arrays["gradient"]
    return cells.arrays["first"] * -2.0


def inside_or_on(domain: Domain, points: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Not strictly outside: the test the diagram applies to its sites, shape (m,)."""
    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    winding, on_boundary = domain.winding_numbers(points)
    return np.asarray((winding != 0) | on_boundary)


def _arg(array: NDArray[Any]) -> NDArray[np.float64]:
    """``array`` as the core takes it: C-contiguous, aligned float64; values unchanged.

    Arrays a task received may be neither (dask unpickles them onto its own buffers).
    """
    return np.require(array, dtype=np.float64, requirements=["C", "A"])


def absorb(domain: Domain, part: Part, cells: PartCells) -> tuple[Part, dict[str, float]]:
    """``part`` with what the next step needs from its cells, and its partial measures.

    Fields set, by the core as in one process (``_core.step_fields``): ``gradient``
    (k, d), ``precond`` (k,) = ``1/(2 m_i)``, ``shift`` (k, d) the move to the centroid
    (0 for an empty cell); the pinned sites are left out of the measures. Partials (summed
    by the client in part order): ``energy``, ``sum_G``, ``cells`` (non-empty), ``sum_r2``,
    ``max_r``, ``counted``, ``g2``, ``x2``, ``pinned`` (the core's ``Measures``, DESIGN §7).
    With a density ``m_i = ∫ρ``, the centroid and gradient are ρ-weighted, and the gap's
    cell size stays the geometric ``V_i^(1/d)``, as in the core.
    """
    a = cells.arrays
    volume, mass, first = a["volume"], a["mass"], a["first"]
    gradient = gradient_of(cells)
    d = domain.cell_dim
    # The core's domain is in its frame: positions and quantities go in and come back.
    frame = domain.frame
    shift, pinned, precond = _core.step_fields(
        domain._core,
        _arg(frame.steps_to_core(part.sites)),
        _arg(frame.quantity_to_core("mass", mass)),
        _arg(frame.quantity_to_core("first", first)),
        _arg(frame.quantity_to_core("boundary_measure", a["boundary_measure"])),
    )
    shift, precond = frame.to_input("shift", shift), frame.to_input("precond", precond)
    counted = ~pinned & (volume > 0) & (mass > 0)
    m, v = mass[counted], volume[counted]
    # |x - c| = |m1| / m; on the sphere the tangent part of m1, |g| / 2 (as the core).
    if d == domain.dim:
        offset = np.sqrt((first[counted] ** 2).sum(axis=1)) / m
    else:
        offset = np.sqrt((gradient[counted] ** 2).sum(axis=1)) / (2.0 * m)
    r = offset / v ** (1.0 / d)
    g = a["G"][~np.isnan(a["G"])]
    partials = {
        "energy": math.fsum(a["energy_terms"]),
        "sum_G": math.fsum(g),
        "cells": float(len(g)),
        "sum_r2": math.fsum(r * r),
        "max_r": float(r.max()) if r.size else 0.0,
        "counted": float(counted.sum()),
        "g2": math.fsum((gradient[counted] ** 2).ravel()),
        "x2": math.fsum((part.sites**2).ravel()),
        "pinned": float(pinned.sum()),
        "empty": float((volume <= 0).sum()),
    }
    fields = dict(part.fields)
    fields["gradient"] = gradient
    fields["precond"] = precond
    fields["shift"] = shift
    return Part(part.index, part.rows, part.sites, fields), partials


def lloyd_part(domain: Domain, part: Part) -> Part:
    """Sites moved to their centroids, held inside: the core's Lloyd step (``lloyd_step``)."""
    frame = domain.frame
    shift = frame.quantity_to_core("shift", part.fields["shift"])
    sites = frame.to_input(
        "sites", _core.lloyd_step(domain._core, _arg(frame.steps_to_core(part.sites)), _arg(shift))
    )
    fields = {k: v for k, v in part.fields.items() if k in ("s", "y")}
    return Part(part.index, part.rows, sites, fields)


def clear_pairs(part: Part) -> Part:
    """``part`` without L-BFGS pairs."""
    fields = {k: v for k, v in part.fields.items() if k not in ("s", "y")}
    return Part(part.index, part.rows, part.sites, fields)


def _dot(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """``Σ a·b`` by numpy's pairwise sum: fixed for given arrays, no BLAS threads."""
    return float(np.add.reduce((a * b).ravel()))


def lbfgs_gram(part: Part) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Partial Gram matrices of ``[s_0..s_{m-1}, y_0..y_{m-1}, g]`` on this part.

    ``plain[a, b] = Σ_i v_a,i · v_b,i``; ``weighted`` the same with the preconditioner
    ``1/(2 m_i)`` on row ``i``. From these sums alone the client runs the two-loop
    recursion in coefficient space (vector-free L-BFGS, Chen et al. 2014), one reduction
    per iteration instead of one per pair.
    """
    s = part.fields.get("s", np.zeros((0, *part.sites.shape)))
    y = part.fields.get("y", np.zeros((0, *part.sites.shape)))
    basis = [*s, *y, part.fields["gradient"]]
    w = part.fields["precond"][:, None]
    size = len(basis)
    plain = np.zeros((size, size))
    weighted = np.zeros((size, size))
    for a in range(size):
        for b in range(a, size):
            plain[a, b] = plain[b, a] = _dot(basis[a], basis[b])
            weighted[a, b] = weighted[b, a] = _dot(basis[a] * w, basis[b])
    return plain, weighted


def lbfgs_direction(
    domain: Domain,
    part: Part,
    weighted_coefficients: NDArray[np.float64],
    s_coefficients: NDArray[np.float64],
) -> tuple[Part, float]:
    """Set field ``direction`` to ``-(P Σ c_j v_j + Σ e_k s_k)``, held inside the domain.

    ``v = [y_0..y_{m-1}, g]``, ``P = diag(1/(2 m_i))``, the coefficients from the core's
    two-loop recursion (``lbfgs_coefficients``); the core forms this part's rows
    (``_core.lbfgs_direction``). Returns the part and its partial slope
    ``g · direction``.
    """
    g = part.fields["gradient"]
    empty = np.zeros((0, *g.shape))
    frame = domain.frame  # P'v' = Pv / s and s' = s / s: the same coefficients serve
    direction = _core.lbfgs_direction(
        domain._core,
        _arg(frame.steps_to_core(part.sites)),
        _arg(frame.quantity_to_core("gradient", g)),
        _arg(frame.quantity_to_core("pair_s", part.fields.get("s", empty))),
        _arg(frame.quantity_to_core("pair_y", part.fields.get("y", empty))),
        _arg(frame.quantity_to_core("precond", part.fields["precond"])),
        _arg(weighted_coefficients),
        _arg(s_coefficients),
    )
    direction = frame.to_input("direction", direction)
    fields = dict(part.fields)
    fields["direction"] = direction
    return Part(part.index, part.rows, part.sites, fields), _dot(g, direction)


def trial_part(domain: Domain, part: Part, t: float) -> tuple[Part, bool]:
    """The sites ``x + t·direction`` (no fields) and whether all are inside or on.

    On the sphere the core's retraction takes them back onto it, as the single process
    does with its trial sites.
    """
    sites = part.sites + t * part.fields["direction"]
    if domain.is_sphere:
        frame = domain.frame
        # The Lloyd step by no move is the core's retraction alone.
        core = _arg(frame.steps_to_core(sites))
        sites = frame.to_input("sites", _core.lloyd_step(domain._core, core, np.zeros_like(core)))
    return Part(part.index, part.rows, sites), bool(inside_or_on(domain, sites).all())


def slope_at(part: Part, cells: PartCells) -> float:
    """Partial ``g(x + t d) · d`` of a trial (``part`` the iterate holding ``direction``)."""
    return _dot(gradient_of(cells), part.fields["direction"])


def accept(old: Part, new: Part, memory: int) -> tuple[Part, dict[str, float]]:
    """``new`` (a trial after :func:`absorb`) with ``old``'s pairs and the pair it makes.

    The pair is ``s = x' - x``, ``y = g' - g``; the oldest is dropped past ``memory``.
    Also returns the partial ``s·y``, ``s·s``, ``y·y`` for the client's curvature test.
    """
    s = new.sites - old.sites
    y = new.fields["gradient"] - old.fields["gradient"]
    shape = (0, *old.sites.shape)
    pairs_s = np.concatenate([old.fields.get("s", np.zeros(shape)), s[None]])[-memory:]
    pairs_y = np.concatenate([old.fields.get("y", np.zeros(shape)), y[None]])[-memory:]
    fields = dict(new.fields)
    fields["s"], fields["y"] = pairs_s, pairs_y
    return Part(new.index, new.rows, new.sites, fields), {
        "sy": _dot(s, y),
        "ss": _dot(s, s),
        "yy": _dot(y, y),
    }


def drop_newest_pair(part: Part) -> Part:
    """``part`` without its newest L-BFGS pair (one of no positive curvature)."""
    fields = dict(part.fields)
    for key in ("s", "y"):
        if key in fields:
            fields[key] = fields[key][:-1]
    return Part(part.index, part.rows, part.sites, fields)


def leaving(part: Part, split: KdSplit) -> int:
    """How many of ``part``'s sites now lie in another part's box."""
    return int((split.locate(part.sites) != part.index).sum())


def split_out(part: Part, split: KdSplit) -> dict[int, Part]:
    """``part``'s rows grouped by the part their site now lies in (non-empty groups)."""
    where = split.locate(part.sites)
    out = {}
    for q in np.unique(where):
        take = where == q
        fields = {k: (v[:, take] if k in ("s", "y") else v[take]) for k, v in part.fields.items()}
        out[int(q)] = Part(int(q), part.rows[take], part.sites[take], fields)
    return out


def empty_like(part: Part) -> Part:
    """A part of no rows with ``part``'s fields (their shapes but the row axis)."""
    fields = {k: (v[:, :0] if k in ("s", "y") else v[:0]) for k, v in part.fields.items()}
    return Part(part.index, part.rows[:0], part.sites[:0], fields)


def merge(index: int, template: Part, *pieces: Part) -> Part:
    """One part from the ``pieces`` that now lie in it, rows increasing again.

    A part of no rows shaped as ``template`` when no piece has rows.
    """
    pieces = tuple(p for p in pieces if len(p.rows))
    if not pieces:
        return Part(index, template.rows, template.sites, dict(template.fields))
    rows = np.concatenate([p.rows for p in pieces])
    order = np.argsort(rows, kind="stable")
    sites = np.concatenate([p.sites for p in pieces])[order]
    keys = set.intersection(*(set(p.fields) for p in pieces))
    fields = {}
    for k in sorted(keys):
        if k in ("s", "y"):
            fields[k] = np.concatenate([p.fields[k] for p in pieces], axis=1)[:, order]
        else:
            fields[k] = np.concatenate([p.fields[k] for p in pieces])[order]
    return Part(index, rows[order], sites, fields)


def save_part(part: Part, path: str) -> str:
    """Write ``part`` to ``path`` (.npz, written whole then renamed); returns the path."""
    target = Path(path)
    tmp = target.with_suffix(".tmp.npz")
    arrays = {"index": np.asarray(part.index), "rows": part.rows, "sites": part.sites}
    arrays.update({f"field_{k}": v for k, v in part.fields.items()})
    np.savez(tmp, **arrays)  # type: ignore[arg-type]
    tmp.replace(target)
    return path


def load_part(path: str) -> Part:
    """The part :func:`save_part` wrote."""
    with np.load(path) as data:
        fields = {k[6:]: data[k] for k in data.files if k.startswith("field_")}
        return Part(int(data["index"]), data["rows"], data["sites"], fields)


def write_part(cells: PartCells, part: Part, directory: str) -> list[str]:
    """Write ``part``'s rows, sites and per-cell arrays as .npy files named by part."""
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    arrays = {"rows": part.rows, "sites": part.sites, **cells.arrays}
    for key, value in arrays.items():
        path = out / f"part{part.index:05d}.{key}.npy"
        np.save(path, value)
        written.append(str(path))
    return written


def peak_rss_mb() -> float:
    """Peak resident memory of this process, MB.

    ``VmHWM`` of /proc/self/status on Linux (a spawned worker's ``ru_maxrss`` can carry
    its parent's peak), else ``ru_maxrss``.
    """
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
