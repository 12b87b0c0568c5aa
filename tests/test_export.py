"""Meshes out (issue 19): PolyMesh geometry, OpenFOAM cases checked by OpenFOAM's own
checkMesh, VTU read back by VTK (pyvista) and meshio, GeoJSON, mesh quality.

The exporters are also checked on meshes from tests/meshes.py: grids and the
Voronoi diagram of CVT sites in the convex real ``sphere.ply`` and ``unit_square.geojson``,
built with scipy; the tests at the end take ``Diagram.mesh()`` of the bunny and the cheese.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
import shapely
from click.testing import CliRunner

import hcvt
import meshes
from hcvt.cli import main
from hcvt.errors import InvalidMeshError
from hcvt.export import (
    boundary_patches,
    merged_boundary,
    mesh_quality,
    to_pyvista,
    write_openfoam,
    write_vtu,
)
from hcvt.io.vtu import _split_for_vtk
from hcvt.mesh.merge import merge_boundary_faces, merge_failing_boundary_faces, outlines
from hcvt.mesh.parts import cell_parts, join_detached_parts
from hcvt.mesh.polymesh import PolyMesh
from helpers import DATA, random_inside

pv = pytest.importorskip("pyvista")
meshio = pytest.importorskip("meshio")

NUM = r"([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)"  # a number as checkMesh prints it


# ----------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def sphere() -> hcvt.Domain:
    return hcvt.load_domain(DATA / "3d" / "sphere.ply")


@pytest.fixture(scope="module")
def sphere_cvt(sphere) -> tuple[hcvt.Diagram, PolyMesh]:
    """A CVT of 150 sites in the (convex, triangulated) sphere and its conforming mesh."""
    run = hcvt.cvt(sphere, random_inside(sphere, 150, seed=3), method="lbfgs", tol=1e-4)
    return run.diagram, meshes.convex_voronoi(sphere, run.sites)


@pytest.fixture(scope="module")
def square_cvt() -> tuple[hcvt.Diagram, PolyMesh]:
    square = hcvt.load_domain(DATA / "2d" / "unit_square.geojson")
    run = hcvt.cvt(square, random_inside(square, 120, seed=1), method="lbfgs", tol=1e-4)
    return run.diagram, meshes.convex_voronoi(square, run.sites)


# ----------------------------------------------------------------------------- PolyMesh
def test_cell_geometry_of_the_sphere_mesh_is_the_exact_diagrams(sphere_cvt, sphere):
    # Volumes and centroids from the faces (divergence theorem) against the core's signed
    # cones: two independent computations of the same cells.
    diagram, mesh = sphere_cvt
    mesh.check()
    volume, centroid = mesh.cell_geometry
    assert np.abs(volume - diagram.volume).max() < 1e-14 * sphere.volume * 10
    assert np.abs(centroid - diagram.centroid).max() < 1e-13
    assert abs(volume.sum() - sphere.volume) < 1e-13 * sphere.volume


def test_cell_geometry_2d_against_the_diagram(square_cvt):
    diagram, mesh = square_cvt
    mesh.check()
    volume, centroid = mesh.cell_geometry
    assert np.abs(volume - diagram.volume).max() < 1e-15
    assert np.abs(centroid - diagram.centroid).max() < 1e-14
    loops = mesh.cell_loops()
    assert all(len(cell) == 1 for cell in loops)  # convex cells: one loop each
    assert (
        sum(len(r) for cell in loops for r in cell)
        == 2 * mesh.interior.sum() + (~mesh.interior).sum()
    )


def test_cell_faces_lists_each_interior_face_twice():
    mesh = meshes.hex_grid((3, 4, 5))
    cf = mesh.cell_faces
    assert np.array_equal(np.diff(cf.offsets), np.full(60, 6))  # boxes: six faces each
    inner = np.flatnonzero(mesh.interior)
    counts = np.bincount(cf.faces, minlength=mesh.n_faces)
    assert set(counts[inner]) == {2} and set(counts[~mesh.interior]) == {1}
    assert cf.outward.sum() == mesh.n_faces


def _replace(mesh: PolyMesh, **fields) -> PolyMesh:
    base = {k: getattr(mesh, k) for k in PolyMesh.__dataclass_fields__}
    base.update(fields)
    return PolyMesh(**base)


def test_check_names_the_defect():
    mesh = meshes.hex_grid((2, 2, 2))
    mesh.check()
    bad_owner = mesh.owner.copy()
    bad_owner[3] = 8
    with pytest.raises(InvalidMeshError, match=r"owner\[3\] = 8"):
        _replace(mesh, owner=bad_owner).check()
    # A face turned over: its owner's boundary is no longer a closed oriented surface.
    k = int(np.flatnonzero(~mesh.interior)[0])
    flipped = mesh.face_vertices.copy()
    s, e = mesh.face_offsets[k], mesh.face_offsets[k + 1]
    flipped[s:e] = flipped[s:e][::-1]
    with pytest.raises(InvalidMeshError, match=f"cell {mesh.owner[k]} is not closed"):
        _replace(mesh, face_vertices=flipped).check()
    # An interior face claiming to lie on the boundary.
    element = mesh.boundary_element.copy()
    element[np.flatnonzero(mesh.interior)[0]] = 0
    with pytest.raises(InvalidMeshError, match="has a boundary element"):
        _replace(mesh, boundary_element=element).check()


def test_compacted_drops_empty_cells_and_unused_points():
    mesh = meshes.hex_grid((2, 1, 1))
    # Cell 0 becomes empty-handed: renumber cells 0, 1 as 1, 2 in a mesh of 3 cells.
    moved = _replace(
        mesh,
        owner=mesh.owner + 1,
        neighbour=np.where(mesh.neighbour >= 0, mesh.neighbour + 1, -1),
        n_cells=3,
        points=np.vstack([mesh.points, [[9.0, 9.0, 9.0]]]),
    )
    compact, kept = moved.compacted()
    assert list(kept) == [1, 2] and compact.n_cells == 2 and len(compact.points) == 12
    assert np.allclose(compact.cell_geometry.volume, 0.5)


# ----------------------------------------------------------------------------- OpenFOAM
def _check_mesh(case: Path) -> str:
    exe = shutil.which("checkMesh")
    if exe is None:
        if os.environ.get("HCVT_REQUIRE_CHECKMESH"):
            pytest.fail("checkMesh is missing: scripts/test.sh should have installed OpenFOAM")
        pytest.skip("OpenFOAM's checkMesh is not installed (scripts/test.sh installs it)")
    env = dict(os.environ)
    env.setdefault("WM_PROJECT_DIR", "/usr/share/openfoam")
    done = subprocess.run(
        [exe, "-case", str(case)], capture_output=True, text=True, env=env, timeout=600
    )
    assert done.returncode == 0, done.stdout + done.stderr
    return done.stdout


def _assert_fails_only_on_boundary_pieces(log: str, case: Path) -> None:
    """checkMesh on the exact pieces of a curved or holed boundary (measured 2026-12-01).

    Topology, closedness of cells and boundary, volumes and non-orthogonality pass. Two
    geometric checks fail, on boundary faces only: "face pyramids" (a non-convex boundary
    cell whose centroid lies behind one of its pieces of an input triangle) and "skewness"
    (a small piece at a cell's rim: OpenFOAM divides its offset by the piece's own extent).
    Hold that nothing else fails and that every flagged face is a boundary face. (The
    merged boundary faces pass: test_merged_boundary_*.)
    """
    for line in ("Boundary definition OK", "Cell to face addressing OK", "Point usage OK"):
        assert line in log
    assert "Upper triangular ordering OK" in log and "Face vertices OK" in log
    assert re.search(r"Max cell openness = \S+ OK", log)
    assert "Non-orthogonality check OK" in log
    failures = re.findall(r"\*\*\*(.*)", log)
    assert all("face pyramids" in f or "skewness" in f for f in failures), failures
    boundary = (case / "constant" / "polyMesh" / "boundary").read_text()
    first_boundary_face = min(int(x) for x in re.findall(r"startFace\s+(\d+);", boundary))
    sets = case / "constant" / "polyMesh" / "sets"
    for name in ("wrongOrientedFaces", "skewFaces"):
        if (sets / name).exists():
            text = (sets / name).read_text()
            body = text[text.index("(", text.index("}")) + 1 : text.rindex(")")]
            faces = np.array(body.split(), dtype=np.int64)
            assert faces.size and faces.min() >= first_boundary_face, name


def _figure(log: str, pattern: str) -> float:
    found = re.search(pattern, log)
    assert found, f"no {pattern!r} in checkMesh's output:\n{log}"
    return float(found.group(1))


def _read_labels(path: Path) -> np.ndarray:
    text = path.read_text()
    body = text[text.index("}") + 1 :]
    count = int(body.split()[0])
    values = body[body.index("(") + 1 : body.rindex(")")].split()
    assert len(values) == count
    return np.asarray(values, dtype=np.intp)


@pytest.mark.parametrize("binary", [False, True])
def test_checkmesh_passes_the_sphere_cvt_mesh(sphere_cvt, sphere, tmp_path, binary):
    diagram, mesh = sphere_cvt
    case = write_openfoam(mesh, tmp_path / "case", domain=sphere, binary=binary)
    log = _check_mesh(case)
    print(log[log.index("Checking geometry") :])
    assert "Mesh OK." in log
    assert "Boundary openness" in log and "***" not in log
    total = _figure(log, rf"Total volume = {NUM}")
    assert abs(total - sphere.volume) < 1e-12 * sphere.volume
    assert _figure(log, r"cells:\s+(\d+)") == mesh.n_cells
    # Our quality figures are checkMesh's, to its printed digits.
    ours = mesh_quality(mesh).summary()
    assert (
        abs(_figure(log, rf"non-orthogonality Max: {NUM}") - ours["non_orthogonality_max"]) < 1e-9
    )
    assert abs(_figure(log, rf"average: {NUM}") - ours["non_orthogonality_average"]) < 1e-9
    assert abs(_figure(log, rf"Max skewness = {NUM}") - ours["skewness_max"]) < 1e-9
    assert _figure(log, rf"Max aspect ratio = {NUM}") == pytest.approx(
        ours["aspect_ratio_max"], rel=1e-9
    )
    # A CVT: centroids sit on (near) the sites, so faces are close to orthogonal.
    assert ours["non_orthogonality_max"] < 30
    # Another OpenFOAM tool on the case as written: foamToVTK, fields included.
    env = {**os.environ, "WM_PROJECT_DIR": os.environ.get("WM_PROJECT_DIR", "/usr/share/openfoam")}
    subprocess.run(["foamToVTK", "-case", str(case)], check=True, capture_output=True, env=env)
    internal = pv.read(next(case.glob("VTK/*_0/internal.vtu")))
    assert internal.n_cells == mesh.n_cells
    assert np.array_equal(np.sort(internal.cell_data["site"]), np.arange(mesh.n_cells))


def test_openfoam_faces_are_upper_triangular(tmp_path):
    # hex_grid owns every interior face by the larger cell: the writer must flip them.
    mesh = meshes.hex_grid((3, 4, 5))
    case = write_openfoam(mesh, tmp_path / "case", domain=meshes.box_domain())
    poly = case / "constant" / "polyMesh"
    owner, neighbour = _read_labels(poly / "owner"), _read_labels(poly / "neighbour")
    n_inner = len(neighbour)
    assert n_inner == mesh.interior.sum() and len(owner) == mesh.n_faces
    assert (owner[:n_inner] < neighbour).all()
    key = owner[:n_inner] * 1000 + neighbour
    assert (np.diff(key) > 0).all()
    log = _check_mesh(case)
    assert "Mesh OK." in log
    assert _figure(log, rf"non-orthogonality Max: {NUM}") == 0
    assert abs(_figure(log, rf"Total volume = {NUM}") - 1) < 1e-14


def test_openfoam_patches_per_label(tmp_path):
    # One patch per side of the box, from a label per boundary triangle.
    box = meshes.box_domain()
    sides = np.array(["zmin", "zmax", "ymin", "ymax", "xmin", "xmax"]).repeat(2)
    mesh = meshes.hex_grid((2, 3, 4))
    case = write_openfoam(mesh, tmp_path / "case", domain=box, labels=sides)
    text = (case / "constant" / "polyMesh" / "boundary").read_text()
    found = dict(re.findall(r"(\w+)\s*\{[^}]*nFaces\s+(\d+);", text))
    assert found == {"xmax": "12", "xmin": "12", "ymax": "8", "ymin": "8", "zmax": "6", "zmin": "6"}
    assert "Mesh OK." in _check_mesh(case)


def test_boundary_components_become_patches():
    # Two disjoint boxes: two components; a letter with two holes: three rings.
    a, b = meshes.box_domain(), meshes.box_domain((2, 0, 0), (3, 1, 1))
    two = hcvt.Domain.from_mesh(
        np.vstack([a.vertices, b.vertices]), np.vstack([a.faces, b.faces + len(a.vertices)])
    )
    from hcvt.mesh.patches import _components

    count, label = _components(two)
    assert count == 2 and list(label) == [0] * 12 + [1] * 12
    letter = hcvt.load_domain(DATA / "2d" / "dejavu_sans_B.geojson")
    count, label = _components(letter)
    rings = [len(r.coords) - 1 for p in [letter.geometry] for r in [p.exterior, *p.interiors]]
    assert count == 3 and list(np.bincount(label)) == rings
    mesh = meshes.quad_tri_grid()
    patch, names = boundary_patches(mesh, meshes.square_domain())
    assert names == ["boundary"] and set(patch[~mesh.interior]) == {0}


def test_2d_mesh_is_extruded_for_openfoam(square_cvt, tmp_path):
    diagram, mesh = square_cvt
    case = write_openfoam(mesh, tmp_path / "case", domain=diagram.domain, thickness=0.5)
    log = _check_mesh(case)
    assert "Mesh OK." in log
    assert "Mesh has 2 solution (non-empty) directions (1 1 0)" in log
    assert abs(_figure(log, rf"Total volume = {NUM}") - 0.5) < 1e-14
    ours = mesh_quality(mesh).summary()
    assert (
        abs(_figure(log, rf"non-orthogonality Max: {NUM}") - ours["non_orthogonality_max"]) < 1e-9
    )


# ----------------------------------------------------------------------------- VTU
def _assert_meshio_reads_faces_paired(path: Path, mesh: PolyMesh) -> None:
    """meshio reads every cell; each interior face is in exactly two cells, once each way
    round, and each boundary face in one (faces VTK would triangulate wrongly are written
    as their triangles: each triangle is such a face)."""
    mesh, kept = mesh.compacted()  # the file has no empty cells
    written = _split_for_vtk(mesh)
    read = meshio.read(path)
    assert sum(len(block.data) for block in read.cells) == mesh.n_cells
    site = np.concatenate(read.cell_data["site"])
    assert sorted(site) == kept.tolist()
    directed: dict[tuple[int, ...], int] = {}
    for block in read.cells:
        for cell in block.data:
            for face in cell:
                loop = [int(v) for v in face]
                k = loop.index(min(loop))
                key = tuple(loop[k:] + loop[:k])
                directed[key] = directed.get(key, 0) + 1
    assert set(directed.values()) == {1}
    paired = sum(1 for f in directed if (f[0], *f[1:][::-1]) in directed)
    assert paired == 2 * written.interior.sum()
    assert len(directed) - paired == (~written.interior).sum()


def _vtk_cell_volumes(grid) -> tuple[np.ndarray, float]:
    """VTK's own volume of each cell of ``grid`` (in its order) and of all cells.

    Each cell's faces as VTK reads them (vtkDataSetSurfaceFilter on the separated cells),
    triangulated by VTK (vtkTriangleFilter); the total by vtkMassProperties, a cell's as
    the signed cones of its triangles. ``separate_cells`` (vtkShrinkFilter) stores its
    points as float32: they are put back as read, else that rounding alone misses the
    domain volume by 2.9e-9 (cheese, 10k cells) and each cell by ~1e-7. Not
    vtkCellSizeFilter (``compute_cell_sizes``): it measures a polyhedron by the Delaunay
    tetrahedra of its points, not its faces (57% off on a cheese boundary cell).
    """
    grid = grid.copy()
    grid.cell_data["cell"] = np.arange(grid.n_cells)
    grid.point_data["xyz"] = np.asarray(grid.points, dtype=np.float64)
    cells = grid.separate_cells()
    cells.points = cells.point_data["xyz"]
    surface = cells.extract_surface(algorithm="dataset_surface").triangulate()
    t = surface.points[surface.faces.reshape(-1, 4)[:, 1:]]
    cones = np.einsum("ij,ij->i", t[:, 0], np.cross(t[:, 1], t[:, 2])) / 6
    return np.bincount(surface.cell_data["cell"], cones, minlength=grid.n_cells), surface.volume


def test_vtk_measures_real_boundary_cells_exactly(tmp_path):
    # Halton sites in the cheese (genus 133): 2000 cells, thousands of non-convex faces
    # between boundary cells. VTK's ear cut loses part of some: with every face written
    # whole, measured 3 cells off by up to 9.3e-7, the total by 4.3e-12; with those faces
    # written as their triangles, 2.4e-13 per cell and 7.1e-15 in all.
    domain = hcvt.load_domain(DATA / "3d" / "cheese.off")
    diagram = hcvt.voronoi(domain, hcvt.initialise(domain, 2000, "halton"))
    mesh = diagram.mesh()
    path = write_vtu(mesh, tmp_path / "cells.vtu")
    grid = pv.read(path)
    assert grid.n_cells == diagram.n and set(grid.celltypes) == {42}
    volumes, total = _vtk_cell_volumes(grid)
    exact = diagram.volume[grid.cell_data["site"]]
    worst, whole = (np.abs(volumes - exact) / exact).max(), abs(total / domain.volume - 1)
    print(f"VTK's volume: per cell up to {worst:.2e}, in all {whole:.2e} relative")
    assert worst < 1e-11 and whole < 1e-13
    _assert_meshio_reads_faces_paired(path, mesh)


def test_faces_with_holes_go_out_as_triangles(tmp_path):
    # 20 sites in the cheese: bisector faces with tunnels through them, each one loop whose
    # bridge to its hole is walked both ways (a keyhole; test_polymesh_geometry). VTK faces
    # cannot repeat a vertex: write_vtu refused this mesh ("face 91 repeats a vertex"),
    # and Diagram.cells() failed in GEOS ("Unable to find a convex corner").
    domain = hcvt.load_domain(DATA / "3d" / "cheese.off")
    diagram = hcvt.voronoi(domain, random_inside(domain, 20, seed=4))
    mesh = diagram.mesh()
    with pytest.raises(InvalidMeshError, match="repeats a vertex"):
        mesh.check()
    path = write_vtu(mesh, tmp_path / "cells.vtu")
    grid = pv.read(path)
    volumes, total = _vtk_cell_volumes(grid)
    exact = diagram.volume[grid.cell_data["site"]]
    assert (np.abs(volumes - exact) / exact).max() < 1e-12  # measured 6.0e-15
    assert abs(total - domain.volume) < 1e-13 * domain.volume
    _assert_meshio_reads_faces_paired(path, mesh)
    closed = [np.linalg.det(v[t]).sum() / 6 for v, t in diagram.cells()]
    assert np.abs(closed / diagram.volume - 1).max() < 1e-12


def test_vtu_read_by_vtk_and_meshio(sphere_cvt, sphere, tmp_path):
    diagram, mesh = sphere_cvt
    path = write_vtu(mesh, tmp_path / "cells.vtu", cell_data={"G": diagram.G})
    grid = pv.read(path)
    assert grid.n_cells == mesh.n_cells and set(grid.celltypes) == {42}
    # VTK's own volume: every cell's faces as VTK reads them, its mass properties.
    surfaces = grid.separate_cells().extract_surface(algorithm="dataset_surface")
    assert abs(surfaces.triangulate().volume - sphere.volume) < 1e-9 * sphere.volume
    assert np.array_equal(grid.cell_data["G"], diagram.G[grid.cell_data["site"]])
    _assert_meshio_reads_faces_paired(path, mesh)


def test_vtk_volume_filter_on_a_grid_and_2d_polygons(square_cvt, tmp_path):
    grid = pv.read(write_vtu(meshes.hex_grid((3, 4, 5)), tmp_path / "hex.vtu"))
    assert np.allclose(grid.compute_cell_sizes()["Volume"], 1 / 60, rtol=1e-14, atol=0)
    diagram, mesh = square_cvt
    polys = pv.read(write_vtu(mesh, tmp_path / "square.vtu"))
    assert set(polys.celltypes) == {7} and polys.n_cells == mesh.n_cells
    area = polys.compute_cell_sizes()["Area"]
    assert np.abs(area - diagram.volume[polys.cell_data["site"]]).max() < 1e-14
    read = meshio.read(tmp_path / "square.vtu")
    assert sum(len(b.data) for b in read.cells) == mesh.n_cells


def test_2d_cell_with_a_hole_and_in_pieces():
    # Cell 0: a 3x3 square minus the middle square (cell 1); a hole → triangles.
    pts = np.array([[x, y] for y in range(4) for x in range(4)], dtype=float)

    def p(x, y):
        return x + 4 * y

    outer = [p(0, 0), p(1, 0), p(2, 0), p(3, 0), p(3, 1), p(3, 2), p(3, 3)]
    outer += [p(2, 3), p(1, 3), p(0, 3), p(0, 2), p(0, 1)]
    inner = [p(1, 1), p(2, 1), p(2, 2), p(1, 2)]  # cell 1, counter-clockwise
    faces = [[outer[k], outer[(k + 1) % 12]] for k in range(12)]
    faces += [[inner[k], inner[(k + 1) % 4]] for k in range(4)]
    mesh = PolyMesh(
        points=pts,
        face_offsets=np.arange(0, 33, 2),
        face_vertices=np.array(faces).ravel(),
        owner=np.array([0] * 12 + [1] * 4),
        neighbour=np.array([-1] * 12 + [0] * 4),
        boundary_element=np.array(list(range(12)) + [-1] * 4),
        n_cells=2,
    )
    mesh.check()
    assert np.allclose(mesh.cell_geometry.volume, [8, 1])
    loops = mesh.cell_loops()
    assert sorted(len(r) for r in loops[0]) == [4, 12]
    triangles = mesh.cell_polygons()[0]
    assert all(len(t) == 3 for t in triangles)
    area = sum(shapely.Polygon(pts[t]).area for t in triangles)
    assert abs(area - 8) < 1e-14


def test_2d_real_polygon_cells_in_pieces_and_with_holes(tmp_path):
    # Five sites in a polygon with two holes: one cell in two pieces, one around a hole.
    domain = hcvt.load_domain(DATA / "2d" / "cgal_skeleton_sample_4.geojson")
    diagram = hcvt.voronoi(domain, random_inside(domain, 5, seed=0))
    mesh = meshes.diagram_mesh_2d(diagram)
    mesh.check()
    assert np.abs(mesh.cell_geometry.volume - diagram.volume).max() < 1e-13 * domain.volume
    shapes = [sorted(len(r) > 0 for r in loops) for loops in mesh.cell_loops()]
    assert sorted(len(s) for s in shapes) == [1, 1, 1, 2, 3]
    grid = pv.read(write_vtu(mesh, tmp_path / "cells.vtu"))
    assert set(np.unique(grid.cell_data["site"])) == set(range(5)) and grid.n_cells > 5
    # VTK's own areas, through its triangulation (vtkCellSizeFilter alone is wrong on the
    # large non-convex polygon of cell 0: 1798 for 439.7, measured with VTK 9.7).
    triangles = grid.extract_surface(algorithm="dataset_surface").triangulate()
    area = np.bincount(triangles.cell_data["site"], triangles.compute_cell_sizes()["Area"])
    assert np.abs(area - diagram.volume).max() < 1e-12 * domain.volume
    features = json.loads(hcvt.write_mesh(mesh, tmp_path / "c.geojson").read_text())["features"]
    cells = [shapely.geometry.shape(f["geometry"]) for f in features]
    assert sorted(c.geom_type for c in cells).count("MultiPolygon") == 1
    assert sum(len(c.interiors) for c in cells if c.geom_type == "Polygon") >= 1
    assert np.abs([c.area for c in cells] - diagram.volume).max() < 1e-12 * domain.volume
    assert shapely.coverage_is_valid(shapely.GeometryCollection(cells))


def test_openfoam_2d_patch_per_boundary_ring_and_checkmesh_errors(tmp_path):
    # The letter B (an outline and two holes): three boundary components, three patches.
    domain = hcvt.load_domain(DATA / "2d" / "dejavu_sans_B.geojson")
    run = hcvt.cvt(domain, random_inside(domain, 200, seed=2), method="lbfgs", tol=1e-3)
    mesh = meshes.diagram_mesh_2d(run.diagram)
    case = write_openfoam(
        mesh, tmp_path / "case", domain=domain, thickness=10.0, boundary_faces="exact"
    )
    text = (case / "constant" / "polyMesh" / "boundary").read_text()
    names = re.findall(r"^\s+(\w+)\s*\n\s*\{", text, flags=re.MULTILINE)
    assert names == ["boundary0", "boundary1", "boundary2", "frontAndBack"]
    log = _check_mesh(case)
    total = _figure(log, rf"Total volume = {NUM}")
    assert abs(total - 10 * domain.volume) < 1e-12 * total
    # The B's reflex corners: a cell wrapping one has its centroid behind a boundary face,
    # which checkMesh calls an error. hcvt counts the same faces, and the same skew ones.
    quality = mesh_quality(mesh).summary()
    assert quality["inverted_pyramids"] > 0
    assert f"Error in face pyramids: {quality['inverted_pyramids']} faces" in log
    assert f"{quality['skew_faces']} highly skew faces" in log
    assert "Non-orthogonality check OK" in log and "Cell volumes OK" in log
    # Each patch's faces are the mesh's boundary edges on that ring, extruded.
    sizes = [int(x) for x in re.findall(r"nFaces\s+(\d+);", text)]
    patch, _ = boundary_patches(mesh, domain)
    assert sizes[:3] == list(np.bincount(patch[~mesh.interior]))
    # By default those faces are joined with their neighbours on the same ring: the
    # patches stay, checkMesh passes, and OpenFOAM's volume moves by the bent faces only.
    merged = write_openfoam(mesh, tmp_path / "merged", domain=domain, thickness=10.0)
    log = _check_mesh(merged)
    assert "Mesh OK" in log
    merged_text = (merged / "constant" / "polyMesh" / "boundary").read_text()
    assert re.findall(r"^\s+(\w+)\s*\n\s*\{", merged_text, flags=re.MULTILINE) == names
    total = _figure(log, rf"Total volume = {NUM}")
    assert abs(total - 10 * domain.volume) < 1e-3 * total


# ----------------------------------------------------------------------------- API, CLI
def test_write_mesh_picks_the_format(square_cvt, tmp_path):
    diagram, mesh = square_cvt
    assert hcvt.write_mesh(mesh, tmp_path / "a.vtu").stat().st_size > 0
    case = hcvt.write_mesh(mesh, tmp_path / "case", domain=diagram.domain)
    assert (case / "system" / "controlDict").exists()
    site = (case / "0" / "site").read_text()
    assert "nonuniform List<scalar>" in site and "frontAndBack" in site
    features = json.loads(hcvt.write_mesh(mesh, tmp_path / "c.geojson").read_text())["features"]
    cells = [shapely.geometry.shape(f["geometry"]) for f in features]
    # Shared vertices: the cells form an exact coverage of the square.
    assert shapely.coverage_is_valid(shapely.GeometryCollection(cells))
    assert abs(sum(c.area for c in cells) - 1) < 1e-14
    with pytest.raises(ValueError, match="meshes are written as"):
        hcvt.write_mesh(mesh, tmp_path / "x.stl")
    with pytest.raises(ValueError, match="for OpenFOAM cases only"):
        hcvt.write_mesh(mesh, tmp_path / "d.vtu", boundary_faces="merged")
    with pytest.raises(ValueError, match="'split' was removed .issue 30.: its parts made"):
        hcvt.write_mesh(mesh, tmp_path / "case2", boundary_faces="split")
    # A 2D mesh's boundary faces are its extruded edges: "merged" (the default) writes
    # them as "exact" does.
    hcvt.write_mesh(mesh, tmp_path / "case_exact", domain=diagram.domain, boundary_faces="exact")
    for name in ("points", "faces", "owner", "neighbour", "boundary"):
        written = (case / "constant" / "polyMesh" / name).read_bytes()
        assert written == (tmp_path / "case_exact" / "constant" / "polyMesh" / name).read_bytes()
    with pytest.raises(ValueError, match="boundary_faces must be one of"):
        hcvt.write_mesh(mesh, tmp_path / "case3", boundary_faces="planar")


def test_to_pyvista(sphere_cvt):
    diagram, mesh = sphere_cvt
    grid = to_pyvista(mesh)
    assert grid.n_cells == mesh.n_cells
    assert np.array_equal(np.sort(grid.cell_data["site"]), np.arange(mesh.n_cells))
    grid = diagram.to_pyvista()
    assert np.array_equal(grid.cell_data["G"], diagram.G[grid.cell_data["site"]])
    surfaces = grid.separate_cells().extract_surface(algorithm="dataset_surface")
    assert abs(surfaces.triangulate().volume - diagram.volume.sum()) < 1e-9 * diagram.volume.sum()


@pytest.mark.parametrize("name", ["3d/sphere.ply", "2d/unit_square.geojson"])
def test_cli_writes_case_and_cells_through_diagram_mesh(name, tmp_path):
    # The whole path `hcvt run --mesh --cells` on real data.
    case, vtu, summary = tmp_path / "case", tmp_path / "cells.vtu", tmp_path / "s.json"
    args = ["run", str(DATA / name), "-n", "80", "--method", "lbfgs", "--tol", "1e-3"]
    args += ["--mesh", str(case), "--cells", str(vtu), "--summary", str(summary)]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    assert "non-orthogonality max" in result.output
    info = json.loads(summary.read_text())
    quality = info["mesh_quality"]
    domain = hcvt.load_domain(DATA / name)
    assert quality["cells"] == 80
    assert abs(quality["volume_total"] - domain.volume) < 1e-12 * domain.volume
    log = _check_mesh(case)
    assert "Mesh OK." in log
    assert abs(_figure(log, rf"Max skewness = {NUM}") - quality["skewness_max"]) < 1e-9
    # In 2D as OpenFOAM measures the one-cell-thick extrusion.
    aspect = _figure(log, rf"Max aspect ratio = {NUM}")
    assert aspect == pytest.approx(quality["aspect_ratio_max"], rel=1e-9)
    grid = pv.read(vtu)
    assert grid.n_cells == 80
    assert sorted(grid.cell_data.keys()) == ["G", "site", "volume"]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "n", "iterations"),
    # "Converged" here: 20 L-BFGS iterations from Halton sites, RMS gap about 4e-3
    # (measured: 25 iterations, 65 s on 2 busy cores, mean G 0.07984) -- a regular
    # mesh, not a CVT to the default rule (minutes at this size: benchmarks/).
    [("bunny.off", 50_000, 20), ("cheese.off", 10_000, 20)],
)
def test_checkmesh_on_a_cvt_of_a_real_mesh(name, n, iterations, tmp_path):
    case, vtu, summary = tmp_path / "case", tmp_path / "cells.vtu", tmp_path / "s.json"
    args = ["run", str(DATA / "3d" / name), "-n", str(n), "--method", "lbfgs"]
    args += ["--init", "halton", "--max-iter", str(iterations), "--tol", "1e-9"]
    args += ["--mesh", str(case), "--cells", str(vtu), "--summary", str(summary)]
    args += ["--out", str(tmp_path / "sites.npy"), "--mesh-boundary", "exact"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    print(result.output)
    domain = hcvt.load_domain(DATA / "3d" / name)
    log = _check_mesh(case)
    print(log[log.index("Checking geometry") :])
    _assert_fails_only_on_boundary_pieces(log, case)
    total = _figure(log, rf"Total volume = {NUM}")
    assert abs(total - domain.volume) < 1e-12 * domain.volume
    info = json.loads(summary.read_text())
    assert abs(_figure(log, rf"Max skewness = {NUM}") - info["mesh_quality"]["skewness_max"]) < 1e-9
    grid = pv.read(vtu)
    assert grid.n_cells == n
    # VTK's own volume, with the float32 points of separate_cells put back as read: that
    # rounding gave 1.05e-9 (bunny) and 2.9e-9 (cheese). Before the faces VTK triangulates
    # wrongly were written as triangles, measured on the same runs through hcvt.cvt:
    # 1.8e-10 and 2.3e-15 (per cell up to 8.5e-6 and 6.8e-5); now: the printed figures.
    _, total = _vtk_cell_volumes(grid)
    print(f"VTK's volume: total {abs(total - domain.volume) / domain.volume:.2e} relative")
    assert abs(total - domain.volume) < 1e-9 * domain.volume
    mesh = hcvt.voronoi(domain, np.load(tmp_path / "sites.npy")).mesh()
    _assert_meshio_reads_faces_paired(vtu, mesh)


# ----------------------------------------------------------------------------- merged boundary
def test_merged_boundary_leaves_a_passing_mesh_alone(sphere_cvt, sphere):
    # The sphere's CVT passes checkMesh with its exact pieces: nothing to merge.
    _, mesh = sphere_cvt
    merged, report = merged_boundary(mesh, sphere)
    assert report.rounds == 0 and report.groups == 0 and len(report.failing) == 0
    assert merged is mesh


def _boxes_with_a_detached_part(shape, cell, gone):
    """``meshes.hex_grid(shape)`` with the last layer of boxes along x half as thick and
    box ``gone`` renamed ``cell``: cell ``cell`` in two parts, the second half as big."""
    grid = meshes.hex_grid(shape, hi=shape)
    points = grid.points.copy()
    points[points[:, 0] == shape[0], 0] = shape[0] - 0.5
    rename = np.arange(grid.n_cells)
    rename[gone] = cell
    neighbour = np.where(grid.neighbour >= 0, rename[np.maximum(grid.neighbour, 0)], -1)
    return PolyMesh(
        points,
        grid.face_offsets,
        grid.face_vertices,
        rename[grid.owner],
        neighbour,
        grid.boundary_element,
        grid.n_cells,
    )


def test_a_detached_part_touching_one_cell_joins_it():
    # Boxes 0, 1, 2 in a row; box 2 (half as thick) renamed 0: cell 0 in two parts.
    mesh = _boxes_with_a_detached_part((3, 1, 1), cell=0, gone=2)
    assert np.bincount(cell_parts(mesh).of_cell).tolist() == [2, 1]
    joined_mesh, joined = join_detached_parts(mesh)
    joined_mesh.check()
    assert joined.cells.tolist() == [0] and joined.to.tolist() == [1]
    assert joined.shared_with.tolist() == [-1] and joined.volume == pytest.approx([0.5])
    assert joined_mesh.cell_geometry.volume == pytest.approx([1.0, 1.5, 0.0])
    assert joined_mesh.n_faces == mesh.n_faces - 1  # the face between box 1 and box 2
    assert np.bincount(cell_parts(joined_mesh).of_cell).tolist() == [1, 1]
    # A mesh of connected cells comes back as it was.
    again, none = join_detached_parts(joined_mesh)
    assert again is joined_mesh and len(none.cells) == 0


def test_a_detached_part_touching_two_cells_is_shared_and_stays_exact():
    # A 3 x 2 grid, the last column half as thick; box 5 (top right) renamed 0: the part
    # touches box 4 (its left, face area 1) and box 2 (below it, area 0.5).
    mesh = _boxes_with_a_detached_part((3, 2, 1), cell=0, gone=5)
    volume = mesh.cell_geometry.volume
    joined_mesh, joined = join_detached_parts(mesh)
    joined_mesh.check()
    assert joined.cells.tolist() == [0] and joined.volume == pytest.approx([0.5])
    assert {joined.to[0], joined.shared_with[0]} <= {4, 2, -1}
    after = joined_mesh.cell_geometry.volume
    assert after[0] == pytest.approx(1.0) and after[5] == 0.0
    assert after.sum() == pytest.approx(volume.sum(), rel=1e-14)
    assert after[2] + after[4] == pytest.approx(volume[2] + volume[4] + 0.5, rel=1e-14)
    assert np.bincount(cell_parts(joined_mesh).of_cell, minlength=6).max() == 1


def test_merged_boundary_joins_detached_parts_first():
    mesh = _boxes_with_a_detached_part((3, 1, 1), cell=0, gone=2)
    merged, report = merged_boundary(mesh)
    assert report.joined_parts == 1 and len(report.failing) == 0
    assert merged.cell_geometry.volume == pytest.approx([1.0, 1.5, 0.0])


def test_outlines_of_pieces_join_discs_and_refuse_annuli_and_pinches():
    # A 3 x 3 grid of unit squares in the plane z = 0, counter-clockwise from +z.
    xy = np.array([(x, y, 0.0) for y in range(4) for x in range(4)], dtype=float)
    quads = [
        [4 * y + x, 4 * y + x + 1, 4 * y + x + 5, 4 * y + x + 4] for y in range(3) for x in range(3)
    ]
    mesh = PolyMesh(
        xy,
        np.arange(0, 37, 4),
        np.array(quads).ravel(),
        owner=np.zeros(9, dtype=np.intp),
        neighbour=np.full(9, -1),
        boundary_element=np.arange(9),
        n_cells=1,
    )
    faces = np.array([0, 1, 0, 4, 0, 1, 2, 3, 5, 6, 7, 8])
    group = np.array([7, 7, 8, 8, 9, 9, 9, 9, 9, 9, 9, 9])  # 7: squares 0, 1; 8: corners
    ids, offsets, vertices, simple = outlines(mesh, faces, group)
    assert list(ids) == [7, 8, 9] and list(simple) == [True, False, False]  # 9: the ring
    # Two squares side by side: the 2 x 1 rectangle, its middle edge gone, from point 0.
    assert list(vertices[offsets[0] : offsets[1]]) == [0, 1, 2, 6, 5, 4]
    merged, rep = merge_boundary_faces(mesh, np.array([0, 0, 2, 3, 4, 5, 6, 7, 8]))
    assert list(rep) == [0, 2, 3, 4, 5, 6, 7, 8] and list(merged.face(0)) == [0, 1, 2, 6, 5, 4]
    assert np.allclose(merged.face_geometry.area_vector[0], [0, 0, 2])
    with pytest.raises(ValueError, match="do not make one simple loop"):
        merge_boundary_faces(mesh, np.array([0, 1, 2, 3, 0, 5, 6, 7, 8]))  # a pinch


def _converged(name: str, n: int) -> tuple[hcvt.Domain, hcvt.Diagram]:
    domain = hcvt.load_domain(DATA / "3d" / name)
    sites = hcvt.initialise(domain, n, "halton", seed=0)
    run = hcvt.cvt(domain, sites, method="newton")
    assert run.converged
    return domain, run.diagram


def test_cli_refuses_the_removed_split_boundary(tmp_path):
    args = ["run", str(DATA / "2d" / "unit_square.geojson"), "-n", "10"]
    args += ["--mesh", str(tmp_path / "case"), "--mesh-boundary", "split"]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 2 and "'split' is not one of 'merged', 'exact'" in result.output
    assert not (tmp_path / "case").exists()


def passing_case(tmp_path: Path, boundary: str, mesh: str = "bunny.off") -> tuple[dict, str, Path]:
    """``hcvt run mesh -n 1000`` to a converged CVT, its case checked by checkMesh.

    Newton from Halton sites to the default rule (RMS gap < 1e-7; on the bunny 106
    iterations, about 30 s), written with ``--mesh-boundary boundary``; checkMesh must say
    "Mesh OK" with no failed check. Returns the run's summary, checkMesh's log and the
    sites file.
    """
    case, summary, sites = tmp_path / "case", tmp_path / "s.json", tmp_path / "x.npy"
    args = ["run", str(DATA / "3d" / mesh), "-n", "1000", "--method", "newton"]
    args += ["--init", "halton", "--mesh", str(case), "--mesh-boundary", boundary]
    args += ["--summary", str(summary), "--out", str(sites)]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    info = json.loads(summary.read_text())
    assert info["rms_gap"] < 1e-7
    log = _check_mesh(case)
    print(log[log.index("Checking geometry") :])
    assert "Mesh OK." in log and "***" not in log
    aspect = _figure(log, rf"Max aspect ratio = {NUM}")
    assert aspect == pytest.approx(info["mesh_quality"]["aspect_ratio_max"], rel=1e-9)
    return info, log, sites


@pytest.mark.slow
def test_merged_boundary_passes_checkmesh_on_a_converged_bunny_cvt(tmp_path):
    info, log, sites = passing_case(tmp_path, "merged")
    # The boundary is still one closed surface: no vertex dropped from a merged face is
    # left in another face (a T-junction would open it).
    assert "ok (closed singly connected)" in log
    # One OpenFOAM cell per site, the interior faces those of the exact mesh.
    domain = hcvt.load_domain(DATA / "3d" / "bunny.off")
    exact = hcvt.voronoi(domain, np.load(sites)).mesh()
    assert _figure(log, r"cells:\s+(\d+)") == 1000
    assert _figure(log, r"internal faces:\s+(\d+)") == exact.interior.sum()
    merged = info["merged_boundary"]
    assert merged["still_failing"] == 0 and merged["faces_merged"] > 0
    # Our figures for the merged mesh are checkMesh's, to its printed digits.
    quality = info["mesh_quality"]
    assert quality["skew_faces"] == 0 and quality["inverted_pyramids"] == 0
    assert abs(_figure(log, rf"Max skewness = {NUM}") - quality["skewness_max"]) < 1e-9
    assert (
        abs(_figure(log, rf"non-orthogonality Max: {NUM}") - quality["non_orthogonality_max"])
        < 1e-9
    )
    # The volume: the exact cells sum to the domain's; a merged face is not planar, so
    # the volume OpenFOAM computes moves, by exactly what hcvt predicts (the cells'
    # face-pyramid sums). Measured: +2.46e-4 relative here (bunny 4k +1.53e-4, 50k
    # +5.8e-5: docs/results/checkmesh.txt): between a merged face's rim vertices OpenFOAM
    # sees a fan from their mean, not the input triangles.
    assert abs(merged["volume_total_exact"] - domain.volume) < 1e-12 * domain.volume
    total = _figure(log, rf"Total volume = {NUM}")
    assert abs(total - quality["volume_total"]) < 1e-12 * total
    change = total / domain.volume - 1
    assert abs(change - merged["volume_total_relative_change"]) < 1e-9
    assert 0 < abs(change) < 5e-4


@pytest.mark.slow
def test_merged_boundary_passes_checkmesh_on_a_converged_cheese_cvt(tmp_path):
    # The cheese (genus 133) at 1000 sites (about 30 s): merging fixes every skew piece
    # (6,745 exact) and every inverted pyramid (327). Merging alone left two faces with
    # an inverted pyramid (cells 333 and 594); this CVT also has two cells in two parts
    # (412 and 733: a thin tunnel crossing their convex regions), whose small parts are
    # joined to neighbours first (hcvt.mesh.parts), after which merging leaves none.
    # (Merging alone is not blind to face numbering: with the two parts joined, cells
    # 333 and 594 pass too. On the L-BFGS CVT of tests/test_solver.py the three failing
    # cells were the cells in parts.)
    domain, diagram = _converged("cheese.off", 1000)
    mesh = diagram.mesh()
    exact = mesh_quality(mesh).summary()
    assert exact["skew_faces"] > 1000 and exact["inverted_pyramids"] > 100
    patch, _ = boundary_patches(mesh, domain)
    _, alone = merge_failing_boundary_faces(mesh, patch)
    in_parts = np.flatnonzero(np.bincount(cell_parts(mesh).of_cell) > 1)
    assert len(alone.failing) > 0 and len(in_parts) > 0
    merged, report = merged_boundary(mesh, domain)
    assert report.joined_parts == len(in_parts) and len(report.failing) == 0
    quality = mesh_quality(merged).summary()
    assert quality["skew_faces"] == 0 and quality["inverted_pyramids"] == 0
    case = write_openfoam(mesh, tmp_path / "case", domain=domain, boundary_faces="merged")
    log = _check_mesh(case)
    assert "Mesh OK." in log and "***" not in log, re.findall(r"\*\*\*(.*)", log)
    assert "ok (closed singly connected)" in log
    assert abs(_figure(log, rf"Max skewness = {NUM}") - quality["skewness_max"]) < 1e-9
    total = _figure(log, rf"Total volume = {NUM}")
    assert abs(total - quality["volume_total"]) < 1e-12 * total
    # Coarse cells on small holes: the merged faces chord much curvature. Measured -3.8e-3
    # relative here (cheese 4k -3.8e-4; 10k -9e-7, a cancellation: the sum of |change| is
    # 3.7e-4 and the largest per-cell change 6.6%: docs/results/checkmesh.txt).
    assert abs(exact["volume_total"] - domain.volume) < 1e-12 * domain.volume
    assert 0 < abs(total / domain.volume - 1) < 1e-2
