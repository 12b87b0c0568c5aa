"""MPAS mesh files of spherical diagrams (issue 35): hcvt.write_mpas read back with xarray.

Each field is checked against what it must be, computed another way: areas against the
sphere's and the core's, arcs against the core's face measures and the haversine of the
file's own latitudes and longitudes, orientations against determinants of the positions,
angles against the great-circle bearing, TRiSK weights against their antisymmetry; and,
when MPAS-Tools' ``MpasMeshConverter.x`` is at hand (``HCVT_MPAS_CONVERTER`` or PATH),
against what it computes from our cells, vertices and ``cellsOnVertex`` alone.
"""

from __future__ import annotations

import os
import shutil
import subprocess

import numpy as np
import pytest
from click.testing import CliRunner

import hcvt
from hcvt.cli import main
from hcvt.mesh.sphere import spherical_mesh

xr = pytest.importorskip("xarray")
pytest.importorskip("netCDF4")

EARTH = 6371229.0  # MPAS-Tools' Earth radius, m


def _write(diagram, path):
    hcvt.write_mpas(diagram, path)
    return xr.open_dataset(path).load()


@pytest.fixture(scope="module")
def icosahedral(tmp_path_factory):
    """The CVT of the 2,562 icosahedral sites on the Earth, its diagram and its file."""
    earth = hcvt.Domain.sphere(EARTH)
    run = hcvt.cvt(earth, hcvt.initialise(earth, 2562, method="icosahedral"))
    assert run.converged
    path = tmp_path_factory.mktemp("mpas") / "icosahedral.nc"
    return run.diagram, _write(run.diagram, path), path


@pytest.fixture(scope="module")
def random(tmp_path_factory):
    """Voronoi cells of 2,000 uniform random sites on the unit sphere (obtuse triangles)."""
    unit = hcvt.Domain.sphere(1.0)
    diagram = hcvt.voronoi(unit, hcvt.initialise(unit, 2000, seed=7))
    path = tmp_path_factory.mktemp("mpas") / "random.nc"
    return diagram, _write(diagram, path), path


CASES = ["icosahedral", "random"]


@pytest.fixture(params=CASES)
def case(request):
    return request.getfixturevalue(request.param)


def _rows(ds, name, count):
    """The valid entries of a padded 1-based array, 0-based, as a list of arrays."""
    values = ds[name].values
    return [values[i, : count[i]] - 1 for i in range(len(values))]


def _unit(ds, kind):
    p = np.stack([ds[f"{a}{kind}"].values for a in "xyz"], axis=1)
    return p / np.linalg.norm(p, axis=1)[:, None]


def test_dimensions_attributes_and_every_index_in_range(case):
    diagram, ds, _ = case
    n, ne, nv = ds.sizes["nCells"], ds.sizes["nEdges"], ds.sizes["nVertices"]
    assert n == diagram.n and ds.sizes["vertexDegree"] == 3 and ds.sizes["TWO"] == 2
    assert (
        ds.sizes["maxEdges"] == ds.nEdgesOnCell.max()
        and ds.sizes["maxEdges2"] == 2 * ds.sizes["maxEdges"]
    )
    assert ds.attrs["on_a_sphere"] == "YES" and ds.attrs["is_periodic"] == "NO"
    assert ds.attrs["sphere_radius"] == diagram.domain.radius and ds.attrs["mesh_spec"] == "1.0"
    assert n - ne + nv == 2  # Euler on the sphere
    sides = ds.nEdgesOnCell.values
    for name, top in (("cellsOnCell", n), ("edgesOnCell", ne), ("verticesOnCell", nv)):
        values = ds[name].values
        inside = np.arange(values.shape[1]) < sides[:, None]
        assert values.dtype == np.int32
        assert np.all((values[inside] >= 1) & (values[inside] <= top)), name
        assert np.all(values[~inside] == 0), name
    for name, top in (
        ("cellsOnEdge", n),
        ("verticesOnEdge", nv),
        ("cellsOnVertex", n),
        ("edgesOnVertex", ne),
    ):
        assert ds[name].values.min() >= 1 and ds[name].values.max() <= top, name
    eoe = ds.edgesOnEdge.values
    inside = np.arange(eoe.shape[1]) < ds.nEdgesOnEdge.values[:, None]
    assert np.all((eoe[inside] >= 1) & (eoe[inside] <= ne)) and np.all(eoe[~inside] == 0)
    for kind, size in (("Cell", n), ("Edge", ne), ("Vertex", nv)):
        assert np.array_equal(ds[f"indexTo{kind}ID"].values, np.arange(1, size + 1))


