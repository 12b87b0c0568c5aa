"""Periodic boxes (``hcvt.Domain.box(..., periodic=...)``, DESIGN §14): lattice cells in
closed form, random cells against the central cells of a tiled non-periodic diagram,
symmetric neighbours with their image shifts, wrapping, CVTs on the torus."""

from __future__ import annotations

import itertools
import pickle

import numpy as np
import pytest

import hcvt

G_HEXAGON = 5.0 / (36.0 * np.sqrt(3.0))
G_TRUNCATED_OCTAHEDRON = 19.0 / (192.0 * 2.0 ** (1.0 / 3.0))
G_RHOMBIC_DODECAHEDRON = 2.0 ** (-11.0 / 3.0)


def faces(d: hcvt.Diagram) -> dict[tuple[int, int, tuple[int, ...]], float]:
    """Every face as ``(i, j, image) -> measure``."""
    images = d.neighbor_images
    assert images is not None and images.dtype == np.int8
    owner = np.repeat(np.arange(d.n), np.diff(d.neighbor_offsets))
    return {
        (int(i), int(j), tuple(int(x) for x in k)): float(m)
        for i, j, k, m in zip(owner, d.neighbor_sites, images, d.neighbor_measures, strict=True)
    }


def assert_symmetric(d: hcvt.Diagram, atol: float) -> None:
    """Each face ``i -> (j, k)`` has its twin ``j -> (i, -k)`` of the same measure."""
    all_faces = faces(d)
    for (i, j, k), m in all_faces.items():
        twin = all_faces.get((j, i, tuple(-x for x in k)))
        assert twin is not None, f"face {i} -> {j} {k} has no twin"
        assert abs(twin - m) <= atol, (i, j, k, m, twin)


def bcc(m: int) -> np.ndarray:
    corners = np.array(list(itertools.product(range(m), repeat=3)), dtype=float)
    return np.concatenate([corners, corners + 0.5])


