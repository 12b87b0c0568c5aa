"""Cells in several parts: each part but the largest joined to a neighbour.

A clipped Voronoi cell is the convex Voronoi cell intersected with the domain, and in a
non-convex domain that can be two or more disjoint solids: on the cheese (genus 133) a
thin tunnel or slot can cross a cell's convex region and leave a small part of it on the
far side, touching the rest of the cell at no face. The diagram's moments are right (they
integrate over every part), but a finite-volume solver treats a cell as one connected
control volume around one centre: OpenFOAM's ``checkMesh`` measures the small part's
faces from the centre of the whole cell, which lies in the large part, about a cell size
away and behind the part's surface, and fails them as inverted face pyramids whatever
way the boundary pieces are grouped into faces (the cones from that centre over the small
part's boundary sum to a negative volume). The three faces the merged boundary of a
converged 1k CVT of the cheese left failing were all on such parts.

:func:`join_detached_parts` gives each part other than the largest to the neighbouring
cell it shares the most face area with: the faces between them disappear into that cell,
and every cell becomes one connected solid. No vertex moves and no face is cut, so the
geometry stays exact (the volumes still sum to the domain's); one cell per site still, but
a cell that receives a part is its Voronoi cell and that part.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from hcvt.mesh.polymesh import PolyMesh
from hcvt.mesh.quality import NON_ORTHOGONALITY_LIMIT, face_quality

#: Steps of :func:`join_detached_parts`: each joins every part that touches one cell, or
#: divides one part that touches several.
MAX_STEPS = 1000

#: A vertex closer than this to a dividing plane, relative to the part's extent, is on it.
CLEARANCE = 1e-9


class Parts(NamedTuple):
    """The connected parts of every cell (:func:`cell_parts`)."""

    cell: NDArray[np.intp]
    """Shape (u,): the cell of each face use (every face once for its owner, once more
    for its neighbour if it has one), in that order: owners of faces 0..f-1, then the
    neighbours of the interior faces in face order."""
    face: NDArray[np.intp]
    """Shape (u,): the face of each use."""
    part: NDArray[np.intp]
    """Shape (u,): the part of each use, numbered over the whole mesh."""
    volume: NDArray[np.float64]
    """Shape (parts,): each part's volume (the divergence theorem on its faces)."""
    of_cell: NDArray[np.intp]
    """Shape (parts,): each part's cell."""


def cell_parts(mesh: PolyMesh) -> Parts:
    """The connected parts of every cell of a 3D mesh: its faces joined by shared edges.

    Two faces of a cell are in one part when they share an edge; in a conforming mesh
    every edge of a cell is used by exactly two of its faces, so a part is a closed
    surface, and a cell of one part is one solid (:meth:`PolyMesh.check`).
    """
    inner = np.flatnonzero(mesh.interior)
    f = mesh.n_faces
    cell = np.concatenate([mesh.owner, mesh.neighbour[inner]]).astype(np.intp)
    face = np.concatenate([np.arange(f), inner]).astype(np.intp)
    sizes = mesh.face_sizes[face]
    start = np.repeat(mesh.face_offsets[face], sizes)
    within = np.arange(len(start)) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    nxt = within + 1
    nxt[np.cumsum(sizes) - 1] = 0
    tail = mesh.face_vertices[start + within].astype(np.int64)
    head = mesh.face_vertices[start + nxt].astype(np.int64)
    use = np.repeat(np.arange(len(face)), sizes)
    lo, hi = np.minimum(tail, head), np.maximum(tail, head)
    # The two uses of each (cell, edge) are joined: sort by (cell, edge), pair neighbours.
    order = np.lexsort((hi, lo, cell[use]))
    c_, lo_, hi_ = cell[use][order], lo[order], hi[order]
    same = (c_[1:] == c_[:-1]) & (lo_[1:] == lo_[:-1]) & (hi_[1:] == hi_[:-1])
    a, b = use[order][:-1][same], use[order][1:][same]
    n = len(face)
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    # Parts numbered by their first use, so that the numbers do not depend on scipy's.
    _, first = np.unique(label, return_index=True)
    rank = np.empty(len(first), dtype=np.intp)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    part = rank[label]
    centre, area = mesh.face_geometry
    sign = np.where(np.arange(n) < f, 1.0, -1.0)  # a neighbour's use faces the other way
    # Cones from a point of each part (its first face's centre) over its faces.
    apex = np.zeros((len(first), 3))
    apex[rank] = centre[face[first]]
    cone = sign * np.einsum("ij,ij->i", area[face], centre[face] - apex[part]) / 3.0
    volume = np.bincount(part, weights=cone, minlength=len(first)).astype(np.float64)
    of_cell = np.zeros(len(first), dtype=np.intp)
    of_cell[part] = cell
    return Parts(cell, face, part, volume, of_cell)


