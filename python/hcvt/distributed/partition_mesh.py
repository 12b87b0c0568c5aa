"""A partitioned diagram's cells as one VTU piece per part and a .pvtu index (DESIGN §10).

Each part's piece is made and written on the worker that holds the part; the client only
moves halo sites between workers and writes the index, so no process ever holds all
cells (:meth:`hcvt.distributed.PartitionedDiagram.write_cells`).

**A piece is the whole mesh's.** The core's ``mesh_part`` (``conforming_mesh_part``
in ``hcvt-core/src/diagram/mesh/mod.rs``) makes the faces of a part's own cells among its
sites and a halo, as :meth:`hcvt.Diagram.mesh` of the whole problem makes them: a vertex
takes its name and position from the first cell in row order that has it, so the core also
computes the ring of other parts' cells that share a vertex with the own cells. Every
computed cell reports its reach; the piece is written only when the halo held every site
within every computed cell's reach (else the halo grows, as for the diagram: the sites
within 1.5 times the reach of each cell not covered). Each face's vertices are then
bitwise those of the single-process mesh.

**Layout of a piece.** Cells are the part's own, in row order (``site`` in the file is
that local index; cell data ``row`` is the problem's row). A face between two cells of
different parts is in both pieces, owned by each piece's own cell (so each piece is a
closed set of cells for VTK); :class:`PieceMesh` records the problem row of the cell
across every face (``across``), which the file does not hold.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

import hcvt._core as _core
from hcvt.distributed import partition as pt
from hcvt.geometry.domain import Domain
from hcvt.io.pvtu import write_pvtu
from hcvt.io.vtu import write_vtu
from hcvt.mesh.polymesh import PolyMesh

#: Per-cell arrays written with each piece besides the row (Float64, as write_vtu writes).
CELL_ARRAYS = ("volume", "G")


@dataclass
class PieceMesh:
    """A part's cells as a mesh of their own (see the module docs).

    Attributes
    ----------
    mesh : PolyMesh
        The own cells ``0..k-1`` (row order) and all their faces; a face toward another
        part's cell has ``neighbour = -1`` and is oriented out of the own cell.
    rows : ndarray of int64, shape (k,)
        Problem row of each cell.
    across : ndarray of int64, shape (f,)
        Problem row of the cell on the other side of each face, ``-1`` on the domain
        boundary.
    """

    mesh: PolyMesh
    rows: NDArray[np.int64]
    across: NDArray[np.int64]


@dataclass
class PieceStatus:
    """One part's attempt: written, or the balls its halo must grow by.

    ``balls`` are ``(rows, centres (m, d), radii (m,))`` of the computed cells whose reach
    the halo missed; ``path`` the piece written (None while not certified or for an empty
    part); ``computed`` the cells computed, ``halo`` the sites of other parts present.
    """

    path: str | None
    balls: tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]] | None
    computed: int
    halo: int


def piece_mesh(
    domain: Domain,
    part: pt.Part,
    total_sites: int,
    allow_outside: bool,
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    ball_rows: NDArray[np.int64],
    ball_radii: NDArray[np.float64],
    *slices: tuple[NDArray[np.int64], NDArray[np.float64]],
) -> tuple[PieceMesh | None, PieceStatus]:
    """The piece of ``part`` among its sites and ``slices`` of other parts' sites.

    ``slices`` hold every site of the problem in the box ``[lo, hi]`` and within
    ``ball_radii`` of the sites of rows ``ball_rows``. Returns the piece when every cell
    the core computed is covered (its reach inside the box or inside its own ball), or
    when every site is present; else None and the balls of the cells not covered.
    """
    rows = np.concatenate([part.rows] + [r for r, _ in slices])
    sites = np.concatenate([part.sites] + [s for _, s in slices])
    # A site may come in a box slice and in a ball slice: once, in row order.
    rows, first = np.unique(rows, return_index=True)
    sites = np.ascontiguousarray(sites[first])
    own = np.searchsorted(rows, part.rows)
    # The core works in the domain's frame; the piece is kept in L.
    frame = domain.frame
    with frame.input_errors():
        out = _core.mesh_part(
            domain._core,
            frame.steps_to_core(sites),
            rows.astype(np.int64),
            own.astype(np.uint32),
            int(total_sites),
            allow_outside=allow_outside,
        )
    mapped: dict[str, Any] = {key: frame.to_input(key, value) for key, value in out.items()}
    computed = mapped["computed"]
    reach = np.sqrt(mapped["reach2"])
    halo = len(rows) - len(part.rows)
    covered = _covered(sites[computed], rows[computed], reach, lo, hi, ball_rows, ball_radii)
    if len(rows) < total_sites and not covered.all():
        bad = computed[~covered]
        balls = (rows[bad], sites[bad], pt.BALL_FACTOR * reach[~covered])
        return None, PieceStatus(None, balls, len(computed), halo)
    local = np.full(len(rows), -1, dtype=np.intp)
    local[own] = np.arange(len(own))
    owner, neighbour = mapped["owner"], mapped["neighbour"]
    across = np.where(neighbour >= 0, rows[neighbour], -1).astype(np.int64)
    mesh = PolyMesh(
        points=mapped["points"],
        face_offsets=mapped["face_offsets"],
        face_vertices=mapped["face_vertices"],
        owner=local[owner],
        neighbour=np.where(neighbour >= 0, local[neighbour], -1),
        boundary_element=mapped["boundary_element"],
        n_cells=len(own),
    )
    return PieceMesh(mesh, part.rows, across), PieceStatus(None, None, len(computed), halo)


def _covered(
    sites: NDArray[np.float64],
    rows: NDArray[np.int64],
    reach: NDArray[np.float64],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    ball_rows: NDArray[np.int64],
    ball_radii: NDArray[np.float64],
) -> NDArray[np.bool_]:
    """Whether each cell's reach lies in the box or in the largest ball of its row."""
    room = pt.room_in_box(sites, lo, hi)
    covered = reach < pt.COVER_FRACTION * room
    if len(ball_rows):
        order = np.argsort(ball_rows, kind="stable")
        keys, radii = ball_rows[order], ball_radii[order]
        largest = np.maximum.reduceat(radii, np.flatnonzero(np.diff(keys, prepend=-1)))
        keys = np.unique(keys)
        at = np.minimum(np.searchsorted(keys, rows), len(keys) - 1)
        has = keys[at] == rows
        covered |= has & (reach < pt.COVER_FRACTION * np.where(has, largest[at], 0.0))
    return covered