def test_a_bcc_lattice_gives_truncated_octahedra():
    m = 3
    torus = hcvt.Domain.box([0, 0, 0], [m, m, m], periodic=True)
    d = hcvt.voronoi(torus, bcc(m))
    assert d.n == 2 * m**3
    np.testing.assert_allclose(d.volume, 0.5, rtol=0, atol=1e-14)
    np.testing.assert_allclose(d.G, G_TRUNCATED_OCTAHEDRON, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(np.diff(d.neighbor_offsets), 14)
    measures = np.sort(d.neighbor_measures.reshape(-1, 14), axis=1)
    np.testing.assert_allclose(measures[:, :6], 1 / 8, rtol=0, atol=1e-14)
    np.testing.assert_allclose(measures[:, 6:], 3 * np.sqrt(3) / 16, rtol=0, atol=1e-14)
    assert abs(d.volume.sum() - m**3) < 1e-13 * m**3
    np.testing.assert_allclose(d.centroid, d.sites, rtol=0, atol=1e-14)
    assert_symmetric(d, 1e-14)


def test_an_fcc_lattice_gives_rhombic_dodecahedra():
    corners = np.array(list(itertools.product(range(2), repeat=3)), dtype=float)
    offsets = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    sites = (corners[:, None, :] + offsets[None, :, :]).reshape(-1, 3)
    d = hcvt.voronoi(hcvt.Domain.box([0, 0, 0], [2, 2, 2], periodic=True), sites)
    np.testing.assert_allclose(d.volume, 0.25, rtol=0, atol=1e-14)
    np.testing.assert_allclose(d.G, G_RHOMBIC_DODECAHEDRON, rtol=0, atol=1e-14)
    # Six cells meet at each octahedral hole: other faces there are round-off slivers.
    rhombus = 1 / (4 * np.sqrt(2))
    big = d.neighbor_measures > 1e-12
    np.testing.assert_allclose(d.neighbor_measures[big], rhombus, rtol=0, atol=1e-14)
    owner = np.repeat(np.arange(d.n), np.diff(d.neighbor_offsets))
    np.testing.assert_array_equal(np.bincount(owner[big], minlength=d.n), 12)


def test_a_hexagonal_lattice_gives_regular_hexagons():
    m = 5
    i, j = np.meshgrid(np.arange(m), np.arange(2 * m))
    sites = np.column_stack([(i + 0.5 * (j % 2)).ravel(), (j * np.sqrt(3) / 2).ravel()])
    torus = hcvt.Domain.box([0, 0], [m, m * np.sqrt(3)], periodic=True)
    d = hcvt.voronoi(torus, sites)
    np.testing.assert_allclose(d.volume, np.sqrt(3) / 2, rtol=1e-14)
    np.testing.assert_allclose(d.G, G_HEXAGON, rtol=0, atol=1e-14)
    np.testing.assert_array_equal(np.diff(d.neighbor_offsets), 6)
    np.testing.assert_allclose(d.neighbor_measures, 1 / np.sqrt(3), rtol=1e-14)
    assert_symmetric(d, 1e-14)


def tiled(sites: np.ndarray, periods: np.ndarray, axes: tuple[bool, ...]):
    """The sites and their images, shift by shift, and the shift of each block."""
    shifts = [
        k
        for k in itertools.product((-1, 0, 1), repeat=len(axes))
        if all(x == 0 or a for x, a in zip(k, axes, strict=True))
    ]
    points = np.concatenate([sites + np.array(k) * periods for k in shifts])
    return points, shifts


@pytest.mark.parametrize(
    ("lo", "hi", "axes", "tiling"),
    [
        ([0, 0], [1.5, 1], (True, True), "polygon"),
        ([-2, 3], [1, 4], (True, False), "polygon"),
        ([0, 0, 0], [1, 2, 1], (True, True, True), "box"),
        ([0, 0, 0], [1, 1, 1], (False, True, True), "box"),
    ],
)
def test_random_cells_are_the_central_cells_of_the_tiled_diagram(lo, hi, axes, tiling):
    lo, hi = np.array(lo, float), np.array(hi, float)
    dim, n = len(lo), 300
    sites = np.random.default_rng(dim).uniform(lo, hi, size=(n, dim))
    d = hcvt.voronoi(hcvt.Domain.box(lo, hi, periodic=axes), sites)
    periods = hi - lo
    points, shifts = tiled(sites, periods, axes)
    big_lo = lo - np.where(axes, periods, 0)
    big_hi = hi + np.where(axes, periods, 0)
    if tiling == "polygon":  # an independent path: signed cones of a polygon
        corners = [(big_lo[0], big_lo[1]), (big_hi[0], big_lo[1]), big_hi, (big_lo[0], big_hi[1])]
        big = hcvt.Domain.from_polygon(corners)
    else:
        big = hcvt.Domain.box(big_lo, big_hi)
    t = hcvt.voronoi(big, points)
    centre = shifts.index((0,) * dim)
    rows = slice(centre * n, (centre + 1) * n)
    h = (np.prod(periods) / n) ** (1 / dim)
    np.testing.assert_allclose(d.volume, t.volume[rows], rtol=1e-12)
    np.testing.assert_allclose(d.centroid, t.centroid[rows], rtol=0, atol=1e-12 * h)
    np.testing.assert_allclose(d.second_moment, t.second_moment[rows], rtol=1e-11)
    np.testing.assert_allclose(d.boundary_measure, t.boundary_measure[rows], atol=1e-12)
    # Faces: the tiled neighbour j is site j % n in image shifts[j // n].
    floor = 1e-12 * h ** (dim - 1)
    got = {key: m for key, m in faces(d).items() if m > floor}
    expected = {}
    for i in range(n):
        js, ms = t.cell_neighbors(centre * n + i)
        for j, m in zip(js, ms, strict=True):
            if m > floor:
                expected[(i, int(j) % n, shifts[int(j) // n])] = float(m)
    assert got.keys() == expected.keys()
    for key, m in got.items():
        assert abs(m - expected[key]) < floor, key
    assert abs(d.volume.sum() - np.prod(periods)) < 1e-13 * np.prod(periods)
    assert_symmetric(d, floor)


def test_sites_wrap_along_periodic_axes_and_are_refused_outside_the_others():
    box = hcvt.Domain.box([0, 0], [1, 1], periodic=(True, False))
    sites = np.random.default_rng(3).random((50, 2))
    moved = sites + np.array([[3.0, 0.0]])
    a, b = hcvt.voronoi(box, sites), hcvt.voronoi(box, moved)
    np.testing.assert_allclose(a.volume, b.volume, rtol=1e-13)
    # Centroids stay next to the sites as given.
    np.testing.assert_allclose(b.centroid - moved, a.centroid - sites, atol=1e-13)
    np.testing.assert_allclose(box.wrap(moved), sites, atol=1e-15)
    assert box.wrap([[1.0, 0.5], [-0.25, 7.0]]).tolist() == [[0.0, 0.5], [0.75, 7.0]]
    outside = sites.copy()
    outside[7, 1] = 1.5
    with pytest.raises(hcvt.InvalidSitesError, match="site 7"):
        hcvt.voronoi(box, outside)
    # Two sites at one point of the torus: x = 0 and x = 1.
    twins = sites.copy()
    twins[[4, 9]] = [[0.0, 0.5], [1.0, 0.5]]
    with pytest.raises(hcvt.InvalidSitesError, match="sites 4 and 9 coincide"):
        hcvt.voronoi(box, twins)


def test_a_box_without_periodic_axes_is_the_square_polygon():
    sites = np.random.default_rng(5).random((200, 2)) * [2, 1]
    a = hcvt.voronoi(hcvt.Domain.box([0, 0], [2, 1]), sites)
    b = hcvt.voronoi(hcvt.Domain.from_polygon([(0, 0), (2, 0), (2, 1), (0, 1)]), sites)
    assert a.neighbor_images is None
    np.testing.assert_allclose(a.volume, b.volume, rtol=1e-12)
    np.testing.assert_array_equal(a.neighbor_sites, b.neighbor_sites)
    np.testing.assert_allclose(a.boundary_measure, b.boundary_measure, atol=1e-13)


def test_a_box_far_from_the_origin_works_in_its_frame():
    lo = np.array([1e6, -3e6])
    torus = hcvt.Domain.box(lo, lo + [2.0, 1.0], periodic=True)
    assert not torus.frame.is_identity
    sites = lo + np.random.default_rng(6).random((100, 2)) * [2, 1]
    d = hcvt.voronoi(torus, sites)
    assert abs(d.volume.sum() - 2.0) < 1e-12
    assert_symmetric(d, 1e-12)


def test_a_bcc_lattice_is_a_fixed_point_of_lloyd_and_lbfgs_on_the_torus():
    torus = hcvt.Domain.box([0, 0, 0], [2, 2, 2], periodic=True)
    sites = torus.wrap(bcc(2) + 0.37)  # sites across every side
    for method in ("lloyd", "lbfgs"):
        out = hcvt.cvt(torus, sites, method, tol=0.0, max_iter=4)
        moved = np.abs((out.sites - sites + 1) % 2 - 1).max()
        assert moved < 1e-13, (method, moved)
        assert abs(out.diagram.mean_G - G_TRUNCATED_OCTAHEDRON) < 1e-13


@pytest.mark.parametrize("method", ["lbfgs", "lloyd"])
def test_random_sites_converge_on_the_torus_and_come_back_wrapped(method):
    lo, hi = np.array([-1.0, 0.0]), np.array([0.5, 1.0])
    torus = hcvt.Domain.box(lo, hi, periodic=True)
    sites = np.random.default_rng(8).uniform(lo, hi, size=(150, 2))
    out = hcvt.cvt(torus, sites, method, max_iter=5000)
    assert out.converged
    assert out.history["rms_gap"][-1] < out.tol
    assert (out.history["pinned"] == 0).all()
    assert ((out.sites >= lo) & (out.sites < hi)).all()
    # Sites crossed the sides on the way: they were not held in.
    assert (np.abs(out.sites - sites) > 0.5).any()
    assert out.diagram.mean_G < 0.081
    assert out.diagram.neighbor_images is not None


def test_what_a_periodic_box_does_not_take_yet_is_refused():
    torus = hcvt.Domain.box([0, 0], [1, 1], periodic=True)
    sites = np.random.default_rng(9).random((20, 2))
    with pytest.raises(ValueError, match="Newton"):
        hcvt.cvt(torus, sites, "newton")
    with pytest.raises(hcvt.InvalidDensityError, match="periodic"):
        hcvt.voronoi(torus, sites, density=lambda p: 1 + p[:, 0])
    with pytest.raises(hcvt.InvalidDomainError, match="bools"):
        hcvt.Domain.box([0, 0], [1, 1], periodic=(True, False, True))
    with pytest.raises(hcvt.InvalidDomainError):
        hcvt.Domain.box([0, 0], [1, 0])


def test_a_periodic_box_pickles():
    torus = hcvt.Domain.box([0, 0, 0], [1, 2, 1], periodic=(True, False, True))
    again = pickle.loads(pickle.dumps(torus))
    assert again.periodic == (True, False, True)
    sites = np.random.default_rng(10).random((60, 3)) * [1, 2, 1]
    a, b = hcvt.voronoi(torus, sites), hcvt.voronoi(again, sites)
    np.testing.assert_array_equal(a.volume, b.volume)
    np.testing.assert_array_equal(a.neighbor_images, b.neighbor_images)
