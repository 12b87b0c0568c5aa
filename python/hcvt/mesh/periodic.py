"""The conforming mesh of a diagram in a box periodic along some axes (DESIGN §14).

The cells of the torus are cut open: each cell is kept whole around its (wrapped) site,
possibly sticking out of the box, and a face between a cell and the image of another
across a periodic side becomes a *periodic face*, paired with the same face seen from the
other cell (translated by whole periods). OpenFOAM reads each pair of sides as two
``cyclic`` patches (:func:`hcvt.io.openfoam.write_openfoam`); VTU shows the unwrapped cells.

How: the mesh of the cells of the sites and of their images within a band around the box,
in a box widened along the periodic axes (an ordinary convex solid or polygon), by the
core's conforming mesh; the band is the exact one the torus diagram's neighbours need
(every image of a neighbour of a cell is present), so the central cells are the torus
cells, and their vertices are named by bisectors as everywhere else. A central cell cut
by a side of the widened box (it cannot be when the band is right) is refused, so a wrong
band can not pass silently.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Protocol

import numpy as np
import shapely
from numpy.typing import NDArray

import hcvt._core as _core
from hcvt.errors import InvalidMeshError
from hcvt.geometry.domain import BOX_FACES, Domain, wrapped
from hcvt.mesh.polymesh import PolyMesh


class PeriodicCells(Protocol):
    """What :func:`periodic_mesh` reads of a :class:`hcvt.Diagram`.

    The diagram sits a layer above the meshes, so it is named here by its shape.
    """

    @property
    def domain(self) -> Domain:
        """The periodic box."""

    @property
    def sites(self) -> NDArray[np.float64]:
        """Sites (n, d), anywhere along the periodic axes."""

    @property
    def neighbor_sites(self) -> NDArray[np.intp]:
        """The other site of each face (m,)."""

    @property
    def neighbor_images(self) -> NDArray[np.int8] | None:
        """The image shift of each face's neighbour (m, d)."""

    @property
    def weights(self) -> NDArray[np.float64] | None:
        """Power weights (n,), or None."""


def periodic_mesh(diagram: PeriodicCells) -> PolyMesh:
    """The mesh of ``diagram``'s cells in its periodic box, periodic faces paired.

    Returns
    -------
    PolyMesh
        Cells numbered as the sites; interior faces between cells that touch inside the
        unwrapped picture; a periodic face has ``neighbour`` -1, ``boundary_element`` -1,
        ``periodic_partner`` the index of the same face seen from the other cell and
        ``periodic_image`` (d,) the whole periods that carry the other cell's site to the
        side of this face (the partner's image is minus this one; the partner's vertices
        are this face's translated by ``-periodic_image * (hi - lo)``). Faces on the sides
        of non-periodic axes are boundary faces as in a box.
    """
    domain = diagram.domain
    # Everything below is in the domain's frame (hcvt.geometry.frame), as the diagram
    # was computed: images tiled by whole periods there are the same at any position and
    # scale of the box (in input coordinates, a box at 1e6 rounds each image's shift).
    frame = domain.frame
    lo, hi = frame.to_core(np.array(domain.bounds, dtype=np.float64), "corners")
    periodic = np.array(domain.periodic, dtype=bool)
    period = np.where(periodic, hi - lo, 0.0)
    sites = wrapped(frame.to_core(diagram.sites), lo, hi, periodic)
    n, d = sites.shape
    images = diagram.neighbor_images
    assert images is not None
    image_site = sites[diagram.neighbor_sites] + images * period
    # How far the images of the neighbours reach beyond the box, per axis.
    beyond = np.maximum(lo - image_site, image_site - hi).max(axis=0, initial=0.0)
    size = float(np.max(hi - lo))
    band = np.where(periodic, np.maximum(beyond, 0.0) + 1e-9 * size, 0.0)
    spacing = (float(np.prod(hi - lo)) / n) ** (1.0 / d)
    weights = None
    if diagram.weights is not None and np.any(diagram.weights):
        weights = frame.quantity_to_core("weights", diagram.weights)
    # Only the images the central cells need: filling the widened box with images (so
    # that the outermost cells are small) cost more than it saved (10k sites: 12.9 s
    # instead of 8.3 s, under load).
    extra = 2.0 * spacing
    for _ in range(6):
        margin = np.where(periodic, band + extra, 0.0)
        mesh = _central_mesh(sites, weights, lo, hi, periodic, band, margin)
        if mesh is not None:
            return replace(mesh, points=frame.points_to_input(mesh.points))
        extra *= 2.0
    raise InvalidMeshError(
        "periodic mesh: a cell reaches the sides of the widened box however wide "
        f"(last margin {(margin * frame.scale).tolist()}); too few sites for the box?"
    )


