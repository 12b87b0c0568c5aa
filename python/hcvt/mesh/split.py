"""Split boundary cells by planes: exact planar faces that pass checkMesh, more cells.

OpenFOAM's ``checkMesh`` fails two of its checks on the exact boundary pieces of a
Voronoi cell (:mod:`hcvt.mesh.merge` explains both): a small piece at a cell's rim is
*skew* (its centre lies far to the side of the cell's centre, compared with its own
extent), and a cell wrapping a reflex edge has its centre *behind* one of its pieces. With
one cell per site and planar faces neither can be fixed: the pieces are what they are and
the cell's centre is the cell's. :mod:`hcvt.mesh.merge` joins pieces into non-planar
faces, which passes on most meshes but moves the volumes OpenFOAM computes.

This module keeps every face planar instead and splits the cell: a plane cuts a failing
cell in two, so that each part's centre lies over its own pieces. Every new face is exact
(a piece of a planar face, or the plane's section of the cell), so the volumes still sum
to the domain's exactly and each site's parts still make up its Voronoi cell; what changes
is that a site may own several cells. :func:`split_failing_cells` returns which site each
cell belongs to (``write_openfoam`` writes it as the field ``0/site``).

A cut is made locally first and measured by the core (``hcvt_core::split`` through
:mod:`hcvt.mesh.cut`: checkMesh's skewness, face pyramids and non-orthogonality
errors on every face of the parts, against the neighbours' centres; a part checkMesh would
call a sliver, aspect ratio above 1000, makes no cut). Every candidate plane is tried, and
the cuts are ranked by the summed badness of their faces (``Editor.measure``), then by how
oblique their faces are (the sum of ``1 - cos`` of their non-orthogonality); only a cut that
lowers the cell's badness is applied. Where no single cut helps, a few are tried two deep
(the cut, then its parts fixed) and undone unless the whole beats the cell: first the cuts
by the failing faces' own planes (for a small piece at a reflex edge, whose cell's centre
lies beyond it), then the best ranked. Applying a cut puts the new vertices where the plane
crosses an edge into *every* face along that edge, so the mesh stays conforming. A cell
whose parts still fail is cut again, up to :data:`MAX_DEPTH` times; the cells still
failing get :data:`SWEEPS` passes (a cut moves a centre its neighbours are measured
against), then passes with a :data:`DEEP_LOOK_AHEAD`-wide look-ahead, the last ranking by
badness alone. :func:`split_boundary` merges what no cut fixed.

The price: a section is not a Voronoi face, so the segment between two parts' centres is
not along its normal (non-orthogonality up to 71.9° on a converged 50k bunny, 86.2° on the
10k cheese, against 0.04° and 0.1° for the exact cells), and a site owns several cells
(3.3% more cells than sites on the bunny, 44% on the cheese). The search took 14 s and 35 s
there, and left no face to merge (``docs/results/checkmesh.txt``).
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hcvt.mesh.cut import Cut, Face, Plane, cut_by_planes, measure_region
from hcvt.mesh.merge import merged_boundary
from hcvt.mesh.polymesh import PolyMesh
from hcvt.mesh.quality import NON_ORTHOGONALITY_LIMIT, face_quality, fails_checkmesh

if TYPE_CHECKING:
    from hcvt.geometry.domain import Domain

#: Cuts a failing cell may receive, one after the other (each part may be cut again).
MAX_DEPTH = 6

#: Cuts tried two levels deep (the cut, then its parts fixed) where no single cut helps.
LOOK_AHEAD = 4

#: The look-ahead's width in a last round over the cells the first rounds left failing.
DEEP_LOOK_AHEAD = 32

#: Guards on every cut (issue 30): a part must hold at least this fraction of its site's
#: Voronoi cell, and no face of a part with a cell across may be further than
#: :data:`hcvt.mesh.quality.NON_ORTHOGONALITY_LIMIT` (70°) from orthogonal. Without them
#: the search cut off slivers (down to 3.5e-3 of the mean cell) with sections at 76-86°,
#: and laplacianFoam's non-orthogonal correctors diverged on meshes checkMesh passed.
MIN_PART_FRACTION = 0.1

#: Directions tried through a cell's centre where the aimed planes fail.
_DIRECTIONS = 24

#: Passes over the cells still failing (a cut moves a centre its neighbours measure against).
SWEEPS = 8

#: Where a candidate plane crosses the segment from a cell's centre to its worst face's
#: centre (0: through the cell's centre).
_OFFSETS = (0.5, 0.3, 0.7, 0.0, 0.85, 0.15)

#: How far in front of a face its own plane is moved (relative to the cell size) in
#: :meth:`Editor.own_planes`: just enough for the face to lie wholly on one side, and
#: further, for a face with coplanar neighbours that would make a part of slivers.
_IN_FRONT = (1e-4, 1e-2)


class SplitReport(NamedTuple):
    """What :func:`split_failing_cells` did."""

    failing_cells: int
    """Cells of the input with a face failing checkMesh's skewness or pyramid check."""
    cuts: int
    """Planes applied."""
    cells: int
    """Cells of the output (the input's plus one per cut, more where a cut part fell in
    pieces)."""
    failing: NDArray[np.intp]
    """Shape (k,): faces of the output that still fail (none when it passed)."""
    merged_faces: int = 0
    """Boundary faces no cut fixed, merged by :func:`split_boundary` (0 from
    :func:`split_failing_cells`)."""