def test_areas_tile_the_sphere_and_kites_split_cells_and_triangles(case):
    diagram, ds, _ = case
    r = diagram.domain.radius
    sphere = 4 * np.pi * r**2
    assert np.array_equal(ds.areaCell.values, diagram.volume)  # the core's exact areas
    assert ds.areaCell.values.sum() == pytest.approx(sphere, rel=1e-13)
    assert ds.areaTriangle.values.sum() == pytest.approx(sphere, rel=1e-13)
    kites = ds.kiteAreasOnVertex.values
    mean_triangle = sphere / ds.sizes["nVertices"]
    assert np.abs(kites.sum(axis=1) - ds.areaTriangle.values).max() < 1e-12 * mean_triangle
    per_cell = np.bincount(
        ds.cellsOnVertex.values.ravel() - 1, kites.ravel(), minlength=ds.sizes["nCells"]
    )
    assert np.abs(per_cell - ds.areaCell.values).max() < 1e-11 * sphere / diagram.n


def test_cells_wind_counter_clockwise_once_around_their_site(case):
    """Each cell's vertices, fanned from its site, have positive areas summing to areaCell:
    the polygon winds once, counter-clockwise seen from outside, and is the core's cell."""
    diagram, ds, _ = case
    x, v = _unit(ds, "Cell"), _unit(ds, "Vertex")
    sides = ds.nEdgesOnCell.values
    voc = _rows(ds, "verticesOnCell", sides)
    r2 = diagram.domain.radius**2
    for i in range(diagram.n):
        a, b = v[voc[i]], v[np.roll(voc[i], -1)]
        det = np.einsum("j,kj->k", x[i], np.cross(a, b))
        assert np.all(det > 0), i
        triple = det
        fan = 2 * np.arctan2(triple, 1 + a @ x[i] + np.sum(a * b, 1) + b @ x[i])
        assert fan.sum() * r2 == pytest.approx(ds.areaCell.values[i], rel=1e-11)


def test_neighbours_are_symmetric_and_sides_consistent(case):
    """cellsOnCell symmetric; side j of a cell: its edge, the cell across it (cellsOnEdge),
    and the vertex shared by edges j and j + 1 (verticesOnEdge)."""
    _, ds, _ = case
    sides = ds.nEdgesOnCell.values
    coc = _rows(ds, "cellsOnCell", sides)
    eoc = _rows(ds, "edgesOnCell", sides)
    voc = _rows(ds, "verticesOnCell", sides)
    coe, voe = ds.cellsOnEdge.values - 1, ds.verticesOnEdge.values - 1
    pairs = {(i, j) for i in range(len(coc)) for j in coc[i]}
    assert all((j, i) in pairs for i, j in pairs)
    for i in range(len(coc)):
        for j in range(sides[i]):
            e, nxt = eoc[i][j], eoc[i][(j + 1) % sides[i]]
            assert set(coe[e]) == {i, coc[i][j]}
            assert set(voe[e]) & set(voe[nxt]) == {voc[i][j]}


