"""The conforming mesh of a diagram (issue 19, DESIGN §9), on the real data of ../shared/data.

What is measured, per cell, from the mesh alone: the faces of a cell (owned as stored,
neighboured reversed) form a closed surface (3D: every directed edge has its reverse,
once; 2D: every vertex is entered as often as it is left), and its volume and centroid by
the divergence theorem about its site equal the diagram's (from the signed cones of the
core, a different computation) to 1e-12 of the cell's volume and 1e-12 of its size
``volume^(1/d)``. Vertices are never duplicated: no two points of the mesh lie within
1e-9 h of each other (a crack would leave two).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

import hcvt
from hcvt import _core
from hcvt.mesh.polymesh import PolyMesh
from helpers import DATA, random_inside

DATA_3D = DATA / "3d"
needs_data = pytest.mark.skipif(not DATA_3D.exists(), reason="shared data not found")
REL = 1e-12


def incidences(mesh: PolyMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (cell, face) pair: the cell, the face, whether the face is reversed for it."""
    inner = np.flatnonzero(mesh.interior)
    cells = np.concatenate([mesh.owner, mesh.neighbour[inner]])
    faces = np.concatenate([np.arange(mesh.n_faces), inner])
    reverse = np.concatenate([np.zeros(mesh.n_faces, bool), np.ones(len(inner), bool)])
    return cells, faces, reverse


