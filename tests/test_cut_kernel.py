"""The split's kernel in the core (hcvt.export._cut_kernel) against the Python reference.

``_Editor.cut`` and ``_Editor.measure`` of hcvt.export.split are the reference: on real
boundary cells of the bunny and of the cheese (which has holes), cut by the planes the
search tries and by random ones, the core must give the same None-ness, the same faces
(loops, sources, parts, what lies across), the same failing faces and badness, and the same
centres, so that the search takes the same decisions. Measured equal bit for bit; the
tolerances are the contract (badness 1e-9, points and centres 1e-12, relative).
"""

from __future__ import annotations

import numpy as np
import pytest

import hcvt
from hcvt import _core
from hcvt.errors import InvalidMeshError
from hcvt.export import _cut_kernel
from hcvt.export import split as split_module
from hcvt.export.split import _Editor, failing_faces
from helpers import DATA, random_inside

#: Cells compared per domain, and random planes per cell besides a fifth of the search's:
#: a few seconds of the Python reference per domain.
CELLS = 8
RANDOM_PLANES = 6


class Case:
    """A mesh's editor, its failing cells as the search lists them, and planes for each."""

    def __init__(self, name: str) -> None:
        domain = hcvt.load_domain(DATA / "3d" / name)
        self.mesh = hcvt.voronoi(domain, random_inside(domain, 300, seed=5)).mesh()
        self.editor = _Editor(self.mesh)
        bad = failing_faces(self.mesh)
        cells = np.unique(
            np.concatenate([self.mesh.owner[bad], self.mesh.neighbour[bad & self.mesh.interior]])
        ).tolist()
        self.cells = [c for c in cells if self.loops(c) is not None]

    def loops(self, c: int) -> tuple[list[int], list[list[int]]] | None:
        """Cell ``c``'s faces and outward loops as ``_Editor.fix`` lists them; None if it
        has a keyhole face (the search leaves those alone)."""
        faces = sorted(self.editor.cell_faces[c])
        loops = [self.editor.outward(c, k) for k in faces]
        if any(len(set(loop)) < len(loop) for loop in loops):
            return None
        return faces, loops

    def planes(self, c: int, rng: np.random.Generator) -> list[tuple[np.ndarray, np.ndarray]]:
        """The search's planes for cell ``c``, random ones through it, one through a vertex
        (moved off it), one beside it."""
        editor = self.editor
        faces, loops = self.loops(c)  # type: ignore[misc]
        now = editor.measure_cell(c)
        worst = now[2] if now is not None else [0]
        planes = [plane for k in worst for plane in editor.candidates(c, faces, loops, k)]
        planes = planes[::5] + editor.more_planes(c, faces, loops)[::5]
        xyz = editor.coords(sorted({v for loop in loops for v in loop}))
        lo, hi = xyz.min(axis=0), xyz.max(axis=0)
        for _ in range(RANDOM_PLANES):
            planes.append((rng.normal(size=3), rng.uniform(lo, hi)))
        planes.append((rng.normal(size=3), xyz[rng.integers(len(xyz))]))
        planes.append((np.array([1.0, 0.0, 0.0]), hi + (hi - lo)))
        return planes


@pytest.fixture(scope="module", params=["bunny.off", "cheese.off"])
def case(request: pytest.FixtureRequest) -> Case:
    return Case(request.param)


def _sample(cells: list[int], k: int) -> list[int]:
    return [cells[i] for i in np.linspace(0, len(cells) - 1, min(k, len(cells))).astype(int)]


def _assert_same_cut(reference, core) -> None:
    assert (reference is None) == (core is None)
    if reference is None:
        return
    assert list(reference.crossings) == list(core.crossings)
    for key, (lid, x) in reference.crossings.items():
        assert core.crossings[key][0] == lid
        np.testing.assert_allclose(core.crossings[key][1], x, rtol=1e-12, atol=0)
    assert [tuple(face) for face in core.faces] == [tuple(face) for face in reference.faces]
    assert core.parts == reference.parts
    assert core.failing == reference.failing
    assert core.part_failing == reference.part_failing
    assert core.failing_sources == reference.failing_sources
    assert core.worst == pytest.approx(reference.worst, rel=1e-9, abs=0)