def test_vertices_edges_and_orientation_follow_mpas(case):
    """cellsOnVertex counter-clockwise; edgesOnVertex[j] joins cells j - 1 and j; each
    edge's tangent v1 -> v2 is its normal c1 -> c2 turned counter-clockwise."""
    _, ds, _ = case
    x, v = _unit(ds, "Cell"), _unit(ds, "Vertex")
    cov, eov = ds.cellsOnVertex.values - 1, ds.edgesOnVertex.values - 1
    coe, voe = ds.cellsOnEdge.values - 1, ds.verticesOnEdge.values - 1
    a, b, c = (x[cov[:, k]] for k in range(3))
    assert np.all(np.einsum("ij,ij->i", a, np.cross(b, c)) > 0)
    for j in range(3):
        ends = np.sort(coe[eov[:, j]], axis=1)
        assert np.array_equal(ends, np.sort(cov[:, [j - 1, j]], axis=1))
    normal = x[coe[:, 1]] - x[coe[:, 0]]
    tangent = v[voe[:, 1]] - v[voe[:, 0]]
    assert np.all(np.einsum("ij,ij->i", np.cross(normal, tangent), x[coe[:, 0]]) > 0)
    assert np.all(coe[:, 0] < coe[:, 1])


def test_arcs_equal_the_cores_faces_and_the_haversine(case):
    diagram, ds, _ = case
    r = diagram.domain.radius
    coe = ds.cellsOnEdge.values - 1
    n = diagram.n
    key = coe[:, 0].astype(np.int64) * n + coe[:, 1]
    pairs = diagram.neighbors[:, 0].astype(np.int64) * n + diagram.neighbors[:, 1]
    assert np.array_equal(key, pairs)  # no cocircular sites: one edge per face
    h = r * np.sqrt(4 * np.pi / n)
    assert np.abs(ds.dvEdge.values - diagram.face_measures).max() < 1e-11 * h

    def haversine(lat, lon, i, j):
        d = np.sin((lat[j] - lat[i]) / 2) ** 2
        d += np.cos(lat[i]) * np.cos(lat[j]) * np.sin((lon[j] - lon[i]) / 2) ** 2
        return 2 * r * np.arcsin(np.sqrt(d))

    dc = haversine(ds.latCell.values, ds.lonCell.values, coe[:, 0], coe[:, 1])
    assert np.abs(ds.dcEdge.values - dc).max() < 1e-9 * h
    voe = ds.verticesOnEdge.values - 1
    dv = haversine(ds.latVertex.values, ds.lonVertex.values, voe[:, 0], voe[:, 1])
    assert np.abs(ds.dvEdge.values - dv).max() < 1e-9 * h
    assert np.all((ds.lonCell.values >= 0) & (ds.lonCell.values < 2 * np.pi))


def test_angle_edge_is_the_normals_bearing(case):
    """angleEdge from east towards north = π/2 − the great-circle bearing (clockwise from
    north) from the edge point to cell 2, from latitudes and longitudes."""
    _, ds, _ = case
    lat, lon = ds.latEdge.values, ds.lonEdge.values
    c2 = ds.cellsOnEdge.values[:, 1] - 1
    lat2, lon2 = ds.latCell.values[c2], ds.lonCell.values[c2]
    dl = lon2 - lon
    bearing = np.arctan2(
        np.sin(dl) * np.cos(lat2),
        np.cos(lat) * np.sin(lat2) - np.sin(lat) * np.cos(lat2) * np.cos(dl),
    )
    diff = np.angle(np.exp(1j * (np.pi / 2 - bearing - ds.angleEdge.values)))
    assert np.abs(diff).max() < 1e-11
    assert np.all(np.abs(ds.angleEdge.values) <= np.pi)


def test_trisk_weights_are_antisymmetric(case):
    """Thuburn et al. (2009): w(e, e') dcEdge_e / dvEdge_e' = −w(e', e) dcEdge_e' / dvEdge_e,
    which holds when each cell's kites sum to its area (signed kites: also on the random
    sites' obtuse triangles, where MPAS-Tools' unsigned ones break it)."""
    _, ds, _ = case
    eoe, w = ds.edgesOnEdge.values - 1, ds.weightsOnEdge.values
    count = ds.nEdgesOnEdge.values
    dc, dv = ds.dcEdge.values, ds.dvEdge.values
    scaled = {}
    for e in range(len(eoe)):
        for k in range(count[e]):
            scaled[e, eoe[e, k]] = w[e, k] * dc[e] / dv[eoe[e, k]]
    assert len(scaled) == count.sum()  # an edge sharing two cells with e: not on a sphere
    worst = max(abs(s + scaled[f, e]) for (e, f), s in scaled.items())
    assert worst < 1e-10  # unsigned kites: O(0.1) on the random sites
    sides = ds.nEdgesOnCell.values[ds.cellsOnEdge.values - 1]
    assert np.array_equal(count, sides.sum(axis=1) - 2)


