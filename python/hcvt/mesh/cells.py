"""Each cell's own geometry, read off the conforming mesh (:class:`hcvt.mesh.polymesh.PolyMesh`).

The mesh stores every face once; a cell is the faces it owns, as they are, and the faces
it neighbours, reversed, so that each cell's faces run counter-clockwise seen from outside
it (3D) or its edges have it on their left (2D).
"""

from __future__ import annotations

import numpy as np
import shapely
from numpy.typing import NDArray

from hcvt.mesh.polymesh import PolyMesh

Triangulation = tuple[NDArray[np.float64], NDArray[np.intp]]


def _cell_faces(mesh: PolyMesh) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.bool_]]:
    """Every (cell, face) incidence, sorted by cell: cells, faces, and whether reversed."""
    inner = np.flatnonzero(mesh.interior)
    cells = np.concatenate([mesh.owner, mesh.neighbour[inner]])
    faces = np.concatenate([np.arange(mesh.n_faces, dtype=np.intp), inner])
    reverse = np.concatenate([np.zeros(mesh.n_faces, bool), np.ones(len(inner), bool)])
    order = np.argsort(cells, kind="stable")
    return cells[order], faces[order], reverse[order]


def triangulated(mesh: PolyMesh) -> list[Triangulation]:
    """Each 3D cell as ``(vertices (k, 3), triangles (t, 3))``, indices local to the cell.

    Convex faces are fanned from their first vertex; the few non-convex ones (bisector
    faces cut by a non-convex boundary) get GEOS's constrained Delaunay triangulation in
    their plane, whose diagonals stay inside the face: a fan's diagonal can run along a
    line where two faces of the cell meet, and be used twice. Triangles run
    counter-clockwise seen from outside the cell and form a closed surface; an empty cell
    gives two empty arrays.
    """
    face_of, triangles = _face_triangles(mesh)
    # Each face's triangles go to its owner as they are and to its neighbour reversed.
    inner = mesh.interior[face_of]
    cells = np.concatenate([mesh.owner[face_of], mesh.neighbour[face_of[inner]]])
    triangles = np.concatenate([triangles, triangles[inner][:, ::-1]])
    order = np.argsort(cells, kind="stable")
    cells, triangles = cells[order], triangles[order]
    # Local vertex numbers: each cell's vertices in increasing global order.
    n_points = len(mesh.points)
    pairs, inverse = np.unique(
        np.repeat(cells, 3) * n_points + triangles.ravel(), return_inverse=True
    )
    pair_cell, pair_vertex = np.divmod(pairs, n_points)
    first_pair = np.searchsorted(pair_cell, np.arange(mesh.n_cells + 1))
    local = (inverse.ravel() - first_pair[np.repeat(cells, 3)]).reshape(-1, 3).astype(np.intp)
    bounds = np.searchsorted(cells, np.arange(mesh.n_cells + 1))
    return [
        (
            mesh.points[pair_vertex[first_pair[i] : first_pair[i + 1]]],
            local[bounds[i] : bounds[i + 1]],
        )
        for i in range(mesh.n_cells)
    ]


