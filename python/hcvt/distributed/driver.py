"""The partitioned diagram and CVT: the client's side (:mod:`hcvt.distributed`)."""

from __future__ import annotations

import math
import operator
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

import hcvt._core as _core
from hcvt.core_results import DiagramArrays
from hcvt.density import DEFAULT_QUADRATURE_DEGREE, DensityLike, core_arguments
from hcvt.diagram import Diagram, as_sites, as_weights
from hcvt.distributed import partition as pt
from hcvt.distributed import partition_mesh
from hcvt.errors import InvalidDomainError, InvalidSitesError
from hcvt.geometry.domain import Domain
from hcvt.optimise import CVTResult, ProgressBar, chain_observers

#: Parts hold at most this many sites unless told otherwise.
DEFAULT_SITES_PER_PARTITION = 200_000
#: First halo width by dimension, in mean spacings ``h = (V/n)^(1/d)``. Measured reach of
#: 5,000 random sites: in 2D median 1.9 h, 95% below 3 h (polygon with a hole, square);
#: in the bunny median 2.3 h, interior cells below 3.5 h, boundary cells median 4.2 h.
#: The few cells beyond go again among a ball past their own reach.
HALO_SPACINGS = {2: 3.0, 3: 4.0}
#: A large part's first halo is widened up to this many spacings while it holds at most
#: ``WIDE_HALO_SHARE`` of the part's sites: a wider halo costs only its sites (indexed,
#: not computed), while any cell it misses costs every part a second round (on 4M sites
#: in 2 parts, 2,080 cells took a round of 5 s under load, mostly in moving the part's
#: arrays). Measured on 1M uniform random sites in the unit square, 2 parts: cells a halo
#: of w spacings misses per part, w = 3: 492-530, 5: 11-17, 8: 0-2, 12: 0 (two seeds);
#: with the sides beyond every site freed (``sites_box`` of ``part_cells``), w = 3: 11-17,
#: 5: 1-2, 8.8: 0 (one seed).
WIDE_HALO_SPACINGS = 16.0
WIDE_HALO_SHARE = 0.05

#: Extra first-halo width of a mesh piece, in spacings (PartitionedDiagram.write_cells).
RING_SPACINGS = 2.0
#: Trials of one line search (the core's default ``max_line_evaluations``).
LINE_TRIALS = 20
#: Times an iteration is restarted from its checkpoint after a worker loss.
MAX_RESTARTS = 3

_S = TypeVar("_S")
_T = TypeVar("_T")


@dataclass
class Rounds:
    """How the halos grew for one diagram: per round, cells computed, halo sites, seconds.

    ``seconds`` is the client's wall time from submitting a round's tasks to having every
    part's status (the workers' computation and the waiting on them).
    """

    cells: list[int] = field(default_factory=list)
    halo: list[int] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)
    #: Energy, sum of G and non-empty cells of each part (``_energy_partial``), taken with
    #: the part's last status when :meth:`_Cluster.cells` is asked for them, else empty.
    partials: list[tuple[float, float, int]] = field(default_factory=list)