class _Journal:
    """What to restore to undo the cuts made since it was opened (see ``Editor.undo``)."""

    def __init__(self, extra: int, faces: int, cells: int, cuts: int) -> None:
        self.extra, self.faces, self.cells, self.cuts = extra, faces, cells, cuts
        self.loops: dict[int, list[int] | None] = {}
        self.cell_faces: dict[int, set[int]] = {}
        self.vertex_faces: dict[int, set[int]] = {}
        self.centroids: dict[int, NDArray[np.float64]] = {}


def failing_faces(mesh: PolyMesh) -> NDArray[np.bool_]:
    """Shape (f,): faces that fail checkMesh's skewness, pyramid or orthogonality checks."""
    return fails_checkmesh(*face_quality(mesh, mesh.cell_geometry.centroid))


def split_boundary(
    mesh: PolyMesh, domain: Domain | None = None, labels: ArrayLike | None = None
) -> tuple[PolyMesh, NDArray[np.intp], SplitReport]:
    """:func:`split_failing_cells`, then the boundary faces no cut fixed merged.

    The faces still failing after the cuts are joined to neighbouring pieces of their cell
    and patch as :func:`hcvt.mesh.merge.merged_boundary` does (``domain`` and ``labels``
    give the patches). Only the cells holding such a face lose their exact volume (a
    merged face is not planar): on a converged CVT of the cheese with 1k sites, 1 face
    after 2,473 cuts, the total moving by 8.9e-11 of the domain's; none at 4k and 10k
    (``docs/results/checkmesh.txt``).
    """
    split, site, report = split_failing_cells(mesh)
    if len(report.failing) == 0:
        return split, site, report
    merged, merge = merged_boundary(split, domain, labels)
    return merged, site, report._replace(failing=merge.failing, merged_faces=merge.merged_faces)