def write_piece(
    domain: Domain,
    part: pt.Part,
    cells: pt.PartCells,
    total_sites: int,
    allow_outside: bool,
    path: str,
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    ball_rows: NDArray[np.int64],
    ball_radii: NDArray[np.float64],
    *slices: tuple[NDArray[np.int64], NDArray[np.float64]],
) -> PieceStatus:
    """Make part's piece (:func:`piece_mesh`) and, when certified, write it to ``path``.

    Cell data: ``row`` (problem row) and :data:`CELL_ARRAYS` from ``cells``.
    """
    if len(part.rows) == 0:
        return PieceStatus(None, None, 0, 0)
    piece, status = piece_mesh(
        domain, part, total_sites, allow_outside, lo, hi, ball_rows, ball_radii, *slices
    )
    if piece is None:
        return status
    data: dict[str, ArrayLike] = {"row": part.rows.astype(np.float64)}
    data.update({name: cells.arrays[name] for name in CELL_ARRAYS})
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    write_vtu(piece.mesh, path, cell_data=data)
    status.path = path
    return status


def cells_paths(path: str | Path) -> tuple[Path, Path]:
    """The index and the pieces' directory of ``path``.

    ``path`` is a ``.pvtu`` file (its pieces in the directory of its name without suffix
    beside it), or a directory (``cells.pvtu`` and the pieces in it).
    """
    path = Path(path)
    if path.suffix.lower() == ".pvtu":
        return path, path.with_suffix("")
    return path / "cells.pvtu", path


def write_pieces(
    cluster: Any, parts: list[Any], cells: list[Any], path: str | Path, rho: float
) -> tuple[Path, list[int]]:
    """Each part's piece written by its worker, then the index by the client.

    ``cluster`` is :class:`hcvt.distributed.driver._Cluster` (the domain on every worker);
    ``parts`` and ``cells`` the futures of a :class:`hcvt.distributed.PartitionedDiagram`;
    ``rho`` the first halo's width around each part's sites' box, L. Returns the index's
    path and the halo sites of every round.
    """
    index, directory = cells_paths(path)
    directory.mkdir(parents=True, exist_ok=True)
    boxes, counts = cluster.boxes(parts)
    d = cluster.domain.dim
    pending = [p for p in range(len(parts)) if counts[p] > 0]
    region = {p: (boxes[p][0] - rho, boxes[p][1] + rho) for p in pending}
    balls: dict[int, list[tuple[Any, Any, Any]]] = {p: [] for p in pending}
    written: dict[int, str] = {}
    halos: list[int] = []
    while pending:
        futures = []
        for p in pending:
            lo, hi = region[p]
            ball_rows, centres, radii = _joined(balls[p], d)
            slices = [
                cluster.submit(pt.halo_slice, parts[q], lo, hi)
                for q in _meeting(boxes, counts, p, lo, hi)
            ]
            if len(radii):
                blo, bhi = (centres - radii[:, None]).min(0), (centres + radii[:, None]).max(0)
                slices += [
                    cluster.submit(pt.ball_slice, parts[q], centres, radii)
                    for q in _meeting(boxes, counts, p, blo, bhi)
                ]
            futures.append(
                cluster.submit(
                    write_piece,
                    cluster.domain_future,
                    parts[p],
                    cells[p],
                    cluster.n,
                    cluster.allow_outside,
                    str(directory / f"part{p:05d}.vtu"),
                    lo,
                    hi,
                    ball_rows,
                    radii,
                    *slices,
                )
            )
        statuses: list[PieceStatus] = cluster.gather(futures)
        halos.append(sum(s.halo for s in statuses))
        still = []
        for p, status in zip(pending, statuses, strict=True):
            if status.path is not None:
                written[p] = status.path
            elif status.balls is not None:
                balls[p].append(status.balls)
                still.append(p)
        pending = still
    names = {"site": "Int64", "row": "Float64", **dict.fromkeys(CELL_ARRAYS, "Float64")}
    write_pvtu(index, [written[p] for p in sorted(written)], names)
    return index, halos


def _meeting(
    boxes: list[Any], counts: list[int], p: int, lo: NDArray[np.float64], hi: NDArray[np.float64]
) -> list[int]:
    """The other non-empty parts whose sites' box meets ``[lo, hi]``."""
    return [
        q
        for q in range(len(boxes))
        if q != p and counts[q] > 0 and np.all(boxes[q][0] <= hi) and np.all(boxes[q][1] >= lo)
    ]


def _joined(
    balls: list[tuple[Any, Any, Any]], d: int
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]:
    """The balls of every round as three arrays."""
    if not balls:
        return np.zeros(0, dtype=np.int64), np.zeros((0, d)), np.zeros(0)
    return (
        np.concatenate([b[0] for b in balls]),
        np.concatenate([b[1] for b in balls]),
        np.concatenate([b[2] for b in balls]),
    )