class Joined(NamedTuple):
    """What :func:`join_detached_parts` moved, one row per detached part."""

    cells: NDArray[np.intp]
    """Shape (k,): the cell each part came from."""
    to: NDArray[np.intp]
    """Shape (k,): the cell that took it (all of it, or its side of the plane)."""
    shared_with: NDArray[np.intp]
    """Shape (k,): the cell that took the other side of a divided part, else -1."""
    volume: NDArray[np.float64]
    """Shape (k,): the part's volume."""


def join_detached_parts(mesh: PolyMesh) -> tuple[PolyMesh, Joined]:
    """``mesh`` with every cell one connected solid (module docs).

    Every part of a cell but its largest goes to the cells across its faces whose own
    largest part lies there (so that it joins a solid, not another detached part): whole
    to the one cell it touches, or, when it touches several, divided between the two it
    shares the most face area with by the plane midway between their centroids
    (:func:`divide_part`; whole to the first if that plane makes no clean cut). The
    faces between a part and its new cell are dropped. A part that touches no other cell
    (surrounded by the boundary) stays where it is. 2D meshes are returned as they are.

    Returns
    -------
    PolyMesh
        ``mesh`` with the moved parts' faces renamed, the faces inside a new cell
        dropped, a divided part's faces cut and its section added; points are added for
        the cut's vertices, cells and every other face are unchanged.
    Joined
        The parts moved: first those that touch one cell, in the order of their cells,
        then the divided ones, each after the last.
    """
    rows: list[tuple[int, int, int, float]] = []
    steps = 0
    while mesh.dim == 3 and steps < MAX_STEPS:
        steps += 1
        parts = cell_parts(mesh)
        found = _detached(mesh, parts)
        if found is None:
            break
        part, target, _ = found
        f = mesh.n_faces
        inner = np.flatnonzero(mesh.interior)
        first = np.concatenate([[True], part[1:] != part[:-1]])
        count = np.diff(np.flatnonzero(np.concatenate([first, [True]])))
        whole = np.repeat(count == 1, count)
        if whole.any():  # every part that touches one cell: renamed at once
            give = np.full(len(parts.volume), -1, dtype=np.intp)
            give[part[whole]] = target[whole]
            new_cell = np.where(give[parts.part] >= 0, give[parts.part], parts.cell)
            neighbour = mesh.neighbour.copy()
            neighbour[inner] = new_cell[f:]
            moving = part[whole]
            rows += [
                (int(parts.of_cell[q]), int(give[q]), -1, float(parts.volume[q]))
                for q in moving.tolist()
            ]
            mesh = _renamed(mesh, new_cell[:f], neighbour)
            continue
        # The first part that touches several cells: divided between two of them, or
        # given whole to one; the first choice whose interior faces pass checkMesh
        # (``target`` is sorted by part, then shared area, largest first).
        q = int(part[0])
        cell = int(parts.of_cell[q])
        near = target[part == q].tolist()
        uses = parts.face[parts.part == q]
        # Divided between the first two, whole to each, divided between other pairs.
        pairs = [(a, b) for i, a in enumerate(near) for b in near[i + 1 :]]
        choices = pairs[:1] + [(a, -1) for a in near] + pairs[1:]
        best: tuple[int, PolyMesh, int, int] | None = None
        for a, b in choices:
            if b >= 0:
                normal, origin = _dividing_plane(mesh, uses, cell, a, b)
                candidate = divide_part(mesh, cell, uses, normal, origin, a, b)
                if candidate is None:
                    continue
            else:
                new_cell = np.where(parts.part == q, a, parts.cell)
                neighbour = mesh.neighbour.copy()
                neighbour[inner] = new_cell[f:]
                candidate = _renamed(mesh, new_cell[:f], neighbour)
            failing = _failing_interior(candidate, [a, b] if b >= 0 else [a])
            if best is None or failing < best[0]:
                best = (failing, candidate, a, b)
            if failing == 0:
                break
        assert best is not None  # a whole join is always a choice
        _, mesh, a, b = best
        rows.append((cell, a, b, float(parts.volume[q])))
    joined = Joined(
        np.array([r[0] for r in rows], dtype=np.intp),
        np.array([r[1] for r in rows], dtype=np.intp),
        np.array([r[2] for r in rows], dtype=np.intp),
        np.array([r[3] for r in rows], dtype=np.float64),
    )
    return mesh, joined