def test_icosahedral_cvt_has_exactly_twelve_pentagons(icosahedral):
    diagram, ds, _ = icosahedral
    sides = ds.nEdgesOnCell.values
    assert np.count_nonzero(sides == 5) == 12 and np.count_nonzero(sides != 6) == 12
    quality = hcvt.sphere_quality(diagram)
    summary = quality.summary()
    assert summary["sides"] == {"5": 12, "6": 2550} and summary["non_hexagonal"] == 12
    assert summary["obtuse_triangles"] == 0 and summary["zero_length_edges"] == 0
    assert np.array_equal(quality.grid_spacing, ds.gridSpacing.values)
    assert np.array_equal(quality.cell_quality, ds.cellQuality.values)
    # the regularity measure of the flat kinds counts the same cells (6 is ideal on S²)
    found = hcvt.defects(diagram)
    assert found.number == 12 and found.interior_cells == 2562
    assert np.array_equal(found.defective, sides != 6)


def test_quality_figures_from_the_file(random):
    """Shortest/longest dvEdge per cell, mean dcEdge per cell, triangle angles whose
    excess is the triangle's area (Girard), and spacing over a requested width."""
    diagram, ds, _ = random
    sides = ds.nEdgesOnCell.values
    eoc = _rows(ds, "edgesOnCell", sides)
    dv, dc = ds.dvEdge.values, ds.dcEdge.values
    mean = 0.15
    quality = hcvt.sphere_quality(diagram, width=lambda lat, lon: np.full_like(lat, mean))
    for i in range(diagram.n):
        assert quality.cell_quality[i] == pytest.approx(dv[eoc[i]].min() / dv[eoc[i]].max())
        assert quality.grid_spacing[i] == pytest.approx(dc[eoc[i]].mean(), rel=1e-14)
    excess = quality.triangle_angles.sum(axis=1) - np.pi
    assert np.abs(excess - ds.areaTriangle.values).max() < 1e-12
    assert np.array_equal(quality.obtuse, quality.triangle_angles.max(axis=1) > np.pi / 2)
    assert quality.spacing_ratio == pytest.approx(quality.grid_spacing / mean)
    assert quality.non_hexagonal == np.count_nonzero(sides != 6) > 0
    assert quality.obtuse.sum() > 0  # random sites: the signed kites are exercised
    with pytest.raises(ValueError, match="positive"):
        hcvt.sphere_quality(diagram, width=np.zeros(diagram.n))


def test_cells_and_pyvista_on_the_sphere(icosahedral):
    diagram, ds, _ = icosahedral
    cells = diagram.cells()
    assert [len(c) for c in cells] == list(ds.nEdgesOnCell.values)
    radius = np.linalg.norm(np.concatenate(cells), axis=1)
    assert np.allclose(radius, EARTH, rtol=1e-15, atol=0)
    with pytest.raises(NotImplementedError, match="spherical_mesh"):
        diagram.mesh()
    pytest.importorskip("pyvista")
    poly = diagram.to_pyvista()
    assert poly.n_cells == diagram.n and poly.n_points == ds.sizes["nVertices"]
    assert poly.cell_data["area"].sum() == pytest.approx(4 * np.pi * EARTH**2, rel=1e-13)


def _cube():
    corners = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)], float)
    return corners / np.sqrt(3)


