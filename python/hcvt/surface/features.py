"""Sharp features kept in isotropic remeshing: detection, sites on the curves, a constrained CVT.

:func:`hcvt.remesh` with ``features=angle`` (DESIGN §12, "feature edges are a 1D restricted
diagram of their own"):

1. **Detection** (:func:`detect_features`). A feature edge is an edge of two triangles whose
   normals differ by more than ``angle`` degrees, or an edge of one triangle only (the
   border of an open surface). Feature edges chain into curves between *corners*: vertices
   with other than two feature edges (ends and junctions) and *kinks*, where a curve
   turns by more than ``angle`` (a feature line bent sharply is two curves).
2. **Sites on the curves** (:func:`feature_sites`). Every corner is a site; each curve gets
   sites at equal arc lengths (the 1D CVT of a curve of constant density, ends fixed), at
   most ``FEATURE_SPACING`` times the surface's site spacing ``h = sqrt(2A / (√3 n))`` apart
   (the edge of an equilateral triangle of area ``A / (2n)``, ``A`` the total area).
   Curves shorter than ``SHORTEST_CURVE`` times ``h`` are dropped first, with the corners
   they alone end at (:func:`long_curves`: a scanned mesh's short creases). Sites of
   different curves closer than ``WELD`` h are then merged (:func:`weld_sites`).
3. **The constrained CVT** (:func:`constrained_cvt`). The feature sites are held fixed;
   the others move freely in space (Yan et al. 2009) to minimise the same energy
   ``F = Σ ∫_{Ω_i} |x - z_i|² dA`` of the whole diagram, by the core's L-BFGS with those
   sites held (:func:`hcvt.cvt`'s ``fixed=``), after ``PRESMOOTH`` Lloyd steps that even
   out the random start's cell sizes, until the RMS gap of the free sites falls below
   ``tol`` (the ``"gap"`` rule of :func:`hcvt.cvt`).

The restricted Delaunay triangulation then joins consecutive sites of a curve: their
cells meet on the curve, no other cell reaches it between them (checked:
:attr:`FeatureSites.segments` missing from the triangles are reported as defects).
Held sites the CVT cannot help (among cells that are not discs, or parting a segment's
ends) are freed by :func:`hcvt.remesh` (:func:`release_sites`, counted in its ``freed``).

Lévy and Liu's Lp-CVT (SIGGRAPH 2010) keeps features by normal anisotropy instead;
geogram's and CGAL's remeshers, like this module, hold vertices on the feature curves.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from hcvt.density import DensityLike
from hcvt.geometry.domain import Domain
from hcvt.lazy import load
from hcvt.optimise import CVTResult, cvt
from hcvt.surface.quality import edge_counts

#: Spacing of the sites along a feature curve, in units of the surface's site spacing h.
#: Closer than h so that no free cell reaches a curve between two of its sites (which
#: would drop the segment from the triangulation). Fandisk, 40°, n = 1,500, the pieces
#: rounded (now ceil) and no flips: segments missing 12 at 1.0, 5 at 0.85, none at 0.7.
#: At 1.0, n = 5,000, the defects they left ran the CVT to max_iter.
FEATURE_SPACING = 0.7
#: Feature curves shorter than this many site spacings h are not kept (nor their
#: corners, unless another curve ends there): a scanned mesh's creases above the angle
#: are mostly runs of one or two input edges whose corners, held a fraction of h apart,
#: make slivers. Kitten, n = 20,000, 30°: 9 of its 193 curves shorter than h; with them
#: Q min 0.211, least angle 13.6°, Hausdorff 0.102% of the diagonal; without them 0.460,
#: 20.2°, 0.101% (MeshLab, whose default keeps creases above 30°: 0.369, 18.1°, 0.141%).
#: Dropping those shorter than 3 h: 0.547, 27.5°, but 0.170%. The fandisk's 35 curves are
#: all longer than 2 h at n = 5,000 and 20,000: not changed.
SHORTEST_CURVE = 1.0
#: Held sites closer than this many site spacings h to an earlier one are merged into it
#: (:func:`weld_sites`): the sites along one curve are at least 0.47 h apart
#: (``FEATURE_SPACING`` and ``SHORTEST_CURVE``), so only sites of different curves merge.
WELD = 0.4
#: ... and only where one of the two is a corner or an end, or where their curves run
#: within this many degrees of parallel: the fandisk's 19.4° wedge between two curves
#: keeps both (welding its sites there doubled the Hausdorff distance at n = 5,000,
#: 0.150% -> 0.285%, for a least angle of 27.1° instead of 17.5°).
WELD_DEGREES = 15.0
#: Lloyd steps of the free sites before L-BFGS: a random start's cells differ in size by
#: an order of magnitude, which scipy's unpreconditioned L-BFGS (used here before the core
#: held sites) did not undo well (fandisk, n = 5,000: Q min 0.21 without, 0.45 with 3). The
#: core's L-BFGS is preconditioned; at n = 1,500 (40°, seed 1) it did as well without them
#: (Hausdorff 0.417% against 0.458%, same Q min 0.474 and θmin 19.9°): not re-measured at
#: 5,000, so they stay.
PRESMOOTH = 3


@dataclass(frozen=True)
class FeatureCurves:
    """The sharp features of a triangle surface (:func:`detect_features`).

    Attributes
    ----------
    angle : float
        The threshold, degrees: edges whose triangles' normals differ by more.
    edges : ndarray of intp, shape (e, 2)
        The feature edges, pairs of vertex indices (smaller first).
    corners : ndarray of intp, shape (c,)
        Vertices where curves end, meet or kink.
    curves : list of (ndarray of intp, bool)
        Each curve as its chain of vertex indices and whether it is closed (a loop with no
        corner, its first vertex not repeated at the end); an open curve runs from a corner
        to a corner.
    """

    angle: float
    edges: NDArray[np.intp]
    corners: NDArray[np.intp]
    curves: list[tuple[NDArray[np.intp], bool]]


@dataclass(frozen=True)
class FeatureSites:
    """The fixed sites on the features of a surface (:func:`feature_sites`).

    Attributes
    ----------
    points : ndarray, shape (k, 3)
        The sites, L: the corners first (in the order of :attr:`FeatureCurves.corners`),
        then each curve's inner sites in order along it.
    segments : ndarray of intp, shape (s, 2)
        Pairs of rows of ``points`` consecutive on a curve: the edges the triangulation
        must contain.
    """

    points: NDArray[np.float64]
    segments: NDArray[np.intp]


def check_angle(angle: float) -> float:
    """``angle`` as a float, or ValueError unless it is finite and in (0, 180) degrees."""
    value = float(angle)
    if not math.isfinite(value) or not 0.0 < value < 180.0:
        raise ValueError(
            f"features= is the dihedral angle in degrees above which an edge is sharp, "
            f"in (0, 180); got {angle!r}"
        )
    return value


def detect_features(
    vertices: NDArray[np.float64],
    faces: NDArray[np.intp],
    angle: float,
    *,
    creases: bool = True,
) -> FeatureCurves:
    """The feature edges of a triangle surface above ``angle`` degrees, chained into curves.

    ``vertices`` (m, 3) and ``faces`` (f, 3) as :meth:`hcvt.Domain.from_surface` takes them.
    The border's edges are features; with ``creases=False`` they alone are (an open
    surface's border, :func:`hcvt.remesh`'s ``border``), ``angle`` then deciding only
    where a curve turns enough to make a corner.
    """
    angle = check_angle(angle)
    faces = np.asarray(faces, dtype=np.intp)
    pairs, counts = edge_counts(faces)
    border = pairs[counts == 1]
    sharp_edges = np.empty((0, 2), dtype=np.intp)
    if creases:
        trimesh = load("trimesh")
        mesh = trimesh.Trimesh(vertices, faces, process=False)
        sharp_edges = mesh.face_adjacency_edges[np.degrees(mesh.face_adjacency_angles) > angle]
    edges = np.unique(np.sort(np.concatenate([sharp_edges, border]), axis=1), axis=0).astype(
        np.intp
    )
    corners = _corners(np.asarray(vertices, dtype=np.float64), edges, angle)
    return FeatureCurves(angle, edges, corners, _chains(edges, corners, len(vertices)))


def _corners(
    vertices: NDArray[np.float64], edges: NDArray[np.intp], angle: float
) -> NDArray[np.intp]:
    """Vertices with other than two feature edges, and those where a curve turns by > angle."""
    degree = np.bincount(edges.ravel(), minlength=len(vertices))
    corner = (degree > 0) & (degree != 2)
    # The two neighbours of each vertex of degree 2: sort the edges' ends by vertex.
    ends = np.concatenate([edges, edges[:, ::-1]])
    ends = ends[np.argsort(ends[:, 0], kind="stable")]
    two = degree[ends[:, 0]] == 2
    pairs = ends[two].reshape(-1, 2, 2)  # (k, 2 edges, (vertex, neighbour))
    middle = pairs[:, 0, 0]
    a = vertices[pairs[:, 0, 1]] - vertices[middle]
    b = vertices[pairs[:, 1, 1]] - vertices[middle]
    cos = np.einsum("ij,ij->i", a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    turn = 180.0 - np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    corner[middle[turn > angle]] = True
    return np.flatnonzero(corner).astype(np.intp)


def _chains(
    edges: NDArray[np.intp], corners: NDArray[np.intp], n_vertices: int
) -> list[tuple[NDArray[np.intp], bool]]:
    """Walk the feature edges into curves from corner to corner, then the closed loops left."""
    neighbours: dict[int, list[tuple[int, int]]] = {}
    for k, (a, b) in enumerate(edges.tolist()):
        neighbours.setdefault(a, []).append((b, k))
        neighbours.setdefault(b, []).append((a, k))
    is_corner = np.zeros(n_vertices, dtype=bool)
    is_corner[corners] = True
    used = np.zeros(len(edges), dtype=bool)

    def walk(start: int, step: int, edge: int) -> tuple[NDArray[np.intp], bool]:
        path = [start]
        while True:
            used[edge] = True
            path.append(step)
            if is_corner[step]:
                return np.array(path, dtype=np.intp), False
            onward = [(c, j) for c, j in neighbours[step] if not used[j]]
            if not onward:  # back at the start of a loop
                return np.array(path[:-1], dtype=np.intp), True
            step, edge = onward[0]

    curves = []
    for corner in corners.tolist():
        for step, edge in neighbours[corner]:
            if not used[edge]:
                curves.append(walk(corner, step, edge))
    for edge in range(len(edges)):
        if not used[edge]:
            a, b = edges[edge].tolist()
            curves.append(walk(a, b, edge))
    return curves


def long_curves(
    features: FeatureCurves,
    vertices: NDArray[np.float64],
    shortest: float,
    *,
    whole: bool = False,
) -> FeatureCurves:
    """``features`` without the curves shorter than ``shortest`` (L), open or closed.

    Their corners go too, unless a curve kept ends there (:data:`SHORTEST_CURVE`). With
    ``whole``, a curve goes only when all the curves joined to it (a border loop cut at
    its corners) are shorter together: a loop's short pieces stay with it.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    lengths = []
    for chain, closed in features.curves:
        polyline = vertices[np.append(chain, chain[0]) if closed else chain]
        lengths.append(float(np.linalg.norm(np.diff(polyline, axis=0), axis=1).sum()))
    if whole and features.curves:
        lengths = _joined_lengths(features.curves, lengths, len(vertices))
    kept = [
        curve for curve, length in zip(features.curves, lengths, strict=True) if length >= shortest
    ]
    ends = {int(c[i]) for c, closed in kept if not closed for i in (0, -1)}
    corners = np.array([c for c in features.corners.tolist() if c in ends], dtype=np.intp)
    edges = [np.sort(np.column_stack([c[:-1], c[1:]]), axis=1) for c, _ in kept]
    edges += [np.sort([[c[-1], c[0]]], axis=1) for c, closed in kept if closed]
    all_edges = np.concatenate(edges).astype(np.intp) if edges else features.edges[:0]
    return FeatureCurves(features.angle, all_edges, corners, kept)