class _Cluster:
    """The client, the domain on every worker, and the parts' diagram rounds."""

    def __init__(
        self,
        client: Any,
        domain: Domain,
        n: int,
        allow_outside: bool = False,
        density: DensityLike = None,
        quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
        power: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    ):
        self.client = client
        self.domain = domain
        self.n = n
        #: A power diagram's weights in L (n,), or None.
        self.weights = None if power is None else power[0]
        #: A periodic box's axes: halos wrap across its sides.
        self.torus = pt.Torus.of(domain)
        if self.torus is not None and power is not None and np.any(power[0]):
            raise NotImplementedError(
                "partitioned power diagrams in a periodic box are not implemented yet"
            )
        self._power = _power_whole(domain, *power) if power is not None else None
        self.allow_outside = allow_outside
        # Spacing and halo by the cells' dimension (2 on the sphere, whose area is `volume`).
        self.h = (domain.volume / n) ** (1.0 / domain.cell_dim)
        self.density = density
        self.quadrature_degree = quadrature_degree
        if density is not None:
            # Checked here, so a bad density or degree is named before any task runs.
            core_arguments(density, domain.dim, quadrature_degree)
        self.scatter()

    def scatter(self) -> None:
        """Send the domain and the density (a callable may hold a large table) to every worker.

        Tasks receive the worker's copy. Sent again after a worker loss: dask's active
        memory manager drops the replicas of scattered data that no task is waiting for,
        so between tasks the only copy may have been on the worker lost, and scattered
        data cannot be recomputed.
        """
        self.domain_future = self.client.scatter(self.domain, broadcast=True, hash=False)
        self.weighting: dict[str, Any] = {}
        if self.density is not None:
            self.weighting = {
                "density": self.client.scatter(self.density, broadcast=True, hash=False),
                "quadrature_degree": self.quadrature_degree,
            }
        if self._power is not None:
            # Every part reads the weights of its own and halo rows from the whole array.
            core_weights, whole = self._power
            self.weighting["weights"] = self.client.scatter(
                core_weights, broadcast=True, hash=False
            )
            self.weighting["power_whole"] = whole

    def submit(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        return self.client.submit(fn, *args, pure=False, **kwargs)

    def gather(self, futures: list[Any]) -> list[Any]:
        return list(self.client.gather(futures))

    def item(self, future: Any, k: int) -> Any:
        return self.submit(operator.getitem, future, k)

    def boxes(self, parts: list[Any]) -> tuple[list[Any], list[int]]:
        info = self.gather([self.submit(_box_and_count, p, self.torus) for p in parts])
        return [b for b, _ in info], [c for _, c in info]

    def first_halo(self, sites: int) -> float:
        """Width of the first halo of a part of ``sites`` sites, L.

        ``HALO_SPACINGS`` spacings, widened for a large part up to ``WIDE_HALO_SPACINGS``
        as long as its faces' halo (``2 d w`` spacings thick over a side of ``k^(1/d)``
        spacings, relative to the part) stays below ``WIDE_HALO_SHARE`` of its sites.
        """
        d = self.domain.cell_dim
        share = WIDE_HALO_SHARE * sites ** (1.0 / d) / (2 * d)
        return max(HALO_SPACINGS[d], min(WIDE_HALO_SPACINGS, share)) * self.h

    def cells(
        self,
        parts: list[Any],
        known: tuple[list[Any], list[int]] | None = None,
        partials: bool = False,
    ) -> tuple[list[Any], Rounds]:
        """The certified cells of every part (futures of :class:`PartCells`).

        ``known``: the boxes (:func:`pt.box_of`) and site counts of the parts when the
        client has them (else asked of the workers). ``partials``: fill
        ``Rounds.partials`` from each part's last status (no round trip of their own).
        """
        boxes, counts = known if known is not None else self.boxes(parts)
        reach_boxes = list(boxes)  # boxes stays the box of each part's sites
        torus = self.torus
        nonempty = [p for p in range(len(parts)) if counts[p] > 0]
        rho = {p: self.first_halo(counts[p]) for p in nonempty}
        # The box of every site: a first halo's side beyond it needs no room.
        sites_box = (
            (
                np.min([boxes[p][0] for p in nonempty], axis=0),
                np.max([boxes[p][1] for p in nonempty], axis=0),
            )
            if nonempty and torus is None
            else None
        )
        cells: list[Any] = [self.submit(pt.empty_cells, self.domain.dim)] * len(parts)
        previous: dict[int, Any] = {}
        pending = list(nonempty)
        rounds = Rounds()
        balls: dict[int, Any] = {}
        done: dict[int, tuple[float, float, int]] = {}
        while pending:
            start = time.perf_counter()
            for p in pending:
                # Where part p's halo must reach: its sites' box widened by rho, or later
                # the box of the balls of its cells not certified.
                lo, hi = reach_boxes[p][0] - rho[p], reach_boxes[p][1] + rho[p]
                neighbours = [q for q in nonempty if q != p and _meets(boxes[q], lo, hi, torus)]
                if p in balls:
                    # Later rounds: a ball around each cell not certified, past its reach.
                    centres, radii = self.item(balls[p], 0), self.item(balls[p], 1)
                    slices = [
                        self.submit(pt.ball_slice, parts[q], centres, radii, torus)
                        for q in neighbours
                    ]
                    cover: Any = radii
                else:
                    slices = [
                        self.submit(pt.halo_slice, parts[q], lo, hi, torus) for q in neighbours
                    ]
                    cover = rho[p]
                cells[p] = self.submit(
                    pt.part_cells,
                    self.domain_future,
                    parts[p],
                    cover,
                    self.n,
                    previous.get(p),
                    self.allow_outside,
                    *slices,
                    sites_box=sites_box,
                    **self.weighting,
                )
            report = _status_and_partial if partials else _status
            status = self.gather([self.submit(report, cells[p]) for p in pending])
            rounds.cells.append(sum(s.computed for s in status))
            rounds.halo.append(sum(s.halo for s in status))
            rounds.seconds.append(time.perf_counter() - start)
            still = []
            for p, s in zip(pending, status, strict=True):
                # The last round's result of p is now in cells[p]: let the worker drop it.
                previous.pop(p, None)
                if s.partial is not None:
                    done[p] = s.partial
                if s.uncertified:
                    previous[p] = cells[p]
                    balls[p] = self.submit(_balls, cells[p])
                    reach_boxes[p], rho[p] = (s.lo, s.hi), 0.0
                    still.append(p)
            pending = still
        if partials:
            rounds.partials = [done.get(p, (0.0, 0.0, 0)) for p in range(len(parts))]
        return cells, rounds


def _power_whole(
    domain: Domain, weights: NDArray[np.float64], points: NDArray[np.float64]
) -> tuple[NDArray[np.float64], tuple[list[float], list[float], float]] | None:
    """The weights in the core's frame and the whole problem's box and largest weight.

    ``(core weights (n,), (lo, hi, largest weight))`` (``hcvt_core::PowerWhole``), or None
    for weights all zero (the Voronoi diagram, as one process computes it).
    """
    if not np.any(weights):
        return None
    frame = domain.frame
    core = frame.steps_to_core(points)
    core_weights = np.ascontiguousarray(frame.quantity_to_core("weights", weights))
    whole = (core.min(axis=0).tolist(), core.max(axis=0).tolist(), float(core_weights.max()))
    return core_weights, whole


def _box_and_count(part: pt.Part, torus: pt.Torus | None) -> tuple[Any, int]:
    return pt.box_of(part, torus), len(part.rows)


def _meets(
    box: tuple[NDArray[np.float64], NDArray[np.float64]],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    torus: pt.Torus | None,
) -> bool:
    """Whether a part's ``box`` (an image of it in a periodic box) meets ``[lo, hi]``."""
    if torus is not None:
        return torus.overlaps(box, lo, hi)
    return bool(np.all(box[0] <= hi) and np.all(box[1] >= lo))


def _status(cells: pt.PartCells) -> pt.Status:
    return cells.status()


def _status_and_partial(cells: pt.PartCells) -> pt.Status:
    """The status, with the energy partial of a part whose cells are all certified."""
    status = cells.status()
    if not status.uncertified:
        status.partial = _energy_partial(cells)
    return status


def _balls(cells: pt.PartCells) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    return cells.balls()


def _energy_partial(cells: pt.PartCells) -> tuple[float, float, int]:
    a = cells.arrays
    g = a["G"][~np.isnan(a["G"])]
    # fsum of a list: the same correctly rounded sum, without a numpy scalar per element.
    return math.fsum(a["energy_terms"].tolist()), math.fsum(g.tolist()), len(g)


def _peak_rss() -> float:
    return pt.peak_rss_mb()


class PartitionedDiagram:
    """A diagram whose cells stay on the workers, one :class:`PartCells` per part.

    Attributes
    ----------
    n : int
        Number of sites.
    parts : int
        Number of parts.
    energy : float
        CVT energy, summed per part in row order, then over the parts in order.
    mean_G : float
        Mean G over the non-empty cells, summed the same way.
    rounds : Rounds
        Cells computed and halo sites per round of halo growth.
    """

    def __init__(
        self,
        cluster: _Cluster,
        parts: list[Any],
        cells: list[Any],
        rounds: Rounds,
        timings: dict[str, float] | None = None,
    ):
        start = time.perf_counter()
        self._cluster = cluster
        self._parts = parts
        self._cells = cells
        self.rounds = rounds
        #: Halo sites of each round of :meth:`write_cells`, once it has run.
        self.piece_rounds: list[int] = []
        self.n = cluster.n
        self.parts = len(parts)
        sums = rounds.partials or cluster.gather(
            [cluster.submit(_energy_partial, c) for c in cells]
        )
        self.energy = math.fsum(s[0] for s in sums)
        count = sum(s[2] for s in sums)
        self.mean_G = math.fsum(s[1] for s in sums) / max(count, 1)
        #: Wall seconds on the client: ``split`` (kd planes and parts), ``scatter`` (the
        #: domain and the parts to the workers), ``cells`` (every round of
        #: :attr:`rounds`, as ``rounds.seconds``), ``sums`` (energy and mean G).
        self.timings = dict(timings or {}, cells=math.fsum(rounds.seconds))
        self.timings["sums"] = time.perf_counter() - start

    def gather(self) -> Diagram:
        """The whole :class:`~hcvt.diagram.Diagram` on the client, row ``i`` site ``i``.

        Part by part, so the client holds one part's cells beside the result. ``energy``
        is this object's (summed per part).
        """
        return self._gather(wrap=False)

    def _gather(self, wrap: bool) -> Diagram:
        """:meth:`gather`; with ``wrap`` the sites wrapped into a periodic box.

        As a single-process CVT returns them (the cells are those of the sites as held).
        """
        domain, n, d = self._cluster.domain, self.n, self._cluster.domain.dim
        sites = np.empty((n, d))
        rows_of: list[NDArray[np.int64]] = []
        arrays: dict[str, Any] = {}
        faces: list[tuple[NDArray[np.int64], dict[str, Any]]] = []
        counts = np.zeros(n, dtype=np.intp)
        for part, cells in zip(self._parts, self._cells, strict=True):
            p, c = self._cluster.gather([part, cells])
            if not len(p.rows):
                continue
            sites[p.rows] = p.sites
            rows_of.append(p.rows)
            for key, value in c.arrays.items():
                if key in ("neighbor_offsets", *pt.FACE_ARRAYS):
                    continue
                if key not in arrays:
                    arrays[key] = np.empty((n, *value.shape[1:]), dtype=value.dtype)
                arrays[key][p.rows] = value
            counts[p.rows] = np.diff(c.arrays["neighbor_offsets"])
            faces.append((p.rows, {k: c.arrays[k] for k in pt.FACE_ARRAYS if k in c.arrays}))
        offsets = np.zeros(n + 1, dtype=np.intp)
        np.cumsum(counts, out=offsets[1:])
        face_arrays: dict[str, Any] = {
            "neighbor_sites": np.empty(offsets[-1], dtype=np.intp),
            "neighbor_measures": np.empty(offsets[-1]),
        }
        if any(domain.periodic):
            face_arrays["neighbor_images"] = np.empty((offsets[-1], d), dtype=np.int8)
        for rows, f in faces:
            # Entry e of row k of the part goes to offsets[rows[k]] + e.
            local = np.diff(np.append(0, np.cumsum(counts[rows])))
            starts = np.repeat(offsets[rows] - np.cumsum(local) + local, local)
            take = starts + np.arange(len(starts))
            for key, values in face_arrays.items():
                values[take] = f[key]
        # Made from the moments, in the core's frame, as one process's diagram is: the
        # measures and the energy go back there (exactly: the scale is a power of two).
        frame = domain.frame
        core: dict[str, Any] = {k: arrays[k] for k in ("moments", "weighted") if k in arrays}
        core.update(
            energy=float(frame.quantity_to_core("energy", np.array([self.energy]))[0]),
            boundary_measure=frame.quantity_to_core("boundary_measure", arrays["boundary_measure"]),
            neighbor_offsets=offsets,
            **face_arrays,
        )
        core["neighbor_measures"] = frame.quantity_to_core(
            "neighbor_measures", face_arrays["neighbor_measures"]
        )
        if wrap and any(domain.periodic):
            # Centroids about the wrapped sites, as a single-process CVT reports them.
            sites = domain.wrap(sites)
        return Diagram(
            domain,
            sites,
            cast(DiagramArrays, core),  # the parts' rows of every DiagramArrays field
            self._cluster.density,
            allow_outside=self._cluster.allow_outside,
            core_sites=frame.steps_to_core(sites),
            weights=self._cluster.weights,
        )

    def write(self, directory: str | Path) -> list[str]:
        """Write every part's rows, sites and per-cell arrays as .npy files, on its worker.

        Files ``part{p:05d}.{name}.npy`` in ``directory`` (which every worker must reach):
        ``rows`` (k,), ``sites`` (k, d) and the arrays of
        :class:`hcvt.distributed.partition.PartCells` (neighbours in problem rows, CSR offsets
        local to the part). Returns the paths.
        """
        futures = [
            self._cluster.submit(pt.write_part, c, p, str(directory))
            for p, c in zip(self._parts, self._cells, strict=True)
        ]
        return [path for paths in self._cluster.gather(futures) for path in paths]

    def write_cells(self, path: str | Path) -> Path:
        """Write the cells as one VTU piece per part, by its worker, and a .pvtu index.

        ``path`` is the index (``cells.pvtu``: pieces ``cells/part{p:05d}.vtu`` beside it)
        or a directory (``cells.pvtu`` and the pieces in it); every worker must reach it.
        Each piece holds its part's cells with the faces and vertex coordinates of
        :meth:`hcvt.Diagram.mesh` of the whole problem, bit for bit, and cell data
        ``row`` (the problem row), ``volume`` and ``G``; the client writes only the index
        (:mod:`hcvt.distributed.partition_mesh`). Returns the index's path; the halo sites of each
        round are in ``self.piece_rounds``.
        """
        if self._cluster.weights is not None:
            raise NotImplementedError("the mesh of a partitioned power diagram is not written yet")
        # The piece also computes the ring of cells across its border (their vertices
        # are shared): two spacings more keep that ring inside the first halo.
        rho = (HALO_SPACINGS[self._cluster.domain.dim] + RING_SPACINGS) * self._cluster.h
        index, self.piece_rounds = partition_mesh.write_pieces(
            self._cluster, self._parts, self._cells, path, rho
        )
        return index

    def peak_memory_mb(self) -> dict[str, float]:
        """Peak resident memory of every worker process (and of this client), MB."""
        out = {str(k): float(v) for k, v in self._cluster.client.run(_peak_rss).items()}
        out["client"] = pt.peak_rss_mb()
        return out


def partitioned_voronoi(
    domain: Domain,
    sites: ArrayLike,
    client: Any,
    *,
    sites_per_partition: int = DEFAULT_SITES_PER_PARTITION,
    allow_outside: bool = False,
    density: DensityLike = None,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
    weights: ArrayLike | None = None,
) -> PartitionedDiagram:
    """The clipped diagram of ``sites`` with its cells computed and kept on dask workers.

    Parameters as :func:`hcvt.voronoi`; ``client`` a ``dask.distributed.Client``;
    ``sites_per_partition`` the most sites one part holds (module docs). Per-cell arrays
    are bitwise those of :func:`hcvt.voronoi` for any number of workers and any
    ``sites_per_partition``, with a ``density`` too (a callable must give each point's
    value whatever the other points of the call: module docs), and with ``weights`` (the
    power diagram, (n,) in L²; the whole array is sent to every worker).
    """
    points = domain.frame.onto_domain(as_sites(sites, domain.dim))
    power = None if weights is None else (as_weights(weights, len(points)), points)
    start = time.perf_counter()
    cluster = _Cluster(
        client, domain, len(points), allow_outside, density, quadrature_degree, power
    )
    split_at = time.perf_counter()
    _, made = pt.split_parts(points, sites_per_partition)
    known = [pt.box_of(p, cluster.torus) for p in made], [len(p.rows) for p in made]
    scatter_at = time.perf_counter()
    # Each worker puts its parts along the curve it visits them in (see pt.along_curve).
    parts = [cluster.submit(pt.along_curve, p) for p in client.scatter(made, hash=False)]
    del made
    timings = {
        "split": scatter_at - split_at,
        "scatter": (split_at - start) + (time.perf_counter() - scatter_at),
    }
    cells, rounds = cluster.cells(parts, known, partials=True)
    return PartitionedDiagram(cluster, parts, cells, rounds, timings)


@dataclass
class _Iterate:
    """The client's view of the current iterate: scalars only, plus futures."""

    parts: list[Any]
    record: dict[str, Any]
    point_parts: list[Any] | None
    point_cells: list[Any] | None
    rounds: Rounds
    #: Cells left empty (a partitioned run does not reseed them: it stops).
    empty: int = 0


class _Cvt:
    """A partitioned CVT run (module docs)."""

    def __init__(
        self,
        cluster: _Cluster,
        split: pt.KdSplit,
        method: str,
        rule: str,
        memory: int,
        checkpoint: str | None,
    ):
        self.cluster = cluster
        self.split = split
        self.method = method
        self.rule = rule
        self.memory = memory
        self.checkpoint = checkpoint
        self.evaluations = 0
        self.migrated = 0
        self.start = time.perf_counter()

    def evaluate(self, parts: list[Any]) -> tuple[list[Any], dict[str, float], list[Any], Rounds]:
        """Diagram of ``parts``: the parts with gradient etc., summed partials, cells."""
        c = self.cluster
        cells, rounds = c.cells(parts)
        self.evaluations += 1
        absorbed = [
            c.submit(pt.absorb, c.domain_future, p, k) for p, k in zip(parts, cells, strict=True)
        ]
        new_parts = [c.item(a, 0) for a in absorbed]
        partials = c.gather([c.item(a, 1) for a in absorbed])
        return new_parts, _reduce(partials), cells, rounds

    def record(self, sums: dict[str, float], step: str) -> dict[str, Any]:
        g2, x2 = sums["g2"], sums["x2"]
        return {
            "energy": sums["energy"],
            "mean_G": sums["sum_G"] / max(sums["cells"], 1.0),
            "rms_gap": math.sqrt(sums["sum_r2"] / max(sums["counted"], 1.0)),
            "max_gap": sums["max_r"],
            "grad_norm": 0.0 if g2 == 0 else math.sqrt(g2) / max(math.sqrt(x2), 5e-324),
            "pinned": int(sums["pinned"]),
            "seconds": time.perf_counter() - self.start,
            "evaluations": self.evaluations,
            "step": step,
            "migrated": 0,
        }

    def rebalance(self, parts: list[Any]) -> list[Any]:
        """Sites that crossed a plane move, with their rows' state, to their new part."""
        c = self.cluster
        moving = c.gather([c.submit(pt.leaving, p, self.split) for p in parts])
        self.migrated += sum(moving)
        if not sum(moving):
            return parts
        pieces = [c.submit(pt.split_out, p, self.split) for p in parts]
        targets = c.gather([c.submit(_keys, x) for x in pieces])
        out = []
        for q in range(len(parts)):
            sources = [c.item(pieces[p], q) for p in range(len(parts)) if q in targets[p]]
            # The shapes of part q's fields, for a part left empty.
            template = c.submit(pt.empty_like, parts[q])
            out.append(c.submit(pt.merge, q, template, *sources))
        return out

    def lloyd(self, parts: list[Any]) -> list[Any]:
        c = self.cluster
        return [c.submit(pt.lloyd_part, c.domain_future, p) for p in parts]

    def step(self, it: _Iterate) -> _Iterate:
        """One iteration from ``it``: L-BFGS with its line search, or Lloyd."""
        self.migrated = 0
        found = self.lbfgs(it) if self.method == "lbfgs" else None
        if found is None:
            found = self.lloyd_step(it)
        found.record["migrated"] = self.migrated
        return found

    def lloyd_step(self, it: _Iterate) -> _Iterate:
        c = self.cluster
        parts = it.parts
        if self.method == "lbfgs":
            parts = [c.submit(pt.clear_pairs, p) for p in parts]
        moved = self.rebalance(self.lloyd(parts))
        new_parts, sums, cells, rounds = self.evaluate(moved)
        record = self.record(sums, "lloyd")
        return _Iterate(new_parts, record, new_parts, cells, rounds, int(sums["empty"]))

    def lbfgs(self, it: _Iterate) -> _Iterate | None:
        c = self.cluster
        grams = c.gather([c.submit(pt.lbfgs_gram, p) for p in it.parts])
        plain = _sum_in_order([g[0] for g in grams])
        weighted = _sum_in_order([g[1] for g in grams])
        wc, sc = _core.lbfgs_coefficients(plain, weighted)
        directed = [c.submit(pt.lbfgs_direction, c.domain_future, p, wc, sc) for p in it.parts]
        parts = [c.item(x, 0) for x in directed]
        slope = math.fsum(c.gather([c.item(x, 1) for x in directed]))
        if not slope < 0:
            # Not downhill (stale pairs, or moves shortened at the boundary): restart from
            # the preconditioner alone, the Lloyd direction, downhill site by site.
            parts = [c.submit(pt.clear_pairs, p) for p in it.parts]
            wc, sc = np.ones(1), np.zeros(0)
            directed = [c.submit(pt.lbfgs_direction, c.domain_future, p, wc, sc) for p in parts]
            parts = [c.item(x, 0) for x in directed]
            slope = math.fsum(c.gather([c.item(x, 1) for x in directed]))
            if not slope < 0:
                return None
        e0 = it.record["energy"]
        t = 1.0
        for _ in range(LINE_TRIALS):
            trials = [c.submit(pt.trial_part, c.domain_future, p, t) for p in parts]
            if not all(c.gather([c.item(x, 1) for x in trials])):
                t *= 0.5
                continue
            trial_parts, sums, cells, rounds = self.evaluate([c.item(x, 0) for x in trials])
            slope_t = math.fsum(
                c.gather([c.submit(pt.slope_at, p, k) for p, k in zip(parts, cells, strict=True)])
            )
            if _core.line_search_accepts(e0, slope, t, sums["energy"], slope_t):
                accepted = [
                    c.submit(pt.accept, p, q, self.memory)
                    for p, q in zip(parts, trial_parts, strict=True)
                ]
                new_parts = [c.item(x, 0) for x in accepted]
                pair = _reduce(c.gather([c.item(x, 1) for x in accepted]))
                if not _core.positive_curvature(pair["sy"], pair["ss"], pair["yy"]):
                    new_parts = [c.submit(pt.drop_newest_pair, p) for p in new_parts]
                record = self.record(sums, "lbfgs")
                moved = self.rebalance(new_parts)
                return _Iterate(moved, record, trial_parts, cells, rounds, int(sums["empty"]))
            t *= 0.5
        return None

    def save(self, it: _Iterate, k: int) -> list[str] | None:
        if self.checkpoint is None:
            return None
        c = self.cluster
        paths = [
            str(Path(self.checkpoint) / f"it{k:06d}-part{p:05d}.npz") for p in range(len(it.parts))
        ]
        return c.gather(
            [c.submit(pt.save_part, part, path) for part, path in zip(it.parts, paths, strict=True)]
        )

    def load(self, paths: list[str]) -> list[Any]:
        return [self.cluster.submit(pt.load_part, path) for path in paths]


class _Restarts:
    """Attempts run again after a worker loss, at most :data:`MAX_RESTARTS` in a run."""

    def __init__(self, cluster: _Cluster):
        self.cluster = cluster
        self.count = 0

    def run(self, attempt: Callable[[_S], _T], state: _S, resume: Callable[[_S], _S | None]) -> _T:
        """``attempt(state)``; after a failure but bad input, again from ``resume(state)``.

        A worker died or its data was lost: every step is deterministic, so running it
        again from what ``resume`` restores (the files of the last iteration completed)
        gives the same result. The domain and density are scattered again first (their
        only copy may have gone with the worker). ``resume`` returning None (no
        checkpoint) re-raises.
        """
        while True:
            try:
                return attempt(state)
            except (InvalidSitesError, InvalidDomainError, ValueError, KeyboardInterrupt):
                raise
            except Exception:
                resumed = None if self.count >= MAX_RESTARTS else resume(state)
                if resumed is None:
                    raise
                self.count += 1
                self.cluster.scatter()
                state = resumed


def _keys(pieces: dict[int, pt.Part]) -> list[int]:
    return sorted(pieces)


def _sum_in_order(arrays: list[NDArray[np.float64]]) -> NDArray[np.float64]:
    """Elementwise sum of the parts' partial matrices, in part order."""
    total = np.zeros_like(arrays[0])
    for a in arrays:
        total = total + a
    return total


def _reduce(partials: list[dict[str, float]]) -> dict[str, float]:
    """Partials summed over the parts in part order (``max_r`` the largest)."""
    out = {}
    for key in partials[0]:
        values = [p[key] for p in partials]
        out[key] = max(values) if key.startswith("max") else math.fsum(values)
    return out


@dataclass
class PartitionedCVTResult:
    """What :func:`partitioned_cvt` returns: the history and the final diagram on workers."""

    diagram: PartitionedDiagram
    history: dict[str, NDArray[Any]]
    rule: str
    tol: float
    stop_reason: str
    restarts: int

    @property
    def converged(self) -> bool:
        """Whether the rule's value fell below ``tol``."""
        return self.stop_reason == "converged"

    def gather(self) -> Any:
        """A :class:`hcvt.CVTResult` with the sites and diagram gathered on the client.

        In a periodic box the sites are wrapped into it, as :func:`hcvt.cvt` returns them.
        """
        diagram = self.diagram._gather(wrap=True)
        return CVTResult(
            sites=diagram.sites,
            diagram=diagram,
            history=self.history,
            rule=self.rule,
            tol=self.tol,
            converged=self.converged,
            stop_reason=self.stop_reason,
            iterations=len(self.history["energy"]) - 1,
            evaluations=int(self.history["evaluations"][-1]),
            seconds=float(self.history["seconds"][-1]),
        )


def partitioned_cvt(
    domain: Domain,
    sites: ArrayLike,
    method: str,
    client: Any,
    *,
    rule: str = "gap",
    tol: float | None = None,
    max_iter: int = 10_000,
    memory: int = 7,
    callback: Callable[[dict[str, Any]], Any] | None = None,
    progress: bool = False,
    sites_per_partition: int = DEFAULT_SITES_PER_PARTITION,
    checkpoint: str | bool = True,
    density: DensityLike = None,
    quadrature_degree: int = DEFAULT_QUADRATURE_DEGREE,
) -> PartitionedCVTResult:
    """A CVT whose sites and per-site state stay on dask workers (module docs).

    Parameters as :func:`hcvt.cvt` (``method`` ``"lbfgs"`` or ``"lloyd"``), and
    ``client`` a ``dask.distributed.Client``; ``sites_per_partition`` the most sites one
    part holds; ``checkpoint`` a directory every worker can write (or True for a temporary
    one on this machine, False for none) where each iteration's parts are written, from
    which an iteration is restarted after a worker loss; ``density`` and
    ``quadrature_degree`` as for :func:`hcvt.cvt` (the preconditioner is then ``1/(2 m_i)``
    with ``m_i = ∫ρ``, as the core's).
    """
    tol = _core.check_settings(method, rule, tol, max_iter, memory)
    if method not in ("lbfgs", "lloyd"):
        raise ValueError(
            f"a partitioned CVT runs 'lbfgs' or 'lloyd' (Newton needs a halo exchange per "
            f"Hessian product), got {method!r}"
        )
    points = domain.frame.onto_domain(as_sites(sites, domain.dim))
    cluster = _Cluster(client, domain, len(points), False, density, quadrature_degree)
    split = pt.kd_split(points, sites_per_partition)
    temporary = None
    if checkpoint is True:
        temporary = tempfile.mkdtemp(prefix="hcvt-checkpoint-")
        directory: str | None = temporary
    elif checkpoint is False:
        directory = None
    else:
        directory = str(checkpoint)
        Path(directory).mkdir(parents=True, exist_ok=True)
    run = _Cvt(cluster, split, method, rule, memory, directory)
    field_name = {"gap": "rms_gap", "paper": "grad_norm"}[rule]
    bar = ProgressBar(rule, tol) if progress else None
    observe = chain_observers(callback, bar)
    restarts = _Restarts(cluster)

    def start(sites: NDArray[np.float64]) -> tuple[_Iterate, list[str] | None]:
        # The first parts are scattered from the sites held here: after a loss, again.
        parts = client.scatter(pt.make_parts(sites, split), hash=False)
        new_parts, sums, cells, rounds = run.evaluate(parts)
        record = run.record(sums, "start")
        first = _Iterate(new_parts, record, new_parts, cells, rounds, int(sums["empty"]))
        return first, run.save(first, 0)

    def step(current: _Iterate) -> tuple[_Iterate, list[str] | None]:
        # Saved within the attempt: a worker lost while writing loses the step's parts,
        # and the step is redone from the previous files.
        done = run.step(current)
        return done, run.save(done, len(history))

    def reload(current: _Iterate) -> _Iterate | None:
        if saved is None:
            return None
        parts = run.load(saved)
        return _Iterate(parts, current.record, None, None, current.rounds, current.empty)

    try:
        it, saved = restarts.run(start, points, lambda sites: sites)
        history = [it.record]
        while True:
            if observe is not None and observe(dict(it.record)):
                stop = "interrupted"
                break
            if it.record[field_name] < tol:
                stop = "converged"
                break
            if len(history) > max_iter:
                stop = "max_iter"
                break
            if it.empty:
                raise InvalidSitesError(
                    f"{it.empty} empty cells: a partitioned CVT does not reseed"
                )
            it, saved = restarts.run(step, it, reload)
            history.append(it.record)
        if it.point_cells is None or it.point_parts is None:
            cells, rounds = cluster.cells(it.parts)
            diagram = PartitionedDiagram(cluster, it.parts, cells, rounds)
        else:
            diagram = PartitionedDiagram(cluster, it.point_parts, it.point_cells, it.rounds)
    finally:
        if bar is not None:
            bar.close()
        if temporary is not None:
            shutil.rmtree(temporary, ignore_errors=True)
    out = {k: np.asarray([r[k] for r in history]) for k in history[0]}
    return PartitionedCVTResult(diagram, out, rule, float(tol), stop, restarts.count)


__all__ = [
    "DEFAULT_SITES_PER_PARTITION",
    "PartitionedCVTResult",
    "PartitionedDiagram",
    "partitioned_cvt",
    "partitioned_voronoi",
]