def _failing_interior(mesh: PolyMesh, cells: list[int]) -> int:
    """Interior faces of ``cells`` that checkMesh would fail (skew, pyramid, > 70 deg).

    Measured on the faces of ``cells`` alone, against the centres of the cells on both
    sides (each computed from all its faces), with checkMesh's orthogonality limit and
    a skewness margin (3.5): merging boundary faces moves the centres a little.
    """
    touching = np.isin(mesh.owner, cells) | np.isin(mesh.neighbour, cells)
    around = np.unique(np.concatenate([mesh.owner[touching], mesh.neighbour[touching]]))
    around = around[around >= 0]
    keep = np.flatnonzero(np.isin(mesh.owner, around) | np.isin(mesh.neighbour, around))
    sub = _subset(mesh, keep)
    angle, skewness, inverted = face_quality(sub, sub.cell_geometry.centroid)
    mine = (np.isin(sub.owner, cells) | np.isin(sub.neighbour, cells)) & sub.interior
    both = mine & np.isin(sub.owner, around) & np.isin(sub.neighbour, around)
    bad = (skewness > 3.5) | inverted | (np.nan_to_num(angle) > NON_ORTHOGONALITY_LIMIT)
    return int((bad & both).sum())


def _subset(
    mesh: PolyMesh,
    kept: NDArray[np.intp],
    owner: NDArray[np.intp] | None = None,
    neighbour: NDArray[np.intp] | None = None,
) -> PolyMesh:
    """The faces ``kept`` of ``mesh``, in order (cells and points as they are).

    ``owner``/``neighbour`` (one per face of ``mesh``) replace its own where given.
    """
    owner = mesh.owner if owner is None else owner
    neighbour = mesh.neighbour if neighbour is None else neighbour
    sizes = mesh.face_sizes[kept]
    offsets = np.zeros(len(kept) + 1, dtype=np.intp)
    np.cumsum(sizes, out=offsets[1:])
    start = np.repeat(mesh.face_offsets[kept], sizes)
    within = np.arange(offsets[-1]) - np.repeat(offsets[:-1], sizes)
    return PolyMesh(
        points=mesh.points,
        face_offsets=offsets,
        face_vertices=mesh.face_vertices[start + within],
        owner=owner[kept],
        neighbour=neighbour[kept],
        boundary_element=mesh.boundary_element[kept],
        n_cells=mesh.n_cells,
    )


