"""Merged boundary faces: a cell's pieces of input triangles joined so that checkMesh passes.

A boundary cell of a diagram meets the domain's surface in one piece per input triangle it
crosses, each an exact planar face (:class:`hcvt.mesh.polymesh.PolyMesh`). OpenFOAM's
``checkMesh`` judges every face against its cell's centre on its own, and two of its
checks fail on such pieces though the cells are the exact Voronoi cells:

- **skewness** of a boundary face is ``|s| / max(0.4 |d|, extent of the face along s)``,
  with ``d`` the normal offset and ``s`` the tangential offset of the face centre from the
  cell centre (:mod:`hcvt.mesh.quality`): a small piece at a cell's rim scores far
  above checkMesh's limit 4 (130 at most on a converged 50k bunny);
- **face pyramids**: a cell that wraps a reflex edge of the surface can have its centre
  behind the plane of one of its pieces, and the cone from the centre over that piece has
  negative volume.

Both vanish when the offending piece is joined to its neighbour pieces of the same cell:
the merged face is larger (its extent grows, ``s`` shrinks) and its area vector averages
the pieces' normals. :func:`merge_failing_boundary_faces` merges only as much as needed:
round after round, a failing face joins the neighbouring face (or faces) of its cell and
patch whose join passes and changes the cell's volume least, until no boundary face
fails. A merged face is one polygon, the outline of its pieces: vertices strictly inside
the merged region (used by that cell's pieces only) drop out of it.

Exact planar faces do not help where a piece fails: a piece is already the largest planar
face of its part of the surface (all of one input triangle within the cell), splitting it
leaves a smaller face at the same rim, and the cell's centre is fixed by the cell.

Nor does any grouping help in a cell that is in several parts (a thin tunnel of the
cheese crossing its convex region): the faces of a small detached part are seen from the
centre of the whole cell, in the large part, from behind. :func:`merged_boundary`
therefore first joins every part of a cell but its largest to a neighbour
(:mod:`hcvt.mesh.parts`); on a converged 1k CVT of the cheese those were the three cells
whose faces merging alone left failing (parts of 3.7e-3, 4.6e-4 and 1.9e-5 of their
cells). Faces that still fail after merging are reported (``MergeReport.failing``).

The cells stay the Voronoi cells, one per site, and every interior face is untouched
(but for the faces of a detached part, which its new cell absorbs). What
changes is how OpenFOAM *measures* a cell with a merged face: a merged face is not planar,
and OpenFOAM takes its area vector (exact: the vector area of a closed loop depends on the
loop alone) and its centre (the area-weighted centre of a fan from the vertex average), so
the volume it computes, ``Σ S_f·(c_f - x0) / 3``, is no longer the cell's exact volume.
:attr:`hcvt.mesh.polymesh.PolyMesh.cell_geometry` computes exactly what OpenFOAM computes, so
the change is measurable before writing: see ``docs/results/checkmesh.txt``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hcvt.mesh.parts import join_detached_parts
from hcvt.mesh.patches import boundary_patches
from hcvt.mesh.polymesh import PolyMesh
from hcvt.mesh.quality import face_quality, fails_checkmesh

if TYPE_CHECKING:
    from hcvt.geometry.domain import Domain

#: The ways :func:`hcvt.export.write_openfoam` writes boundary faces.
BOUNDARY_FACES = ("exact", "merged")
#: Why ``boundary_faces="split"`` is refused.
SPLIT_REMOVED = (
    "boundary_faces='split' was removed (issue 30): its parts made OpenFOAM's laplacianFoam "
    "diverge; 'merged', the default, passes checkMesh and the solver converges"
)

#: Rounds of :func:`merge_failing_boundary_faces` before it gives up on the faces left.
MAX_ROUNDS = 60


class MergeReport(NamedTuple):
    """What :func:`merge_failing_boundary_faces` did."""

    rounds: int
    """Rounds of merging run."""
    merged_faces: int
    """Boundary faces of the input that were joined into others (they are gone)."""
    groups: int
    """Merged faces made (each of two or more input faces)."""
    failing: NDArray[np.intp]
    """Shape (k,): boundary faces of the output that still fail (none when it passed)."""
    joined_parts: int = 0
    """Detached parts of cells joined to a neighbour first (:mod:`hcvt.mesh.parts`)."""


#: Relative round-off of a candidate's change of volume ``|S·c - Σ S_i·c_i| / 3``: 64 ulps
#: of the moments it is the difference of.
ROUND_OFF = 64 * np.finfo(np.float64).eps


def merged_boundary(
    mesh: PolyMesh, domain: Domain | None = None, labels: ArrayLike | None = None
) -> tuple[PolyMesh, MergeReport]:
    """``mesh`` with its failing boundary faces merged, within each patch (module docs).

    First every cell in several parts keeps its largest and gives the others to
    neighbours (:func:`hcvt.mesh.parts.join_detached_parts`; their number is
    ``MergeReport.joined_parts``). ``domain`` and ``labels`` give the patches as
    :func:`write_openfoam` makes them (:func:`hcvt.mesh.patches.boundary_patches`); see
    :func:`merge_failing_boundary_faces`.
    """
    mesh, joined = join_detached_parts(mesh)
    patch, _ = boundary_patches(mesh, domain, labels)
    merged, report = merge_failing_boundary_faces(mesh, patch)
    return merged, report._replace(joined_parts=len(joined.cells))


def merge_boundary_faces(
    mesh: PolyMesh, group: NDArray[np.intp]
) -> tuple[PolyMesh, NDArray[np.intp]]:
    """Join the boundary faces of ``mesh`` that share a group into one face each.

    Parameters
    ----------
    mesh : PolyMesh
        A 3D conforming mesh.
    group : ndarray of intp, shape (f,)
        For every face the face that represents its group (``group[k] == k`` for a face
        left alone, and for every interior face). The faces of one group must be boundary
        faces of the same cell, oriented out of it (as they are in a conforming mesh),
        whose outline is one simple loop (:func:`outlines`).

    Returns
    -------
    merged : PolyMesh
        The faces of ``mesh`` in order, each group in place of its representative and its
        other members left out; a merged face's vertex loop is the outline of its
        members, in their orientation; its ``boundary_element`` is the representative's.
        The points are ``mesh.points`` (the vertices that dropped out are unused:
        :meth:`PolyMesh.compacted` removes them).
    faces : ndarray of intp, shape (f',)
        For every face of ``merged``, the face of ``mesh`` that represents it.

    Raises
    ------
    ValueError
        A group whose outline is not one simple loop.
    """
    f = mesh.n_faces
    size = np.bincount(group, minlength=f)
    joined = np.flatnonzero(size[group] > 1)  # faces of groups of two or more
    ids, loop_offsets, loops, simple = outlines(mesh, joined, group[joined])
    if not simple.all():
        raise ValueError(f"the faces of group {ids[~simple][0]} do not make one simple loop")
    rep = np.flatnonzero(group == np.arange(f))
    sizes = mesh.face_sizes[rep].copy()
    is_loop = size[rep] > 1
    sizes[is_loop] = np.diff(loop_offsets)  # ids is rep[is_loop], both sorted
    offsets = np.zeros(len(rep) + 1, dtype=np.intp)
    np.cumsum(sizes, out=offsets[1:])
    vertices = np.empty(offsets[-1], dtype=np.intp)
    start, fsize = mesh.face_offsets[rep[~is_loop]], sizes[~is_loop]
    within = _within(fsize)
    vertices[np.repeat(offsets[:-1][~is_loop], fsize) + within] = mesh.face_vertices[
        np.repeat(start, fsize) + within
    ]
    at = offsets[:-1][is_loop]
    vertices[np.repeat(at, sizes[is_loop]) + _within(sizes[is_loop])] = loops
    merged = PolyMesh(
        points=mesh.points,
        face_offsets=offsets,
        face_vertices=vertices,
        owner=mesh.owner[rep],
        neighbour=mesh.neighbour[rep],
        boundary_element=mesh.boundary_element[rep],
        n_cells=mesh.n_cells,
    )
    return merged, rep


def outlines(
    mesh: PolyMesh, faces: NDArray[np.intp], group: NDArray[np.intp]
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp], NDArray[np.bool_]]:
    """The outline of each group of faces as one vertex loop, where it is one.

    Parameters
    ----------
    mesh : PolyMesh
    faces, group : ndarray of intp, shape (m,)
        Face ``faces[j]`` belongs to group ``group[j]`` (any integer id; a face may be in
        several groups).

    Returns
    -------
    ids : ndarray of intp, shape (g,)
        The distinct groups, sorted.
    offsets, vertices : ndarray of intp
        The outline of each group whose outline is one simple loop, in the order of
        ``ids``, starting at its lowest point id: loop ``j`` is
        ``vertices[offsets[j]:offsets[j + 1]]``.
    simple : ndarray of bool, shape (g,)
        Whether it is: the directed edges of a group's faces, less every edge whose
        reverse is in the group too (the edges between two of its pieces), form its
        outline; it is one simple loop when every vertex starts at most one outline edge
        and following them from any edge visits them all before coming back. An annulus,
        or pieces touching at a single vertex, are not.
    """
    if len(faces) == 0:
        empty = np.zeros(0, dtype=np.intp)
        return empty, np.zeros(1, dtype=np.intp), empty, np.zeros(0, dtype=bool)
    sizes = mesh.face_sizes[faces]
    within = _within(sizes)
    first = np.repeat(mesh.face_offsets[faces], sizes)
    tail = mesh.face_vertices[first + within]
    head = mesh.face_vertices[first + (within + 1) % np.repeat(sizes, sizes)]
    ids, grp = np.unique(group, return_inverse=True)
    grp = np.repeat(grp, sizes).astype(np.int64)
    lo, hi = np.minimum(tail, head), np.maximum(tail, head)
    # Edges inside a group come as a pair a->b, b->a: sort by (group, edge) and drop runs
    # of two opposite uses. An edge used twice the same way would be a fold: it stays,
    # and the loop test below fails.
    order = np.lexsort((tail, hi, lo, grp))
    g_, lo_, hi_, t_ = grp[order], lo[order], hi[order], tail[order]
    pair = (g_[1:] == g_[:-1]) & (lo_[1:] == lo_[:-1]) & (hi_[1:] == hi_[:-1])
    pair &= t_[1:] != t_[:-1]
    inner = np.zeros(len(tail), dtype=bool)
    inner[order[1:][pair]] = inner[order[:-1][pair]] = True
    tail, head, grp = tail[~inner], head[~inner], grp[~inner]
    bad = np.zeros(len(ids), dtype=bool)
    count = np.bincount(grp, minlength=len(ids))
    bad |= count < 3
    # Successor of each outline edge: the edge of its group leaving its head.
    p = np.int64(len(mesh.points))
    key = grp * p + tail
    order = np.argsort(key, kind="stable")
    key_sorted = key[order]
    bad[grp[order[1:][key_sorted[1:] == key_sorted[:-1]]]] = True  # a pinch
    look = np.minimum(np.searchsorted(key_sorted, grp * p + head), len(key) - 1)
    found = key_sorted[look] == grp * p + head
    bad[grp[~found]] = True
    successor = np.where(found, order[look], -1)
    # Walk every group's loop from its first edge at once: a simple loop comes back to
    # its first edge after exactly as many steps as the group has outline edges.
    start = np.full(len(ids), -1, dtype=np.intp)
    start[grp[::-1]] = np.arange(len(grp))[::-1]
    steps = int(count.max()) if len(count) else 0
    walk = np.full((steps, len(ids)), -1, dtype=np.intp)
    current = start.copy()
    closed_at = np.full(len(ids), -1, dtype=np.intp)
    for step in range(steps):
        alive = (closed_at < 0) & (current >= 0)
        if not alive.any():
            break
        walk[step, alive] = current[alive]
        current = np.where(alive, successor[np.maximum(current, 0)], current)
        closed_at[alive & (current == start)] = step + 1
    bad |= closed_at != count
    # The loops as rows of the walk, each rotated to start at its lowest point id.
    good = np.flatnonzero(~bad)
    rows = tail[walk[:, good].T]  # (g', steps); entries past a loop's length are junk
    length = count[good]
    valid = np.arange(steps)[None, :] < length[:, None]
    shift = np.argmin(np.where(valid, rows, np.iinfo(np.intp).max), axis=1)
    column = (np.arange(steps)[None, :] + shift[:, None]) % np.maximum(length, 1)[:, None]
    rings = np.take_along_axis(rows, column, axis=1)[valid]
    offsets = np.zeros(len(good) + 1, dtype=np.intp)
    np.cumsum(length, out=offsets[1:])
    return ids, offsets, rings, ~bad


def _within(sizes: NDArray[np.intp]) -> NDArray[np.intp]:
    """0, 1, ..., sizes[0] - 1, 0, 1, ..., sizes[1] - 1, ...: positions within blocks."""
    return np.arange(int(sizes.sum())) - np.repeat(np.cumsum(sizes) - sizes, sizes)


def boundary_adjacency(
    mesh: PolyMesh, patch: NDArray[np.intp]
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Pairs of boundary faces of one cell and one patch that share an edge.

    Returns ``a``, ``b`` (shape (m,), ``a < b``, one row per shared edge). An edge used by
    more than two boundary faces of one cell (the cell touching itself) gives no pair.
    """
    boundary = np.flatnonzero(~mesh.interior)
    sizes = mesh.face_sizes[boundary]
    start = mesh.face_offsets[boundary]
    within = np.arange(sizes.sum()) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    tail = mesh.face_vertices[np.repeat(start, sizes) + within]
    head = mesh.face_vertices[np.repeat(start, sizes) + (within + 1) % np.repeat(sizes, sizes)]
    face = np.repeat(boundary, sizes)
    cell = mesh.owner[face].astype(np.int64)
    lo, hi = np.minimum(tail, head), np.maximum(tail, head)
    order = np.lexsort((face, hi, lo, cell))
    key = np.column_stack([cell, lo, hi])[order]
    change = np.flatnonzero(np.any(np.diff(key, axis=0) != 0, axis=1)) + 1
    starts = np.concatenate([[0], change])
    length = np.diff(np.concatenate([starts, [len(order)]]))
    pair = starts[length == 2]
    a, b = face[order][pair], face[order][pair + 1]
    ok = (a != b) & (patch[a] == patch[b])
    a, b = a[ok], b[ok]
    return np.minimum(a, b), np.maximum(a, b)


def failing_boundary_faces(mesh: PolyMesh) -> NDArray[np.intp]:
    """Boundary faces checkMesh flags: skewness above ``SKEWNESS_TARGET``, inverted pyramid."""
    bad = fails_checkmesh(*face_quality(mesh, mesh.cell_geometry.centroid))
    return np.flatnonzero(bad & ~mesh.interior)


def merge_failing_boundary_faces(
    mesh: PolyMesh, patch: NDArray[np.intp], max_rounds: int = MAX_ROUNDS
) -> tuple[PolyMesh, MergeReport]:
    """Merge boundary faces of ``mesh`` until none fails checkMesh's skewness or pyramids.

    Each round measures the current faces as checkMesh does (:mod:`hcvt.mesh.quality`)
    and offers each failing boundary face its joins with the neighbouring faces of its
    cell and patch (sharing an edge), one at a time and all at once, whose outline is one
    simple loop. It takes a join whose face passes (against the current cell centres),
    and among those, or if none passes, the one that changes its cell's volume as
    OpenFOAM computes it the least: a merged face's area vector ``S`` is the sum of its
    pieces', so the cell's volume ``Σ S_f·c_f / 3`` changes by ``(S·c - Σ S_i·c_i) / 3``
    with ``c`` the merged face's centre (OpenFOAM's fan) and ``c_i`` the pieces'. Joins
    are made smallest change first, each face at most once per round. Stops when no
    boundary face fails, or when no failing face can be joined further (those are in
    ``MergeReport.failing``).

    Parameters
    ----------
    mesh : PolyMesh
        A 3D conforming mesh (:meth:`PolyMesh.check` passes).
    patch : ndarray of intp, shape (f,)
        The patch of every boundary face (-1 interior), as
        :func:`hcvt.mesh.patches.boundary_patches` gives: faces of different patches
        are never merged.
    max_rounds : int
        Rounds before giving up on the faces left.

    Returns
    -------
    PolyMesh
        As :func:`merge_boundary_faces` makes it; its interior faces and cells are
        ``mesh``'s.
    MergeReport
    """
    if mesh.dim != 3:
        raise ValueError("boundary faces are merged in 3D meshes only (a 2D mesh's are edges)")
    a, b = boundary_adjacency(mesh, patch)
    group = np.arange(mesh.n_faces, dtype=np.intp)
    merged, rep = mesh, group.copy()
    rounds = 0
    failing = failing_boundary_faces(merged)
    while len(failing) and rounds < max_rounds:
        centroid = merged.cell_geometry.centroid
        joins = _best_joins(mesh, group, rep[failing], a, b, centroid)
        if not joins:
            break
        rounds += 1
        # Joins are disjoint sets of representatives: each points at its smallest.
        relabel = np.arange(mesh.n_faces, dtype=np.intp)
        for members in joins:
            relabel[members] = members[0]
        group = relabel[group]
        merged, rep = merge_boundary_faces(mesh, group)
        failing = failing_boundary_faces(merged)
    size = np.bincount(group, minlength=mesh.n_faces)
    report = MergeReport(
        rounds=rounds,
        merged_faces=int((size[group] > 1).sum() - (size > 1).sum()),
        groups=int((size > 1).sum()),
        failing=failing,
    )
    return merged, report


def _best_joins(
    mesh: PolyMesh,
    group: NDArray[np.intp],
    failing: NDArray[np.intp],
    a: NDArray[np.intp],
    b: NDArray[np.intp],
    centroid: NDArray[np.float64],
) -> list[NDArray[np.intp]]:
    """The joins to make this round: each a set of group representatives.

    A failing group's candidates are its union with one neighbouring group, and with all
    of them at once (two pieces can touch along an edge and again at a vertex, a pinch
    that a third piece closes). Of those with one simple outline it takes the one that
    passes checkMesh's face checks, measured against the current cell centres
    ``centroid``, and among equals the smallest change of volume
    ``|S·c - Σ S_i·c_i| / 3``. Candidates are taken smallest change first, skipping any
    that touches a group already joined this round (it is offered again next round).
    """
    f = mesh.n_faces
    ga, gb = group[a], group[b]
    across = ga != gb
    src = np.concatenate([ga[across], gb[across]])
    dst = np.concatenate([gb[across], ga[across]])
    want = np.zeros(f, dtype=bool)
    want[failing] = True
    key = np.unique(src[want[src]].astype(np.int64) * f + dst[want[src]])
    if len(key) == 0:
        return []
    src, dst = key // f, key % f
    # Candidates: one per (failing group, neighbour), then one star per failing group
    # with two or more neighbours. Rows (candidate, group) list their groups.
    stars, first, count = np.unique(src, return_index=True, return_counts=True)
    multi = count >= 2
    star_id = len(key) + np.cumsum(multi) - 1  # by entry of stars
    of_row = np.searchsorted(stars, src)
    in_star = multi[of_row]
    n_pairs = len(key)
    cand_src = np.concatenate([src, stars[multi]])
    row_cand = np.concatenate(
        [np.arange(n_pairs), np.arange(n_pairs), star_id[of_row][in_star], star_id[multi]]
    )
    row_group = np.concatenate([src, dst, dst[in_star], stars[multi]])
    # Member faces of each candidate.
    order = np.argsort(group, kind="stable")
    starts = np.searchsorted(group[order], np.arange(f + 1))
    n = starts[row_group + 1] - starts[row_group]
    faces_all = order[np.repeat(starts[row_group], n) + _within(n)]
    cand_all = np.repeat(row_cand, n)
    ids, loop_offsets, loops, simple = outlines(mesh, faces_all, cand_all)
    ok = ids[simple]
    if len(ok) == 0:
        return []
    # The change of volume of each simple candidate, from OpenFOAM's face geometry, and
    # whether its face would pass.
    rings = PolyMesh(
        points=mesh.points,
        face_offsets=loop_offsets,
        face_vertices=loops,
        owner=mesh.owner[cand_src[ok]],
        neighbour=np.full(len(ok), -1, dtype=np.intp),
        boundary_element=np.zeros(len(ok), dtype=np.intp),
        n_cells=mesh.n_cells,
    )
    centre, area = rings.face_geometry
    fails = fails_checkmesh(*face_quality(rings, centroid))
    piece_centre, piece_area = mesh.face_geometry
    moment = np.einsum("ij,ij->i", piece_area[faces_all], piece_centre[faces_all])
    exact = np.bincount(cand_all, weights=moment, minlength=len(cand_src))[ok]
    joined = np.einsum("ij,ij->i", area, centre)
    change = np.abs(joined - exact) / 3.0
    # Coplanar pieces change nothing: their change is 0 but for round-off, which must not
    # rank candidates (it follows the last bits of the geometry, and with them the
    # summation orders of numpy and of the core). Below it, ties go by candidate order.
    gross = np.bincount(cand_all, weights=np.abs(moment), minlength=len(cand_src))[ok]
    change[change <= ROUND_OFF * (np.abs(joined) + gross)] = 0.0
    # Each failing group's best candidate (passing first, then least change), then
    # those best first.
    best = np.lexsort((change, fails, cand_src[ok]))
    head = np.concatenate([[True], cand_src[ok][best][1:] != cand_src[ok][best][:-1]])
    chosen = best[head]
    chosen = chosen[np.lexsort((change[chosen], fails[chosen]))]
    row_order = np.argsort(row_cand, kind="stable")
    row_start = np.searchsorted(row_cand[row_order], np.arange(len(cand_src) + 1))
    joins: list[NDArray[np.intp]] = []
    busy = np.zeros(f, dtype=bool)
    for c in ok[chosen].tolist():
        members = np.unique(row_group[row_order[row_start[c] : row_start[c + 1]]])
        if busy[members].any():
            continue
        busy[members] = True
        joins.append(members)
    return joins