def _face_triangles(mesh: PolyMesh) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Each face's triangles, sorted by face: the face of each, and (t, 3) vertex indices.

    Triangles run the way their face does.
    """
    sizes = np.diff(mesh.face_offsets)
    fans = np.maximum(sizes - 2, 0)
    face_of = np.repeat(np.arange(mesh.n_faces), fans)
    q = np.arange(fans.sum()) - np.repeat(np.cumsum(fans) - fans, fans) + 1
    start = mesh.face_offsets[face_of]
    triangles = np.stack(
        [
            mesh.face_vertices[start],
            mesh.face_vertices[start + q],
            mesh.face_vertices[start + q + 1],
        ],
        axis=1,
    )
    bad = np.flatnonzero(non_convex_faces(mesh))
    if len(bad) == 0:
        return face_of, triangles
    keep = ~np.isin(face_of, bad)
    made_face, made = planar_triangles(mesh, bad)
    face_of = np.concatenate([face_of[keep], made_face])
    order = np.argsort(face_of, kind="stable")
    return face_of[order], np.concatenate([triangles[keep], made])[order]


def non_convex_faces(mesh: PolyMesh) -> NDArray[np.bool_]:
    """Shape (f,): faces with a reflex corner (turning against the face's normal)."""
    sizes = np.diff(mesh.face_offsets)
    face_of = np.repeat(np.arange(mesh.n_faces), sizes)
    first = mesh.face_offsets[face_of]
    pos = np.arange(len(mesh.face_vertices)) - first
    p = mesh.points[mesh.face_vertices]
    following = p[first + (pos + 1) % sizes[face_of]]
    preceding = p[first + (pos - 1) % sizes[face_of]]
    # Newell's normal: the face's vector area, exact for any simple planar polygon.
    normal = np.zeros((mesh.n_faces, 3))
    np.add.at(normal, face_of, np.cross(p, following))
    turn = np.einsum("ij,ij->i", np.cross(p - preceding, following - p), normal[face_of])
    # Reflex beyond round-off: collinear corners (turn 0) fan well.
    scale = np.linalg.norm(p - preceding, axis=1) * np.linalg.norm(following - p, axis=1)
    scale *= np.linalg.norm(normal, axis=1)[face_of]
    reflex = turn < -1e-9 * scale
    out = np.zeros(mesh.n_faces, dtype=bool)
    np.logical_or.at(out, face_of, reflex)
    return out


def planar_triangles(
    mesh: PolyMesh, faces: NDArray[np.intp]
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Constrained Delaunay triangles (shapely/GEOS, one vectorised call) of planar faces.

    Each face is projected to the two coordinates its normal leaves out, triangulated,
    and its triangles mapped back to vertex indices by their (exact) projected corners,
    turned the way the face runs. A face GEOS cannot triangulate with its own corners
    (it moved a point, or the loop is not simple) keeps its fan.

    Returns the face of each triangle, shape (t,) (entries of ``faces``, grouped by face
    but not sorted), and the triangles' vertex indices, shape (t, 3); a face of ``k``
    corners gives ``k - 2`` triangles, which use every corner.
    """
    sizes = np.diff(mesh.face_offsets)[faces]
    starts = mesh.face_offsets[faces]
    which = np.repeat(np.arange(len(faces)), sizes)
    first = np.cumsum(sizes) - sizes  # of each face in the flat arrays below
    pos = np.arange(sizes.sum()) - first[which]
    vertex = mesh.face_vertices[starts[which] + pos]
    p = mesh.points[vertex]
    following = p[first[which] + (pos + 1) % sizes[which]]
    normal = np.zeros((len(faces), 3))
    np.add.at(normal, which, np.cross(p, following))
    axis = np.argmax(np.abs(normal), axis=1)
    u, v = (axis + 1) % 3, (axis + 2) % 3
    # Keep counter-clockwise seen from +normal counter-clockwise in the projection.
    flip = normal[np.arange(len(faces)), axis] < 0
    u, v = np.where(flip, v, u), np.where(flip, u, v)
    flat = np.stack([p[np.arange(len(p)), u[which]], p[np.arange(len(p)), v[which]]], axis=1)
    polygons = shapely.polygons(shapely.linearrings(flat, indices=which))
    # A face with a hole is one loop, its bridge to the hole walked both ways: a ring that
    # touches itself, on which GEOS's triangulator can fail. It gets the polygon with its
    # hole instead, made of the same coordinates (no point is made).
    key = np.sort(which.astype(np.int64) * len(mesh.points) + vertex)
    keyhole = np.unique(key[1:][key[1:] == key[:-1]] // len(mesh.points))
    polygons[keyhole] = shapely.make_valid(polygons[keyhole], method="structure")
    parts, part_of = _constrained_delaunay(polygons)
    rings = shapely.get_exterior_ring(parts)
    corners = shapely.get_coordinates(rings).reshape(-1, 4, 2)[:, :3].reshape(-1, 2)
    found = _lookup(
        np.column_stack([which, flat]), vertex, np.column_stack([np.repeat(part_of, 3), corners])
    ).reshape(-1, 3)
    ccw = shapely.is_ccw(rings)
    found = np.where(ccw[:, None], found, found[:, ::-1])
    failed = np.zeros(len(faces), dtype=bool)
    failed[part_of[(found < 0).any(axis=1)]] = True
    counts = np.bincount(part_of, minlength=len(faces))
    failed |= counts != sizes - 2
    good = ~failed[part_of]
    out_face, out = [faces[part_of[good]]], [found[good]]
    for k in np.flatnonzero(failed).tolist():
        out.append(_fan(mesh.face(int(faces[k]))))
        out_face.append(np.full(sizes[k] - 2, faces[k], dtype=np.intp))
    return np.concatenate(out_face), np.concatenate(out)


def _constrained_delaunay(
    polygons: NDArray[np.object_],
) -> tuple[NDArray[np.object_], NDArray[np.intp]]:
    """GEOS's triangles of all polygons (one call), and the polygon of each triangle.

    A polygon GEOS fails on (it raises for the whole call) gets no triangles.
    """
    try:
        made = shapely.constrained_delaunay_triangles(polygons)
    except shapely.errors.GEOSException:
        made = np.array([_one_constrained_delaunay(p) for p in polygons], dtype=object)
    return shapely.get_parts(made, return_index=True)


def _one_constrained_delaunay(polygon: shapely.Geometry) -> shapely.Geometry:
    try:
        return shapely.constrained_delaunay_triangles(polygon)
    except shapely.errors.GEOSException:
        return shapely.GeometryCollection()


def _lookup(
    keys: NDArray[np.float64], values: NDArray[np.intp], queries: NDArray[np.float64]
) -> NDArray[np.intp]:
    """``values`` of the rows of ``keys`` (m, c) equal to each row of ``queries``, or -1.

    Exact equality of floats, by sorting the rows' bytes (one sort, no Python loop);
    ``+ 0.0`` makes -0.0 and 0.0 the same bytes.
    """
    width = np.dtype((np.void, 8 * keys.shape[1]))
    k = np.ascontiguousarray(keys + 0.0, dtype=np.float64).view(width).ravel()
    q = np.ascontiguousarray(queries + 0.0, dtype=np.float64).view(width).ravel()
    order = np.argsort(k, kind="stable")
    at = np.minimum(np.searchsorted(k[order], q), len(k) - 1)
    return np.where(k[order][at] == q, values[order][at], -1)


def _fan(face: NDArray[np.intp]) -> NDArray[np.intp]:
    q = np.arange(1, len(face) - 1)
    return np.stack([np.full_like(q, face[0]), face[q], face[q + 1]], axis=1)


def polygons(mesh: PolyMesh) -> list[shapely.Geometry]:
    """Each 2D cell as a shapely geometry.

    A Polygon (with holes where the cell has them), a MultiPolygon when the cell is in
    several pieces, or an empty Polygon.
    """
    cells, faces, reverse = _cell_faces(mesh)
    ends = mesh.face_vertices.reshape(-1, 2)[faces]
    ends = np.where(reverse[:, None], ends[:, ::-1], ends)
    bounds = np.searchsorted(cells, np.arange(mesh.n_cells + 1))
    return [_polygon(mesh.points, ends[bounds[i] : bounds[i + 1]]) for i in range(mesh.n_cells)]


def _polygon(points: NDArray[np.float64], edges: NDArray[np.intp]) -> shapely.Geometry:
    """The region left of the directed edges (a closed set of loops)."""
    if len(edges) == 0:
        return shapely.Polygon()
    following: dict[int, list[int]] = {}
    for a, b in edges.tolist():
        following.setdefault(a, []).append(b)
    loops = []
    while following:
        first = next(iter(following))
        loop, at = [first], first
        while True:
            nxt = following[at].pop()
            if not following[at]:
                del following[at]
            if nxt == first:
                break
            loop.append(nxt)
            at = nxt
        loops.append(points[loop])
    rings = [shapely.LinearRing(p) for p in loops if len(p) >= 3]
    shells = [r for r in rings if r.is_ccw]
    holes = [r for r in rings if not r.is_ccw]
    parts = [shapely.Polygon(s) for s in shells]
    inner: list[list[shapely.LinearRing]] = [[] for _ in shells]
    for h in holes:
        # A hole lies in the smallest shell that covers it.
        inside = [k for k, p in enumerate(parts) if p.covers(h)]
        if inside:
            inner[min(inside, key=lambda k: parts[k].area)].append(h)
    made = [shapely.Polygon(s, inner[k]) for k, s in enumerate(shells)]
    return made[0] if len(made) == 1 else shapely.MultiPolygon(made)
