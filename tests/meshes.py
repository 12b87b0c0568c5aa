"""Conforming PolyMeshes built without the core, to test the exporters against.

- :func:`hex_grid`: a structured grid of boxes (3D), the simplest mesh with known answers.
- :func:`quad_tri_grid`: a 2D grid of squares, every other one split into two triangles.
- :func:`convex_voronoi`: the Voronoi diagram of sites clipped to a *convex* domain (the
  real ``sphere.ply``, a box), one scipy ``HalfspaceIntersection`` per cell, the cells'
  vertices welded into shared points. Every face lies on a bisector plane or on a domain
  triangle's plane, so Σ volume equals the domain's volume to round-off.

Each returns a :class:`hcvt.mesh.PolyMesh` in the contract's layout (owner < neighbour is
*not* imposed: the exporters must order faces themselves).
"""

from __future__ import annotations

import numpy as np
import shapely
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import HalfspaceIntersection, cKDTree

import hcvt
from hcvt.mesh.polymesh import PolyMesh


def box_domain(lo=(0.0, 0.0, 0.0), hi=(1.0, 1.0, 1.0)) -> hcvt.Domain:
    """The box [lo, hi] as a closed mesh of 12 outward triangles."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    corners = np.array([[(hi if (k >> a) & 1 else lo)[a] for a in range(3)] for k in range(8)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    faces = [t for q in quads for t in ((q[0], q[1], q[2]), (q[0], q[2], q[3]))]
    return hcvt.Domain.from_mesh(corners, faces)


def square_domain(lo=(0.0, 0.0), hi=(1.0, 1.0)) -> hcvt.Domain:
    """The rectangle [lo, hi] with its four sides as boundary segments 0..3."""
    (x0, y0), (x1, y1) = lo, hi
    return hcvt.Domain.from_polygon([(x0, y0), (x1, y0), (x1, y1), (x0, y1)])


def _mesh(points, faces, owner, neighbour, element, n_cells) -> PolyMesh:
    sizes = np.array([len(f) for f in faces], dtype=np.intp)
    offsets = np.zeros(len(faces) + 1, dtype=np.intp)
    np.cumsum(sizes, out=offsets[1:])
    return PolyMesh(
        points=np.asarray(points, dtype=np.float64),
        face_offsets=offsets,
        face_vertices=np.concatenate([np.asarray(f, dtype=np.intp) for f in faces]),
        owner=np.asarray(owner, dtype=np.intp),
        neighbour=np.asarray(neighbour, dtype=np.intp),
        boundary_element=np.asarray(element, dtype=np.intp),
        n_cells=n_cells,
    )


def hex_grid(shape=(3, 4, 5), lo=(0.0, 0.0, 0.0), hi=(1.0, 1.0, 1.0)) -> PolyMesh:
    """Boxes of a structured grid; boundary faces name a triangle of :func:`box_domain`.

    Cell ``(i, j, k)`` is ``i + nx (j + ny k)``; interior faces are owned by the cell with
    the *larger* index, so the writers' reordering is exercised.
    """
    nx, ny, nz = shape
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    axes = [np.linspace(lo[a], hi[a], shape[a] + 1) for a in range(3)]
    gx, gy, gz = np.meshgrid(*axes, indexing="ij")
    points = np.column_stack([gx.ravel(order="F"), gy.ravel(order="F"), gz.ravel(order="F")])

    def pid(i, j, k):
        return i + (nx + 1) * (j + (ny + 1) * k)

    def cid(i, j, k):
        return i + nx * (j + ny * k)

    faces, owner, neighbour, element = [], [], [], []
    # Per axis a: the face at index t along a of cell c, counter-clockwise seen from +a.
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3
        for t in range(shape[a] + 1):
            for u in range(shape[b]):
                for v in range(shape[c]):
                    corner = [[0, 0], [1, 0], [1, 1], [0, 1]]
                    loop = []
                    for du, dv in corner:
                        idx = [0, 0, 0]
                        idx[a], idx[b], idx[c] = t, u + du, v + dv
                        loop.append(pid(*idx))
                    lower = [0, 0, 0]
                    lower[a], lower[b], lower[c] = t - 1, u, v
                    upper = list(lower)
                    upper[a] = t
                    if t == 0:  # normal must point out of the upper cell, i.e. towards -a
                        faces.append(loop[::-1])
                        owner.append(cid(*upper))
                        neighbour.append(-1)
                        element.append(_box_element(a, 0))
                    elif t == shape[a]:
                        faces.append(loop)
                        owner.append(cid(*lower))
                        neighbour.append(-1)
                        element.append(_box_element(a, 1))
                    else:  # owned by the upper cell (the larger index): normal towards -a
                        faces.append(loop[::-1])
                        owner.append(cid(*upper))
                        neighbour.append(cid(*lower))
                        element.append(-1)
    return _mesh(points, faces, owner, neighbour, element, nx * ny * nz)


# box_domain's quads by (axis, side): its triangles are 2 q and 2 q + 1.
_BOX_QUAD = {(2, 0): 0, (2, 1): 1, (1, 0): 2, (1, 1): 3, (0, 0): 4, (0, 1): 5}


def _box_element(axis: int, side: int) -> int:
    """The first triangle of :func:`box_domain` on side ``(axis, side)``.

    Both triangles of a side lie in one plane and a grid face may straddle the diagonal;
    the element only decides the face's patch, the same for both.
    """
    return 2 * _BOX_QUAD[(axis, side)]


def quad_tri_grid(shape=(4, 3), lo=(0.0, 0.0), hi=(1.0, 1.0)) -> PolyMesh:
    """Squares of a grid, every other one split along a diagonal into two triangles.

    Boundary faces name the side of :func:`square_domain` they lie on (0 bottom, 1 right,
    2 top, 3 left).
    """
    nx, ny = shape
    xs = np.linspace(lo[0], hi[0], nx + 1)
    ys = np.linspace(lo[1], hi[1], ny + 1)
    points = np.array([[x, y] for y in ys for x in xs])

    def pid(i, j):
        return i + (nx + 1) * j

    # Each cell as a counter-clockwise loop of point ids.
    loops = []
    for j in range(ny):
        for i in range(nx):
            a, b, c, d = pid(i, j), pid(i + 1, j), pid(i + 1, j + 1), pid(i, j + 1)
            if (i + j) % 2:
                loops += [[a, b, c], [a, c, d]]
            else:
                loops.append([a, b, c, d])
    edge_cells: dict[tuple[int, int], list[int]] = {}
    for cell, loop in enumerate(loops):
        for k in range(len(loop)):
            e = (loop[k], loop[(k + 1) % len(loop)])
            edge_cells.setdefault(e, []).append(cell)
    faces, owner, neighbour, element = [], [], [], []
    for (u, v), cells in edge_cells.items():
        if (v, u) in edge_cells:
            if u < v:
                continue  # seen from the other side
            faces.append([u, v])
            owner.append(cells[0])
            neighbour.append(edge_cells[(v, u)][0])
            element.append(-1)
        else:
            faces.append([u, v])
            owner.append(cells[0])
            neighbour.append(-1)
            mid = (points[u] + points[v]) / 2
            side = np.argmin([mid[1] - lo[1], hi[0] - mid[0], hi[1] - mid[1], mid[0] - lo[0]])
            element.append(int(side))
    return _mesh(points, faces, owner, neighbour, element, len(loops))


def convex_voronoi(domain: hcvt.Domain, sites: np.ndarray, k: int = 48) -> PolyMesh:
    """The Voronoi cells of ``sites`` clipped to a convex ``domain`` (2D or 3D), as one PolyMesh.

    Each cell is a ``HalfspaceIntersection`` of the bisectors with its ``k`` nearest sites
    (more where needed) and the planes of the domain's triangles, in coordinates relative
    to its site. The cells' vertices are then welded (within 1e-9 h) into shared points and
    each face is the ring of its cell's vertices on its plane, in angular order. Raises
    AssertionError if two cells disagree on a shared face.
    """
    sites = np.asarray(sites, dtype=np.float64)
    n, d = sites.shape
    h = (domain.volume / n) ** (1 / d)
    tol = 1e-9 * h
    if d == 3:
        tri = domain.vertices[domain.faces]
        normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    else:  # segments a -> b with the domain on their left: outward normal to the right
        tri = domain.vertices[np.asarray(domain._core.segments)]
        t = tri[:, 1] - tri[:, 0]
        normals = np.column_stack([t[:, 1], -t[:, 0]])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    offsets = -np.einsum("ij,ij->i", normals, tri[:, 0])
    tree = cKDTree(sites)
    # One half-space per plane: coplanar triangles (a box's sides) would give a face twice.
    _, rep = np.unique(
        np.round(np.column_stack([normals, offsets / h]), 9), axis=0, return_index=True
    )
    rep = np.sort(rep)
    planes_at_origin = np.column_stack([normals[rep], offsets[rep]])
    cells = []  # per cell: (vertices (v, d), [(key, vertex rows, plane normal)])
    for i in range(n):
        v, halfspaces, others = _clipped_cell(sites, i, tree, k, planes_at_origin)
        signed = v @ halfspaces[:, :d].T + halfspaces[:, d]
        faces = []
        for h_idx in np.flatnonzero((np.abs(signed) < tol).sum(axis=0) >= d):
            ring = np.flatnonzero(np.abs(signed[:, h_idx]) < tol)
            is_site = h_idx < len(others)
            key = ("site", int(others[h_idx])) if is_site else ("tri", rep[h_idx - len(others)])
            faces.append((key, ring, halfspaces[h_idx, :d]))
        cells.append((v + sites[i], faces))
    # Weld every cell's vertices into shared points.
    all_v = np.concatenate([c[0] for c in cells])
    starts = np.cumsum([0] + [len(c[0]) for c in cells])
    pairs = cKDTree(all_v).query_pairs(tol, output_type="ndarray")
    graph = coo_matrix(
        (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(all_v), len(all_v))
    )
    _, label = connected_components(graph, directed=False)
    _, first, label = np.unique(label, return_index=True, return_inverse=True)
    points = all_v[first]
    seen: dict[tuple[int, int], list[int]] = {}
    faces, owner, neighbour, element = [], [], [], []
    for i, (_, cell_faces) in enumerate(cells):
        for key, ring, normal in cell_faces:
            ids = list(dict.fromkeys(label[starts[i] + ring].tolist()))
            if len(ids) < d:
                continue
            loop = _ccw(points, ids, normal)
            if key[0] == "tri":
                faces.append(loop)
                owner.append(i)
                neighbour.append(-1)
                element.append(_element_on_plane(tri, normals, key[1], points[loop].mean(axis=0)))
                continue
            j = key[1]
            pair = (min(i, j), max(i, j))
            if pair in seen:
                assert sorted(seen[pair]) == sorted(loop), f"cells {pair} disagree on their face"
                continue
            seen[pair] = loop
            faces.append(loop)
            owner.append(i)
            neighbour.append(j)
            element.append(-1)
    used = np.zeros(len(points), dtype=bool)
    used[np.concatenate(faces)] = True
    remap = np.cumsum(used) - 1
    faces = [remap[f] for f in faces]
    return _mesh(points[used], faces, owner, neighbour, element, n)


def _clipped_cell(sites, i, tree, k, planes):
    """Vertices of cell ``i`` relative to its site, its half-spaces and their sites.

    ``k`` doubles until the farthest neighbour used is beyond twice the cell's radius (the
    security radius of Ray et al. 2018), when no other site can cut the cell.
    """
    n, p = len(sites), sites[i]
    while True:
        dist, near = tree.query(p, k=min(k + 1, n))
        others = near[1:]
        q = sites[others] - p
        bisectors = np.column_stack([q, -0.5 * np.einsum("ij,ij->i", q, q)])
        d = len(p)
        shifted = np.column_stack([planes[:, :d], planes[:, d] + planes[:, :d] @ p])
        halfspaces = np.vstack([bisectors, shifted])
        v = HalfspaceIntersection(halfspaces, np.zeros(d)).intersections
        if len(others) == n - 1 or dist[-1] > 2 * np.linalg.norm(v, axis=1).max():
            return v, halfspaces, others
        k *= 2


def _ccw(points: np.ndarray, ids: list[int], normal: np.ndarray) -> list[int]:
    """``ids`` (points of a convex planar polygon) counter-clockwise about ``normal``.

    2D: the edge's two ends, ordered so that ``normal`` points to its right.
    """
    if points.shape[1] == 2:
        direction = np.array([-normal[1], normal[0]])
        a, b = ids
        return [a, b] if (points[b] - points[a]) @ direction > 0 else [b, a]
    xyz = points[ids]
    centre = xyz.mean(axis=0)
    u = xyz[0] - centre
    u /= np.linalg.norm(u)
    w = np.cross(normal / np.linalg.norm(normal), u)
    rel = xyz - centre
    angle = np.arctan2(rel @ w, rel @ u)
    return [ids[k] for k in np.argsort(angle)]


def _element_on_plane(tri, normals, t, point) -> int:
    """Of the triangles coplanar with triangle ``t``, the one whose closure holds ``point``.

    2D: of the segments on the line of segment ``t``, the one holding ``point``.
    """
    if tri.shape[2] == 2:
        on_line = np.flatnonzero(
            (np.abs(normals @ normals[t] - 1) < 1e-12)
            & (np.abs((tri[:, 0] - tri[t, 0]) @ normals[t]) < 1e-12)
        )
        for c in on_line:
            a, b = tri[c]
            u = (point - a) @ (b - a) / ((b - a) @ (b - a))
            if -1e-9 <= u <= 1 + 1e-9:
                return int(c)
        return int(t)
    coplanar = np.flatnonzero(
        (np.abs(normals @ normals[t] - 1) < 1e-12)
        & (np.abs((tri[:, 0] - tri[t, 0]) @ normals[t]) < 1e-12)
    )
    for c in coplanar:
        a, b, d = tri[c]
        m = np.column_stack([b - a, d - a, normals[c]])
        s, r, _ = np.linalg.solve(m, point - a)
        if s >= -1e-9 and r >= -1e-9 and s + r <= 1 + 1e-9:
            return int(c)
    return int(t)


def diagram_mesh_2d(diagram: hcvt.Diagram) -> PolyMesh:
    """The conforming mesh of a 2D diagram of any polygon, from its shapely cells.

    ``Diagram.cells()`` cuts each cell by GEOS on its own, so neighbours compute their shared
    vertices separately: they are welded here (within 1e-9 h). Every welded ring edge
    ``a -> b`` of cell i (outer rings counter-clockwise, holes clockwise) whose reverse
    ``b -> a`` belongs to cell j is an interior face; the others lie on the domain boundary,
    on the segment nearest their midpoint. Raises AssertionError if an edge is used twice
    the same way (a T-junction the welding missed).
    """
    from shapely.geometry.polygon import orient

    h = (diagram.domain.volume / diagram.n) ** 0.5
    rings, ring_cell = [], []
    for i, cell in enumerate(diagram.cells()):
        for part in shapely.get_parts(cell):
            part = orient(part, 1.0)
            for ring in [part.exterior, *part.interiors]:
                rings.append(np.asarray(ring.coords)[:-1])
                ring_cell.append(i)
    all_v = np.concatenate(rings)
    pairs = cKDTree(all_v).query_pairs(1e-9 * h, output_type="ndarray")
    graph = coo_matrix(
        (np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(len(all_v), len(all_v))
    )
    _, label = connected_components(graph, directed=False)
    _, first, label = np.unique(label, return_index=True, return_inverse=True)
    points = all_v[first]
    edges: dict[tuple[int, int], int] = {}
    start = 0
    for ring, cell in zip(rings, ring_cell, strict=True):
        ids = label[start : start + len(ring)]
        start += len(ring)
        for a, b in zip(ids, np.roll(ids, -1), strict=True):
            if a != b:
                assert (int(a), int(b)) not in edges, f"edge {a}->{b} used twice"
                edges[(int(a), int(b))] = cell
    segments = diagram.domain.vertices[np.asarray(diagram.domain._core.segments)]
    faces, owner, neighbour, element = [], [], [], []
    for (a, b), cell in edges.items():
        other = edges.get((b, a))
        if other is not None:
            if a > b:
                continue  # the face was added from (b, a)
            faces.append([a, b])
            owner.append(cell)
            neighbour.append(other)
            element.append(-1)
        else:
            faces.append([a, b])
            owner.append(cell)
            neighbour.append(-1)
            element.append(_nearest_segment(segments, (points[a] + points[b]) / 2))
    return _mesh(points, faces, owner, neighbour, element, diagram.n)


def _nearest_segment(segments: np.ndarray, point: np.ndarray) -> int:
    a, b = segments[:, 0], segments[:, 1]
    t = np.clip(np.einsum("ij,ij->i", point - a, b - a) / np.einsum("ij,ij->i", b - a, b - a), 0, 1)
    return int(np.argmin(np.linalg.norm(a + t[:, None] * (b - a) - point, axis=1)))
