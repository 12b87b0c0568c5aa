"""A partitioned diagram's cells as VTU pieces and a .pvtu index (hcvt.distributed.partition_mesh).

A LocalCluster of 2 worker *processes* (one thread each): every piece is made and written
by the worker holding its part. Each piece's faces, read back by VTK (pyvista), are those
of the single-process ``Diagram.mesh()``, vertex coordinates bit for bit.
"""

from __future__ import annotations

import os
from collections import Counter

import numpy as np
import pytest

import hcvt
from hcvt.distributed import partition as pt
from hcvt.distributed import partition_mesh as pm
from hcvt.distributed.driver import partitioned_voronoi
from hcvt.io.vtu import _split_for_vtk

distributed = pytest.importorskip("dask.distributed")
pv = pytest.importorskip("pyvista")

DATA = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data")
if not os.path.isdir(DATA):
    DATA = "/work/shared/data"


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


@pytest.fixture(scope="module")
def holes():
    """A polygon with a hole from ../shared/data, 1,200 random sites, the whole mesh."""
    domain = hcvt.load_domain(os.path.join(DATA, "2d", "triangle_square_circle_hole.geojson"))
    sites = hcvt.initialise(domain, n=1200, method="random", seed=3)
    return domain, sites, hcvt.voronoi(domain, sites)


@pytest.fixture(scope="module")
def bunny():
    """The Stanford bunny from ../shared/data, 500 random sites, the whole mesh."""
    domain = hcvt.load_domain(os.path.join(DATA, "3d", "bunny.off"))
    sites = hcvt.initialise(domain, n=500, method="random", seed=5)
    return domain, sites, hcvt.voronoi(domain, sites)


def _point(p) -> tuple[float, ...]:
    return tuple(float(x) for x in p)


def whole_faces(mesh: hcvt.PolyMesh) -> dict[int, Counter]:
    """Per cell: its faces, each the frozenset of its vertex coordinates, counted."""
    out: dict[int, Counter] = {}
    for k in range(mesh.n_faces):
        face = frozenset(_point(p) for p in mesh.points[mesh.face(k)])
        for cell in (mesh.owner[k], mesh.neighbour[k]):
            if cell >= 0:
                out.setdefault(int(cell), Counter())[face] += 1
    return out


def read_faces(grid, dim: int) -> dict[int, Counter]:
    """Per problem row: the faces of its cell in the file, as :func:`whole_faces`.

    3D: the polyhedron's faces. 2D: the edges of the cell's polygons that only one of
    them has (a cell with a hole is written as triangles: their inner edges cancel).
    """
    rows = grid.cell_data["row"].astype(np.int64)
    points = grid.points[:, :dim]
    out: dict[int, Counter] = {}
    for c in range(grid.n_cells):
        cell = grid.get_cell(c)
        faces = out.setdefault(int(rows[c]), Counter())
        if dim == 3:
            for face in cell.faces:
                faces[frozenset(_point(points[i]) for i in face.point_ids)] += 1
        else:
            ids = list(cell.point_ids)
            for a, b in zip(ids, ids[1:] + ids[:1], strict=True):
                faces[frozenset((_point(points[a]), _point(points[b])))] += 1
    if dim == 2:
        for row, faces in out.items():
            twice = [f for f, k in faces.items() if k > 1]
            inner = Counter({f: faces[f] for f in twice})
            out[row] = faces - inner
    return out


@pytest.mark.parametrize("per_part", [150, 400])
def test_pvtu_pieces_are_the_single_process_mesh_bit_for_bit(
    client, holes, bunny, per_part, tmp_path
):
    for name, (domain, sites, expected) in (("holes", holes), ("bunny", bunny)):
        parted = partitioned_voronoi(domain, sites, client, sites_per_partition=per_part)
        assert parted.parts >= 2
        index = parted.write_cells(tmp_path / f"{name}.pvtu")
        assert index == tmp_path / f"{name}.pvtu"
        pieces = sorted((tmp_path / name).glob("part*.vtu"))
        assert len(pieces) == parted.parts
        grid = pv.read(index)
        rows = grid.cell_data["row"].astype(np.int64)
        nonempty = np.flatnonzero(expected.volume > 0)
        if domain.dim == 3:
            # One polyhedron per cell, each in one piece.
            assert grid.n_cells == len(nonempty)
            assert np.array_equal(np.sort(rows), nonempty)
        else:
            # A cell with a hole or in pieces is several polygons, all of one piece.
            assert np.array_equal(np.unique(rows), nonempty)
        # The cell data: the problem's volume and G, bit for bit.
        assert np.array_equal(grid.cell_data["volume"], expected.volume[rows])
        assert np.array_equal(grid.cell_data["G"], expected.G[rows])
        # Every cell's faces and their vertices' coordinates: the whole mesh's, exactly, as
        # the VTU writer puts them (3D faces VTK triangulates wrongly as their triangles).
        got = read_faces(grid, domain.dim)
        whole = expected.mesh()
        want = whole_faces(_split_for_vtk(whole) if domain.dim == 3 else whole)
        assert got.keys() == {int(r) for r in nonempty}
        for row in got:
            assert got[row] == want[row], f"{name} cell {row}"
        # And each cell's volume from its faces (VTK's surface) matches the diagram's.
        if domain.dim == 3:
            volume = np.array(
                [
                    grid.extract_cells([c])
                    .extract_surface(algorithm="dataset_surface")
                    .triangulate()
                    .volume
                    for c in range(0, grid.n_cells, 7)
                ]
            )
            np.testing.assert_allclose(volume, expected.volume[rows[::7]], rtol=1e-9)
        print(
            f"{name}, {parted.parts} parts of <= {per_part}: halo sites per round "
            f"{parted.piece_rounds}; peak RSS MB {parted.peak_memory_mb()}"
        )