def split_failing_cells(mesh: PolyMesh) -> tuple[PolyMesh, NDArray[np.intp], SplitReport]:
    """Cut the cells of ``mesh`` whose faces fail checkMesh until they pass (module docs).

    Parameters
    ----------
    mesh : PolyMesh
        A 3D conforming mesh with planar faces (``Diagram.mesh()``), cell ``i`` the cell
        of site ``i``.

    Returns
    -------
    split : PolyMesh
        The mesh with the failing cells cut: the cells of ``mesh`` keep their indices
        (the first part of a cut cell keeps it), new parts come after them; new vertices
        come after ``mesh.points``. Faces on an input triangle keep its index in
        ``boundary_element``.
    site : ndarray of intp, shape (split.n_cells,)
        The site (cell of ``mesh``) each cell belongs to.
    report : SplitReport
    """
    if mesh.dim != 3:
        raise ValueError("cells are split in 3D meshes only")
    editor = Editor(mesh)
    failing = failing_faces(mesh)
    cells = np.unique(
        np.concatenate([mesh.owner[failing], mesh.neighbour[failing & mesh.interior]])
    )
    result, site, bad = mesh, np.arange(mesh.n_cells), failing
    first = len(cells)
    # The wide look-ahead is costly, so only the few cells the narrow one left get it;
    # the last round ranks the cuts by badness alone (the first plane among equals), a
    # second path through the search for the cells the least oblique cuts lead nowhere.
    for width, rank in (
        (LOOK_AHEAD, _rank),
        (DEEP_LOOK_AHEAD, _rank),
        (DEEP_LOOK_AHEAD, _by_badness),
    ):
        editor.look_ahead_width, editor.rank = width, rank
        editor.stuck.clear()
        for _ in range(SWEEPS):
            before = editor.cuts
            for c in cells.tolist():
                editor.fix(int(c), MAX_DEPTH)
            result, site = editor.mesh()
            bad = failing_faces(result)
            cells = np.unique(
                np.concatenate([result.owner[bad], result.neighbour[bad & result.interior]])
            )
            if editor.cuts == before or not bad.any():
                break
        if not bad.any():
            break
    return result, site, SplitReport(first, editor.cuts, result.n_cells, np.flatnonzero(bad))