def _joined_lengths(
    curves: list[tuple[NDArray[np.intp], bool]], lengths: list[float], n_vertices: int
) -> list[float]:
    """Per curve, the total length (L) of the curves joined to it through shared vertices."""
    chains = [np.append(c, c[0]) if closed else c for c, closed in curves]
    a = np.concatenate([c[:-1] for c in chains])
    b = np.concatenate([c[1:] for c in chains])
    graph = coo_matrix((np.ones(len(a)), (a, b)), shape=(n_vertices, n_vertices))
    _, label = connected_components(graph, directed=False)
    of_curve = np.array([label[c[0]] for c, _ in curves])
    total = np.bincount(of_curve, weights=np.asarray(lengths))
    return [float(total[k]) for k in of_curve]


def site_spacing(area: float, n: int) -> float:
    """The spacing h of ``n`` sites on a surface of ``area`` (L²), L.

    The edge of an equilateral triangle of area ``area / (2n)`` (a CVT's Delaunay
    triangles, 2n of them).
    """
    return math.sqrt(2.0 * area / (math.sqrt(3.0) * n))


def feature_sites(
    features: FeatureCurves, vertices: NDArray[np.float64], spacing: float
) -> FeatureSites:
    """Sites on the corners and at equal arc lengths along each curve, ``spacing`` (L) apart.

    ``ceil(length / spacing)`` pieces on an open curve, as many sites on a closed one (at
    least three): the 1D CVT of the curve, its ends held, at most ``spacing`` apart.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    corner_row = {int(c): row for row, c in enumerate(features.corners.tolist())}
    points = [vertices[features.corners]]
    segments: list[tuple[int, int]] = []
    row = len(features.corners)
    for chain, closed in features.curves:
        polyline = vertices[np.append(chain, chain[0]) if closed else chain]
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(polyline, axis=0), axis=1))])
        length = arc[-1]
        # At most `spacing` apart: a longer gap between two sites lets a free site settle
        # on the curve between them (fandisk, n = 1,000: a 0.93 h curve between two corners).
        pieces = (
            max(3, math.ceil(length / spacing)) if closed else max(1, math.ceil(length / spacing))
        )
        # Evenly spaced: on a regular mesh (CAD models, a box) the meeting points of their
        # cells with a neighbour's then fall exactly on the input's edges and vertices,
        # which the core's restricted Delaunay triangulation finds once (a shift off these
        # positions dodged it before it did).
        at = (np.arange(pieces) if closed else np.arange(1, pieces)) * (length / pieces)
        inner = np.column_stack([np.interp(at, arc, polyline[:, j]) for j in range(3)])
        rows = list(range(row, row + len(inner)))
        row += len(inner)
        if closed:
            order = [*rows, rows[0]]
        else:
            order = [corner_row[int(chain[0])], *rows, corner_row[int(chain[-1])]]
        segments.extend(zip(order[:-1], order[1:], strict=True))
        points.append(inner)
    return FeatureSites(np.concatenate(points), np.array(segments, dtype=np.intp).reshape(-1, 2))


def weld_sites(sites: FeatureSites, radius: float) -> FeatureSites:
    """``sites`` with those closer than ``radius`` (L) to an earlier kept one merged into it.

    In order (the corners first, then each curve's sites along it), a site is kept unless
    a kept site lies within ``radius``; one that is not is replaced, in every segment, by
    the nearest kept site within ``radius``, and segments whose two ends became one are
    dropped (duplicates once). Two curves leaving a corner at an acute angle (the bunny's
    creases: 7.4°; the fandisk's 19.4° wedge), or running side by side closer than a site
    spacing, would otherwise hold sites a small fraction of a spacing apart whose cells are
    not discs (:data:`WELD`).
    """
    points = np.asarray(sites.points, dtype=np.float64)
    k = len(points)
    if k == 0 or radius <= 0.0:
        return sites
    tree = cKDTree(points)
    near = tree.query_ball_point(points, radius)
    # Each site's direction along its curve (segments run along the curves, in order);
    # sites with other than two segments (ends, junctions) have none.
    ends = np.asarray(sites.segments, dtype=np.intp).reshape(-1, 2)
    step = points[ends[:, 1]] - points[ends[:, 0]]
    step /= np.maximum(np.linalg.norm(step, axis=1), 1e-300)[:, None]
    tangent = np.zeros_like(points)
    np.add.at(tangent, ends[:, 0], step)
    np.add.at(tangent, ends[:, 1], step)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1), 1e-300)[:, None]
    along = np.bincount(ends.ravel(), minlength=k) == 2
    parallel = math.cos(math.radians(WELD_DEGREES))

    def merges(i: int, j: int) -> bool:
        """Sites i and j merge: one is a corner, or their curves run (anti)parallel."""
        return not (along[i] and along[j]) or abs(float(tangent[i] @ tangent[j])) > parallel

    kept = np.zeros(k, dtype=bool)
    rep = np.arange(k)
    for i in range(k):
        earlier = [j for j in near[i] if j < i and kept[j] and merges(i, j)]
        if earlier:
            d = np.linalg.norm(points[earlier] - points[i], axis=1)
            rep[i] = earlier[int(np.argmin(d))]
        else:
            kept[i] = True
    if kept.all():
        return sites
    row = np.cumsum(kept) - 1  # the kept sites' new rows
    segments = row[rep[sites.segments]].reshape(-1, 2)
    segments = segments[segments[:, 0] != segments[:, 1]]
    if len(segments):
        _, first = np.unique(np.sort(segments, axis=1), axis=0, return_index=True)
        segments = segments[np.sort(first)]
    points = points[kept]
    return FeatureSites(points, _without_shortcuts(points, segments.astype(np.intp)))


#: A triangle of segments whose least angle is below this (degrees) loses its longest
#: segment (:func:`_without_shortcuts`).
_SHORTCUT_DEGREES = 20.0


def _without_shortcuts(points: NDArray[np.float64], segments: NDArray[np.intp]) -> NDArray[np.intp]:
    """``segments`` (s, 2) without the longest side of each flat triangle of segments.

    Welding (:func:`weld_sites`) maps a site of one curve onto a kept site of another, so
    that a curve's segment may run beside two segments of the other through a site nearly
    on it: three held sites whose triangle (an angle near 180°) the triangulation would
    have to contain (bunny, n = 5,000: 5.9°, sides 0.47, 0.46, 0.93 h).
    """
    segments = segments.reshape(-1, 2)
    while True:
        near: dict[int, set[int]] = {}
        for a, b in segments.tolist():
            near.setdefault(a, set()).add(b)
            near.setdefault(b, set()).add(a)
        drop = None
        for a, b in segments.tolist():
            for c in near[a] & near[b]:
                p = points[[a, b, c]]
                sides = np.linalg.norm(p - p[[1, 2, 0]], axis=1)  # ab, bc, ca
                u, v = p[1] - p[0], p[2] - p[0]
                area2 = float(np.linalg.norm(np.cross(u, v)))
                # The least angle, opposite the shortest side: sin = 2A / (the other two).
                k = int(np.argmin(sides))
                others = float(np.prod(sides)) / float(sides[k])
                if np.degrees(np.arcsin(min(1.0, area2 / others))) < _SHORTCUT_DEGREES:
                    longest = [(a, b), (b, c), (c, a)][int(np.argmax(sides))]
                    drop = tuple(sorted(longest))
                    break
            if drop is not None:
                break
        if drop is None:
            return segments
        keep = np.any(np.sort(segments, axis=1) != np.array(drop), axis=1)
        segments = segments[keep]


def plan_feature_sites(
    surface: Domain, n: int, angle: float, *, creases: bool = True
) -> FeatureSites:
    """The fixed sites of :func:`hcvt.remesh` with ``features=angle`` for ``n`` sites in all.

    With ``creases=False`` those of the border alone (:func:`detect_features`).
    Raises ValueError for a bad angle, or when the features take all ``n`` sites.
    """
    features = detect_features(surface.vertices, surface.faces, angle, creases=creases)
    spacing = FEATURE_SPACING * site_spacing(surface.volume, n)
    features = long_curves(
        features,
        surface.vertices,
        SHORTEST_CURVE * site_spacing(surface.volume, n),
        whole=not creases,
    )
    sites = feature_sites(features, surface.vertices, spacing)
    sites = weld_sites(sites, WELD * site_spacing(surface.volume, n))
    if len(sites.points) >= n:
        raise ValueError(
            f"the features above {angle}° take {len(sites.points)} sites, n = {n} leaves "
            "none for the rest of the surface: raise n or the angle"
            if creases
            else f"the border takes {len(sites.points)} sites, n = {n} leaves none for the "
            "rest of the surface: raise n, or remesh with border=False"
        )
    return sites


def missing_segments(faces: NDArray[np.intp], segments: NDArray[np.intp]) -> NDArray[np.intp]:
    """The rows of ``segments`` (s, 2), vertex pairs, that are no edge of ``faces`` (f, 3)."""
    edges = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    wanted = np.sort(segments, axis=1)
    key = int(max(edges.max(initial=0), wanted.max(initial=0))) + 1
    present = np.isin(wanted[:, 0] * key + wanted[:, 1], edges[:, 0] * key + edges[:, 1])
    return np.flatnonzero(~present).astype(np.intp)


def restore_segments(
    faces: NDArray[np.intp], vertices: NDArray[np.float64], plan: FeatureSites
) -> NDArray[np.intp]:
    """``faces`` (f, 3) with each missing feature segment crossed by one edge flipped in.

    ``vertices`` (n, 3) end with ``plan``'s points. A segment ``(a, b)`` goes missing where
    the cells of two free sites ``c``, ``d`` meet across the curve between ``a`` and ``b``:
    the triangles ``(a, c, d)`` and ``(d, c, b)`` then make a quadrilateral whose diagonal
    ``c-d`` crosses the segment, and flipping it to ``a-b`` gives ``(a, c, b)`` and
    ``(a, b, d)``, as a constrained Delaunay triangulation would. Done only where both new
    triangles face the way the old ones did (a convex quadrilateral); other misses stay,
    and :func:`segment_defects` names them.
    """
    first = len(vertices) - len(plan.points)
    missing = missing_segments(faces, plan.segments + first)
    if not len(missing):
        return faces
    faces = faces.copy()

    def normal(t: list[int]) -> NDArray[np.float64]:
        p = vertices[t]
        return np.cross(p[1] - p[0], p[2] - p[0])

    for a, b in (plan.segments[missing] + first).tolist():
        for t in np.flatnonzero((faces == a).any(axis=1)).tolist():
            row = faces[t].tolist()
            c, d = row[(row.index(a) + 1) % 3], row[(row.index(a) + 2) % 3]
            across = np.flatnonzero(
                (faces == d).any(axis=1) & (faces == c).any(axis=1) & (faces == b).any(axis=1)
            )
            if len(across) != 1:
                continue
            old = normal([a, c, d]) + normal([d, c, b])
            new = ([a, c, b], [a, b, d])
            if all(normal(tri) @ old > 0.0 for tri in new):
                faces[t], faces[across[0]] = new
                break
    return faces


def intruding_sites(
    vertices: NDArray[np.float64], faces: NDArray[np.intp], plan: FeatureSites
) -> NDArray[np.intp]:
    """The sites whose cells part those of a missing feature segment's ends.

    ``vertices`` (n, 3) end with ``plan``'s points. For each segment ``(a, b)`` missing
    from ``faces``, the vertex of triangles at both ends nearest the segment (free or
    held), if any; sorted, once each.
    """
    first = len(vertices) - len(plan.points)
    missing = missing_segments(faces, plan.segments + first)
    intruders: set[int] = set()
    for a, b in (plan.segments[missing] + first).tolist():
        common = np.intersect1d(faces[(faces == a).any(axis=1)], faces[(faces == b).any(axis=1)])
        if len(common):
            p, q = vertices[a], vertices[b]
            along = np.clip((vertices[common] - p) @ (q - p) / ((q - p) @ (q - p)), 0.0, 1.0)
            off = np.linalg.norm(vertices[common] - (p + along[:, None] * (q - p)), axis=1)
            intruders.add(int(common[np.argmin(off)]))
    return np.array(sorted(intruders), dtype=np.intp)


def move_intruders(
    vertices: NDArray[np.float64], faces: NDArray[np.intp], plan: FeatureSites
) -> NDArray[np.float64] | None:
    """``vertices`` (n, 3) with the free sites that cut feature segments moved, or None.

    A segment ``(a, b)`` also goes missing where a free site ``c`` settled on the curve
    between ``a`` and ``b`` (its cell spans the crease: both sides pull it there), so that
    its cell parts theirs. The CVT leaves it there: at remesh's tolerance 4 times tighter
    it took 31 more iterations to move off (fandisk, n = 5,000, 30°). For each missing
    segment, ``c`` is the free vertex of triangles at both ends nearest the segment; it
    goes to the centroid of the largest triangle of free sites (the widest gap; one per
    ``c``, none sharing a site with another or with a moved one), from where the CVT (a
    step or two: the rest is converged) spaces the sites again. None when nothing moves.
    """
    first = len(vertices) - len(plan.points)
    intruders = [c for c in intruding_sites(vertices, faces, plan).tolist() if c < first]
    moved, count = move_to_gaps(vertices, faces, first, intruders)
    return moved if count else None


def move_to_gaps(
    vertices: NDArray[np.float64], faces: NDArray[np.intp], first: int, sites: list[int]
) -> tuple[NDArray[np.float64], int]:
    """``vertices`` (n, 3) with ``sites`` moved to the widest gaps, and how many moved.

    Each, in order, to the centroid of the largest triangle of ``faces`` (f, 3) whose
    vertices are all below ``first`` (free sites), none sharing a vertex with another
    chosen or with ``sites`` (:func:`move_intruders`).
    """
    free = faces[(faces < first).all(axis=1)]
    corners = vertices[free]
    area = np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    gaps = iter(np.argsort(-area, kind="stable").tolist())
    moved, taken, count = vertices.copy(), set(sites), 0
    for c in sites:
        gap = next((t for t in gaps if not taken & set(free[t].tolist())), None)
        if gap is None:
            break
        taken |= set(free[gap].tolist())
        moved[c] = corners[gap].mean(axis=0)
        count += 1
    return moved, count


def release_sites(plan: FeatureSites, rows: NDArray[np.intp]) -> FeatureSites:
    """``plan`` without the sites ``rows`` (indices into ``plan.points``) and their segments.

    :func:`hcvt.remesh` lets those sites move with the free ones: held sites whose cells
    are not discs (the closed-ball property fails among them; bunny, n = 20,000, 30°: the
    creases of its patched base, folded by up to 147°, crowd held sites there).
    """
    keep = np.ones(len(plan.points), dtype=bool)
    keep[np.asarray(rows, dtype=np.intp)] = False
    row = np.cumsum(keep) - 1
    segments = plan.segments[keep[plan.segments].all(axis=1)]
    return FeatureSites(plan.points[keep], row[segments].astype(np.intp).reshape(-1, 2))


def segment_defects(faces: NDArray[np.intp], plan: FeatureSites, n: int) -> list[str]:
    """The defect naming the feature segments missing from ``faces`` (f, 3), or none.

    ``faces`` index ``n`` sites whose last ``len(plan.points)`` are ``plan``'s.
    """
    first = n - len(plan.points)
    missing = missing_segments(faces, plan.segments + first)
    if not len(missing):
        return []
    a, b = (plan.segments[missing[0]] + first).tolist()
    return [
        f"{len(missing)} segment(s) of the feature curves not in the triangulation, first "
        f"between sites {a} and {b}"
    ]


def constrained_cvt(
    surface: Domain,
    sites: NDArray[np.float64],
    fixed: int,
    method: str,
    *,
    tol: float,
    max_iter: int,
    density: DensityLike = None,
) -> CVTResult:
    """A CVT of ``surface`` whose last ``fixed`` rows of ``sites`` (n, 3) do not move.

    The core's optimiser with those sites held (:func:`hcvt.cvt`'s ``fixed=``): L-BFGS
    (``method="lbfgs"``) after :data:`PRESMOOTH` Lloyd steps, or Lloyd steps (``"lloyd"``),
    the free sites moving in space until the RMS of their gaps (the ``"gap"`` rule over the
    free sites) is below ``tol`` or ``max_iter`` iterations; then the free ones are
    projected onto the surface (the fixed ones lie on it already and keep their bits).
    The history is the runs' one after the other.
    """
    if method not in ("lbfgs", "lloyd"):
        raise ValueError(f"remesh with features= runs lbfgs or lloyd, not {method!r}")
    start = time.perf_counter()
    mask = np.zeros(len(sites), dtype=bool)
    mask[len(sites) - fixed :] = True
    lloyd_steps = max_iter if method == "lloyd" else min(PRESMOOTH, max_iter)
    runs = [
        cvt(surface, sites, "lloyd", tol=tol, max_iter=lloyd_steps, fixed=mask, density=density)
    ]
    if method == "lbfgs" and not runs[0].converged and runs[0].iterations < max_iter:
        rest = max_iter - runs[0].iterations
        runs.append(
            cvt(
                surface,
                runs[0].sites,
                "lbfgs",
                tol=tol,
                max_iter=rest,
                fixed=mask,
                density=density,
            )
        )
    last = runs[-1]
    # One history: the later run's first record is the earlier's last iterate (projected).
    history = {
        key: np.concatenate([r.history[key][1 if k else 0 :] for k, r in enumerate(runs)])
        for key in last.history
    }
    return replace(
        last,
        history=history,
        iterations=sum(r.iterations for r in runs),
        evaluations=sum(r.evaluations for r in runs),
        seconds=time.perf_counter() - start,
    )


__all__ = [
    "FEATURE_SPACING",
    "SHORTEST_CURVE",
    "WELD",
    "WELD_DEGREES",
    "FeatureCurves",
    "FeatureSites",
    "check_angle",
    "constrained_cvt",
    "detect_features",
    "feature_sites",
    "intruding_sites",
    "long_curves",
    "missing_segments",
    "move_intruders",
    "move_to_gaps",
    "plan_feature_sites",
    "release_sites",
    "restore_segments",
    "segment_defects",
    "weld_sites",
]
