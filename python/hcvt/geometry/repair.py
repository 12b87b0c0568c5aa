"""Checks and repairs of closed triangle meshes bounding 3D domains (DESIGN §3.6).

The exact clipping needs the boundary to be a closed, consistently and outwardly oriented
cycle of triangles: every directed edge matched by its reverse, positive volume. This
module finds every defect that breaks that (with counts and the first offending element)
and, on request, repairs the mesh and says what it changed.

Arrays: ``vertices`` (V, 3) float64, ``faces`` (F, 3) intp indices into ``vertices``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NoReturn

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

import hcvt._core as _core
from hcvt.errors import InvalidDomainError
from hcvt.lazy import load

Vertices = NDArray[np.float64]
Faces = NDArray[np.intp]


@dataclass
class MeshDefects:
    """Defects of a triangle mesh as a boundary; each list entry is one message line."""

    lines: list[str] = field(default_factory=list)

    def add(self, line: str) -> None:
        """Record one defect."""
        self.lines.append(line)

    def __bool__(self) -> bool:
        return bool(self.lines)


def as_mesh_arrays(vertices: object, faces: object) -> tuple[Vertices, Faces]:
    """Shape- and type-check the input; NaN/inf and out-of-range indices raise at once."""
    v = np.asarray(vertices)
    f = np.asarray(faces)
    if v.dtype.kind not in "iuf" or v.ndim != 2 or v.shape[1] != 3 or len(v) == 0:
        raise InvalidDomainError(
            f"vertices must be real numbers of shape (V, 3), got {v.dtype} {v.shape}"
        )
    if f.dtype.kind not in "iu" or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise InvalidDomainError(f"faces must be integers of shape (F, 3), got {f.dtype} {f.shape}")
    v = np.ascontiguousarray(v, dtype=np.float64)
    f = np.ascontiguousarray(f, dtype=np.intp)
    bad = ~np.isfinite(v).all(axis=1)
    if bad.any():
        raise InvalidDomainError(
            f"{int(bad.sum())} vertices have NaN or infinite coordinates (first: vertex "
            f"{int(np.argmax(bad))}); this cannot be repaired"
        )
    out = (f < 0) | (f >= len(v))
    if out.any():
        row = int(np.argmax(out.any(axis=1)))
        raise InvalidDomainError(
            f"{int(out.any(axis=1).sum())} faces refer to missing vertices (first: face {row} = "
            f"{f[row].tolist()}, there are {len(v)} vertices)"
        )
    return v, f


def signed_volume(v: Vertices, f: Faces) -> float:
    """Σ over faces of ``a · (b × c) / 6`` about the bounding-box centre, L³."""
    c = 0.5 * (v.min(axis=0) + v.max(axis=0))
    a, b, d = v[f[:, 0]] - c, v[f[:, 1]] - c, v[f[:, 2]] - c
    return float(np.einsum("ij,ij->i", a, np.cross(b, d)).sum() / 6.0)


def _degenerate_faces(v: Vertices, f: Faces) -> NDArray[np.bool_]:
    """Faces with a repeated index or exactly zero area."""
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])
    normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    return repeated | ~(normal != 0).any(axis=1)


def _duplicate_vertices(v: Vertices, f: Faces) -> tuple[int, tuple[int, int] | None]:
    """Referenced vertices sharing a position with an earlier one: count and first pair."""
    used = np.unique(f)
    _, first, inverse = np.unique(v[used], axis=0, return_index=True, return_inverse=True)
    dup = np.flatnonzero(first[inverse.ravel()] != np.arange(len(used)))
    if len(dup) == 0:
        return 0, None
    k = dup[0]
    return len(dup), (int(used[first[inverse.ravel()[k]]]), int(used[k]))


def _edges(f: Faces) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Directed edges (3F, 2) in face order, and the face of each (3F,)."""
    directed = np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2)
    return directed, np.repeat(np.arange(len(f)), 3)