class Editor:
    """A mesh under cutting: faces as Python lists, maps kept up to date."""

    def __init__(self, mesh: PolyMesh) -> None:
        self.base = mesh.points
        self.extra: list[NDArray[np.float64]] = []
        sizes = mesh.face_sizes.tolist()
        flat = mesh.face_vertices.tolist()
        starts = mesh.face_offsets[:-1].tolist()
        self.faces: list[list[int] | None] = [
            flat[s : s + k] for s, k in zip(starts, sizes, strict=True)
        ]
        self.owner = mesh.owner.tolist()
        self.neighbour = mesh.neighbour.tolist()
        self.element = mesh.boundary_element.tolist()
        cf = mesh.cell_faces
        bounds = cf.offsets.tolist()
        listed = cf.faces.tolist()
        self.cell_faces = [set(listed[bounds[c] : bounds[c + 1]]) for c in range(mesh.n_cells)]
        self.site = list(range(mesh.n_cells))
        self.site_volume = mesh.cell_geometry.volume.copy()
        self.centroid = [row for row in mesh.cell_geometry.centroid]
        self.vertex_faces: defaultdict[int, set[int]] = defaultdict(set)
        for k, loop in enumerate(self.faces):
            for v in loop or ():
                self.vertex_faces[v].add(k)
        self.cuts = 0
        self.journal: _Journal | None = None
        # Cells no cut helped, with their faces then: not tried again while unchanged.
        self.stuck: dict[int, list[int]] = {}
        self.look_ahead_width = LOOK_AHEAD
        self.rank: Callable[[Cut], Any] = _rank

    # ------------------------------------------------------------------ geometry access
    def coords(self, ids: list[int]) -> NDArray[np.float64]:
        """The points of vertex ids ``ids`` (the mesh's, then the cuts' new ones), (k, 3)."""
        nb = len(self.base)
        return np.array([self.base[v] if v < nb else self.extra[v - nb] for v in ids])

    def outward(self, c: int, k: int) -> list[int]:
        """Face ``k``'s vertex loop, oriented out of cell ``c``."""
        loop = self.faces[k]
        assert loop is not None
        return list(loop) if self.owner[k] == c else loop[::-1]

    def other(self, c: int, k: int) -> int:
        """The cell across face ``k`` from cell ``c`` (-1 on the boundary)."""
        return self.neighbour[k] if self.owner[k] == c else self.owner[k]

    # ------------------------------------------------------------------ the search
    def fix(self, c: int, depth: int) -> None:
        """Cut cell ``c`` (and its parts, ``depth`` levels deep) while that helps."""
        if depth == 0:
            return
        faces = sorted(self.cell_faces[c])
        loops = [self.outward(c, k) for k in faces]
        if any(len(set(loop)) < len(loop) for loop in loops):
            return  # a face with a hole (keyhole): not cut
        if self.stuck.get(c) == faces:
            return  # tried before, and nothing around it has changed since
        now = self.measure_cell(c)
        if now is None or now[0] == 0:
            return
        # Each face's Newell vector, once: every plane below is aimed with them.
        normals = [_newell(self.coords(loop)) for loop in loops]
        planes = [p for k in now[2] for p in self.candidates(c, faces, loops, normals, k)]
        behind = self.try_planes(c, faces, loops, self.own_planes(loops, normals, now[2]))
        tried = sorted(self.try_planes(c, faces, loops, planes) + behind, key=self.rank)
        if not tried or tried[0].worst >= now[1]:
            more = self.more_planes(c, faces, normals)
            tried += self.try_planes(c, faces, loops, more)
            tried.sort(key=self.rank)
        if tried and tried[0].worst < now[1]:
            self.apply_and_fix(c, faces, tried[0], depth)
        elif self.journal is None:
            # Look ahead first from the cuts that fix the worst face, whatever they break.
            # (A cut that leaves the worst face failing as badly only moves the problem.)
            target = faces[now[2][0]]
            moved = [
                cut for cut in tried if target not in cut.failing_sources or cut.worst != now[1]
            ]
            moved.sort(key=lambda cut: (target in cut.failing_sources, cut.worst))
            chosen = behind + moved[: self.look_ahead_width]
            if not self.look_ahead(c, faces, chosen, now[1], depth):
                self.stuck[c] = faces

    def try_planes(
        self, c: int, faces: list[int], loops: list[list[int]], planes: list[Plane]
    ) -> list[Cut]:
        """The cuts of cell ``c`` by ``planes``, best first (``self.rank``, :func:`_rank`)."""
        # The size guard on every cut (cheap), the angle guard on the best ranked only:
        # the search reads at most the first DEEP_LOOK_AHEAD + 1 of them.
        tried = [
            cut for cut in cut_by_planes(self, c, faces, loops, planes) if self.big_enough(c, cut)
        ]
        tried.sort(key=self.rank)
        kept: list[Cut] = []
        for cut in tried:
            if self.orthogonal_enough(cut):
                kept.append(cut)
                if len(kept) > DEEP_LOOK_AHEAD:
                    break
        return kept

    def big_enough(self, c: int, cut: Cut) -> bool:
        """Whether every part of ``cut`` holds :data:`MIN_PART_FRACTION` of its site's cell."""
        return bool(cut.part_volumes.min() >= MIN_PART_FRACTION * self.site_volume[self.site[c]])

    def orthogonal_enough(self, cut: Cut) -> bool:
        """Whether every face of the parts with a cell across is within 70° of orthogonal.

        A section, or a piece of an interior face, measured between the parts' centres and
        the neighbours' (:data:`NON_ORTHOGONALITY_LIMIT`).
        """
        centroids = cut.part_centroids
        nb = len(self.base)
        points = {lid: x for lid, x in cut.crossings.values()}
        cos_limit = np.cos(np.radians(NON_ORTHOGONALITY_LIMIT))
        for face in cut.faces:
            if face.across >= 0:
                other = centroids[face.across]
            elif face.ghost >= 0:
                other = self.centroid[face.ghost]
            else:
                continue
            xyz = np.array(
                [
                    points[v] if v < 0 else (self.base[v] if v < nb else self.extra[v - nb])
                    for v in face.loop
                ]
            )
            area = _newell(xyz)
            d = other - centroids[face.part]
            if area @ d < cos_limit * np.linalg.norm(area) * np.linalg.norm(d):
                return False
        return True

    def more_planes(
        self, c: int, faces: list[int], normals: list[NDArray[np.float64]]
    ) -> list[Plane]:
        """Planes through the centre of cell ``c`` for where :meth:`candidates` fail.

        Four containing the axis its boundary pieces turn around (the axis of a tunnel
        the cell wraps: the direction their normals least point along), then
        :data:`_DIRECTIONS` normals spread over the sphere (a Fibonacci lattice).
        """
        cc = self.centroid[c]
        pieces = np.array([v for k, v in zip(faces, normals, strict=True) if self.neighbour[k] < 0])
        planes = []
        if len(pieces):
            weighted = pieces / np.sqrt(np.linalg.norm(pieces, axis=1))[:, None]
            frame = np.linalg.eigh(weighted.T @ weighted)[1]  # ascending: frame[:, 0] the axis
            for angle in np.radians([0.0, 45.0, 90.0, 135.0]):
                normal = np.cos(angle) * frame[:, 1] + np.sin(angle) * frame[:, 2]
                planes.append((normal, cc))
        k = np.arange(_DIRECTIONS) + 0.5
        z = 1 - k / _DIRECTIONS  # a hemisphere: a plane's normal and its opposite are one
        r = np.sqrt(1 - z * z)
        turn = np.pi * (1 + 5**0.5) * k
        spread = np.column_stack([r * np.cos(turn), r * np.sin(turn), z])
        planes += [(normal, cc) for normal in spread]
        return planes

    def own_planes(
        self, loops: list[list[int]], normals: list[NDArray[np.float64]], worst: list[int]
    ) -> list[Plane]:
        """The planes of the faces ``worst`` (indices into ``faces``), just in front of them.

        For a small piece at a reflex edge of the surface, whose cell wraps around the
        edge so that the cell's centre lies beyond the piece's plane (an inverted
        pyramid): the part behind that plane holds the piece with its centre on the right
        side, and its own cuts then fix its skewness. No single cut shows that promise, so
        the look-ahead tries these first.
        """
        xyz = self.coords(sorted({v for loop in loops for v in loop}))
        size = float(np.ptp(xyz, axis=0).max())
        planes = []
        for j in worst:
            normal = normals[j] / np.linalg.norm(normals[j])
            centre = self.coords(loops[j]).mean(axis=0)
            planes += [(normal, centre + t * size * normal) for t in _IN_FRONT]
        return planes

    def apply_and_fix(self, c: int, faces: list[int], cut: Cut, depth: int) -> None:
        """Make ``cut`` in cell ``c``, then fix its failing parts."""
        parts = self.apply(c, faces, cut)
        for part, bad in zip(parts, cut.part_failing, strict=True):
            if bad:
                self.fix(part, depth - 1)

    def look_ahead(
        self, c: int, faces: list[int], cuts: list[Cut], badness: float, depth: int
    ) -> bool:
        """Keep the first of ``cuts`` that, its parts fixed in turn, beats ``badness``.

        For a cell where no single cut helps; the cuts that do not beat it are undone.
        Returns whether one was kept.
        """
        for cut in cuts:
            self.journal = _Journal(len(self.extra), len(self.faces), len(self.site), self.cuts)
            self.apply_and_fix(c, faces, cut, depth)
            region = [c, *range(self.journal.cells, len(self.site))]
            after = self.measure(self.region_faces(region), len(region))
            if after is not None and after[1].sum() < badness:
                self.journal = None
                return True
            self.undo()
        return False

    def candidates(
        self,
        c: int,
        faces: list[int],
        loops: list[list[int]],
        normals: list[NDArray[np.float64]],
        worst: int,
    ) -> list[Plane]:
        """Planes to try on cell ``c``: across the line from its centre to its worst face.

        Normals: that line's part along the surface (as seen by the face, and by the
        cell's whole boundary), turned by ±30° and ±60° about the surface normal, the line
        itself, and the face's normal; each plane placed at :data:`_OFFSETS` along it.
        Then the planes through the cell's centre across its principal axes.
        """
        cc = self.centroid[c]
        fc = self.coords(loops[worst]).mean(axis=0)
        n = normals[worst] / np.linalg.norm(normals[worst])
        cpf = fc - cc
        tangential = cpf - (n @ cpf) * n
        boundary = [v for k, v in zip(faces, normals, strict=True) if self.neighbour[k] < 0]
        mean = np.sum(boundary, axis=0) if boundary else n
        mean = mean / (np.linalg.norm(mean) or 1.0)
        flat = tangential - (mean @ tangential) * mean
        side = np.cross(mean, flat)
        turned = [
            np.cos(a) * flat + np.sin(a) * side for a in np.radians([30.0, -30.0, 60.0, -60.0])
        ]
        normals = []
        for v in (tangential, flat, *turned, cpf, n):
            length = np.linalg.norm(v)
            if length > 1e-9 * (np.linalg.norm(cpf) + 1e-300):
                normals.append(v / length)
        planes = [(normal, cc + t * cpf) for t in _OFFSETS for normal in normals]
        # Just in front of the face's own plane: the part behind it holds the face and
        # little else, so its centre lies behind the face (for a wrong pyramid).
        planes += [(n, cc + t * cpf) for t in (0.97, 0.995, 1.0)]
        # The cell's own axes through its centre: for cells wrapping a tunnel or an edge.
        xyz = self.coords(sorted({v for loop in loops for v in loop}))
        axes = np.linalg.svd(xyz - xyz.mean(axis=0), full_matrices=False)[2]
        planes += [(axis, cc) for axis in axes]
        return planes

    def measure_cell(self, c: int) -> tuple[int, float, list[int]] | None:
        """(failing faces, badness, indices of the 3 worst) of cell ``c``.

        Indices into its faces in increasing order, as :meth:`fix` lists them.
        """
        measured = self.measure(self.region_faces([c]), 1)
        if measured is None:
            return None
        bad, badness, _ = measured
        worst = np.argsort(-badness, kind="stable")[: min(3, int(bad.sum()))]
        return int(bad.sum()), float(badness.sum()), worst.tolist()

    def measure(
        self, faces: list[Face], parts: int
    ) -> tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]] | None:
        """Failing flags and badness of ``faces`` bounding ``parts`` parts, their centres.

        The parts are cells ``0..parts-1`` of a small mesh; the cells across the faces
        from outside (``Face.ghost``) are ghosts there, with their true centres. A face's
        badness is 0 if it passes, else its skewness over checkMesh's limit (at least 1),
        plus 1 for an inverted pyramid. None if a part has no positive volume.
        """
        return measure_region(self, faces, parts)

    # ------------------------------------------------------------------ applying a cut
    def apply(self, c: int, faces: list[int], cut: Cut) -> list[int]:
        """Make the cut in the mesh; return the cells of its parts (the first is ``c``)."""
        nb = len(self.base)
        global_id: dict[int, int] = {}
        old = set(faces)
        for (a, b), (lid, x) in cut.crossings.items():
            g = nb + len(self.extra)
            self.extra.append(x)
            global_id[lid] = g
            for k in self.vertex_faces[a] & self.vertex_faces[b]:
                if k in old:
                    continue
                self._keep(k, None, None)
                loop = self.faces[k]
                assert loop is not None
                m = len(loop)
                for i in range(m):
                    if {loop[i], loop[(i + 1) % m]} == {a, b}:
                        loop.insert(i + 1, g)
                        self.vertex_faces[g].add(k)
                        break
        parts = [c] + [len(self.site) + j for j in range(cut.parts - 1)]
        for _ in range(cut.parts - 1):
            self.site.append(self.site[c])
            self.cell_faces.append(set())
            self.centroid.append(self.centroid[c])
        for k in faces:
            self._keep(k, None, None)
            for cell in (self.owner[k], self.neighbour[k]):
                if cell >= 0:
                    self._keep(None, cell, None)
                    self.cell_faces[cell].discard(k)
            for v in self.faces[k] or ():
                self._keep(None, None, v)
                self.vertex_faces[v].discard(k)
            self.faces[k] = None
        for face in cut.faces:
            loop = [global_id.get(v, v) for v in face.loop]
            part = parts[face.part]
            if face.across >= 0:
                owner, neighbour, element = part, parts[face.across], -1
            elif self.neighbour[face.source] < 0:
                owner, neighbour, element = part, -1, self.element[face.source]
            else:
                other = self.other(c, face.source)
                owner, neighbour, element = part, other, -1
                if other < part:  # keep the original's owner where it was the owner
                    owner, neighbour, loop = other, part, loop[::-1]
            k = len(self.faces)
            self.faces.append(loop)
            self.owner.append(owner)
            self.neighbour.append(neighbour)
            self.element.append(element)
            for cell in (owner, neighbour):
                if cell >= 0:
                    self._keep(None, cell, None)
                    self.cell_faces[cell].add(k)
            for v in loop:
                self._keep(None, None, v)
                self.vertex_faces[v].add(k)
        for part in parts:
            if self.journal is not None and part < self.journal.cells:
                self.journal.centroids.setdefault(part, self.centroid[part])
            self.centroid[part] = self._centroid(part)
        self.cuts += 1
        return parts

    def _keep(self, face: int | None, cell: int | None, vertex: int | None) -> None:
        """Note a face's loop, a cell's faces or a vertex's faces before they change."""
        j = self.journal
        if j is None:
            return
        if face is not None and face < j.faces and face not in j.loops:
            loop = self.faces[face]
            j.loops[face] = None if loop is None else list(loop)
        if cell is not None and cell < j.cells and cell not in j.cell_faces:
            j.cell_faces[cell] = set(self.cell_faces[cell])
        if vertex is not None and vertex < len(self.base) + j.extra:
            j.vertex_faces.setdefault(vertex, set(self.vertex_faces[vertex]))

    def undo(self) -> None:
        """Restore the mesh as it was when the journal was opened, and close it."""
        j = self.journal
        assert j is not None
        self.journal = None
        for v in range(len(self.base) + j.extra, len(self.base) + len(self.extra)):
            self.vertex_faces.pop(v, None)
        del self.extra[j.extra :]
        for column in (self.faces, self.owner, self.neighbour, self.element):
            del column[j.faces :]
        for column in (self.site, self.cell_faces, self.centroid):
            del column[j.cells :]
        for k, loop in j.loops.items():
            self.faces[k] = loop
        for cell, faces in j.cell_faces.items():
            self.cell_faces[cell] = faces
        for v, faces in j.vertex_faces.items():
            self.vertex_faces[v] = faces
        for cell, x in j.centroids.items():
            self.centroid[cell] = x
        self.cuts = j.cuts

    def _centroid(self, c: int) -> NDArray[np.float64]:
        measured = self.measure(self.region_faces([c]), 1)
        assert measured is not None
        return measured[2][0]

    def region_faces(self, cells: list[int]) -> list[Face]:
        """The faces of ``cells`` (parts ``0..len(cells)-1``), each once, out of a part."""
        index = {cell: j for j, cell in enumerate(cells)}
        out = []
        for j, cell in enumerate(cells):
            for k in sorted(self.cell_faces[cell]):
                other = self.other(cell, k)
                if other in index and index[other] < j:
                    continue  # met from the other part already
                across = index.get(other, -1)
                ghost = other if across < 0 else -1
                out.append(Face(self.outward(cell, k), k, j, across, ghost))
        return out

    def mesh(self) -> tuple[PolyMesh, NDArray[np.intp]]:
        """The edited mesh, and the site of each of its cells."""
        keep = [k for k, loop in enumerate(self.faces) if loop is not None]
        loops = [loop for loop in self.faces if loop is not None]
        sizes = np.array([len(loop) for loop in loops], dtype=np.intp)
        offsets = np.zeros(len(keep) + 1, dtype=np.intp)
        np.cumsum(sizes, out=offsets[1:])
        points = np.vstack([self.base, np.array(self.extra).reshape(-1, 3)])
        result = PolyMesh(
            points=points,
            face_offsets=offsets,
            face_vertices=np.fromiter(
                (v for loop in loops for v in loop),
                dtype=np.intp,
                count=int(offsets[-1]),
            ),
            owner=np.array([self.owner[k] for k in keep], dtype=np.intp),
            neighbour=np.array([self.neighbour[k] for k in keep], dtype=np.intp),
            boundary_element=np.array([self.element[k] for k in keep], dtype=np.intp),
            n_cells=len(self.site),
        )
        return result, np.array(self.site, dtype=np.intp)


def _rank(cut: Cut) -> tuple[float, float]:
    """How a cut compares: by its faces' badness, then by how oblique they are."""
    return cut.worst, cut.oblique


def _by_badness(cut: Cut) -> float:
    """How a cut compares in the last round: by its faces' badness alone."""
    return cut.worst


def _newell(pts: NDArray[np.float64]) -> NDArray[np.float64]:
    """Twice the vector area of the closed loop ``pts`` (k, 3)."""
    return np.cross(pts, np.roll(pts, -1, axis=0)).sum(axis=0)