def _detached(
    mesh: PolyMesh, parts: Parts
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.float64]] | None:
    """The detached parts and the cells they touch: rows (part, cell, shared area).

    Sorted by part, then shared area (largest first), then cell; None when no detached
    part touches another cell's largest part.
    """
    count = np.bincount(parts.of_cell, minlength=mesh.n_cells)
    if count.max(initial=0) <= 1:
        return None
    # Each cell's main part: the largest (the first on a tie).
    main = np.full(mesh.n_cells, -1, dtype=np.intp)
    order = np.lexsort((np.arange(len(parts.volume)), -parts.volume, parts.of_cell))
    firsts = np.concatenate([[True], parts.of_cell[order][1:] != parts.of_cell[order][:-1]])
    main[parts.of_cell[order][firsts]] = order[firsts]
    detached = parts.part != main[parts.cell]
    # The use on the other side of each use's face, and whether it is a main part's.
    f = mesh.n_faces
    inner = np.flatnonzero(mesh.interior)
    use_of = np.full((f, 2), -1, dtype=np.intp)
    use_of[:, 0] = np.arange(f)
    use_of[inner, 1] = np.arange(f, f + len(inner))
    own = np.arange(len(parts.face)) < f
    across = np.where(own, use_of[parts.face, 1], use_of[parts.face, 0])
    ok = detached & (across >= 0)
    ok[ok] = parts.part[across[ok]] == main[parts.cell[across[ok]]]
    if not ok.any():
        return None
    _, area = mesh.face_geometry
    weight = np.linalg.norm(area[parts.face[ok]], axis=1)
    pair, inverse = np.unique(
        np.column_stack([parts.part[ok], parts.cell[across[ok]]]), axis=0, return_inverse=True
    )
    shared = np.bincount(inverse.ravel(), weights=weight, minlength=len(pair)).astype(np.float64)
    best = np.lexsort((pair[:, 1], -shared, pair[:, 0]))
    return pair[best, 0], pair[best, 1], shared[best]


