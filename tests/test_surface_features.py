"""Sharp features kept in remeshing (issue 33): ``hcvt.remesh(features=angle)``.

Checked against what is known another way: a box's twelve edges and eight corners; on the
fandisk, the Hausdorff distance with features against the same remeshing without them,
each detected corner found among the output's vertices, the segments between consecutive
sites of a curve found among the triangles' edges (by edge counts, not by the module's own
check).
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

import hcvt
from hcvt.surface.features import (
    FeatureSites,
    detect_features,
    long_curves,
    move_intruders,
    plan_feature_sites,
    release_sites,
    restore_segments,
    site_spacing,
    weld_sites,
)
from hcvt.surface.quality import edge_topology
from helpers import DATA

DATA_3D = DATA / "3d"
needs_data = pytest.mark.skipif(not DATA_3D.is_dir(), reason="../shared/data/3d not found")


@cache
def fandisk() -> hcvt.Domain:
    return hcvt.load_domain(DATA_3D / "fandisk.off", surface=True)


def box_surface() -> hcvt.Domain:
    import trimesh

    # Subdivided twice: a regular mesh, the evenly spaced feature sites' cells meeting
    # exactly on its edges and vertices (the core's triangulation finds each meeting once).
    box = trimesh.creation.box(extents=(2.0, 1.0, 1.0)).subdivide().subdivide()
    return hcvt.Domain.from_surface(box.vertices, box.faces)


def test_a_box_has_twelve_edges_between_eight_corners() -> None:
    domain = box_surface()
    features = detect_features(domain.vertices, domain.faces, 40.0)
    corners = domain.vertices[features.corners]
    assert np.array_equal(np.sort(np.abs(corners), axis=0), np.tile([1.0, 0.5, 0.5], (8, 1)))
    assert len(features.curves) == 12 and not any(closed for _, closed in features.curves)
    lengths = sorted(
        float(np.linalg.norm(domain.vertices[chain[-1]] - domain.vertices[chain[0]]))
        for chain, _ in features.curves
    )
    assert lengths == [1.0] * 8 + [2.0] * 4
    assert len(features.edges) == 48  # four mesh edges per box edge, no face diagonal
    # Curves shorter than 1.5 dropped: the four long edges and their eight corners stay.
    long = long_curves(features, domain.vertices, 1.5)
    assert len(long.curves) == 4 and len(long.edges) == 16
    assert np.array_equal(long.corners, features.corners)
    assert len(long_curves(features, domain.vertices, 2.5).corners) == 0
    # Edges of 90°: none above 95°.
    assert len(detect_features(domain.vertices, domain.faces, 95.0).edges) == 0


def test_the_box_remeshed_keeps_its_edges() -> None:
    domain = box_surface()
    n = 400
    plan = plan_feature_sites(domain, n, 40.0)
    out = hcvt.remesh(domain, n, seed=2, features=40.0)
    assert out.vertices.shape == (n, 3) and out.defects == []
    # Flat faces, straight edges: the remeshed box is the box (to round-off).
    assert out.quality.hausdorff is not None and out.quality.hausdorff < 1e-9
    held = out.vertices[n - len(plan.points) :]
    assert np.array_equal(held, plan.points)


@needs_data
def test_features_bring_the_fandisk_closer() -> None:
    domain = fandisk()
    n = 1500
    # The features' own effect: without the tightening moves on either side.
    plain = hcvt.remesh(domain, n, seed=1, tighten=False, density=None)  # uniform, as sharp
    sharp = hcvt.remesh(domain, n, seed=1, features=40.0, tighten=False)
    assert sharp.vertices.shape == (n, 3) and sharp.defects == []
    topology = edge_topology(sharp.faces, n)
    assert topology["manifold"] and topology["closed"] and topology["genus"] == 0
    # Measured 1.16% without, 0.53% with (2.2 times closer).
    assert plain.quality.hausdorff is not None and sharp.quality.hausdorff is not None
    assert sharp.quality.hausdorff * 1.8 < plain.quality.hausdorff
    assert sharp.quality.q_min > 0.4 and sharp.quality.angle_min > 18
    # Every corner is a vertex of the output.
    features = detect_features(domain.vertices, domain.faces, 40.0)
    corners = domain.vertices[features.corners]
    gaps = np.linalg.norm(corners[:, None, :] - sharp.vertices[None, :, :], axis=2).min(axis=1)
    assert len(corners) >= 20 and gaps.max() == 0.0
    # Consecutive sites of a curve are joined: segments as long as the spacing, each an
    # edge of two triangles.
    plan = plan_feature_sites(domain, n, 40.0)
    first = n - len(plan.points)
    edges = np.sort(np.concatenate([sharp.faces[:, [0, 1]], sharp.faces[:, [1, 2]]]), axis=1)
    edges = np.concatenate([edges, np.sort(sharp.faces[:, [2, 0]], axis=1)])
    pairs, counts = np.unique(edges, axis=0, return_counts=True)
    found = {tuple(p): c for p, c in zip(pairs.tolist(), counts.tolist(), strict=True)}
    wanted = np.sort(plan.segments + first, axis=1).tolist()
    assert all(found.get(tuple(s)) == 2 for s in wanted)
    lengths = np.linalg.norm(sharp.vertices[wanted][:, 0] - sharp.vertices[wanted][:, 1], axis=1)
    assert np.median(lengths) < site_spacing(domain.volume, n)


def test_a_segment_crossed_by_one_diagonal_is_flipped_in() -> None:
    # Free sites c (0) below and d (1) above the segment a (2) - b (3) on the x axis; the
    # triangles (a, c, d) and (d, c, b) join c-d across it.
    vertices = np.array([[1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [0.0, 0.0, 0.0], [2.0, 0.0, 0.0]])
    plan = FeatureSites(vertices[2:], np.array([[0, 1]]))
    faces = restore_segments(np.array([[2, 0, 1], [1, 0, 3]]), vertices, plan)
    assert faces.tolist() == [[2, 0, 3], [2, 3, 1]]
    # A non-convex quadrilateral (d below the segment, both triangles still counter-
    # clockwise) is left alone: the flip would fold (a, b, d) over.
    vertices[1] = [1.5, -0.2, 0.0]
    kept = np.array([[2, 0, 1], [1, 0, 3]])
    assert restore_segments(kept, vertices, plan).tolist() == kept.tolist()


def test_a_free_site_on_a_segment_moves_to_the_widest_gap() -> None:
    # Free sites 0-5, held sites a (6) and b (7) of one segment, the free site 0 on it
    # between them (1 above, 2 below also touch both ends, farther from it): the segment
    # is missing. The one triangle of free sites, (3, 4, 5), is the widest gap.
    vertices = np.array(
        [
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [1.0, -1.0, 0.0],
            [5.0, 0.0, 0.0],
            [9.0, 0.0, 0.0],
            [7.0, 6.0, 0.0],
            [0.0, 0.0, 0.0],
            [2.0, 0.0, 0.0],
        ]
    )
    plan = FeatureSites(vertices[6:], np.array([[0, 1]]))
    faces = np.array([[6, 0, 1], [0, 7, 1], [6, 2, 0], [0, 2, 7], [3, 4, 5]])
    moved = move_intruders(vertices, faces, plan)
    assert moved is not None
    assert np.array_equal(moved[0], [7.0, 2.0, 0.0])
    assert np.array_equal(moved[1:], vertices[1:])
    # With the segment an edge, nothing moves.
    assert move_intruders(vertices, np.array([[6, 7, 1], [3, 4, 5]]), plan) is None


def test_close_held_sites_weld_unless_their_curves_part_at_an_angle() -> None:
    # A corner (0) and two curves leaving it along x: sites 1-3 at y = 0 and 4-6 at
    # y = 0.05 (side by side), then a curve 7-9 leaving at 30° (its sites 0.25-0.5 from
    # the first curve's).
    c30, s30 = np.cos(np.radians(30.0)), np.sin(np.radians(30.0))
    points = np.array(
        [[0.0, 0.0, 0.0]]
        + [[x, 0.0, 0.0] for x in (1.0, 2.0, 3.0)]
        + [[x, 0.05, 0.0] for x in (1.0, 2.0, 3.0)]
        + [[x * c30, x * s30, 0.0] for x in (1.0, 2.0, 3.0)]
    )
    segments = np.array([[0, 1], [1, 2], [2, 3], [0, 4], [4, 5], [5, 6], [0, 7], [7, 8], [8, 9]])
    welded = weld_sites(FeatureSites(points, segments), 0.6)
    # The side-by-side curve merges into the first; the one at 30° stays, though its
    # first site is 0.5 from the first curve's.
    assert np.array_equal(welded.points, points[[0, 1, 2, 3, 7, 8, 9]])
    assert welded.segments.tolist() == [[0, 1], [1, 2], [2, 3], [0, 4], [4, 5], [5, 6]]
    # A site nearly on a segment of another curve, welded onto a kept one, would close a
    # flat triangle of segments (0-2 beside 0-1-2): its longest side is dropped.
    flat = FeatureSites(
        np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 0.1, 0.0]]),
        np.array([[0, 1], [1, 2], [0, 3], [3, 2]]),
    )
    assert weld_sites(flat, 0.3).segments.tolist() == [[0, 1], [1, 2]]
    assert weld_sites(flat, 0.05) == flat  # nothing that close


def test_released_sites_leave_the_plan_with_their_segments() -> None:
    plan = FeatureSites(np.arange(15.0).reshape(5, 3), np.array([[0, 1], [1, 2], [2, 3], [3, 4]]))
    freed = release_sites(plan, np.array([2]))
    assert np.array_equal(freed.points, plan.points[[0, 1, 3, 4]])
    assert freed.segments.tolist() == [[0, 1], [2, 3]]


@needs_data
def test_the_bunny_with_its_creases_is_sound() -> None:
    # 600 vertices, creases above 30° (MeshLab's default): 50 curves, 164 held sites
    # (187 before welding). Before welding and freeing (c5e6c55): 5 triples of cells that
    # are not discs, genus -2, 152 iterations; also at 1,000, 5,000 and 20,000.
    domain = hcvt.load_domain(DATA_3D / "bunny.off", surface=True)
    out = hcvt.remesh(domain, 600, seed=0, features=30.0)
    assert out.defects == [] and 0 < out.freed < 20
    assert out.quality.closed and out.quality.genus == 0


def test_a_free_site_beyond_a_held_corner_stays_off_it() -> None:
    # A free site out beyond the held corner (1, 0.5, 0.5) of the box: projected, it
    # would land on the corner's site or on another free site's projection.
    domain = box_surface()
    corner = np.array([[1.0, 0.5, 0.5]])
    free = hcvt.initialise(domain, 40, seed=3)
    sites = np.vstack([free, corner + 0.5, corner])
    held = np.zeros(len(sites), dtype=bool)
    held[-1] = True
    run = hcvt.cvt(domain, sites, "lbfgs", max_iter=2, fixed=held)
    assert np.array_equal(run.sites[-1], corner[0])
    assert len(np.unique(run.sites, axis=0)) == len(sites)
    assert abs(run.diagram.volume.sum() - domain.volume) < 1e-12 * domain.volume


def test_features_that_take_every_site_are_refused() -> None:
    with pytest.raises(ValueError, match="take .* sites"):
        hcvt.remesh(box_surface(), 30, features=40.0)


def test_command_line_keeps_the_features(tmp_path) -> None:
    from click.testing import CliRunner

    from hcvt.cli import main

    trimesh = pytest.importorskip("trimesh")
    pytest.importorskip("meshio")
    box = box_surface()
    source, out = tmp_path / "box.off", tmp_path / "box.ply"
    trimesh.Trimesh(box.vertices, box.faces, process=False).export(source)
    args = ["run", str(source), "--surface", "-n", "300", "--features", "40"]
    result = CliRunner().invoke(main, [*args, "--out", str(out)], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    # Read back by trimesh: 300 vertices, the box's eight corners among them.
    mesh = trimesh.load(out, process=False)
    assert mesh.vertices.shape == (300, 3) and mesh.is_watertight
    assert np.sum(np.all(np.abs(mesh.vertices) == [1.0, 0.5, 0.5], axis=1)) == 8
    refused = CliRunner().invoke(main, ["run", "square", "-n", "10", "--features", "40"])
    assert refused.exit_code == 2 and "--features keeps sharp edges" in refused.output
