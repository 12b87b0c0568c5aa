"""GeoPandas in and out (issue 31): CRS kept, row i the cell of site i, GeoPackage round trip.

Staten Island (``../shared/data/2d/nybb_staten_island_main.geojson``) is in NAD83 / New
York Long Island State Plane, US feet (EPSG:2263, coordinates near 1e6), as its
``notes`` say; the file itself declares no CRS, so GDAL reads it as WGS 84 and the tests
declare the real one, as a user would.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import shapely

import hcvt
from hcvt.errors import InvalidDomainError
from helpers import DATA

gpd = pytest.importorskip("geopandas")

ISLAND = DATA / "2d" / "nybb_staten_island_main.geojson"
STATE_PLANE = "EPSG:2263"


@pytest.fixture(scope="module")
def island() -> gpd.GeoDataFrame:
    return gpd.read_file(ISLAND).set_crs(STATE_PLANE, allow_override=True)


@pytest.fixture(scope="module")
def diagram(island: gpd.GeoDataFrame) -> hcvt.Diagram:
    domain = hcvt.load_domain(island)
    return hcvt.voronoi(domain, hcvt.initialise(domain, 2000, seed=0))


def test_geodataframe_row_i_is_the_cell_of_site_i(island, diagram) -> None:
    cells = diagram.to_geopandas()
    assert cells.crs == island.crs
    assert list(cells.index) == list(range(diagram.n))
    assert cells.index.name == "site"
    # Every site lies in its own row's cell, and in no other row's.
    inside = shapely.contains(cells.geometry.values, shapely.points(diagram.sites))
    assert inside.all(), np.flatnonzero(~inside)[:5]
    tree = shapely.STRtree(cells.geometry.values)
    site_of, cell_of = tree.query(shapely.points(diagram.sites), predicate="within")
    assert np.array_equal(site_of, cell_of)
    area = island.geometry.iloc[0].area
    assert abs(cells.area.sum() - area) <= 1e-12 * area, cells.area.sum() - area
    assert abs(cells["volume"].sum() - area) <= 1e-12 * area
    np.testing.assert_allclose(cells.area, cells["volume"], rtol=1e-9)
    np.testing.assert_array_equal(cells["G"], diagram.G)
    np.testing.assert_array_equal(cells[["site_x", "site_y"]].to_numpy(), diagram.sites)
    np.testing.assert_array_equal(cells[["centroid_x", "centroid_y"]], diagram.centroid)
    assert cells["neighbors"].sum() == 2 * len(diagram.neighbors)
    assert "mass" not in cells  # no density


def test_geopackage_round_trip(tmp_path, island, diagram) -> None:
    path = hcvt.write_cells(diagram, tmp_path / "cells.gpkg")
    back = gpd.read_file(path)
    assert back.crs == island.crs
    assert list(back["site"]) == list(range(diagram.n))
    assert (back.geom_type == "MultiPolygon").all()
    mine = diagram.to_geopandas().geometry.values
    # The same cells, coordinate for coordinate (GeoPackage stores them as MultiPolygons).
    assert shapely.equals(back.geometry.values, mine).all()
    for a, b in zip(back.geometry.values, mine, strict=True):
        np.testing.assert_array_equal(shapely.get_coordinates(a), shapely.get_coordinates(b))
    np.testing.assert_array_equal(back["G"], diagram.G)
    # And read back as a domain, CRS and all: the island again.
    again = hcvt.load_domain(path)
    assert again.crs == island.crs
    assert again.volume == pytest.approx(diagram.domain.volume, rel=1e-9)
    one = hcvt.load_domain(path, feature=7)
    assert one.volume == pytest.approx(diagram.volume[7], rel=1e-12)
    two = hcvt.load_domain(path, query="site in (3, 4)")
    assert two.volume == pytest.approx(diagram.volume[[3, 4]].sum(), rel=1e-9)


def test_geojson_cells_carry_the_crs(tmp_path, island, diagram) -> None:
    path = hcvt.write_cells(diagram, tmp_path / "cells.geojson")
    assert gpd.read_file(path).crs == island.crs
    assert hcvt.load_domain(path, feature=0).crs == island.crs
    mesh = hcvt.write_mesh(diagram, tmp_path / "mesh.geojson")  # on shared vertices
    back = gpd.read_file(mesh)
    assert back.crs == island.crs
    assert back.area.sum() == pytest.approx(diagram.domain.volume, rel=1e-12)


def test_formats_geopandas_writes(tmp_path, island) -> None:
    for name, driver in [("island.gpkg", "GPKG"), ("island.shp", "ESRI Shapefile")]:
        island.to_file(tmp_path / name, driver=driver)
        domain = hcvt.load_domain(tmp_path / name)
        assert domain.crs == island.crs, name
        assert domain.volume == pytest.approx(island.area.iloc[0], rel=1e-12)
    island.to_file(tmp_path / "island.geojson")  # GDAL writes the crs member
    plain = hcvt.load_domain(tmp_path / "island.geojson")
    assert plain.crs == island.crs


def test_series_and_feature_choice(tmp_path, island) -> None:
    assert hcvt.load_domain(island.geometry).crs == island.crs
    assert hcvt.load_domain(island, query="name == 'nybb_staten_island_main'").crs is not None
    with pytest.raises(InvalidDomainError, match="kept none of 1 features"):
        hcvt.load_domain(island, query="name == 'Bronx'")
    with pytest.raises(InvalidDomainError, match="no feature 1; there are 1"):
        hcvt.load_domain(island, feature=1)
    (tmp_path / "island.txt").write_text(ISLAND.read_text())
    with pytest.raises(InvalidDomainError, match=r"unknown file type '\.txt'.*\.gpkg"):
        hcvt.load_domain(tmp_path / "island.txt")
    with pytest.raises(ValueError, match="for polygon data only"):
        hcvt.load_domain(DATA / "3d" / "bunny.off", crs=STATE_PLANE)


def test_geographic_crs_is_refused(island) -> None:
    # As GDAL reads the file: WGS 84, while the numbers are feet.
    with pytest.raises(InvalidDomainError, match="geographic.*project it first.*not degrees"):
        hcvt.load_domain(gpd.read_file(ISLAND))
    lonlat = island.to_crs("EPSG:4326")
    with pytest.raises(InvalidDomainError, match=r"EPSG:4326 \(WGS 84\) is geographic") as err:
        hcvt.load_domain(lonlat)
    assert "not degrees" not in str(err.value)
    # Projected as the message says, it is accepted, in metres now.
    utm = hcvt.load_domain(lonlat.to_crs(lonlat.estimate_utm_crs()))
    assert utm.crs.axis_info[0].unit_name == "metre"
    assert utm.volume == pytest.approx(island.area.iloc[0] * 0.3048006096**2, rel=1e-3)
    with pytest.raises(InvalidDomainError, match="geographic"):
        hcvt.Domain.from_polygon([(0, 0), (1, 0), (0, 1)], crs=4326)
    with pytest.raises(InvalidDomainError, match="not a coordinate reference system"):
        hcvt.Domain.from_polygon([(0, 0), (1, 0), (0, 1)], crs="EPSG:nonsense")


def test_crs_survives_pickling(diagram) -> None:
    domain = pickle.loads(pickle.dumps(diagram.domain))
    assert domain.crs == diagram.domain.crs
    assert repr(domain).endswith("crs=EPSG:2263>")


def test_no_crs_and_3d(tmp_path) -> None:
    square = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])
    cells = hcvt.voronoi(square, [[0.25, 0.5], [0.75, 0.5]]).to_geopandas()
    assert cells.crs is None
    assert list(cells["volume"]) == [0.5, 0.5]
    v = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
    f = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    solid = hcvt.voronoi(hcvt.Domain.from_mesh(v, f), [[0.1, 0.1, 0.1]])
    with pytest.raises(ValueError, match="GeoDataFrame holds 2D cells"):
        solid.to_geopandas()