def _lat_lon_grid(rows=6, columns=10):
    """Sites on parallels and meridians, and the poles: every grid quad is cocircular."""
    lat = np.linspace(-75, 75, rows)
    lon = np.arange(columns) * 360 / columns
    lat, lon = np.radians(np.meshgrid(lat, lon, indexing="ij"))
    points = np.stack(
        [np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=-1
    ).reshape(-1, 3)
    return np.concatenate([points, [[0, 0, 1], [0, 0, -1]]])


@pytest.mark.parametrize(("sites", "quads"), [(_cube(), 6), (_lat_lon_grid(), 50)])
def test_cocircular_sites_get_zero_length_edges(sites, quads, tmp_path):
    """A face of four cocircular sites is two triangles at one point joined by an edge of
    length 0 (the diagonal from its smallest site); the rest of the file stays valid."""
    unit = hcvt.Domain.sphere(1.0)
    diagram = hcvt.voronoi(unit, sites)
    mesh = diagram.spherical_mesh()
    assert mesh.zero_length_edges == quads
    assert mesh.n_cells - mesh.n_edges + mesh.n_vertices == 2
    path = tmp_path / "degenerate.nc"
    with pytest.warns(UserWarning, match=f"{quads} edge"):
        hcvt.write_mpas(diagram, path)
    ds = xr.open_dataset(path).load()
    assert np.count_nonzero(ds.dvEdge.values == 0) == quads
    coe = ds.cellsOnEdge.values - 1
    key = coe[:, 0].astype(np.int64) * diagram.n + coe[:, 1]
    faces = diagram.neighbors[:, 0].astype(np.int64) * diagram.n + diagram.neighbors[:, 1]
    kept = np.isin(key, faces)
    assert np.array_equal(key[kept], faces) and np.all(ds.dvEdge.values[~kept] == 0)
    assert np.abs(ds.dvEdge.values[kept] - diagram.face_measures).max() < 1e-12
    assert ds.areaTriangle.values.sum() == pytest.approx(4 * np.pi, rel=1e-13)
    per_cell = np.bincount(ds.cellsOnVertex.values.ravel() - 1, ds.kiteAreasOnVertex.values.ravel())
    assert np.abs(per_cell - diagram.volume).max() < 1e-12


def test_icosahedral_sites_have_no_cocircular_faces():
    """The subdivided icosahedron's sites are in general position: no zero-length edge."""
    unit = hcvt.Domain.sphere(1.0)
    for n in (12, 42, 162, 642, 2562):
        mesh = hcvt.voronoi(unit, hcvt.initialise(unit, n, method="icosahedral")).spherical_mesh()
        assert mesh.zero_length_edges == 0 and mesh.n_vertices == 2 * n - 4


def test_too_few_or_gathered_sites_are_refused():
    unit = hcvt.Domain.sphere(1.0)
    three = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    with pytest.raises(ValueError, match="at least three"):
        hcvt.voronoi(unit, three).spherical_mesh()
    north = np.array([[0.1, 0, 1], [-0.1, 0.05, 1], [0, -0.1, 1], [0.02, 0.02, 1]])
    north /= np.linalg.norm(north, axis=1)[:, None]
    with pytest.raises(ValueError, match="90°"):
        hcvt.voronoi(unit, north).spherical_mesh()
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    with pytest.raises(ValueError, match="Domain.sphere"):
        hcvt.write_mpas(hcvt.voronoi(square, [[0.2, 0.2], [0.7, 0.6]]), "never.nc")


def test_rotation_moves_the_mesh_with_it():
    """The mesh of rotated sites is the rotated mesh (same topology, same lengths)."""
    unit = hcvt.Domain.sphere(1.0)
    sites = hcvt.initialise(unit, 500, seed=3)
    q, _ = np.linalg.qr(np.random.default_rng(0).standard_normal((3, 3)))
    q *= np.sign(np.linalg.det(q))
    a = hcvt.voronoi(unit, sites).spherical_mesh()
    b = spherical_mesh(sites @ q.T, hcvt.voronoi(unit, sites).neighbors)
    for name in ("cells_on_edge", "vertices_on_edge", "cells_on_vertex", "cells_on_cell",
                 "vertices_on_cell", "edges_on_cell"):  # fmt: skip
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.allclose(a.vertices @ q.T, b.vertices, atol=1e-12, rtol=0)
    assert np.allclose(a.dv_edge, b.dv_edge, atol=1e-12, rtol=0)


def test_cli_writes_an_mpas_mesh(tmp_path):
    out = tmp_path / "mesh.nc"
    result = CliRunner().invoke(
        main, ["run", "sphere", "-n", "642", "--radius", "2", "--out", str(out)],
        catch_exceptions=False,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "12 with 5, 630 with 6" in result.output
    ds = xr.open_dataset(out)
    assert ds.sizes["nCells"] == 642 and ds.attrs["sphere_radius"] == 2.0
    assert ds.areaCell.values.sum() == pytest.approx(16 * np.pi, rel=1e-13)
    refused = CliRunner().invoke(main, ["run", "square", "-n", "50", "--out", str(out)])
    assert refused.exit_code == 2 and "sphere only" in refused.output


def _converter():
    return os.environ.get("HCVT_MPAS_CONVERTER") or shutil.which("MpasMeshConverter.x")


@pytest.mark.skipif(_converter() is None, reason="MPAS-Tools' MpasMeshConverter.x not found")
@pytest.mark.parametrize("name", CASES)
def test_mpas_tools_converter_agrees(name, request, tmp_path):
    """MpasMeshConverter.x rebuilds the mesh from xCell, xVertex and cellsOnVertex alone.

    Topology: the same edges, the same cyclic orders. Lengths and areas agree to its float
    precision (it takes single-precision sines in its arc lengths). On the random sites
    it computes unsigned kites, and orders cellsOnVertex by where the edge points lie:
    those differ on obtuse triangles only.
    """
    _, ours, path = request.getfixturevalue(name)
    out = tmp_path / "converted.nc"
    subprocess.run(
        [_converter(), str(path), str(out)], check=True, capture_output=True, cwd=tmp_path
    )
    theirs = xr.open_dataset(out).load()
    n = ours.sizes["nCells"]

    def key(ds):
        cells = ds.cellsOnEdge.values.astype(np.int64) - 1
        return cells[:, 0] * n + cells[:, 1]

    order = np.argsort(key(theirs))
    assert np.array_equal(key(ours), key(theirs)[order])
    assert np.array_equal(ours.verticesOnEdge.values, theirs.verticesOnEdge.values[order])
    scale = ours.dcEdge.values.mean()
    for field in ("dcEdge", "dvEdge"):
        assert np.abs(ours[field].values - theirs[field].values[order]).max() < 1e-6 * scale
    assert np.array_equal(ours.nEdgesOnCell.values, theirs.nEdgesOnCell.values)
    sides = ours.nEdgesOnCell.values
    for field in ("cellsOnCell", "verticesOnCell"):
        for i in range(n):
            a, b = ours[field].values[i, : sides[i]], theirs[field].values[i, : sides[i]]
            assert np.array_equal(np.roll(b, -int(np.flatnonzero(b == a[0])[0])), a), (field, i)
    obtuse = ours.obtuseTriangle.values.astype(bool)
    area = ours.areaTriangle.values.mean()
    assert (
        np.abs(ours.areaTriangle.values - theirs.areaTriangle.values)[~obtuse].max() < 1e-6 * area
    )
    cell = ours.areaCell.values
    assert np.abs(theirs.areaCell.values / cell - 1).max() < 1e-4
    if not obtuse.any():
        position = {e: k for k, e in enumerate(order)}
        eoe = theirs.edgesOnEdge.values[order]
        mapped = np.where(eoe > 0, np.vectorize(lambda e: position.get(e - 1, -1))(eoe) + 1, 0)
        assert np.array_equal(ours.edgesOnEdge.values, mapped)
        weights = theirs.weightsOnEdge.values[order]
        assert np.abs(ours.weightsOnEdge.values - weights).max() < 1e-6
