"""Each cell's own geometry, read off the conforming mesh (:class:`hcvt.polymesh.PolyMesh`).

The mesh stores every face once; a cell is the faces it owns, as they are, and the faces
it neighbours, reversed, so that each cell's faces run counter-clockwise seen from outside
it (3D) or its edges have it on their left (2D).
"""

from __future__ import annotations

import numpy as np
import shapely
from numpy.typing import NDArray

from hcvt.polymesh import PolyMesh

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
    bounds = np.searchsorted(cells, np.arange(mesh.n_cells + 1))
    empty = (np.zeros((0, 3)), np.zeros((0, 3), dtype=np.intp))
    out: list[Triangulation] = []
    for i in range(mesh.n_cells):
        t = triangles[bounds[i] : bounds[i + 1]]
        if len(t) == 0:
            out.append(empty)
            continue
        used, local = np.unique(t, return_inverse=True)
        out.append((mesh.points[used], local.reshape(-1, 3).astype(np.intp)))
    return out


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
    bad = np.flatnonzero(_non_convex(mesh))
    if len(bad) == 0:
        return face_of, triangles
    keep = ~np.isin(face_of, bad)
    faces, tris = [face_of[keep]], [triangles[keep]]
    for k in bad.tolist():
        t = _planar_triangles(mesh.points, mesh.face(k))
        faces.append(np.full(len(t), k, dtype=np.intp))
        tris.append(t)
    face_of = np.concatenate(faces)
    order = np.argsort(face_of, kind="stable")
    return face_of[order], np.concatenate(tris)[order]


def _non_convex(mesh: PolyMesh) -> NDArray[np.bool_]:
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


def _planar_triangles(points: NDArray[np.float64], face: NDArray[np.intp]) -> NDArray[np.intp]:
    """A planar polygon's constrained Delaunay triangles (shapely/GEOS) in its orientation."""
    p = points[face]
    normal = np.cross(p, np.roll(p, -1, axis=0)).sum(axis=0)
    axis = int(np.argmax(np.abs(normal)))
    u, v = (axis + 1) % 3, (axis + 2) % 3
    if normal[axis] < 0:
        u, v = v, u  # keep counter-clockwise seen from +normal counter-clockwise in 2D
    flat = p[:, [u, v]]
    index = {tuple(xy): k for k, xy in enumerate(flat.tolist())}
    cdt = shapely.constrained_delaunay_triangles(shapely.Polygon(flat))
    out = []
    for tri in shapely.get_parts(cdt):
        found = [index.get(tuple(c)) for c in np.asarray(tri.exterior.coords)[:3].tolist()]
        corners = [k for k in found if k is not None]
        if len(corners) != 3:
            return _fan(face)  # GEOS moved a point: keep the fan
        if not tri.exterior.is_ccw:
            corners = corners[::-1]
        out.append(face[corners])
    if len(out) != len(face) - 2:
        return _fan(face)
    return np.array(out, dtype=np.intp)


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
