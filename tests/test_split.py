"""Split boundary cells (issue 19): exact planar faces that pass OpenFOAM's checkMesh.

A cut must keep the mesh conforming (the new vertices in every face along a cut edge),
every cell closed, and each site's cells summing to its Voronoi cell; a split mesh of a
converged CVT must pass checkMesh with the domain's exact volume.
"""

from __future__ import annotations

import numpy as np
import pytest

import hcvt
from hcvt.export import merged_boundary, split_boundary, split_failing_cells, write_vtu
from hcvt.mesh import split as split_module
from hcvt.mesh.cut import cut_by_planes
from hcvt.mesh.split import Editor, failing_faces
from helpers import DATA, random_inside
from test_export import NUM, _figure, _vtk_cell_volumes, passing_case

pv = pytest.importorskip("pyvista")


@pytest.fixture(scope="module")
def bunny_diagram() -> hcvt.Diagram:
    """300 random sites in the bunny: boundary cells with skew pieces and wrong pyramids."""
    domain = hcvt.load_domain(DATA / "3d" / "bunny.off")
    return hcvt.voronoi(domain, random_inside(domain, 300, seed=5))


def _cut(mesh, cell, normal):
    """``mesh`` with ``cell`` cut by the plane through its centroid across ``normal``."""
    editor = Editor(mesh)
    faces = sorted(editor.cell_faces[cell])
    loops = [editor.outward(cell, k) for k in faces]
    centre = mesh.cell_geometry.centroid[cell]
    (cut,) = cut_by_planes(editor, cell, faces, loops, [(np.asarray(normal, float), centre)])
    parts = editor.apply(cell, faces, cut)
    split, site = editor.mesh()
    return split, site, parts


def test_a_cut_keeps_the_mesh_conforming_and_each_sites_volume(bunny_diagram, tmp_path):
    mesh = bunny_diagram.mesh()
    volume = bunny_diagram.volume
    boundary_cells = np.unique(mesh.owner[~mesh.interior])
    cell = int(boundary_cells[np.argmax(volume[boundary_cells])])
    split, site, parts = _cut(mesh, cell, [0.3, 1.0, -0.2])
    split.check()  # every cell closed, positive volumes
    assert len(parts) >= 2 and split.n_cells == mesh.n_cells + len(parts) - 1
    assert list(site[: mesh.n_cells]) == list(range(mesh.n_cells))
    assert all(site[p] == cell for p in parts)
    # Each site's cells make up its Voronoi cell; the other cells are untouched.
    by_site = np.bincount(site, weights=split.cell_geometry.volume)
    assert np.allclose(by_site, volume, rtol=1e-12, atol=0)
    assert abs(split.cell_geometry.volume.sum() / volume.sum() - 1) < 1e-13
    # Conforming: each new vertex (where the plane crosses an edge) is in every face
    # along that edge -- two pieces of each of the cut cell's two faces there, its
    # section, and the faces of the other cells around the edge.
    new = np.arange(len(mesh.points), len(split.points))
    uses = np.bincount(split.face_vertices, minlength=len(split.points))[new]
    assert len(new) >= 3 and uses.min() >= 3
    # The section is planar and lies in the plane through the cell's old centroid.
    section = np.flatnonzero(np.isin(split.owner, parts) & np.isin(split.neighbour, parts))
    assert len(section) >= 1
    normal = np.array([0.3, 1.0, -0.2]) / np.linalg.norm([0.3, 1.0, -0.2])
    height = (
        split.points[split.face(int(section[0]))] - mesh.cell_geometry.centroid[cell]
    ) @ normal
    assert np.abs(height).max() < 1e-12
    # VTK reads the split cells and measures the domain's volume.
    grid = pv.read(write_vtu(split, tmp_path / "split.vtu"))
    cells, total = _vtk_cell_volumes(grid)
    assert grid.n_cells == split.n_cells
    assert abs(total / volume.sum() - 1) < 1e-9


def test_a_plane_missing_the_cell_is_no_cut(bunny_diagram):
    mesh = bunny_diagram.mesh()
    editor = Editor(mesh)
    faces = sorted(editor.cell_faces[0])
    loops = [editor.outward(0, k) for k in faces]
    far = mesh.cell_geometry.centroid[0] + [1e3, 0, 0]
    assert cut_by_planes(editor, 0, faces, loops, [(np.array([1.0, 0, 0]), far)]) == []


def test_split_fixes_random_cells_of_the_sphere_and_keeps_volumes():
    # 300 random sites (not a CVT) in the triangulated sphere: 407 faces fail to start
    # with (pieces of its triangles at cells' rims), none after about 150 cuts (measured).
    domain = hcvt.load_domain(DATA / "3d" / "sphere.ply")
    diagram = hcvt.voronoi(domain, random_inside(domain, 300, seed=5))
    mesh = diagram.mesh()
    before = failing_faces(mesh)
    split, site, report = split_failing_cells(mesh)
    split.check()
    after = failing_faces(split)
    print(
        f"\nfailing faces {before.sum()} -> {after.sum()}, cells {mesh.n_cells} -> "
        f"{split.n_cells}, cuts {report.cuts}"
    )
    assert before.sum() > 100
    assert after.sum() == len(report.failing) == 0
    # Every site keeps at least one cell; the report counts the cells made.
    assert report.cells == split.n_cells and set(site.tolist()) == set(range(mesh.n_cells))
    by_site = np.bincount(site, weights=split.cell_geometry.volume, minlength=mesh.n_cells)
    assert np.allclose(by_site, diagram.volume, rtol=1e-12, atol=0)