def test_cuts_match_the_reference(case: Case) -> None:
    rng = np.random.default_rng(1)
    editor = case.editor
    compared = made = 0
    for j, c in enumerate(_sample(case.cells, CELLS)):
        faces, loops = case.loops(c)  # type: ignore[misc]
        planes = case.planes(c, rng)
        for normal, origin in planes:
            reference = editor.cut(c, faces, loops, normal, origin)
            _assert_same_cut(reference, _cut_kernel.cut(editor, c, faces, loops, normal, origin))
            compared += 1
            made += reference is not None
        if j % 2:
            continue
        # All planes at once, as the search tries them: stops at the first passing cut.
        reference_cuts = editor.try_planes(c, faces, loops, planes)
        core_cuts = _cut_kernel.try_planes(editor, c, faces, loops, planes)
        assert len(core_cuts) == len(reference_cuts)
        for reference, core in zip(reference_cuts, core_cuts, strict=True):
            _assert_same_cut(reference, core)
    print(f"\n{compared} (cell, plane) pairs, {made} cuts made")
    assert compared > 15 * CELLS and made > compared // 2


def test_measures_match_the_reference(case: Case) -> None:
    """Per face of a cut, the failing flag, the badness and the parts' centres; per cell, its
    measure as the search takes it (``measure_cell``)."""
    rng = np.random.default_rng(2)
    editor = case.editor
    for c in _sample(case.cells, CELLS // 2):
        faces, loops = case.loops(c)  # type: ignore[misc]
        region = editor.region_faces([c])
        reference = editor.measure(region, 1)
        core = _cut_kernel.measure(editor, region, 1)
        _assert_same_measure(reference, core)
        cell = _cut_kernel._local_cell(editor, c, faces, loops)
        for normal, origin in case.planes(c, rng)[::4]:
            cut = editor.cut(c, faces, loops, normal, origin)
            if cut is None:
                continue
            reference = editor.measure(cut.faces, cut.parts, _coords(editor, cut))
            out = cell.cut(normal[None], origin[None])
            _assert_same_measure(reference, (out["bad"], out["badness"], out["centroids"]))


def _coords(editor: _Editor, cut):
    """Vertex ids of ``cut`` (its crossings negative) to coordinates, as ``_Editor.cut`` has."""
    position = dict(cut.crossings.values())
    return lambda ids: np.array([position[v] if v < 0 else editor.coords([v])[0] for v in ids])


def _assert_same_measure(reference, core) -> None:
    assert (reference is None) == (core is None)
    if reference is None:
        return
    assert np.array_equal(core[0], reference[0])
    np.testing.assert_allclose(core[1], reference[1], rtol=1e-9, atol=0)
    np.testing.assert_allclose(core[2], reference[2], rtol=1e-12, atol=0)


class _EnoughCutsError(Exception):
    pass


def test_the_search_makes_the_same_cuts_as_it_goes(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every cut and measure of the search itself, on cells it has already cut and inside
    its look-ahead, compared until 300 cuts have been."""
    mesh = Case("bunny.off").mesh
    cut, measure = _Editor.cut, _Editor.measure
    count = {"cut": 0, "measure": 0}

    def checked_cut(self, c, faces, loops, normal, origin):
        reference = cut(self, c, faces, loops, normal, origin)
        _assert_same_cut(reference, _cut_kernel.cut(self, c, faces, loops, normal, origin))
        count["cut"] += 1
        if count["cut"] == 300:
            raise _EnoughCutsError
        return reference

    def checked_measure(self, faces, parts, coords=None):
        reference = measure(self, faces, parts, coords)
        _assert_same_measure(reference, _cut_kernel.measure(self, faces, parts, coords))
        count["measure"] += 1
        return reference

    monkeypatch.setattr(_Editor, "cut", checked_cut)
    monkeypatch.setattr(_Editor, "measure", checked_measure)
    with pytest.raises(_EnoughCutsError):
        split_module.split_failing_cells(mesh)
    assert count["measure"] > count["cut"]


def test_bad_input_is_an_invalid_mesh_error() -> None:
    points = np.eye(3)
    offsets = np.array([0, 3], dtype=np.int64)
    no_plane = np.zeros((0, 3))
    with pytest.raises(InvalidMeshError, match="face 0: vertex 5"):
        _core.cut_cell_3d(
            points,
            offsets,
            np.array([0, 1, 5]),
            np.array([-1]),
            no_plane,
            no_plane,
            no_plane,
        )
    with pytest.raises(InvalidMeshError, match="face 0: ghost 0, but 0 ghost centroids"):
        _core.cut_cell_3d(
            points, offsets, np.array([0, 1, 2]), np.array([0]), no_plane, no_plane, no_plane
        )
    with pytest.raises(InvalidMeshError, match="face 0: 2 vertices"):
        _core.measure_region_3d(
            points,
            np.array([0, 2], dtype=np.int64),
            np.array([0, 1]),
            np.array([0]),
            np.array([-1]),
            1,
            no_plane,
        )
