"""3D domains: validation errors that name the defect, and repairs that say what changed."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import hcvt

BAD = Path(__file__).resolve().parents[2] / "shared" / "data" / "3d" / "bad"
needs_data = pytest.mark.skipif(not BAD.is_dir(), reason="../shared/data/3d/bad not found")

# The defect each bad file has (data README), as the error message names it.
DEFECTS = {
    "blobby-shuffled.off": "inconsistent winding",
    "bunny.ply": "non-manifold edges",
    "cow.obj": "pinched",
    "elephant-with-holes.off": "open boundary",
    "featuretype.ply": "duplicate vertices",
    "stanford-bunny.obj": "open boundary",
}
# What the repair report must mention for each.
REPAIRS = {
    "blobby-shuffled.off": "flipped",
    "bunny.ply": "non-manifold",
    "cow.obj": "pinched",
    "elephant-with-holes.off": "filled",
    "featuretype.ply": "merged",
    "stanford-bunny.obj": "filled 5 holes",
}

TETRA_V = np.array([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], dtype=float)
TETRA_F = np.array([(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])


@needs_data
@pytest.mark.parametrize("name", sorted(DEFECTS))
def test_bad_mesh_error_names_the_defect(name: str) -> None:
    with pytest.raises(hcvt.InvalidDomainError, match=DEFECTS[name]) as info:
        hcvt.load_domain(BAD / name)
    assert "repair=True" in str(info.value)
    assert "first" in str(info.value)


@needs_data
@pytest.mark.parametrize("name", sorted(DEFECTS))
def test_bad_mesh_repairs_and_gives_an_exact_diagram(name: str) -> None:
    domain = hcvt.load_domain(BAD / name, repair=True)
    report = domain.repair_report
    assert report is not None and report.changed
    assert REPAIRS[name] in str(report)
    assert np.isfinite(report.volume_after) and report.volume_after > 0
    assert abs(domain.volume - report.volume_after) <= 1e-9 * domain.volume
    rng = np.random.default_rng(1)
    lo, hi = domain.bounds
    sites = rng.uniform(lo, hi, size=(400, 3))
    d = hcvt.voronoi(domain, sites, allow_outside=True)
    assert np.isfinite(d.volume).all() and np.isfinite(d.centroid).all()
    assert abs(d.volume.sum() - domain.volume) <= 1e-12 * domain.volume


def test_good_tetrahedron_and_its_first_moment() -> None:
    domain = hcvt.Domain.from_mesh(TETRA_V, TETRA_F)
    assert abs(domain.volume - 1 / 6) < 1e-15
    np.testing.assert_allclose(domain.centroid, 0.25, atol=1e-15)
    assert domain.contains([[0.1, 0.1, 0.1], [1, 1, 1]]).tolist() == [True, False]
    np.testing.assert_allclose(
        domain.generalized_winding_numbers([[0.1, 0.1, 0.1], [1, 1, 1]]), [1, 0], atol=1e-12
    )


@pytest.mark.parametrize(
    ("vertices", "faces", "match"),
    [
        (np.where(TETRA_V == 1, np.nan, TETRA_V), TETRA_F, "NaN"),
        (TETRA_V, TETRA_F[:, ::-1], "inward orientation"),
        (TETRA_V, TETRA_F[:3], "open boundary: 3 edges"),
        (TETRA_V, np.vstack([TETRA_F, [[0, 1, 1]]]), "degenerate"),
        (TETRA_V, np.vstack([TETRA_F[:3], [[1, 3, 2]]]), "inconsistent winding"),
        (TETRA_V, np.vstack([TETRA_F[:3], [[1, 2, 7]]]), "missing vertices"),
        (TETRA_V * [1, 1, 0], TETRA_F, "degenerate"),
    ],
)
def test_synthetic_defects(vertices: np.ndarray, faces: np.ndarray, match: str) -> None:
    with pytest.raises(hcvt.InvalidDomainError, match=match):
        hcvt.Domain.from_mesh(vertices, faces)


def test_repair_flips_an_inside_out_mesh() -> None:
    domain = hcvt.Domain.from_mesh(TETRA_V, TETRA_F[:, ::-1], repair=True)
    assert abs(domain.volume - 1 / 6) < 1e-15
    assert "outward" in str(domain.repair_report)
    clean = hcvt.Domain.from_mesh(TETRA_V, TETRA_F, repair=True)
    assert clean.repair_report is not None and not clean.repair_report.changed


def test_flat_mesh_cannot_be_repaired() -> None:
    with pytest.raises(hcvt.InvalidDomainError):
        hcvt.Domain.from_mesh(TETRA_V * [1, 1, 0], TETRA_F, repair=True)


def test_stl_and_off_round_trip(tmp_path: Path) -> None:
    import trimesh

    mesh = trimesh.Trimesh(TETRA_V, TETRA_F, process=False)
    for suffix in (".stl", ".off", ".ply", ".obj"):
        path = tmp_path / f"tetra{suffix}"
        mesh.export(path)
        assert abs(hcvt.load_domain(path).volume - 1 / 6) < 1e-12, suffix


@needs_data
def test_generalized_winding_number_agrees_with_the_exact_one() -> None:
    domain = hcvt.load_domain(BAD.parent / "bunny.off")
    points = np.random.default_rng(4).uniform(*domain.bounds, size=(3000, 3))
    exact = domain.contains(points)
    gwn = domain.generalized_winding_numbers(points)
    assert ((gwn > 0.5) == exact).mean() > 0.999
    np.testing.assert_allclose(gwn[exact], 1.0, atol=0.05)
    np.testing.assert_allclose(gwn[~exact], 0.0, atol=0.05)


def test_crossing_surfaces_are_reported() -> None:
    v = np.vstack([TETRA_V, TETRA_V + 0.2])
    f = np.vstack([TETRA_F, TETRA_F + 4])
    with pytest.raises(hcvt.InvalidDomainError, match="self-intersection: .* cross"):
        hcvt.Domain.from_mesh(v, f)
    domain = hcvt.Domain.from_mesh(v, f, repair=True)
    assert "united 2 shells" in str(domain.repair_report)
    # The union: both tetrahedra less their overlap, a tetrahedron of legs 0.4.
    assert abs(domain.volume - (2 / 6 - 0.4**3 / 6)) < 1e-15
