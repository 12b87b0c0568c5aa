"""Mesh quality (hcvt.mesh.quality) through the binding: one core pass, errors by name.

The definitions are tested against closed forms in crates/hcvt-core/src/quality.rs and
against checkMesh's printed figures in tests/test_export.py; here: the 2D dispatch on a
case worked by hand, ``face_quality``'s centres, malformed arrays, and bits that depend on
neither the thread count nor the order of the calls.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import hcvt
from hcvt.errors import InvalidMeshError
from hcvt.mesh.polymesh import PolyMesh
from hcvt.mesh.quality import cell_aspect_ratio, face_quality, mesh_quality
from helpers import DATA


def sheared_pair(shear: float) -> PolyMesh:
    """The unit square beside the parallelogram (1, 0), (2, shear), (2, 1 + shear), (1, 1)."""
    points = np.array([[0, 0], [1, 0], [2, shear], [0, 1], [1, 1], [2, 1 + shear]], float)
    edges = [[1, 4], [0, 1], [4, 3], [3, 0], [1, 2], [2, 5], [5, 4]]
    return PolyMesh(
        points,
        np.arange(0, 15, 2),
        np.array(edges).ravel(),
        owner=np.array([0, 0, 0, 0, 1, 1, 1]),
        neighbour=np.array([1, -1, -1, -1, -1, -1, -1]),
        boundary_element=np.array([-1, 0, 1, 2, 0, 3, 1]),
        n_cells=2,
    )


def test_a_sheared_2d_pair_has_the_figures_worked_by_hand():
    # d = C_N - C_P = (1, shear / 2) against S = (1, 0); s = (0, -shear / 4) over a face
    # that reaches 1/2 along y: non-orthogonality atan(shear / 2), skewness shear / 2.
    shear = 0.8
    mesh = sheared_pair(shear)
    q = mesh_quality(mesh)
    assert q.volume == pytest.approx([1.0, 1.0], rel=1e-15)
    assert q.non_orthogonality[0] == pytest.approx(math.degrees(math.atan(shear / 2)), 1e-12)
    assert q.skewness[0] == pytest.approx(shear / 2, rel=1e-12)
    assert np.isnan(q.non_orthogonality[1:]).all() and np.isnan(q.volume_ratio[1:]).all()
    assert q.volume_ratio[0] == pytest.approx(1.0)
    assert mesh.cell_geometry.centroid[1] == pytest.approx([1.5, 0.5 + shear / 2], rel=1e-15)
    assert cell_aspect_ratio(mesh) is q.aspect_ratio  # one pass serves both


def test_face_quality_measures_against_the_centres_given():
    mesh = sheared_pair(0.8)
    q = mesh_quality(mesh)
    own = face_quality(mesh, mesh.cell_geometry.centroid)
    expected_all = (q.non_orthogonality, q.skewness, q.inverted_pyramid)
    for got, expected in zip(own, expected_all, strict=True):
        assert np.array_equal(got, expected, equal_nan=got.dtype != bool)
    angle, skewness, _ = face_quality(mesh, [[0.5, 0.5], [1.5, 0.5]])  # as if unsheared
    assert angle[0] == 0.0 and skewness[0] == 0.0
    with pytest.raises(ValueError, match=r"centres must have shape \(2, 2\), got \(1, 2\)"):
        face_quality(mesh, [[0.5, 0.5]])


def test_malformed_arrays_are_refused_by_name():
    mesh = sheared_pair(0.5)
    vertices = mesh.face_vertices.copy()
    vertices[3] = 9
    with pytest.raises(InvalidMeshError, match=r"face 1: vertex 9 does not exist \(6 points\)"):
        mesh_quality(PolyMesh(**{**_fields(mesh), "face_vertices": vertices}))
    vertices[3] = -1
    with pytest.raises(InvalidMeshError, match=r"face_vertices\[3\] = -1 is not an index"):
        mesh_quality(PolyMesh(**{**_fields(mesh), "face_vertices": vertices}))
    owner = mesh.owner.copy()
    owner[2] = 5
    with pytest.raises(InvalidMeshError, match=r"face 2: owner 5 is not a cell \(2 cells\)"):
        mesh_quality(PolyMesh(**{**_fields(mesh), "owner": owner}))
    points = mesh.points.copy()
    points[4, 1] = np.inf
    with pytest.raises(InvalidMeshError, match="point 4 has a non-finite coordinate"):
        mesh_quality(PolyMesh(**{**_fields(mesh), "points": points}))


def _fields(mesh: PolyMesh) -> dict:
    return {
        "points": mesh.points,
        "face_offsets": mesh.face_offsets,
        "face_vertices": mesh.face_vertices,
        "owner": mesh.owner,
        "neighbour": mesh.neighbour,
        "boundary_element": mesh.boundary_element,
        "n_cells": mesh.n_cells,
    }


def test_the_bits_do_not_depend_on_the_thread_count():
    domain = hcvt.load_domain(DATA / "3d" / "cheese.off")
    diagram = hcvt.voronoi(domain, hcvt.initialise(domain, 400, method="random", seed=3))
    mesh = diagram.mesh()
    before = hcvt.get_num_threads()
    try:
        measured = []
        for n in (1, 2, 3):
            hcvt.set_num_threads(n)
            measured.append(mesh.measure())
    finally:
        hcvt.set_num_threads(before)
    for other in measured[1:]:
        for key, value in measured[0].items():
            assert value.tobytes() == other[key].tobytes(), key
    assert mesh.cell_geometry.volume.sum() == pytest.approx(domain.volume, rel=1e-13)