def test_split_boundary_merges_the_faces_no_cut_fixed(monkeypatch):
    # With no cut allowed, every failing face is left to the merge: split_boundary is then
    # merged_boundary, one cell per site.
    domain = hcvt.load_domain(DATA / "3d" / "sphere.ply")
    mesh = hcvt.voronoi(domain, random_inside(domain, 100, seed=4)).mesh()
    monkeypatch.setattr(split_module, "MAX_DEPTH", 0)
    split, site, report = split_boundary(mesh, domain)
    merged, merge = merged_boundary(mesh, domain)
    assert report.cuts == 0 and report.merged_faces == merge.merged_faces > 0
    assert np.array_equal(site, np.arange(mesh.n_cells))
    assert np.array_equal(split.face_vertices, merged.face_vertices)
    assert len(report.failing) == len(merge.failing) == 0


def test_split_leaves_a_passing_mesh_alone():
    domain = hcvt.load_domain(DATA / "3d" / "sphere.ply")
    run = hcvt.cvt(domain, random_inside(domain, 60, seed=2), method="lbfgs", tol=1e-6)
    mesh = run.diagram.mesh()
    if failing_faces(mesh).any():
        pytest.skip("this CVT of the sphere has failing faces")
    split, site, report = split_failing_cells(mesh)
    assert report.cuts == 0 and split.n_cells == mesh.n_cells
    assert np.array_equal(split.face_vertices, mesh.face_vertices)
    assert np.array_equal(site, np.arange(mesh.n_cells))


def test_split_is_refused_in_2d():
    square = hcvt.load_domain(DATA / "2d" / "unit_square.geojson")
    mesh = hcvt.voronoi(square, random_inside(square, 20, seed=1)).mesh()
    with pytest.raises(ValueError, match="3D meshes only"):
        split_failing_cells(mesh)


def _site_field(text: str) -> np.ndarray:
    body = text[text.index("List<scalar>") :]
    count = int(body.split()[1])
    values = body[body.index("(") + 1 : body.index(")")].split()
    assert len(values) == count
    return np.asarray(values, dtype=float).astype(np.intp)


@pytest.mark.slow
def test_split_passes_checkmesh_with_the_exact_volume_on_a_converged_bunny_cvt(tmp_path):
    # "Mesh OK", every face planar, and the total volume OpenFOAM computes is the input
    # mesh's to the 17 digits it prints.
    info, log, _ = passing_case(tmp_path, "split")
    case = tmp_path / "case"
    assert "ok (closed singly connected)" in log
    split = info["split_cells"]
    assert split["still_failing"] == 0 and split["cuts"] > 0 and split["faces_merged"] == 0
    assert abs(split["volume_total_relative_change"]) < 1e-14
    # One cell per cut more, or a few more where a cut left a side in two pieces.
    assert _figure(log, r"cells:\s+(\d+)") == split["cells"] >= 1000 + split["cuts"]
    domain = hcvt.load_domain(DATA / "3d" / "bunny.off")
    total = _figure(log, rf"Total volume = {NUM}")
    print(f"total volume {total!r}, input mesh {domain.volume!r}")
    assert abs(total / domain.volume - 1) < 1e-14
    # 0/site: each site owns one cell or more.
    site = _site_field((case / "0" / "site").read_text())
    assert np.array_equal(np.unique(site), np.arange(1000))
    quality = info["mesh_quality"]
    assert quality["skew_faces"] == 0 and quality["inverted_pyramids"] == 0
    assert abs(_figure(log, rf"Max skewness = {NUM}") - quality["skewness_max"]) < 1e-9
    angle = _figure(log, rf"non-orthogonality Max: {NUM}")
    assert abs(angle - quality["non_orthogonality_max"]) < 1e-9
    # The price: the sections are not Voronoi faces, so they are not orthogonal (the
    # exact mesh's max is 0.03 degrees; measured here 85.5 degrees, 16 faces above 70).
    assert 1.0 < angle < 90.0


@pytest.mark.slow
def test_split_passes_checkmesh_on_a_converged_cheese_cvt(tmp_path):
    # The cheese (genus 133) at 1k sites has boundary cells as large as its tunnels, many
    # wrapped around them: the hardest case measured. "Mesh OK"; the cuts leave at most a
    # face or two to merge (measured: 1 after about 2,500 cuts), so the total volume
    # moves by no more than that face's cell's change.
    info, log, _ = passing_case(tmp_path, "split", "cheese.off")
    split = info["split_cells"]
    print(split)
    assert split["still_failing"] == 0 and split["faces_merged"] <= 2
    assert split["cuts"] > 1000
    domain = hcvt.load_domain(DATA / "3d" / "cheese.off")
    total = _figure(log, rf"Total volume = {NUM}")
    print(f"total volume {total!r}, input mesh {domain.volume!r}")
    assert abs(total / domain.volume - 1) < 1e-9  # measured +8.9e-11
    assert abs(split["volume_total_relative_change"] - (total / domain.volume - 1)) < 1e-12
