"""The 3D clipped Voronoi diagram: closed forms, invariants on every closed mesh of
``../shared/data/3d``, and independent references (scipy half-space intersection on a
convex mesh, Monte-Carlo on a non-convex one)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import ConvexHull, HalfspaceIntersection, cKDTree

import hcvt

DATA_3D = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d"
CLOSED = sorted(p.name for p in DATA_3D.glob("*.*") if p.suffix in {".obj", ".off", ".ply"})
needs_data = pytest.mark.skipif(not DATA_3D.is_dir(), reason="../shared/data/3d not found")


def box_domain(lo: float = 0.0, hi: float = 1.0) -> hcvt.Domain:
    """The cube [lo, hi]³ as 12 outward triangles."""
    v = np.array([[(i >> k) & 1 for k in range(3)] for i in range(8)], dtype=float) * (hi - lo) + lo
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    f = [[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads]
    return hcvt.Domain.from_mesh(v, f)


def interior_sites(domain: hcvt.Domain, n: int, seed: int) -> np.ndarray:
    """``n`` uniform random sites strictly inside ``domain`` (exact winding numbers)."""
    rng = np.random.default_rng(seed)
    lo, hi = domain.bounds
    out: list[np.ndarray] = []
    count = 0
    while count < n:
        p = rng.uniform(lo, hi, size=(4 * n, 3))
        p = p[domain.contains(p)]
        out.append(p)
        count += len(p)
    return np.concatenate(out)[:n]


@pytest.fixture(scope="module")
def domains() -> dict[str, hcvt.Domain]:
    """Every closed mesh of the data folder, loaded once."""
    return {name: hcvt.load_domain(DATA_3D / name) for name in CLOSED}


def test_cube_grid_cells_are_cubes() -> None:
    n = 6
    h = 1.0 / n
    axis = (np.arange(n) + 0.5) * h
    sites = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    d = hcvt.voronoi(box_domain(), sites)
    np.testing.assert_allclose(d.volume, h**3, rtol=1e-13)
    np.testing.assert_allclose(d.G, 1 / 12, rtol=0, atol=1e-12)
    np.testing.assert_allclose(d.centroid, sites, rtol=0, atol=1e-15)
    # 3 n² (n - 1) shared square faces of side h.
    assert len(d.neighbors) == 3 * n * n * (n - 1)
    np.testing.assert_allclose(d.face_measures, h * h, rtol=1e-12)


def test_bcc_lattice_gives_truncated_octahedra() -> None:
    side = 5
    base = np.stack(np.meshgrid(*[np.arange(side)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    sites = np.concatenate([base + 0.25, base + 0.75])
    d = hcvt.voronoi(box_domain(0.0, side), sites)
    interior = ((sites >= 1.0) & (sites <= side - 1.0)).all(axis=1)
    assert interior.sum() == 54
    exact = 19 / (192 * 2 ** (1 / 3))
    np.testing.assert_allclose(d.G[interior], exact, rtol=0, atol=1e-12)
    np.testing.assert_allclose(d.volume[interior], 0.5, rtol=1e-13)
    assert abs(d.volume.sum() - side**3) < 1e-12 * side**3
    # Boundary cells exact too: the first moment of the cube.
    first = (d.volume[:, None] * d.centroid).sum(axis=0)
    np.testing.assert_allclose(first, side**3 * side / 2, rtol=1e-12)


def test_sites_on_the_boundary_count_as_inside() -> None:
    # Integer grid in [0, 2]³: 26 of 27 sites on faces, edges and corners of the cube, so
    # cell faces lie on the mesh faces and cell vertices on its edges.
    grid = np.stack(np.meshgrid(*[np.arange(3.0)] * 3, indexing="ij"), axis=-1).reshape(-1, 3)
    d = hcvt.voronoi(box_domain(0.0, 2.0), grid)
    on_boundary = (grid == 0) | (grid == 2)
    expected = 0.5 ** on_boundary.sum(axis=1)  # halved once per boundary coordinate
    np.testing.assert_allclose(d.volume, expected, rtol=1e-14)
    shift = np.where(grid == 0, 0.25, np.where(grid == 2, -0.25, 0.0))
    np.testing.assert_allclose(d.centroid, grid + shift, atol=1e-14)


def _assert_sums(domain: hcvt.Domain, d: hcvt.Diagram, what: str) -> None:
    rel = abs(d.volume.sum() - domain.volume) / domain.volume
    assert rel < 1e-12, f"{what}: Σ volume off by {rel:.2e}"
    first = (d.volume[:, None] * d.centroid).sum(axis=0)
    scale = domain.volume * np.linalg.norm(domain.bounds[1] - domain.bounds[0])
    err = np.abs(first - domain.first_moment).max() / scale
    assert err < 1e-12, f"{what}: Σ first moment off by {err:.2e}"
    assert np.isfinite(d.second_moment).all() and (d.second_moment >= 0).all()


@needs_data
@pytest.mark.parametrize("name", CLOSED)
@pytest.mark.parametrize("n", [100, 10_000])
def test_sums_match_the_mesh(domains: dict[str, hcvt.Domain], name: str, n: int) -> None:
    domain = domains[name]
    sites = interior_sites(domain, n, seed=n)
    d = hcvt.voronoi(domain, sites)
    _assert_sums(domain, d, f"{name}, n = {n}")
    assert (d.volume > 0).all()


@needs_data
def test_sites_outside_the_bounding_box_of_a_thin_part(domains: dict[str, hcvt.Domain]) -> None:
    domain = domains["fandisk.off"]
    lo, hi = domain.bounds
    rng = np.random.default_rng(3)
    sites = rng.uniform(lo - 0.5 * (hi - lo), hi + 0.5 * (hi - lo), size=(500, 3))
    with pytest.raises(hcvt.InvalidSitesError, match="outside"):
        hcvt.voronoi(domain, sites)
    d = hcvt.voronoi(domain, sites, allow_outside=True)
    _assert_sums(domain, d, "fandisk, sites around the box")
    assert (d.volume >= -1e-15).all()
    assert np.isnan(d.G).any()  # some cells miss the part entirely


def _reference_cell(halfspaces: np.ndarray, site: np.ndarray) -> tuple[float, np.ndarray, float]:
    """Volume, centroid and ∫|x - c|² of {x : A x + b <= 0} by scipy, fanned into
    tetrahedra from the vertex mean."""
    hs = HalfspaceIntersection(halfspaces, site)
    hull = ConvexHull(hs.intersections)
    pts = hull.points
    o = pts.mean(axis=0)
    a, b, c = (pts[hull.simplices[:, k]] - o for k in range(3))
    vol6 = np.abs(np.einsum("ij,ij->i", a, np.cross(b, c)))
    mass = vol6 / 6
    first = (mass[:, None] * (a + b + c) / 4).sum(axis=0)
    second = (
        mass
        * (
            (a * a).sum(1)
            + (b * b).sum(1)
            + (c * c).sum(1)
            + (a * b).sum(1)
            + (b * c).sum(1)
            + (c * a).sum(1)
        )
        / 10
    ).sum()
    volume = mass.sum()
    centroid = first / volume
    return volume, o + centroid, second - volume * centroid @ centroid


@needs_data
def test_icosphere_cells_match_halfspace_intersection(domains: dict[str, hcvt.Domain]) -> None:
    domain = domains["sphere.ply"]
    sites = interior_sites(domain, 60, seed=11)
    d = hcvt.voronoi(domain, sites)
    v, f = domain.vertices, domain.faces.astype(np.int64)
    normal = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    mesh_planes = np.column_stack([normal, -(normal * v[f[:, 0]]).sum(axis=1)])
    for i, s in enumerate(sites):
        q = np.delete(sites, i, axis=0) - s
        bis = np.column_stack([q, -(0.5 * (q * q).sum(axis=1) + q @ s)])
        vol, cen, sec = _reference_cell(np.concatenate([bis, mesh_planes]), s)
        assert abs(d.volume[i] - vol) < 1e-9 * vol
        assert np.abs(d.centroid[i] - cen).max() < 1e-9
        assert abs(d.second_moment[i] - sec) < 1e-9 * sec


@needs_data
def test_bunny_cells_match_monte_carlo(domains: dict[str, hcvt.Domain]) -> None:
    domain = domains["bunny.off"]
    sites = interior_sites(domain, 40, seed=5)
    d = hcvt.voronoi(domain, sites)
    rng = np.random.default_rng(8)
    lo, hi = domain.bounds
    m = 400_000
    x = rng.uniform(lo, hi, size=(m, 3))
    inside = domain.contains(x)
    owner = cKDTree(sites).query(x[inside])[1]
    p = np.bincount(owner, minlength=len(sites)) / m
    box = np.prod(hi - lo)
    sigma = box * np.sqrt(p * (1 - p) / m)
    assert (np.abs(d.volume - box * p) <= 5 * sigma + 1e-12).all()


@needs_data
def test_neighbors_are_symmetric(domains: dict[str, hcvt.Domain]) -> None:
    domain = domains["anchor_dense.off"]
    sites = interior_sites(domain, 2000, seed=2)
    d = hcvt.voronoi(domain, sites)
    seen: dict[tuple[int, int], float] = {}
    for i in range(d.n):
        for j, a in zip(*d.cell_neighbors(i), strict=True):
            seen[(i, int(j))] = float(a)
    h = (domain.volume / d.n) ** (1 / 3)
    for (i, j), a in seen.items():
        if a > 1e-9 * h * h:
            assert (j, i) in seen and abs(seen[(j, i)] - a) <= 1e-9 * h * h, (i, j)
    assert len(d.neighbors) > 5 * d.n


@needs_data
def test_results_do_not_depend_on_threads(domains: dict[str, hcvt.Domain]) -> None:
    domain = domains["kitten.obj"]
    sites = interior_sites(domain, 5000, seed=4)
    before = hcvt.get_num_threads()
    try:
        hcvt.set_num_threads(1)
        one = hcvt.voronoi(domain, sites)
        hcvt.set_num_threads(2)
        two = hcvt.voronoi(domain, sites)
    finally:
        hcvt.set_num_threads(before)
    for name in ("volume", "centroid", "second_moment", "neighbor_sites", "neighbor_measures"):
        assert np.array_equal(getattr(one, name), getattr(two, name)), name
    assert one.energy == two.energy


def _surface_volume(v: np.ndarray, f: np.ndarray) -> float:
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6)


def _is_closed(f: np.ndarray) -> bool:
    """Every directed edge has its reverse, once."""
    directed = np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2)
    fwd = {tuple(e) for e in directed.tolist()}
    return len(fwd) == len(directed) and all((b, a) in fwd for a, b in fwd)


@needs_data
def test_cells_are_closed_outward_and_export(
    domains: dict[str, hcvt.Domain], tmp_path: Path
) -> None:
    import xml.etree.ElementTree as ET

    import trimesh

    domain = domains["bunny.off"]
    sites = interior_sites(domain, 150, seed=9)
    d = hcvt.voronoi(domain, sites)
    cells = d.cells()
    assert len(cells) == d.n
    for i, (v, f) in enumerate(cells):
        assert _is_closed(f), f"cell {i} is not closed"
        vol = _surface_volume(v, f)
        assert vol > 0 and abs(vol - d.volume[i]) <= 1e-9 * d.volume[i], i
    assert (d.boundary_measure == 0).any() and (d.boundary_measure > 0).any()

    vtu = hcvt.io.write_cells(d, tmp_path / "cells.vtu")
    piece = ET.parse(vtu).getroot().find("UnstructuredGrid/Piece")
    assert piece is not None and int(piece.get("NumberOfCells")) == d.n
    names = {a.get("Name") for a in piece.iter("DataArray")}
    assert {"site", "G", "volume", "faces", "faceoffsets"} <= names

    ply = hcvt.io.write_cells(d, tmp_path / "cells.ply")
    mesh = trimesh.load(ply, process=False)
    assert abs(_surface_volume(mesh.vertices, mesh.faces) - domain.volume) < 1e-9 * domain.volume


@needs_data
def test_sites_on_mesh_vertices_and_a_single_site(domains: dict[str, hcvt.Domain]) -> None:
    domain = domains["bunny.off"]
    sites = np.vstack([interior_sites(domain, 200, seed=6), domain.vertices[::300]])
    d = hcvt.voronoi(domain, sites)
    _assert_sums(domain, d, "bunny with sites on mesh vertices")
    assert np.isfinite(d.G).all()
    one = hcvt.voronoi(domain, sites[:1])
    assert abs(one.volume[0] - domain.volume) < 1e-13 * domain.volume
    np.testing.assert_allclose(one.centroid[0], domain.centroid, rtol=0, atol=1e-14)


def test_integer_arrays_are_intp() -> None:
    # issue 16: neighbour offsets were uint64, neighbour sites uint32, faces uint32.
    domain = hcvt.load_domain(DATA_3D / "sphere.ply")
    d = hcvt.voronoi(domain, interior_sites(domain, 60, seed=2))
    arrays = {
        "neighbor_offsets": d.neighbor_offsets,
        "neighbor_sites": d.neighbor_sites,
        "neighbors": d.neighbors,
        "cell_neighbors": d.cell_neighbors(0)[0],
        "faces": domain.faces,
        "read_mesh": hcvt.io.read_mesh(DATA_3D / "sphere.ply")[1],
        "cell faces": d.cells()[0][1],
    }
    result = hcvt.cvt(domain, d.sites, max_iter=2)
    arrays["pinned"] = result.history["pinned"]
    arrays["evaluations"] = result.history["evaluations"]
    for name, array in arrays.items():
        assert array.dtype == np.intp, f"{name}: {array.dtype}"


def test_adjacency_is_the_restricted_delaunay_graph(domains: dict[str, hcvt.Domain]) -> None:
    from scipy.sparse.csgraph import connected_components

    domain = domains["bunny.off"]
    d = hcvt.voronoi(domain, interior_sites(domain, 400, seed=5))
    a = d.adjacency
    assert a.shape == (400, 400) and a.format == "csr" and a.dtype == np.float64
    assert (a != a.T).nnz == 0
    i, j = d.neighbors.T
    np.testing.assert_array_equal(a[i, j], d.face_measures)
    assert a.nnz == 2 * len(d.neighbors)
    assert connected_components(a, directed=False)[0] == 1  # the bunny is one piece