def _tiled(
    sites: NDArray[np.float64],
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    periodic: NDArray[np.bool_],
    band: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.intp], NDArray[np.int8]]:
    """The sites (first, shift 0) and their images within ``band`` of the box.

    Returns positions (t, d), the site of each (t,) and its shift in periods (t, d).
    """
    n, d = sites.shape
    period = hi - lo
    reach = [int(np.ceil(band[a] / period[a])) if periodic[a] else 0 for a in range(d)]
    grids = np.meshgrid(*[np.arange(-r, r + 1) for r in reach], indexing="ij")
    shifts = np.stack([g.ravel() for g in grids], axis=1)
    shifts = shifts[np.any(shifts != 0, axis=1)]
    # A fixed order of shifts (lexicographic): the tiled numbering is deterministic.
    shifts = shifts[np.lexsort(shifts.T[::-1])]
    positions, origin, image = [sites], [np.arange(n)], [np.zeros((n, d), dtype=np.int8)]
    for k in shifts:
        moved = sites + k * np.where(periodic, period, 0.0)
        inside = np.all((moved >= lo - band) & (moved <= hi + band), axis=1)
        positions.append(moved[inside])
        origin.append(np.flatnonzero(inside))
        image.append(np.tile(k.astype(np.int8), (int(inside.sum()), 1)))
    return np.concatenate(positions), np.concatenate(origin), np.concatenate(image)


def bounded(domain: Domain) -> Domain:
    """``domain`` itself, or for a box the polygon or solid it is (what the core meshes)."""
    if not isinstance(domain._core, (_core.BoxDomain2, _core.BoxDomain3)):
        return domain
    lo, hi = domain.bounds
    return _widened(lo, hi)


def _widened(lo: NDArray[np.float64], hi: NDArray[np.float64]) -> Domain:
    """The box ``[lo, hi]`` as a convex polygon (2D) or solid of 12 triangles (3D)."""
    if len(lo) == 2:
        return Domain.from_polygon(shapely.box(lo[0], lo[1], hi[0], hi[1]))
    corners = Domain.box(lo, hi).vertices
    return Domain.from_mesh(corners, BOX_FACES)


def _central_mesh(
    sites: NDArray[np.float64],
    weights: NDArray[np.float64] | None,
    lo: NDArray[np.float64],
    hi: NDArray[np.float64],
    periodic: NDArray[np.bool_],
    band: NDArray[np.float64],
    margin: NDArray[np.float64],
) -> PolyMesh | None:
    """The central cells' mesh, or None when a side of the widened box cuts one.

    Positions (sites, ``lo``, ``hi``, band and margin) and weights in the periodic box's
    frame, and so the mesh's points.
    """
    n, d = sites.shape
    tiled, origin, image = _tiled(sites, lo, hi, periodic, band)
    box = _widened(lo - margin, hi + margin)
    frame = box.frame
    core_weights = None
    if weights is not None:
        core_weights = frame.quantity_to_core("weights", weights[origin])
    with frame.input_errors():
        arrays = _core.mesh(box._core, frame.to_core(tiled), weights=core_weights)
    owner, neighbour = arrays["owner"], arrays["neighbour"]
    element = arrays["boundary_element"]
    keep = owner < n
    wall = keep & (neighbour < 0)
    side_axis = _side_axis(box, d)
    if np.any(periodic[side_axis[element[wall]]]):
        return None
    faces = np.flatnonzero(keep)
    sizes = np.diff(arrays["face_offsets"])[faces]
    offsets = np.zeros(len(faces) + 1, dtype=np.intp)
    np.cumsum(sizes, out=offsets[1:])
    starts = np.repeat(arrays["face_offsets"][faces], sizes)
    vertices = arrays["face_vertices"][
        starts + np.arange(offsets[-1]) - np.repeat(offsets[:-1], sizes)
    ]
    all_points = frame.to_input("points", arrays["points"])
    if d == 3 and not np.all(periodic):
        faces, offsets, vertices = _whole_sides(
            box, all_points, faces, offsets, vertices, owner, neighbour, element, periodic
        )
    nb = neighbour[faces]
    cross = nb >= n
    other = np.where(nb >= 0, origin[np.maximum(nb, 0)], -1)
    shift = np.zeros((len(faces), d), dtype=np.int8)
    shift[cross] = image[nb[cross]]
    partner = _partners(owner[faces], other, shift, cross, n)
    used = np.zeros(len(arrays["points"]), dtype=bool)
    used[vertices] = True
    renumber = np.cumsum(used) - 1
    points = all_points[used]
    elements = np.where(nb < 0, element[faces], -1)
    return PolyMesh(
        points=points,
        face_offsets=offsets,
        face_vertices=renumber[vertices].astype(np.intp),
        owner=owner[faces].astype(np.intp),
        neighbour=np.where(cross, -1, nb).astype(np.intp),
        boundary_element=elements.astype(np.intp),
        n_cells=n,
        periodic_partner=partner,
        periodic_image=shift,
    )


def _side_axis(box: Domain, d: int) -> NDArray[np.intp]:
    """The axis each boundary element of the widened box is a side of, (E,)."""
    if d == 3:
        corners = box.vertices
        triangles = corners[box.faces]
    else:
        segments = np.asarray(box._core.segments)
        triangles = box.vertices[segments]
    flat = np.ptp(triangles, axis=1) == 0
    return np.argmax(flat, axis=1).astype(np.intp)