def test_a_piece_records_the_row_across_each_face(holes):
    """Without dask: part 1's piece; every face toward another part's cell names that
    cell's row, and the faces between two parts are the whole mesh's faces between them."""
    domain, sites, expected = holes
    parts = pt.make_parts(sites, pt.kd_split(sites, 300))
    part = parts[1]
    h = (domain.volume / len(sites)) ** 0.5
    lo, hi = part.box()
    lo, hi = lo - 3 * h, hi + 3 * h
    balls = [np.zeros(0, dtype=np.int64), np.zeros((0, 2)), np.zeros(0)]
    while True:
        others = [q for q in parts if q.index != part.index]
        slices = [pt.halo_slice(q, lo, hi) for q in others]
        slices += [pt.ball_slice(q, balls[1], balls[2]) for q in others]
        piece, status = pm.piece_mesh(
            domain, part, len(sites), False, lo, hi, balls[0], balls[2], *slices
        )
        if piece is not None:
            break
        assert status.balls is not None
        balls = [np.concatenate([a, b]) for a, b in zip(balls, status.balls, strict=True)]
    mesh = piece.mesh
    mesh.check()
    own = set(part.rows.tolist())
    cross = (mesh.neighbour < 0) & (piece.across >= 0)
    assert cross.any() and not np.isin(piece.across[cross], part.rows).any()
    inner = mesh.neighbour >= 0
    assert np.array_equal(piece.across[inner], part.rows[mesh.neighbour[inner]])
    whole = expected.mesh()
    pairs = {
        (min(int(o), int(n)), max(int(o), int(n)))
        for o, n in zip(whole.owner, whole.neighbour, strict=True)
        if n >= 0 and ((o in own) != (n in own))
    }
    got = {
        (min(int(r), int(a)), max(int(r), int(a)))
        for r, a in zip(part.rows[mesh.owner[cross]], piece.across[cross], strict=True)
    }
    assert got == pairs


def test_cli_run_with_a_scheduler_writes_pvtu_pieces(client, tmp_path):
    """``hcvt run --scheduler ADDRESS --cells out.pvtu``: pieces ``out/part*.vtu`` by the
    workers; read back, the cells' volumes are the single-process diagram's. Without
    ``--scheduler`` a .pvtu is refused."""
    from click.testing import CliRunner

    from hcvt.cli import main

    path = os.path.join(DATA, "2d", "star5.geojson")
    args = ["run", path, "-n", "600", "--method", "lloyd", "--max-iter", "1", "--seed", "2"]
    out = tmp_path / "out.pvtu"
    with_cells = CliRunner().invoke(
        main,
        [*args, "--scheduler", client.scheduler.address, "--sites-per-partition", "200"]
        + ["--cells", str(out), "--out", str(tmp_path / "sites.npy")],
    )
    assert with_cells.exit_code == 0, with_cells.output
    assert len(list((tmp_path / "out").glob("part*.vtu"))) >= 3
    domain = hcvt.load_domain(path)
    expected = hcvt.voronoi(domain, np.load(tmp_path / "sites.npy"))
    grid = pv.read(out)
    rows = grid.cell_data["row"].astype(np.int64)
    assert np.array_equal(np.unique(rows), np.arange(600))
    assert np.array_equal(grid.cell_data["volume"], expected.volume[rows])
    refused = CliRunner().invoke(main, [*args, "--cells", str(tmp_path / "x.pvtu")])
    assert refused.exit_code != 0 and "needs --scheduler" in refused.output
