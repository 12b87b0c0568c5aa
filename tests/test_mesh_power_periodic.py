"""Conforming meshes of power diagrams and of periodic boxes (issue 34).

References: each cell's volume and centroid recomputed from the mesh's faces (OpenFOAM's
decomposition, :attr:`PolyMesh.cell_geometry`) against the diagram's exact moments (signed
cones from the sites, another computation); a periodic face against its twin, translated
by whole periods.
"""

from __future__ import annotations

from pathlib import Path

import meshio
import numpy as np
import pytest

import hcvt

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def _power(domain: hcvt.Domain, n: int, spread: float, seed: int) -> hcvt.Diagram:
    """Random sites in ``domain`` with random weights of ``spread`` squared spacings."""
    rng = np.random.default_rng(seed)
    sites = hcvt.initialise(domain, n, seed=seed)
    spacing2 = (domain.volume / n) ** (2 / domain.dim)
    return hcvt.voronoi(domain, sites, weights=rng.uniform(0, spread, n) * spacing2)


def _agrees(diagram: hcvt.Diagram, centroids: bool = True) -> hcvt.PolyMesh:
    """The mesh, its cells' volumes (and centroids) checked against the diagram's.

    Centroids only where every face is convex: OpenFOAM's face centre (which the mesh's
    geometry follows) is not the centroid of a non-convex face (a bisector piece cut by
    a non-convex solid; tests/quality.rs).
    """
    mesh = diagram.mesh()
    mesh.check()
    geometry = mesh.cell_geometry
    scale = diagram.domain.volume / diagram.n
    assert np.max(np.abs(geometry.volume - diagram.volume)) < 1e-12 * scale
    if not centroids:
        return mesh
    full = diagram.volume > 0
    size = scale ** (1 / diagram.domain.dim)
    error = np.abs(geometry.centroid[full] - diagram.centroid[full])
    assert np.max(error) < 1e-10 * size
    return mesh


@pytest.mark.parametrize(
    "domain",
    [
        hcvt.Domain.box([0, 0], [2, 1]),
        hcvt.Domain.box([0, 0, 0], [1, 2, 1]),
        hcvt.load_domain(DATA / "2d" / "triangle_square_circle_hole.geojson"),
    ],
    ids=["box2", "box3", "holed-polygon"],
)
def test_power_cells_from_faces_equal_the_diagrams(domain):
    # Weights up to 3 squared spacings: a third of the cells or so empty.
    diagram = _power(domain, 400, 3.0, seed=1)
    empty = diagram.volume == 0
    assert 50 < empty.sum() < 250
    mesh = _agrees(diagram)
    faces_per_cell = np.diff(mesh.cell_faces.offsets)
    assert np.array_equal(faces_per_cell == 0, empty)
    compact, kept = mesh.compacted()
    assert compact.n_cells == (~empty).sum() and np.array_equal(kept, np.flatnonzero(~empty))


def test_power_mesh_of_the_bunny():
    domain = hcvt.load_domain(DATA / "3d" / "bunny.off")
    diagram = _power(domain, 500, 1.0, seed=2)
    assert (diagram.volume == 0).any()
    mesh = _agrees(diagram, centroids=False)
    assert abs(mesh.cell_geometry.volume.sum() - domain.volume) < 1e-12 * domain.volume


@pytest.mark.parametrize("dim", [2, 3])
def test_zero_weights_are_the_voronoi_mesh_bit_for_bit(dim):
    domain = hcvt.Domain.box([0] * dim, [1] * dim)
    sites = hcvt.initialise(domain, 200, seed=3)
    a = hcvt.voronoi(domain, sites).mesh()
    b = hcvt.voronoi(domain, sites, weights=np.zeros(200)).mesh()
    for name in ("points", "face_offsets", "face_vertices", "owner", "neighbour"):
        assert np.array_equal(getattr(a, name), getattr(b, name))


