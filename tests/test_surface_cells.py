"""The cells of a restricted Voronoi diagram on a triangle surface as planar pieces (issue 33).

Each piece is checked against something computed another way: the same triangle clipped
in its own plane by the bisector half-planes with shapely (``test_surface``'s oracle),
the diagram's own areas and centroids (summed by the core from the pieces' closed-form
moments, not from the arrays returned), the input triangles' planes, and the files read
back by VTK and meshio.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

import hcvt
from test_surface import CLOSED, DATA_3D, OPEN, clipped_pieces, needs_data, sites_near, surface

meshio = pytest.importorskip("meshio")
pv = pytest.importorskip("pyvista")


def piece_measures(pieces: hcvt.mesh.pieces.SurfacePieces) -> tuple[np.ndarray, np.ndarray]:
    """Each piece's area and centroid from its fan triangles, and the fan's normals."""
    fan = pieces.fan()
    a, b, c = (pieces.points[fan[:, k]] for k in range(3))
    twice = np.cross(b - a, c - a)
    area = 0.5 * np.linalg.norm(twice, axis=1)
    owner = np.repeat(np.arange(pieces.n_pieces), np.diff(pieces.piece_offsets) - 2)
    areas = np.bincount(owner, area, minlength=pieces.n_pieces)
    moments = np.column_stack(
        [np.bincount(owner, area * (a + b + c)[:, k] / 3, pieces.n_pieces) for k in range(3)]
    )
    return areas, moments / np.where(areas > 0, areas, 1.0)[:, None]


def cut_open(name: str) -> hcvt.Domain:
    """The surface ``name`` without the triangles whose centroid lies above the median
    height: an open surface with a long border, small enough for the oracle."""
    closed = surface(name)
    v, f = closed.vertices, closed.faces
    y = v[f].mean(axis=1)[:, 1]
    return hcvt.Domain.from_surface(v, f[y < np.median(y)])


@needs_data
@pytest.mark.parametrize("open_", [False, True])
def test_pieces_are_the_triangles_clipped_in_their_planes(open_: bool) -> None:
    # Per input triangle: the piece the core measured and the one shapely clips from the
    # triangle by the bisector half-planes of the sites near (reach as in test_surface).
    # Cells of 31 and 18 input triangles on average.
    n = 400
    domain = cut_open("bunny.off") if open_ else surface("bunny.off")
    v, f = domain.vertices, domain.faces
    sites = sites_near(domain, n, 2)
    d = hcvt.voronoi(domain, sites)
    pieces = d.surface_pieces()
    areas, centroids = piece_measures(pieces)
    h = np.sqrt(domain.volume / n)
    rng = np.random.default_rng(1)  # not test_surface's cells (seed 0)
    cells = rng.choice(n, 3, replace=False)  # the oracle takes ~0.25 s a cell
    if open_:  # and one on the border
        cells[0] = rng.choice(np.flatnonzero(d.boundary_measure > 0))
    for i in cells:
        mine = np.flatnonzero(pieces.piece_cell == i)
        got = dict(zip(pieces.piece_face[mine].tolist(), mine.tolist(), strict=True))
        expected = {}
        for t, origin, e1, e2, piece in clipped_pieces(v, f, sites, int(i), 4.0 * h):
            c = np.asarray(piece.centroid.coords[0])
            expected[t] = (piece.area, origin + c[0] * e1 + c[1] * e2)
        # Slivers of round-off area may be kept by one clipper and dropped by the other.
        tiny = 1e-12 * h * h
        assert {t for t in got if areas[got[t]] > tiny} <= set(expected), i
        assert {t for t, (a, _) in expected.items() if a > tiny} <= set(got), i
        for t, (area, centroid) in expected.items():
            k = got.get(t)
            assert (0.0 if k is None else areas[k]) == pytest.approx(area, rel=1e-10, abs=tiny)
            if k is not None and area > 1e-6 * h * h:
                assert np.abs(centroids[k] - centroid).max() <= 1e-10 * h, (i, t)


@needs_data
@pytest.mark.parametrize("name", [*CLOSED[::2], OPEN])
def test_pieces_sum_to_the_cells_and_lie_in_their_triangles(name: str) -> None:
    domain = surface(name)
    v, f = domain.vertices, domain.faces
    n = 3000
    # Sites off the surface by up to half a spacing, and one far away: an empty cell.
    sites = sites_near(domain, n, 1)
    lo, hi = v.min(axis=0), v.max(axis=0)
    diagonal = np.linalg.norm(hi - lo)
    sites[17] = hi + 10 * diagonal
    d = hcvt.voronoi(domain, sites)
    pieces = d.surface_pieces()
    assert np.all(np.diff(pieces.piece_cell) >= 0) and np.all(np.diff(pieces.piece_offsets) >= 3)
    areas, centroids = piece_measures(pieces)
    area = np.bincount(pieces.piece_cell, areas, minlength=n)
    moment = np.column_stack(
        [np.bincount(pieces.piece_cell, areas * centroids[:, k], n) for k in range(3)]
    )
    assert d.volume[17] == 0 and area[17] == 0
    assert np.abs(area - d.volume).max() <= 1e-12 * d.volume.max()
    full = area > 0
    centroid = moment[full] / area[full, None]
    assert np.abs(centroid - d.centroid[full]).max() <= 1e-12 * diagonal
    # Each piece in its input triangle's plane, counter-clockwise about its normal.
    corners = v[f[pieces.piece_face]]
    normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    per_point = np.repeat(np.arange(pieces.n_pieces), np.diff(pieces.piece_offsets))
    off = np.einsum("ij,ij->i", pieces.points - corners[per_point, 0], normal[per_point])
    assert np.abs(off).max() < 1e-12 * diagonal
    fan = pieces.fan()
    owner = np.repeat(np.arange(pieces.n_pieces), np.diff(pieces.piece_offsets) - 2)
    a, b, c = (pieces.points[fan[:, k]] for k in range(3))
    turn = np.einsum("ij,ij->i", np.cross(b - a, c - a), normal[owner])
    assert turn.min() >= -1e-15 * diagonal**2
    # cells(): the pieces fanned, per cell; empty arrays for the empty cell.
    cells = d.cells()
    assert len(cells) == n and cells[17][0].shape == (0, 3) and cells[17][1].shape == (0, 3)
    for i in (0, n // 2, n - 1):
        vertices, triangles = cells[i]
        t = vertices[triangles]
        fanned = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
        assert fanned.sum() == pytest.approx(d.volume[i], rel=1e-12)


@needs_data
def test_pieces_do_not_depend_on_a_density_or_the_threads() -> None:
    domain = surface("fandisk.off")
    sites = sites_near(domain, 1500, 3)
    plain = hcvt.voronoi(domain, sites).surface_pieces()
    weighted = hcvt.voronoi(domain, sites, density=lambda x: 1.0 + x[:, 0] ** 2)
    assert not np.array_equal(weighted.mass, weighted.volume)  # the density is on
    before = hcvt.get_num_threads()
    try:
        hcvt.set_num_threads(1)
        one = hcvt.voronoi(domain, sites).surface_pieces()
    finally:
        hcvt.set_num_threads(before)
    for other in (weighted.surface_pieces(), one):
        np.testing.assert_array_equal(other.points, plain.points)
        np.testing.assert_array_equal(other.piece_offsets, plain.piece_offsets)
        np.testing.assert_array_equal(other.piece_cell, plain.piece_cell)
        np.testing.assert_array_equal(other.piece_face, plain.piece_face)


@needs_data
def test_pieces_written_as_vtu_and_viewed_in_pyvista(tmp_path) -> None:
    domain = surface("bunny.off")
    d = hcvt.voronoi(domain, sites_near(domain, 800, 4))
    pieces = d.surface_pieces()
    areas, _ = piece_measures(pieces)
    path = hcvt.write_mesh(d, tmp_path / "energy.vtu", cell_data={"energy": d.energy_terms})
    plain = hcvt.write_mesh(d, tmp_path / "plain.vtu").read_bytes()
    assert hcvt.io.write_cells(d, tmp_path / "cells.vtu").read_bytes() == plain
    grid = pv.read(path)
    assert set(grid.celltypes) == {7} and grid.n_cells == pieces.n_pieces
    site, face = grid.cell_data["site"], grid.cell_data["face"]
    np.testing.assert_array_equal(grid.cell_data["area"], d.volume[site])
    np.testing.assert_array_equal(grid.cell_data["G"], d.G[site])
    np.testing.assert_array_equal(grid.cell_data["energy"], d.energy_terms[site])
    # VTK's own measure of each polygon, per cell.
    vtk_area = grid.compute_cell_sizes()["Area"]
    per_cell = np.bincount(site, vtk_area, minlength=d.n)
    assert np.abs(per_cell - d.volume).max() <= 1e-12 * d.volume.max()
    order = np.lexsort((face, site))
    mine = np.lexsort((pieces.piece_face, pieces.piece_cell))
    np.testing.assert_array_equal(face[order], pieces.piece_face[mine])
    np.testing.assert_allclose(vtk_area[order], areas[mine], rtol=1e-12, atol=1e-15)
    # meshio reads every piece in blocks by vertex count, its site paired with it.
    read = meshio.read(path)
    by_count = np.argsort(np.diff(pieces.piece_offsets), kind="stable")
    np.testing.assert_array_equal(
        np.concatenate(read.cell_data["site"]), pieces.piece_cell[by_count]
    )
    rings = [read.points[block.data] for block in read.cells]
    twice = [
        sum(np.cross(r[:, j] - r[:, 0], r[:, j + 1] - r[:, 0]) for j in range(1, r.shape[1] - 1))
        for r in rings
    ]
    meshio_area = np.concatenate([0.5 * np.linalg.norm(t, axis=1) for t in twice])
    np.testing.assert_allclose(meshio_area, areas[by_count], rtol=1e-12, atol=1e-15)
    # to_pyvista: the pieces themselves, cell data as the sphere's.
    poly = d.to_pyvista()
    assert isinstance(poly, pv.PolyData) and poly.n_cells == pieces.n_pieces
    np.testing.assert_array_equal(poly.points, pieces.points)
    np.testing.assert_array_equal(poly.cell_data["site"], pieces.piece_cell)
    np.testing.assert_array_equal(poly.cell_data["area"], d.volume[pieces.piece_cell])
    np.testing.assert_array_equal(poly.cell_data["G"], d.G[pieces.piece_cell])
    np.testing.assert_array_equal(poly.cell_data["face"], pieces.piece_face)


def test_surface_cells_refuse_what_they_are_not() -> None:
    cube = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    faces = np.array([t for q in quads for t in ([q[0], q[1], q[2]], [q[0], q[2], q[3]])])
    domain = hcvt.Domain.from_surface(cube, faces)
    d = hcvt.voronoi(domain, hcvt.initialise(domain, 40, seed=1))
    with pytest.raises(NotImplementedError, match=r"no PolyMesh.*surface_pieces\(\)"):
        d.mesh()
    # In a notebook the cells are drawn from their pieces, the whole surface.
    assert d._repr_png_().startswith(b"\x89PNG")
    with pytest.raises(NotImplementedError, match="no PolyMesh"):
        hcvt.write_mesh(d, "cells.geojson")
    solid = hcvt.voronoi(hcvt.Domain.from_mesh(cube, faces), [[0.5, 0.5, 0.5], [0.2, 0.2, 0.2]])
    with pytest.raises(ValueError, match="triangle surface"):
        solid.surface_pieces()


@needs_data
def test_command_line_writes_the_remeshed_surfaces_cells(tmp_path) -> None:
    from click.testing import CliRunner

    from hcvt.cli import main

    cells, summary = tmp_path / "cells.vtu", tmp_path / "s.json"
    args = ["run", str(DATA_3D / "bunny.off"), "--surface", "-n", "200", "--max-iter", "5"]
    result = CliRunner().invoke(
        main, [*args, "--cells", str(cells), "--summary", str(summary)], catch_exceptions=False
    )
    assert result.exit_code == 0, result.output
    assert json.loads(summary.read_text())["cells"] == str(cells)
    # VTK's areas of the pieces add up to the surface's, each cell's to its diagram's.
    grid = pv.read(cells)
    area = np.bincount(grid.cell_data["site"], grid.compute_cell_sizes()["Area"], 200)
    assert area.sum() == pytest.approx(surface("bunny.off").volume, rel=1e-12)
    written = np.zeros(200)
    written[grid.cell_data["site"]] = grid.cell_data["area"]
    np.testing.assert_allclose(area, written, rtol=1e-12)
