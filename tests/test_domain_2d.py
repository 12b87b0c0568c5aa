"""2D domains: every accepted input form, validation messages, repair, bad files."""

from __future__ import annotations

import json

import numpy as np
import pytest
import shapely
from shapely.geometry import MultiPolygon, Polygon, box

import hcvt
from helpers import BAD_POLYGON_FILES, DATA, POLYGON_FILES, random_inside

OUTER = [(0, 0), (4, 0), (4, 4), (0, 4)]
HOLE = [(1, 1), (1, 2), (2, 2), (2, 1)]


def test_every_input_form_gives_the_same_domain(tmp_path):
    polygon = shapely.Polygon(OUTER, [HOLE])
    (tmp_path / "d.wkt").write_text(polygon.wkt)
    (tmp_path / "d.geojson").write_text(json.dumps(shapely.geometry.mapping(polygon)))
    domains = [
        hcvt.Domain.from_polygon(polygon),
        hcvt.Domain.from_polygon(OUTER, holes=[HOLE]),
        hcvt.Domain.from_polygon((np.array(OUTER), [np.array(HOLE)])),
        hcvt.Domain.from_polygon(shapely.MultiPolygon([polygon])),
        hcvt.load_domain(tmp_path / "d.wkt"),
        hcvt.load_domain(tmp_path / "d.geojson"),
    ]
    for d in domains:
        assert d.dim == 2 and d.volume == 15.0
        np.testing.assert_allclose(d.centroid, polygon.centroid.coords[0], rtol=1e-15)


def test_orientation_of_the_input_does_not_matter():
    clockwise = hcvt.Domain.from_polygon(OUTER[::-1], holes=[HOLE[::-1]])
    assert clockwise.volume == 15.0
    assert clockwise.contains([[0.5, 0.5], [1.5, 1.5], [5, 5]]).tolist() == [True, False, False]


@pytest.mark.parametrize("path", [pytest.param(p, id=p.stem) for p in POLYGON_FILES])
def test_real_polygons_load_with_the_documented_area(path):
    properties = {p["file"]: p for p in json.loads((DATA / "2d" / "properties.json").read_text())}
    domain = hcvt.load_domain(path)
    assert domain.volume == pytest.approx(properties[path.name]["area"], rel=1e-12)
    inside = random_inside(domain, 200, seed=0)
    assert shapely.contains_xy(domain.geometry, inside[:, 0], inside[:, 1]).all()


@pytest.mark.parametrize(
    ("polygon", "match"),
    [
        ([(0, 0), (1, 1), (1, 0), (0, 1)], r"Self-intersection\[0.5 0.5\]"),
        ([(0, 0), (1, 0), (2, 0)], "zero area"),
        ([(0, 0), (1, 0)], "distinct vertices"),
        ([(0, 0), (1, np.nan), (1, 1)], "non-finite coordinate at vertex 1"),
        ([(0, 0), (1, 0), (np.inf, 1)], "non-finite coordinate at vertex 2"),
        ([(0, 0), (1, 0), (1, 1), (1, 0)], r"Self-intersection\[1 1\]"),
    ],
)
def test_invalid_polygons_raise_naming_the_problem(polygon, match):
    with pytest.raises(hcvt.InvalidDomainError, match=match):
        hcvt.Domain.from_polygon(polygon)


def test_a_bad_hole_is_named():
    with pytest.raises(hcvt.InvalidDomainError, match="hole 1 .*non-finite"):
        hcvt.Domain.from_polygon(OUTER, holes=[HOLE, [(3, 3), (3.5, np.nan), (3.5, 3.5)]])


EXPECTED_BAD = {
    # file: (error message without repair or None if accepted, area after repair)
    "bad_bowtie": (r"Self-intersection\[0.5 0.5\]", 0.5),
    "bad_hole_shares_outer_edge": (r"Self-intersection\[0 3\]", 12.0),
    "bad_spike_zero_width": (r"Self-intersection\[3 1\]", 4.0),
    "bad_duplicate_consecutive_vertices": (None, 3.0),
    "bad_hole_touches_outer_at_vertex": (None, 14.0),
}


@pytest.mark.parametrize("path", [pytest.param(p, id=p.stem) for p in BAD_POLYGON_FILES])
def test_bad_polygon_files_give_the_documented_error_or_repair(path):
    error, repaired_area = EXPECTED_BAD[path.stem]
    if error is None:
        domain = hcvt.load_domain(path)
    else:
        with pytest.raises(hcvt.InvalidDomainError, match=error + ".*repair=True"):
            hcvt.load_domain(path)
        domain = hcvt.load_domain(path, repair=True)
        assert domain.repair_report.changed
        assert "made valid" in str(domain.repair_report)
    assert domain.volume == pytest.approx(repaired_area, rel=1e-14)
    diagram = hcvt.voronoi(domain, random_inside(domain, 500, seed=1))
    assert abs(diagram.volume.sum() - domain.volume) <= 1e-12 * domain.volume


def test_unreadable_files_are_refused(tmp_path):
    (tmp_path / "x.geojson").write_text('{"type": "Point", "coordinates": [0, 0]}')
    with pytest.raises(hcvt.InvalidDomainError, match="no Polygon"):
        hcvt.load_domain(tmp_path / "x.geojson")
    (tmp_path / "y.wkt").write_text("POLYGON ((0 0, 1 0")
    with pytest.raises(hcvt.InvalidDomainError, match="cannot read"):
        hcvt.load_domain(tmp_path / "y.wkt")
    (tmp_path / "z.txt").write_text("")
    with pytest.raises(hcvt.InvalidDomainError, match="unknown file type"):
        hcvt.load_domain(tmp_path / "z.txt")
    with pytest.raises(FileNotFoundError):
        hcvt.load_domain(tmp_path / "missing.wkt")


@pytest.mark.parametrize(
    ("geometry", "match", "area"),
    [
        (
            MultiPolygon([box(0, 0, 2, 2), box(1, 1, 3, 3)]),
            r"parts 0 and 1 overlap: the winding number is 2 on an area of 1 around \(1\.5, 1\.5\)",
            7.0,
        ),
        (
            MultiPolygon([box(0, 0, 4, 4), box(1, 1, 2, 2)]),
            r"parts 0 and 1 overlap: the winding number is 2 on an area of 1",
            16.0,
        ),
        (
            Polygon(
                [(0, 0), (2, 0), (2, 2), (0, 2)],
                [box(0.5, 0.5, 1.5, 1.5).exterior.coords, box(0.7, 0.7, 1.2, 1.2).exterior.coords],
            ),
            r"hole 0 and hole 1 overlap: the winding number is -1 on an area of 0\.25",
            None,
        ),
    ],
)
def test_overlapping_rings_are_named_or_repaired(geometry, match: str, area) -> None:
    with pytest.raises(hcvt.InvalidDomainError, match=match):
        hcvt.Domain.from_polygon(geometry)
    repaired = hcvt.Domain.from_polygon(geometry, repair=True)
    assert "made valid" in str(repaired.repair_report)
    if area is not None:
        assert repaired.volume == area
    # The repaired domain's exact winding number is 0 or 1 everywhere.
    points = np.random.default_rng(0).uniform(-1, 5, size=(2000, 2))
    winding, _ = repaired.winding_numbers(points)
    assert set(winding.tolist()) <= {0, 1}