@pytest.mark.parametrize(
    ("periodic", "hi"),
    [
        ((True, True, True), [2.0, 1.0, 1.0]),
        ((True, True, False), [1.0, 1.0, 1.0]),
        ((False, True, False), [1.0, 1.0, 1.0]),
        ((True, True), [1.0, 2.0]),
        ((True, False), [1.0, 1.0]),
    ],
)
@pytest.mark.parametrize("power", [False, True])
def test_periodic_mesh_pairs_its_faces(periodic, hi, power):
    domain = hcvt.Domain.box([0.0] * len(hi), hi, periodic=periodic)
    diagram = (
        _power(domain, 300, 1.0, seed=4)
        if power
        else hcvt.voronoi(domain, hcvt.initialise(domain, 300, seed=4))
    )
    mesh = _agrees(diagram)
    # Each cell's centroid is the diagram's, unwrapped around its wrapped site.
    partner, image = mesh.periodic_partner, mesh.periodic_image
    assert partner is not None and image is not None
    twin = np.flatnonzero(partner >= 0)
    assert len(twin) > 0 and np.array_equal(partner[partner[twin]], twin)
    assert np.array_equal(image[partner[twin]], -image[twin])
    period = np.where(periodic, np.asarray(hi), 0.0)
    faces = mesh.face_geometry
    moved = faces.centre[twin] - image[twin] * period
    assert np.max(np.abs(faces.centre[partner[twin]] - moved)) < 1e-12
    assert np.max(np.abs(faces.area_vector[partner[twin]] + faces.area_vector[twin])) < 1e-12
    # Twins have as many vertices, each at its twin's vertex translated (OpenFOAM's match).
    assert np.array_equal(mesh.face_sizes[twin], mesh.face_sizes[partner[twin]])
    for f in twin[:200].tolist():
        mine = mesh.points[mesh.face(f)] - image[f] * period
        theirs = mesh.points[mesh.face(int(partner[f]))]
        gap = np.linalg.norm(mine[:, None, :] - theirs[None, :, :], axis=2).min(axis=1)
        assert gap.max() < 1e-12
    # The other boundary faces lie on the sides of the non-periodic axes.
    wall = (mesh.neighbour < 0) & (partner < 0)
    fixed = ~np.asarray(periodic)
    assert wall.any() == fixed.any()
    centre = faces.centre[wall][:, fixed]
    if fixed.any():
        gaps = np.minimum(np.abs(centre), np.abs(centre - np.asarray(hi)[fixed]))
        assert np.all(gaps.min(axis=1) < 1e-12)
    assert abs(mesh.cell_geometry.volume.sum() - np.prod(hi)) < 1e-12 * np.prod(hi)


def test_periodic_vtu_holds_the_unwrapped_cells(tmp_path):
    domain = hcvt.Domain.box([0, 0, 0], [1, 1, 1], periodic=True)
    diagram = _power(domain, 200, 1.0, seed=5)
    path = hcvt.write_mesh(diagram, tmp_path / "cells.vtu")
    read = meshio.read(path)
    kept = diagram.volume > 0
    assert sum(len(block.data) for block in read.cells) == kept.sum()
    # Cells stick out of the box (unwrapped), and sum to its volume.
    assert read.points.min() < 0 and read.points.max() > 1
    import pyvista

    grid = pyvista.read(path)
    assert grid.n_cells == kept.sum()
    # VTK's polyhedron volumes are approximate (3.6e-5 off in all here): a loose check
    # that the cells were read whole.
    volumes = grid.compute_cell_sizes(length=False, area=False)["Volume"]
    assert abs(volumes.sum() - 1.0) < 1e-3


def test_periodic_power_mesh_does_not_depend_on_threads():
    domain = hcvt.Domain.box([0, 0, 0], [1, 1, 1], periodic=(True, False, True))
    meshes = []
    before = hcvt.get_num_threads()
    try:
        for threads in (1, 3):
            hcvt.set_num_threads(threads)
            meshes.append(_power(domain, 300, 1.0, seed=7).mesh())
    finally:
        hcvt.set_num_threads(before)
    a, b = meshes
    for name in ("points", "face_vertices", "owner", "neighbour", "periodic_partner"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert a.points.tobytes() == b.points.tobytes()