def corner_arrays(mesh: PolyMesh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per (cell, face, corner): the cell, the corner's vertex, the next vertex round the
    face as the cell sees it."""
    cells, faces, reverse = incidences(mesh)
    sizes = np.diff(mesh.face_offsets)[faces]
    inc = np.repeat(np.arange(len(faces)), sizes)
    pos = np.arange(sizes.sum()) - np.repeat(np.cumsum(sizes) - sizes, sizes)
    step = np.where(reverse[inc], -1, 1)
    first = mesh.face_offsets[faces][inc]
    here = mesh.face_vertices[first + pos]
    after = mesh.face_vertices[first + (pos + step) % sizes[inc]]
    return cells[inc], here, after


def cell_moments_3d(mesh: PolyMesh, sites: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Volume and centroid of every cell from its faces (divergence theorem: cones from
    the site over the faces' fan triangles, signed)."""
    cells, faces, reverse = incidences(mesh)
    sizes = np.diff(mesh.face_offsets)[faces]
    fans = sizes - 2
    inc = np.repeat(np.arange(len(faces)), fans)
    q = np.arange(fans.sum()) - np.repeat(np.cumsum(fans) - fans, fans) + 1
    first = mesh.face_offsets[faces][inc]
    c = cells[inc]
    a = mesh.points[mesh.face_vertices[first]] - sites[c]
    b = mesh.points[mesh.face_vertices[first + q]] - sites[c]
    d = mesh.points[mesh.face_vertices[first + q + 1]] - sites[c]
    vol = np.einsum("ij,ij->i", a, np.cross(b, d)) / 6 * np.where(reverse[inc], -1, 1)
    volume = np.bincount(c, vol, minlength=mesh.n_cells)
    first_moment = np.stack(
        [np.bincount(c, vol * (a + b + d)[:, k] / 4, minlength=mesh.n_cells) for k in range(3)],
        axis=1,
    )
    return volume, sites + first_moment / np.where(volume == 0, 1, volume)[:, None]


def oriented_edges(mesh: PolyMesh) -> tuple[np.ndarray, np.ndarray]:
    """2D: every (cell, edge) pair, the edge's ends in the cell's direction (cell on the left)."""
    cells, faces, reverse = incidences(mesh)
    ends = mesh.face_vertices.reshape(-1, 2)[faces]
    return cells, np.where(reverse[:, None], ends[:, ::-1], ends)


def cell_moments_2d(mesh: PolyMesh, sites: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Area and centroid of every cell from its edges (shoelace about the site)."""
    cells, ends = oriented_edges(mesh)
    a, b = mesh.points[ends[:, 0]] - sites[cells], mesh.points[ends[:, 1]] - sites[cells]
    area = 0.5 * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
    volume = np.bincount(cells, area, minlength=mesh.n_cells)
    first = np.stack(
        [np.bincount(cells, area * (a + b)[:, k] / 3, minlength=mesh.n_cells) for k in range(2)],
        axis=1,
    )
    return volume, sites + first / np.where(volume == 0, 1, volume)[:, None]


def assert_closed_3d(mesh: PolyMesh) -> None:
    """Every cell's directed edges pair with their reverses, each exactly once."""
    cells, here, after = corner_arrays(mesh)
    edges = np.stack([cells, here, after], axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    assert (counts == 1).all(), f"{(counts > 1).sum()} directed edges used twice in one cell"
    reverse = np.unique(edges[:, [0, 2, 1]], axis=0)
    assert len(reverse) == len(unique) and (reverse == unique).all(), "a cell is not closed"


def assert_closed_2d(mesh: PolyMesh) -> None:
    """Every cell enters each of its vertices as often as it leaves it."""
    cells, ends = oriented_edges(mesh)
    balance = np.zeros((mesh.n_cells, len(mesh.points)), dtype=np.int64)
    np.add.at(balance, (cells, ends[:, 0]), 1)
    np.add.at(balance, (cells, ends[:, 1]), -1)
    assert not balance.any(), f"{np.count_nonzero(balance.any(axis=1))} cells not closed"


def assert_no_cracks(mesh: PolyMesh, h: float) -> None:
    """No two distinct points of the mesh coincide, and every point is used."""
    pairs = cKDTree(mesh.points).query_pairs(1e-9 * h)
    assert not pairs, f"{len(pairs)} pairs of coinciding points, first {sorted(pairs)[0]}"
    assert np.array_equal(np.unique(mesh.face_vertices), np.arange(len(mesh.points)))


def assert_layout(mesh: PolyMesh, n_elements: int) -> None:
    """Interior faces first, owner < neighbour, sorted; boundary faces name an element."""
    inner = mesh.interior
    k = int(inner.sum())
    assert inner[:k].all() and not inner[k:].any()
    assert (mesh.owner[:k] < mesh.neighbour[:k]).all()
    key = mesh.owner[:k] * mesh.n_cells + mesh.neighbour[:k]
    assert (np.diff(key) >= 0).all()
    assert (mesh.boundary_element[:k] == -1).all()
    b = mesh.boundary_element[k:]
    assert ((b >= 0) & (b < n_elements)).all()


def assert_moments(d: hcvt.Diagram, volume: np.ndarray, centroid: np.ndarray, label: str) -> None:
    live = d.volume > 0
    rel_v = np.abs(volume - d.volume)[live] / d.volume[live]
    size = d.volume[live] ** (1 / d.domain.dim)
    rel_c = np.linalg.norm(centroid - d.centroid, axis=1)[live] / size
    assert rel_v.max() <= REL, f"{label}: volume off by {rel_v.max():.2e} of the cell"
    assert rel_c.max() <= REL, f"{label}: centroid off by {rel_c.max():.2e} of the cell size"
    total = volume.sum()
    assert abs(total - d.domain.volume) <= 1e-13 * d.domain.volume, (label, total)


def check_3d(d: hcvt.Diagram, label: str) -> PolyMesh:
    mesh = d.mesh()
    assert mesh.dim == 3 and mesh.n_cells == d.n
    h = (d.domain.volume / d.n) ** (1 / 3)
    assert_layout(mesh, len(d.domain._core.faces))
    assert_closed_3d(mesh)
    assert_no_cracks(mesh, h)
    volume, centroid = cell_moments_3d(mesh, d.sites)
    assert_moments(d, volume, centroid, label)
    return mesh


def check_2d(d: hcvt.Diagram, label: str) -> PolyMesh:
    mesh = d.mesh()
    assert mesh.dim == 2 and (np.diff(mesh.face_offsets) == 2).all()
    h = (d.domain.volume / d.n) ** 0.5
    assert_layout(mesh, len(d.domain._core.segments))
    assert_closed_2d(mesh)
    assert_no_cracks(mesh, h)
    volume, centroid = cell_moments_2d(mesh, d.sites)
    assert_moments(d, volume, centroid, label)
    return mesh


def euler_of_interior_cells(mesh: PolyMesh) -> np.ndarray:
    """V - E + F of every cell with no boundary face (a convex polyhedron: 2)."""
    boundary_cells = np.unique(mesh.owner[~mesh.interior])
    cells, here, after = corner_arrays(mesh)
    out = []
    for c in np.setdiff1d(np.arange(mesh.n_cells), boundary_cells)[:200]:
        m = cells == c
        v = len(np.unique(here[m]))
        e = len({(min(a, b), max(a, b)) for a, b in zip(here[m], after[m], strict=True)})
        f = int((mesh.owner == c).sum() + (mesh.neighbour == c).sum())
        out.append(v - e + f)
    return np.array(out)


def cube() -> hcvt.Domain:
    v = np.array([[x, y, z] for z in (0, 1) for y in (0, 1) for x in (0, 1)], float)
    f = [[0, 2, 1], [1, 2, 3], [4, 5, 6], [5, 7, 6], [0, 1, 4], [1, 5, 4]]
    f += [[2, 6, 3], [3, 6, 7], [0, 4, 2], [2, 4, 6], [1, 3, 5], [3, 7, 5]]
    return hcvt.Domain.from_mesh(v, np.array(f))


@needs_data
@pytest.mark.parametrize(("name", "n"), [("bunny.off", 1500), ("cheese.off", 600)])
def test_3d_mesh_is_closed_conforming_and_exact(name: str, n: int) -> None:
    domain = hcvt.load_domain(DATA_3D / name)
    d = hcvt.voronoi(domain, random_inside(domain, n, seed=19))
    mesh = check_3d(d, name)
    assert (~mesh.interior).any() and mesh.interior.any()
    euler = euler_of_interior_cells(mesh)
    assert len(euler) > 0 and (euler == 2).all(), np.unique(euler)
    # The boundary faces tile the domain's boundary: their area is the surface area.
    _, tri = _area_of(mesh, ~mesh.interior)
    v, f = domain.vertices, domain.faces
    surface = 0.5 * np.linalg.norm(
        np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1
    )
    assert abs(tri - surface.sum()) <= 1e-12 * surface.sum()
    np.testing.assert_allclose(
        np.bincount(mesh.owner[~mesh.interior], _area_of(mesh, ~mesh.interior)[0], minlength=d.n),
        d.boundary_measure,
        rtol=0,
        atol=1e-12 * surface.sum(),
    )


def _area_of(mesh: PolyMesh, which: np.ndarray) -> tuple[np.ndarray, float]:
    """Vector-area norm of the faces selected by ``which``, and their sum."""
    out = []
    for k in np.flatnonzero(which):
        p = mesh.points[mesh.face(k)]
        out.append(0.5 * np.linalg.norm(np.cross(p, np.roll(p, -1, axis=0)).sum(axis=0)))
    a = np.array(out)
    return a, float(a.sum())


@pytest.mark.parametrize("lattice", ["cubic", "bcc", "on the boundary", "initialise"])
def test_3d_lattices_merge_degenerate_vertices(lattice: str) -> None:
    # Cospherical sites: up to 8 cells meet at one vertex, and their faces of zero area
    # must vanish without leaving two names for one point.
    domain = cube()
    g, on = (np.arange(4) + 0.5) / 4, np.arange(4) / 3
    cubic = np.array([(x, y, z) for x in g for y in g for z in g])
    sites = {
        "cubic": cubic,
        "bcc": np.vstack([cubic, cubic[(cubic < 0.8).all(axis=1)] + 0.125]),
        "on the boundary": np.array([(x, y, z) for x in on for y in on for z in on]),
        "initialise": hcvt.initialise(domain, 200, method="lattice", seed=0),
    }[lattice]
    d = hcvt.voronoi(domain, sites)
    mesh = check_3d(d, lattice)
    if lattice == "cubic":
        # 5^3 lattice points, 144 squares inside; on the boundary 96 squares, the 8 on the
        # cube faces' diagonals cut in two by the triangles' shared edge.
        assert len(mesh.points) == 125
        assert int(mesh.interior.sum()) == 144 and int((~mesh.interior).sum()) == 96 + 24
    if lattice == "on the boundary":
        assert len(mesh.points) == 5**3  # 0, 1/6, 1/2, 5/6, 1


@pytest.mark.parametrize("name", ["star5.geojson", "triangle_square_circle_hole.geojson"])
def test_2d_mesh_is_closed_conforming_and_exact(name: str) -> None:
    domain = hcvt.load_domain(DATA / "2d" / name)
    d = hcvt.voronoi(domain, random_inside(domain, 800, seed=19))
    mesh = check_2d(d, name)
    length = np.linalg.norm(
        np.diff(mesh.points[mesh.face_vertices.reshape(-1, 2)], axis=1)[:, 0], axis=1
    )
    boundary = np.bincount(mesh.owner[~mesh.interior], length[~mesh.interior], minlength=d.n)
    np.testing.assert_allclose(boundary, d.boundary_measure, rtol=0, atol=1e-12 * boundary.sum())
    # Each restricted Delaunay edge of the diagram is an interior edge of the mesh, as
    # long as the diagram measures it; the mesh has no other edges of positive length.
    inner = mesh.interior
    got: dict[tuple[int, int], float] = {}
    for o, n, length_k in zip(mesh.owner[inner], mesh.neighbour[inner], length[inner], strict=True):
        got[(int(o), int(n))] = got.get((int(o), int(n)), 0.0) + float(length_k)
    h = np.sqrt(domain.volume / d.n)
    expected = dict(zip(map(tuple, d.neighbors.tolist()), d.face_measures.tolist(), strict=True))
    for pair, m in expected.items():
        assert abs(got.get(pair, 0.0) - m) <= 1e-12 * h, pair
    assert all(m <= 1e-9 * h for pair, m in got.items() if pair not in expected)


@pytest.mark.parametrize("layout", ["square", "on the boundary", "hexagonal"])
def test_2d_lattices_have_no_cracks(layout: str) -> None:
    # Four cocircular sites meet at every lattice point: one vertex, not four.
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    g = {"square": (np.arange(8) + 0.5) / 8, "on the boundary": np.arange(9) / 8}.get(layout)
    if g is None:
        sites = hcvt.initialise(square, 100, method="lattice", seed=0)
    else:
        sites = np.array([(x, y) for x in g for y in g])
    d = hcvt.voronoi(square, sites)
    mesh = check_2d(d, layout)
    if layout == "square":
        assert len(mesh.points) == 81 and int(mesh.interior.sum()) == 2 * 8 * 7
    if layout == "on the boundary":
        assert len(mesh.points) == 10**2  # 0, 1/16, 3/16, ..., 15/16, 1


def test_2d_cells_keep_their_holes() -> None:
    domain = hcvt.load_domain(DATA / "2d" / "triangle_square_circle_hole.geojson")
    one = hcvt.voronoi(domain, random_inside(domain, 1, seed=3))
    (cell,) = one.cells()
    assert cell.geom_type == "Polygon" and len(cell.interiors) == len(domain.geometry.interiors)
    assert abs(cell.area - domain.volume) <= 1e-12 * domain.volume
    assert cell.equals(domain.geometry)


@needs_data
def test_3d_cells_are_closed_triangulations_of_the_mesh() -> None:
    domain = hcvt.load_domain(DATA_3D / "cheese.off")
    d = hcvt.voronoi(domain, random_inside(domain, 200, seed=7))
    for i, (v, f) in enumerate(d.cells()):
        directed = np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2)
        edges = {tuple(e) for e in directed.tolist()}
        assert len(edges) == len(directed) and all((b, a) in edges for a, b in edges), i
        vol = np.einsum("ij,ij->i", v[f[:, 0]], np.cross(v[f[:, 1]], v[f[:, 2]])).sum() / 6
        assert abs(vol - d.volume[i]) <= 1e-12 * d.volume[i], i


@needs_data
def test_mesh_does_not_depend_on_the_thread_count() -> None:
    domain = hcvt.load_domain(DATA_3D / "bunny.off")
    sites = random_inside(domain, 800, seed=2)
    before = _core.get_num_threads()
    try:
        meshes = []
        for threads in (1, 2):
            _core.set_num_threads(threads)
            meshes.append(hcvt.voronoi(domain, sites).mesh())
    finally:
        _core.set_num_threads(before)
    a, b = meshes
    for name in (
        "points",
        "face_offsets",
        "face_vertices",
        "owner",
        "neighbour",
        "boundary_element",
    ):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


@needs_data
def test_faces_with_holes_are_keyholes() -> None:
    # With 20 sites in cheese.off (genus 133) some bisector faces have tunnels through
    # them: each such face is one loop, its hole joined to its rim by a bridge edge walked
    # both ways, and every interior face faces from its owner to its neighbour.
    domain = hcvt.load_domain(DATA_3D / "cheese.off")
    d = hcvt.voronoi(domain, random_inside(domain, 20, seed=3))
    mesh = check_3d(d, "cheese 20")
    keyholes = [
        k for k in range(mesh.n_faces) if len(set(mesh.face(k).tolist())) < len(mesh.face(k))
    ]
    assert keyholes and all(mesh.interior[keyholes])
    for k in np.flatnonzero(mesh.interior):
        p = mesh.points[mesh.face(k)]
        area = np.cross(p, np.roll(p, -1, axis=0)).sum(axis=0)
        assert area @ (d.sites[mesh.neighbour[k]] - d.sites[mesh.owner[k]]) > 0, k


@needs_data
def test_sites_outside_the_domain_get_their_part() -> None:
    # allow_outside: a site just outside owns a sliver of the domain, and its cell is
    # meshed like any other (closed, exact); one far outside owns nothing and no face.
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    sites = np.vstack([random_inside(square, 50, seed=1), [[1.01, 0.5], [-0.01, 0.3], [3, 3]]])
    d = hcvt.voronoi(square, sites, allow_outside=True)
    mesh = check_2d(d, "square, sites outside")
    assert (d.volume[-3:-1] > 0).all() and d.volume[-1] == 0
    assert mesh.n_cells - 1 not in set(mesh.owner) | set(mesh.neighbour)
    bunny = hcvt.load_domain(DATA_3D / "bunny.off")
    sites = np.vstack([random_inside(bunny, 200, seed=1), bunny.vertices[::500] * 1.01])
    d = hcvt.voronoi(bunny, sites, allow_outside=True)
    check_3d(d, "bunny, sites outside")
    assert (d.volume[200:] > 0).any()