def _partners(
    owner: NDArray[np.intp],
    other: NDArray[np.intp],
    shift: NDArray[np.int8],
    cross: NDArray[np.bool_],
    n: int,
) -> NDArray[np.intp]:
    """For each periodic face the index of its twin, -1 elsewhere.

    The twin has owner and other cell swapped and the shift negated; InvalidMeshError
    when a face has no twin or several.
    """
    d = shift.shape[1]
    code = (shift.astype(np.int64) + 64) @ (128 ** np.arange(d, dtype=np.int64))
    back = (-shift.astype(np.int64) + 64) @ (128 ** np.arange(d, dtype=np.int64))
    span = 128**d
    rows = np.flatnonzero(cross)
    key = (owner[rows].astype(np.int64) * n + other[rows]) * span + code[rows]
    want = (other[rows].astype(np.int64) * n + owner[rows]) * span + back[rows]
    order = np.argsort(key, kind="stable")
    if np.any(key[order][1:] == key[order][:-1]):
        raise InvalidMeshError("periodic mesh: two faces between one pair of cells and image")
    at = np.searchsorted(key[order], want)
    found = (at < len(rows)) & (key[order][np.minimum(at, len(rows) - 1)] == want)
    if not np.all(found):
        k = rows[np.flatnonzero(~found)[0]]
        raise InvalidMeshError(
            f"periodic mesh: face of cell {owner[k]} toward cell {other[k]} (image "
            f"{shift[k].tolist()}) has no twin"
        )
    partner = np.full(len(owner), -1, dtype=np.intp)
    partner[rows] = rows[order[at]]
    return partner


def _whole_sides(
    box: Domain,
    points: NDArray[np.float64],
    faces: NDArray[np.intp],
    offsets: NDArray[np.intp],
    vertices: NDArray[np.intp],
    owner: NDArray[np.intp],
    neighbour: NDArray[np.intp],
    element: NDArray[np.intp],
    periodic: NDArray[np.bool_],
) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
    """Each cell's pieces of a side joined into one face, and no points on its diagonals.

    The pieces of one side of a non-periodic axis are joined, and the points where
    bisectors cross the sides' diagonals (the edge between a side's two triangles) are
    left out of every face.

    A face across a periodic side must have the same vertices as its twin, translated;
    the diagonals are not periodic (a face and its twin meet them at different places),
    and a side of a box is one plane: its cells need no split there.
    """
    corners = box.vertices
    triangles = np.asarray(box.faces)
    size = float(np.max(np.ptp(corners, axis=0)))
    tol = 1e-12 * size
    on_diagonal = np.zeros(len(points), dtype=bool)
    for pair in range(0, len(triangles), 2):  # BOX_FACES: two triangles per side
        a, b = set(triangles[pair].tolist()) & set(triangles[pair + 1].tolist())
        axis = int(np.argmax(np.ptp(corners[triangles[pair]], axis=0) == 0))
        if periodic[axis]:
            continue
        p, q = corners[a], corners[b]
        t = (points - p) @ (q - p) / ((q - p) @ (q - p))
        off = np.linalg.norm(points - p - np.outer(t, q - p), axis=1)
        on_diagonal |= (off <= tol) & (t > 1e-12) & (t < 1 - 1e-12)
    side_of = np.arange(len(triangles)) // 2
    loops = [vertices[offsets[k] : offsets[k + 1]] for k in range(len(faces))]
    wall = np.flatnonzero(neighbour[faces] < 0)
    groups: dict[tuple[int, int], list[int]] = {}
    for k in wall.tolist():
        groups.setdefault((int(owner[faces[k]]), int(side_of[element[faces[k]]])), []).append(k)
    dropped = np.zeros(len(faces), dtype=bool)
    for members in groups.values():
        if len(members) > 1:
            loops[members[0]] = _joined([loops[k] for k in members])
            dropped[members[1:]] = True
    kept = np.flatnonzero(~dropped)
    loops = [loop[~on_diagonal[loop]] for loop in (loops[k] for k in kept.tolist())]
    sizes = np.array([len(loop) for loop in loops], dtype=np.intp)
    new_offsets = np.zeros(len(loops) + 1, dtype=np.intp)
    np.cumsum(sizes, out=new_offsets[1:])
    return faces[kept], new_offsets, np.concatenate(loops).astype(np.intp)


def _joined(loops: list[NDArray[np.intp]]) -> NDArray[np.intp]:
    """One loop from loops that share edges (walked opposite ways).

    The shared edges cancel, the rest is chained.
    """
    edges = {
        (int(a), int(b)) for loop in loops for a, b in zip(loop, np.roll(loop, -1), strict=True)
    }
    outer = {a: b for a, b in edges if (b, a) not in edges}
    if not outer:
        raise InvalidMeshError("periodic mesh: the pieces of a side of a cell do not join")
    start = min(outer)
    chain = [start]
    while (nxt := outer[chain[-1]]) != start:
        chain.append(nxt)
        if len(chain) > len(outer):
            raise InvalidMeshError("periodic mesh: the pieces of a side of a cell do not join")
    return np.array(chain, dtype=np.intp)