def _edge_counts(f: Faces) -> dict[str, tuple[int, list[int] | None]]:
    """Open, non-manifold and same-direction edges: count and first (in face order)."""
    directed, _ = _edges(f)
    undirected = np.sort(directed, axis=1)
    keys, first, inverse, uses = np.unique(
        undirected, axis=0, return_index=True, return_inverse=True, return_counts=True
    )
    _, dfirst, dinverse, duses = np.unique(
        directed, axis=0, return_index=True, return_inverse=True, return_counts=True
    )
    out: dict[str, tuple[int, list[int] | None]] = {}
    for name, mask, at in (
        ("open", uses == 1, first),
        ("non-manifold", uses > 2, first),
        ("same-direction", duses > 1, dfirst),
    ):
        count = int(mask.sum())
        out[name] = (count, directed[int(at[mask].min())].tolist() if count else None)
    del keys, inverse, dinverse
    return out


def vertex_fans(f: Faces, n_vertices: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Edge-connected fans of faces around each vertex.

    Returns the fan label of each corner (3F,), corner ``3 t + k`` being vertex ``f[t, k]``,
    and the number of fans of each vertex (V,). A vertex with more than one fan is pinched
    (non-manifold) even when every edge has two faces.
    """
    nf = len(f)
    corner_vertex = f.ravel()
    corner_id = np.arange(3 * nf)
    # Each corner touches the two edges of its face through its vertex; corners of the same
    # vertex on the same undirected edge (v, w) lie in the same fan.
    key1 = np.column_stack([corner_vertex, f[:, [1, 2, 0]].ravel()])
    key2 = np.column_stack([corner_vertex, f[:, [2, 0, 1]].ravel()])
    both = np.concatenate([key1, key2])
    ids = np.concatenate([corner_id, corner_id])
    _, group = np.unique(both, axis=0, return_inverse=True)
    group = group.ravel()
    order = np.argsort(group, kind="stable")
    same = group[order][1:] == group[order][:-1]
    r, c = ids[order][1:][same], ids[order][:-1][same]
    graph = coo_matrix((np.ones(len(r)), (r, c)), shape=(3 * nf, 3 * nf))
    _, label = connected_components(graph, directed=False)
    pairs = np.unique(np.column_stack([corner_vertex, label]), axis=0)
    fans = np.bincount(pairs[:, 0], minlength=n_vertices)
    return label, fans


def find_defects(v: Vertices, f: Faces, *, allow_duplicates: bool = False) -> MeshDefects:
    """Every defect that keeps the mesh from bounding a domain, one line each.

    ``allow_duplicates`` accepts vertices sharing a position (a repaired mesh has them
    where a pinched vertex was split).
    """
    d = MeshDefects()
    degenerate = _degenerate_faces(v, f)
    if degenerate.any():
        i = int(np.argmax(degenerate))
        count = int(degenerate.sum())
        d.add(f"{count} degenerate (zero-area) faces, first: face {i} = {f[i].tolist()}")
    count, pair = (0, None) if allow_duplicates else _duplicate_vertices(v, f)
    if count and pair is not None:
        a, b = pair
        d.add(f"{count} duplicate vertices, first: vertices {a} and {b} at {v[a].tolist()}")
    edges = _edge_counts(f)
    count, edge = edges["open"]
    if count:
        d.add(f"open boundary: {count} edges have only one face, first: edge {edge}")
    count, edge = edges["non-manifold"]
    if count:
        d.add(f"{count} non-manifold edges with more than two faces, first: edge {edge}")
    count, edge = edges["same-direction"]
    if count:
        d.add(
            f"inconsistent winding: {count} directed edges are used twice in the same "
            f"direction, first: {edge}"
        )
    if not d:
        _, fans = vertex_fans(f, len(v))
        pinched = np.flatnonzero(fans > 1)
        if len(pinched):
            d.add(
                f"{len(pinched)} non-manifold (pinched) vertices, first: vertex {int(pinched[0])}"
            )
        volume = signed_volume(v, f)
        if not np.isfinite(volume):
            d.add(
                f"volume not representable ({volume}): coordinates up to "
                f"{np.max(np.abs(v)):.3g} overflow when multiplied; scale the mesh down"
            )
        elif volume == 0:
            d.add(f"zero volume ({volume})")
        elif volume < 0:
            d.add(f"inward orientation: the signed volume is {volume:.6g} < 0")
    return d


def check_mesh(v: Vertices, f: Faces, *, repaired: bool = False) -> None:
    """Raise InvalidDomainError listing every defect, or return."""
    d = find_defects(v, f, allow_duplicates=repaired)
    if d:
        refuse(d.lines, repaired=repaired)


def refuse(
    lines: list[str], *, repaired: bool = False, advice: str = "pass repair=True to fix it"
) -> NoReturn:
    """Raise InvalidDomainError with one line per defect, and what to do about it."""
    if repaired:
        advice = "repair=True could not fix it"
    raise InvalidDomainError(
        "the mesh does not bound a solid:\n  - " + "\n  - ".join(lines) + "\n" + advice
    )


# ---------------------------------------------------------------------------- repair
def repair_mesh(v: Vertices, f: Faces) -> tuple[Vertices, Faces, list[str]]:
    """Repair a mesh; return the new arrays and one line per action taken.

    Merge duplicate vertices, drop degenerate and duplicate faces and faces on
    non-manifold edges, fill holes, split pinched vertices, orient every shell
    consistently and by the parity of its nesting (outward, cavities inward).
    """
    actions: list[str] = []
    v, f = _merge_vertices(v, f, actions)
    # Filling holes next to non-manifold spots can make new ones: a few rounds settle it.
    for _ in range(REPAIR_ROUNDS):
        f = _drop_faces(v, f, actions)
        f = _orient_consistently(f, actions)
        v, f = _fill_holes(v, f, actions)
        edges = _edge_counts(f)
        if edges["open"][0] == 0 and edges["non-manifold"][0] == 0:
            break
    f = _orient_consistently(f, actions)
    v, f = _split_pinched(v, f, actions)
    f = orient_by_nesting(v, f, actions)
    return v, f, actions


REPAIR_ROUNDS = 4


def _merge_vertices(v: Vertices, f: Faces, actions: list[str]) -> tuple[Vertices, Faces]:
    unique, inverse = np.unique(v, axis=0, return_inverse=True)
    merged = len(v) - len(unique)
    if merged:
        actions.append(f"merged {merged} duplicate vertices")
        return unique, inverse.ravel()[f]
    return v, f


def _drop_faces(v: Vertices, f: Faces, actions: list[str]) -> Faces:
    degenerate = _degenerate_faces(v, f)
    if degenerate.any():
        actions.append(f"dropped {int(degenerate.sum())} degenerate faces")
        f = f[~degenerate]
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    if len(first) < len(f):
        actions.append(f"dropped {len(f) - len(first)} duplicate faces")
        f = f[np.sort(first)]
    directed, owner = _edges(f)
    _, inverse, uses = np.unique(
        np.sort(directed, axis=1), axis=0, return_inverse=True, return_counts=True
    )
    bad = np.unique(owner[uses[inverse.ravel()] > 2])
    if len(bad):
        actions.append(f"dropped {len(bad)} faces on non-manifold edges (their holes are filled)")
        f = np.delete(f, bad, axis=0)
    if len(f) == 0:
        raise InvalidDomainError("no faces are left after dropping the degenerate ones")
    return f


def _face_adjacency(f: Faces) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.bool_]]:
    """Pairs of faces sharing a manifold edge, and whether they run it the same way.

    Faces running a shared edge the same way disagree: one of them must flip.
    """
    directed, owner = _edges(f)
    und = np.sort(directed, axis=1)
    _, group, uses = np.unique(und, axis=0, return_inverse=True, return_counts=True)
    group = group.ravel()
    keep = uses[group] == 2
    order = np.argsort(group[keep], kind="stable")
    idx = np.flatnonzero(keep)[order]
    a, b = idx[0::2], idx[1::2]
    same = (directed[a, 0] == directed[b, 0]) & (directed[a, 1] == directed[b, 1])
    return owner[a], owner[b], same


def _orient_consistently(f: Faces, actions: list[str]) -> Faces:
    """Breadth-first over manifold edges, flipping faces to agree with their neighbours."""
    fa, fb, same = _face_adjacency(f)
    if not same.any():
        return f
    n = len(f)
    neighbours: list[list[tuple[int, bool]]] = [[] for _ in range(n)]
    for a, b, s in zip(fa.tolist(), fb.tolist(), same.tolist(), strict=True):
        neighbours[a].append((b, s))
        neighbours[b].append((a, s))
    flip = np.zeros(n, dtype=bool)
    seen = np.zeros(n, dtype=bool)
    for start in range(n):
        if seen[start]:
            continue
        seen[start] = True
        queue = [start]
        while queue:
            t = queue.pop()
            for u, s in neighbours[t]:
                if not seen[u]:
                    seen[u] = True
                    flip[u] = flip[t] ^ s
                    queue.append(u)
    f = f.copy()
    f[flip] = f[flip][:, ::-1]
    actions.append(f"flipped {int(flip.sum())} faces to orient each component consistently")
    return f


def _boundary_loops(f: Faces) -> list[list[int]]:
    """Loops of open directed edges, each as a vertex list."""
    directed, _ = _edges(f)
    und = np.sort(directed, axis=1)
    _, group, uses = np.unique(und, axis=0, return_inverse=True, return_counts=True)
    open_edges = directed[uses[group.ravel()] == 1]
    nxt: dict[int, list[int]] = {}
    for a, b in open_edges.tolist():
        nxt.setdefault(a, []).append(b)
    loops = []
    while nxt:
        start = next(iter(nxt))
        loop = [start]
        at = start
        while True:
            targets = nxt.get(at)
            if not targets:
                break
            b = targets.pop()
            if not targets:
                del nxt[at]
            if b == start:
                break
            loop.append(b)
            at = b
        loops.append(loop)
    return loops


def _simple_loops(loop: list[int]) -> list[list[int]]:
    """Cut a loop that passes a vertex twice (a figure eight) into simple loops.

    A fan over a repeated vertex would put three faces on one edge.
    """
    out: list[list[int]] = []
    stack: list[int] = []
    where: dict[int, int] = {}
    for x in loop:
        if x in where:
            k = where[x]
            out.append(stack[k:])
            for y in stack[k + 1 :]:
                del where[y]
            del stack[k + 1 :]
        else:
            where[x] = len(stack)
            stack.append(x)
    out.append(stack)
    return out


def _fill_holes(v: Vertices, f: Faces, actions: list[str]) -> tuple[Vertices, Faces]:
    """Close every boundary loop by a fan from a new vertex at its centroid.

    The fan runs opposite to the loop's open edges, so that every edge gets its reverse.
    """
    loops = [part for loop in _boundary_loops(f) for part in _simple_loops(loop) if len(part) >= 3]
    if not loops:
        return v, f
    new_v, new_f = [v], [f]
    at = len(v)
    for loop in loops:
        ring = np.asarray(loop)
        if len(ring) == 3:  # a triangle closes itself, no new vertex
            new_f.append(ring[[1, 0, 2]][None, :])
            continue
        new_v.append(v[ring].mean(axis=0)[None, :])
        new_f.append(np.column_stack([np.roll(ring, -1), ring, np.full(len(ring), at)]))
        at += 1
    sizes = sorted(len(loop) for loop in loops)
    actions.append(f"filled {len(loops)} holes (boundary loops of {sizes[0]} to {sizes[-1]} edges)")
    return np.concatenate(new_v), np.concatenate(new_f)


def _split_pinched(v: Vertices, f: Faces, actions: list[str]) -> tuple[Vertices, Faces]:
    """Give each extra fan of a pinched vertex its own copy of the vertex."""
    label, fans = vertex_fans(f, len(v))
    if not (fans > 1).any():
        return v, f
    corner_vertex = f.ravel().copy()
    _, first_label = np.unique(corner_vertex, return_index=True)
    base = np.full(len(v), -1)
    base[corner_vertex[first_label]] = label[first_label]
    extra = (fans[corner_vertex] > 1) & (label != base[corner_vertex])
    keys, inverse = np.unique(label[extra], return_inverse=True)
    copies = v[corner_vertex[extra]][np.unique(inverse.ravel(), return_index=True)[1]]
    corner_vertex[np.flatnonzero(extra)] = len(v) + inverse.ravel()
    actions.append(f"split {int((fans > 1).sum())} pinched vertices ({len(keys)} copies)")
    return np.concatenate([v, copies]), corner_vertex.reshape(-1, 3)


def shells(f: Faces) -> tuple[int, NDArray[np.intp]]:
    """Edge-connected components of the faces: their count and the shell of each face (F,)."""
    fa, fb, _ = _face_adjacency(f)
    graph = coo_matrix((np.ones(len(fa)), (fa, fb)), shape=(len(f), len(f)))
    count, label = connected_components(graph, directed=False)
    return int(count), label.astype(np.intp)


@dataclass
class Nesting:
    """How the closed shells of a mesh sit inside each other.

    Attributes
    ----------
    label : ndarray of intp, shape (F,)
        Shell of each face, numbered by first face.
    sign : ndarray of int, shape (S,)
        +1 where a shell faces outward on its own (positive volume), -1 inward.
    inside : ndarray of bool, shape (S, S)
        ``inside[i, j]``: shell ``i`` lies inside shell ``j`` (exact winding number of a
        point of shell ``i`` about shell ``j`` alone, from the core).
    """

    label: NDArray[np.intp]
    sign: NDArray[np.intp]
    inside: NDArray[np.bool_]

    @property
    def depth(self) -> NDArray[np.intp]:
        """How many shells enclose each shell (S,)."""
        return self.inside.sum(axis=1).astype(np.intp)

    @property
    def outside_winding(self) -> NDArray[np.intp]:
        """Winding number just outside each shell, from all the others as oriented (S,)."""
        return (self.inside * self.sign[None, :]).sum(axis=1)

    def first_face(self, shell: int) -> int:
        """The lowest face index of a shell."""
        return int(np.argmax(self.label == shell))


# Faces of a shell tried, in turn, as the point whose winding number about the other shells
# says where the shell lies; only a face lying on another shell is passed over.
NESTING_TRIES = 8


def nesting(v: Vertices, f: Faces, *, crossing_is_error: bool = False) -> Nesting:
    """Shells of a closed, consistently oriented mesh whose shells do not cross.

    With ``crossing_is_error``, shells found on both sides of each other (crossing along
    edges, which the core's crossing test does not see) raise InvalidDomainError.

    Each shell's signed volume gives its orientation; a point of each shell (the centroid of
    one of its faces not lying on another shell) tested against every other shell, oriented
    outward on its own, by the core's exact winding number, says which shells enclose it.
    """
    count, label = shells(f)
    order = np.argsort(label, kind="stable")
    starts = np.searchsorted(label[order], np.arange(count + 1))
    members = [order[starts[s] : starts[s + 1]] for s in range(count)]
    volume = np.array([signed_volume(v, f[m]) for m in members])
    sign = np.where(flat_shells(v, volume), 0, np.sign(volume)).astype(np.intp)
    inside = np.zeros((count, count), dtype=bool)
    if count == 1:
        return Nesting(label, sign, inside)
    tries = [
        m[np.linspace(0, len(m) - 1, min(NESTING_TRIES, len(m))).astype(np.intp)] for m in members
    ]
    # Vertices too: shells crossing only along edges (no edge through a triangle, which
    # is all the core's crossing test sees) can have every face centroid on one side.
    corners = [np.unique(f[m]) for m in members]
    corners = [
        c[np.linspace(0, len(c) - 1, min(NESTING_TRIES, len(c))).astype(np.intp)] for c in corners
    ]
    for j, m in enumerate(members):
        if sign[j] == 0:
            continue  # encloses nothing: the winding number is 0 about it everywhere
        shell = f[m] if sign[j] > 0 else f[m][:, ::-1]
        core = _core.SolidDomain(v, np.ascontiguousarray(shell, dtype=np.uint32))
        for i in range(count):
            if i == j:
                continue
            points = np.concatenate([v[f[tries[i]]].mean(axis=1), v[corners[i]]])
            winding, on = core.winding_numbers(points)
            if on[: len(tries[i])].all():
                a, b = min(i, j), max(i, j)
                refuse(
                    [
                        f"shells {a} and {b} (faces {members[a][0]} and {members[b][0]}) touch "
                        "along a surface"
                    ]
                )
            off = winding[~on]  # the centroids first: as before for shells that do not cross
            if crossing_is_error and off.min() != off.max():
                # Points of shell i on both sides of shell j: they cross, though no edge
                # passes strictly through a triangle (the core's test): edges meeting
                # edges or touching faces, as two unit cubes offset by (1/2, 1/2, 1/2).
                a, b = min(i, j), max(i, j)
                refuse(
                    [
                        f"self-intersection: shells {a} and {b} (faces {members[a][0]} and "
                        f"{members[b][0]}) cross each other along edges"
                    ],
                    advice="repair=True cannot unite them (it unites shells whose edges pass "
                    "through triangles): unite them before (manifold3d, a CAD boolean)",
                )
            inside[i, j] = off[0] != 0
    return Nesting(label, sign, inside)


def flat_shells(v: Vertices, volume: NDArray[np.float64]) -> NDArray[np.bool_]:
    """Shells whose volume is round-off of the mesh's extent (a sheet folded onto itself)."""
    extent = np.max(v.max(axis=0) - v.min(axis=0))
    with np.errstate(over="ignore"):
        return np.abs(volume) <= 1e-12 * extent**3


def nesting_defects(nest: Nesting) -> list[str]:
    """Shells where the winding number is not 0 on one side and 1 on the other.

    A shell facing outward needs winding number 0 just outside it, one facing inward (a
    cavity) needs 1 there; anything else counts some region twice or below zero.
    """
    lines = []
    outside = nest.outside_winding
    for i in np.flatnonzero(nest.sign == 0).tolist():
        lines.append(f"shell {i} (first face {nest.first_face(i)}) encloses no volume")
    for i in np.flatnonzero((outside != (nest.sign < 0)) & (nest.sign != 0)).tolist():
        enclosing = np.flatnonzero(nest.inside[i]).tolist()
        facing = "outward" if nest.sign[i] > 0 else "inward"
        where = f"inside shells {enclosing}" if enclosing else "inside no other shell"
        lines.append(
            f"shell {i} (first face {nest.first_face(i)}) faces {facing} {where}: the winding "
            f"number is {int(outside[i])} outside it and {int(outside[i] + nest.sign[i])} "
            "inside, not 0 and 1 (nested shells must alternate: a cavity faces inward)"
        )
    return lines


def orient_by_nesting(v: Vertices, f: Faces, actions: list[str]) -> Faces:
    """Orient each shell by the parity of its nesting depth.

    Shells inside an even number of others bound solid and face outward; inside an odd
    number they bound a cavity and face inward. So a cavity stays a cavity, a reversed outer
    shell turns outward, and a nested shell facing the same way as its parent becomes one.
    """
    edges = _edge_counts(f)
    if any(edges[k][0] for k in ("open", "non-manifold", "same-direction")):
        return f  # not closed: check_mesh reports why
    if not np.isfinite(signed_volume(v, f)):
        return f  # the volume overflows: check_mesh reports it
    nest = nesting(v, f)
    if (nest.sign == 0).any():
        flat = np.flatnonzero(nest.sign == 0)
        actions.append(f"dropped {len(flat)} shells enclosing no volume (first: shell {flat[0]})")
        f = f[~np.isin(nest.label, flat)]
        if len(f) == 0:
            raise InvalidDomainError("no faces are left after dropping the flat shells")
        nest = nesting(v, f)
    wanted = np.where(nest.depth % 2 == 0, 1, -1)
    flip = np.flatnonzero(nest.sign != wanted)
    if len(flip) == 0:
        return f
    f = f.copy()
    rows = np.isin(nest.label, flip)
    f[rows] = f[rows][:, ::-1]
    for i in flip.tolist():
        depth = int(nest.depth[i])
        why = (
            "to face outward: it encloses solid"
            if wanted[i] > 0
            else "to face inward: it bounds a cavity"
        )
        actions.append(
            f"flipped shell {i} (first face {nest.first_face(i)}, inside {depth} other "
            f"shells) {why}"
        )
    return f


def describe_crossings(f: Faces, count: int, pairs: list[tuple[int, int]]) -> str:
    """The first crossing pair of faces, with the shells they belong to."""
    _, label = shells(f)
    s, t = pairs[0]
    where = f"shell {label[s]}" if label[s] == label[t] else f"shells {label[s]} and {label[t]}"
    return f"{count} pairs of triangles cross each other, first: faces ({s}, {t}) of {where}"


def unite_shells(
    v: Vertices, f: Faces, pairs: list[tuple[int, int]], actions: list[str]
) -> tuple[Vertices, Faces]:
    """Replace the shells, which cross each other, by their union (manifold3d, float64).

    Where shells cross, nesting no longer says which side is a cavity: every shell is taken
    as a solid on its own, facing outward, and the solids are united. A shell that crosses
    itself is left as it is, and the action says so.
    """
    count, label = shells(f)
    crossing = np.array(pairs, dtype=np.intp).reshape(-1, 2)
    same = label[crossing[:, 0]] == label[crossing[:, 1]]
    if same.any():
        # manifold3d's booleans need inputs free of self-intersections; a shell crossing
        # itself has winding number 2 or -1 beside the crossing whatever its orientation.
        s, t = crossing[int(np.argmax(same))].tolist()
        actions.append(
            f"left a self-intersection ({len(crossing)} pairs of triangles cross, first: faces "
            f"({s}, {t}) of shell {label[s]}, which crosses itself and cannot be repaired): "
            "the winding number is 2 or -1 beside it, and overlaps count with it"
        )
        return v, f
    members = [np.flatnonzero(label == k) for k in range(count)]
    m3 = _manifold_module()
    parts = []
    for m in members:
        shell = f[m] if signed_volume(v, f[m]) > 0 else f[m][:, ::-1]
        used, local = np.unique(shell, return_inverse=True)
        mesh = m3.Mesh64(
            vert_properties=np.ascontiguousarray(v[used], dtype=np.float64),
            tri_verts=np.ascontiguousarray(local.reshape(-1, 3), dtype=np.uint32),
        )
        parts.append(m3.Manifold(mesh))
    union = m3.Manifold.batch_boolean(parts, m3.OpType.Add).to_mesh64()
    v_out = np.ascontiguousarray(np.asarray(union.vert_properties)[:, :3], dtype=np.float64)
    f_out = np.ascontiguousarray(union.tri_verts, dtype=np.intp)
    k = len(np.unique(label[crossing]))
    actions.append(
        f"united {count} shells, {k} of them crossing (first: faces {crossing[0].tolist()}), "
        f"each taken as a solid, with manifold3d: "
        f"{len(f)} -> {len(f_out)} faces"
    )
    return v_out, f_out


def _manifold_module() -> Any:
    return load("manifold3d")