def _dividing_plane(
    mesh: PolyMesh, faces: NDArray[np.intp], cell: int, a: int, b: int
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The plane that divides a part of ``cell`` between cells ``a`` and ``b``.

    Its normal is the direction from ``a``'s centroid to ``b``'s; where the part's faces
    with ``a`` and with ``b`` meet along an edge (on the Voronoi edge of the three sites,
    which lies on the sites' bisector of ``a`` and ``b``), the plane is turned about that
    edge so that the edge lies in it: then each of those faces falls wholly on its own
    cell's side, and no sliver of one is left on the other. Elsewhere it passes midway
    between the centroids.
    """
    centroid = mesh.cell_geometry.centroid
    normal = centroid[b] - centroid[a]
    origin = 0.5 * (centroid[a] + centroid[b])
    other = np.where(mesh.owner[faces] == cell, mesh.neighbour[faces], mesh.owner[faces])
    edges = []
    for target in (a, b):
        ids = set()
        for k in faces[other == target].tolist():
            loop = mesh.face(k).tolist()
            ids |= {(min(u, v), max(u, v)) for u, v in zip(loop, loop[1:] + loop[:1], strict=True)}
        edges.append(ids)
    common = sorted(edges[0] & edges[1])
    if common:
        u, v = common[0]
        along = mesh.points[v] - mesh.points[u]
        along /= np.linalg.norm(along)
        normal = normal - (normal @ along) * along
        origin = mesh.points[u]
    return normal / np.linalg.norm(normal), origin


def divide_part(
    mesh: PolyMesh,
    cell: int,
    faces: NDArray[np.intp],
    normal: NDArray[np.float64],
    origin: NDArray[np.float64],
    near: int,
    far: int,
) -> PolyMesh | None:
    """``mesh`` with a part of ``cell`` divided by a plane between cells ``near`` and ``far``.

    Parameters
    ----------
    mesh : PolyMesh
        A 3D conforming mesh.
    cell : int
        The cell the part belongs to.
    faces : ndarray of intp
        The part's faces (a closed surface: :func:`cell_parts`).
    normal, origin : ndarray, shape (3,)
        The plane ``(x - origin) · normal = 0``; the side ``normal`` points to goes to
        ``far``, the other to ``near``. Vertices within :data:`CLEARANCE` of the plane
        (relative to the part's extent) count as on it.

    Returns
    -------
    PolyMesh or None
        Every face of the part replaced by its pieces on either side, each renamed to its
        side's cell (dropped where that cell is on its other side too); the section (the
        plane inside the part) as faces from ``near`` to ``far``; a new vertex where the
        plane crosses an edge, in every face along that edge. None when the plane makes
        no clean cut: a face lies in it or is crossed more than twice (not convex), or
        the section is not simple loops facing ``normal``.
    """
    faces = np.asarray(faces, dtype=np.intp)
    outward = mesh.owner[faces] == cell
    loops = [
        (mesh.face(k) if out else mesh.face(k)[::-1]).tolist()
        for k, out in zip(faces.tolist(), outward.tolist(), strict=True)
    ]
    ids = np.unique(np.concatenate(loops))
    where = mesh.points[ids]
    dist = (where - origin) @ normal
    tol = CLEARANCE * float(np.ptp(where, axis=0).max())
    signs_of = np.where(np.abs(dist) <= tol, 0, np.sign(dist)).astype(int)
    side = dict(zip(ids.tolist(), signs_of.tolist(), strict=True))
    distance = dict(zip(ids.tolist(), dist.tolist(), strict=True))
    fresh: list[NDArray[np.float64]] = []
    crossing: dict[tuple[int, int], int] = {}

    def cross(u: int, v: int) -> int:
        key = (u, v) if u < v else (v, u)
        if key not in crossing:
            a, b = key  # from the lower id, so that both faces of the edge agree
            t = distance[a] / (distance[a] - distance[b])
            fresh.append(mesh.points[a] + t * (mesh.points[b] - mesh.points[a]))
            crossing[key] = len(mesh.points) + len(fresh) - 1
        return crossing[key]

    pieces: list[tuple[int, list[int], int]] = []  # (face, loop outward from cell, cell)
    for k, loop in zip(faces.tolist(), loops, strict=True):
        signs = [side[v] for v in loop]
        if not any(signs):
            return None  # in the plane
        if max(signs) <= 0 or min(signs) >= 0:
            pieces.append((k, loop, near if min(signs) < 0 else far))
            continue
        strict = [sg for sg in signs if sg]
        runs = sum(strict[i] != strict[i - 1] for i in range(len(strict)))
        if runs != 2:
            return None  # crossed more than twice
        mine: list[int] = []
        theirs: list[int] = []
        for i, v in enumerate(loop):
            w = loop[(i + 1) % len(loop)]
            if signs[i] <= 0:
                mine.append(v)
            if signs[i] >= 0:
                theirs.append(v)
            if signs[i] * side[w] < 0:
                x = cross(v, w)
                mine.append(x)
                theirs.append(x)
        pieces.append((k, mine, near))
        pieces.append((k, theirs, far))
    # The section: edges of the near side without a reverse on the near side, walked back.
    used = {
        (a, b)
        for _, loop, c in pieces
        if c == near
        for a, b in zip(loop, loop[1:] + loop[:1], strict=True)
    }
    open_edges = [(b, a) for a, b in used if (b, a) not in used]
    section = dict(open_edges)
    if len(section) != len(open_edges):
        return None  # the section touches itself at a vertex
    cuts = _loops(section) if section else []
    if cuts is None:
        return None
    points = np.vstack([mesh.points, *fresh]) if fresh else mesh.points
    if any(_vector_area(points[cut]) @ normal <= 0 for cut in cuts):
        return None  # a hole in the section, or a fold
    other = np.where(mesh.owner == cell, mesh.neighbour, mesh.owner)
    new_loops: list[list[int]] = []
    new_owner: list[int] = []
    new_neighbour: list[int] = []
    new_element: list[int] = []

    def add(loop: list[int], owner: int, neighbour: int, element: int) -> None:
        new_loops.append(loop)
        new_owner.append(owner)
        new_neighbour.append(neighbour)
        new_element.append(element)

    # Faces outside the part along a cut edge take its new vertex.
    touched = _faces_along(mesh, crossing)
    touched = touched[~np.isin(touched, faces)]
    for k in touched.tolist():
        loop = mesh.face(k).tolist()
        grown: list[int] = []
        for i, v in enumerate(loop):
            grown.append(v)
            w = loop[(i + 1) % len(loop)]
            edge = (v, w) if v < w else (w, v)
            if edge in crossing:
                grown.append(crossing[edge])
        add(grown, int(mesh.owner[k]), int(mesh.neighbour[k]), int(mesh.boundary_element[k]))
    for k, loop, owner_now in pieces:
        across = int(other[k])
        if across == owner_now:
            continue  # between the part and its new cell: inside that cell now
        element = int(mesh.boundary_element[k])
        if mesh.owner[k] == cell:
            add(loop, owner_now, across, element)
        else:  # ``cell`` was the neighbour: keep the face's direction
            add([loop[0], *loop[:0:-1]], across, owner_now, element)
    for cut in cuts:
        add(cut, near, far, -1)
    keep = np.ones(mesh.n_faces, dtype=bool)
    keep[faces] = False
    keep[touched] = False
    kept = np.flatnonzero(keep)
    sizes = np.concatenate([mesh.face_sizes[kept], [len(loop) for loop in new_loops]])
    offsets = np.zeros(len(sizes) + 1, dtype=np.intp)
    np.cumsum(sizes, out=offsets[1:])
    start = np.repeat(mesh.face_offsets[kept], mesh.face_sizes[kept])
    within = np.arange(len(start)) - np.repeat(offsets[: len(kept)], mesh.face_sizes[kept])
    vertices = np.concatenate([mesh.face_vertices[start + within], np.concatenate(new_loops)])
    return PolyMesh(
        points=points,
        face_offsets=offsets,
        face_vertices=vertices.astype(np.intp),
        owner=np.concatenate([mesh.owner[kept], new_owner]).astype(np.intp),
        neighbour=np.concatenate([mesh.neighbour[kept], new_neighbour]).astype(np.intp),
        boundary_element=np.concatenate([mesh.boundary_element[kept], new_element]).astype(np.intp),
        n_cells=mesh.n_cells,
    )


def _faces_along(mesh: PolyMesh, edges: Collection[tuple[int, int]]) -> NDArray[np.intp]:
    """The faces that use any of ``edges`` (pairs of point ids, lower first)."""
    if not edges:
        return np.zeros(0, dtype=np.intp)
    tail = mesh.face_vertices
    nxt = np.arange(1, len(tail) + 1)
    nxt[mesh.face_offsets[1:] - 1] = mesh.face_offsets[:-1]
    head = tail[nxt]
    p = np.int64(len(mesh.points))
    key = np.minimum(tail, head).astype(np.int64) * p + np.maximum(tail, head)
    wanted = np.array([a * p + b for a, b in edges], dtype=np.int64)
    face_of = np.repeat(np.arange(mesh.n_faces), mesh.face_sizes)
    return np.unique(face_of[np.isin(key, wanted)])


def _loops(edges: dict[int, int]) -> list[list[int]] | None:
    """The directed edges ``tail -> head`` as closed loops, or None if they are not."""
    heads = list(edges.values())
    if len(set(heads)) != len(heads):
        return None
    left = dict(edges)
    loops = []
    while left:
        start = min(left)
        loop = [start]
        v = left.pop(start)
        while v != start:
            if v not in left:
                return None
            loop.append(v)
            v = left.pop(v)
        if len(loop) < 3:
            return None
        loops.append(loop)
    return loops


def _vector_area(xyz: NDArray[np.float64]) -> NDArray[np.float64]:
    """The vector area of a closed loop of points, shape (3,)."""
    rel = xyz - xyz.mean(axis=0)
    return 0.5 * np.cross(rel, np.roll(rel, -1, axis=0)).sum(axis=0)


def _renamed(mesh: PolyMesh, owner: NDArray[np.intp], neighbour: NDArray[np.intp]) -> PolyMesh:
    """``mesh`` with new owners and neighbours; faces with one cell on both sides dropped."""
    return _subset(mesh, np.flatnonzero(owner != neighbour), owner, neighbour)
