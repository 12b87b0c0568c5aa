"""A region of the sphere bounded by lon/lat polygons (issue 35's should: a regional ocean).

Oracles, each independent of the core's closed forms: the region's area by Gauss–Bonnet
(``2π − Σ turning angles`` of its geodesic polygon), its perimeter from ``arccos`` of its
vertices, each cell rebuilt by shapely in the gnomonic projection about the region's
centre (great circles are straight lines there: the region ∩ the half-planes of every
bisector) and measured by a Gauss quadrature of the projection's Jacobian.
"""

from __future__ import annotations

import json
import math
import pickle
from pathlib import Path

import numpy as np
import pytest
from shapely.geometry import Polygon, box, mapping, shape

import hcvt
from hcvt.errors import InvalidSitesError
from hcvt.geometry.sphere_region import lonlat_to_unit

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "2d"

#: A rough outline of the Mediterranean Sea (lon, lat in degrees), typed from well-known
#: coasts: Gibraltar, the Gulf of Lion, the Ligurian and Tyrrhenian Seas (around Italy's
#: boot, whose heel makes the outline non-convex), the Adriatic, Greece, Turkey, the
#: Levant, Egypt, Libya's Gulf of Sidra, Tunisia and Algeria.
MEDITERRANEAN = np.array([
    (-5.6, 36.0), (-2.0, 36.7), (0.5, 38.8), (0.0, 39.9), (3.0, 41.8), (3.2, 43.3),
    (6.0, 43.1), (8.8, 44.4), (10.3, 43.5), (12.3, 41.7), (15.6, 40.0), (15.7, 38.2),
    (16.6, 38.4), (17.2, 39.0), (18.5, 40.1), (16.0, 41.4), (12.3, 44.4), (13.6, 45.7),
    (14.5, 45.2), (19.4, 41.8), (19.4, 40.3), (21.1, 38.3), (22.4, 36.4), (23.2, 38.1),
    (22.9, 40.5), (26.0, 40.8), (26.2, 39.4), (27.3, 37.0), (28.3, 36.7), (30.6, 36.8),
    (32.9, 36.1), (36.0, 36.8), (35.8, 34.9), (34.9, 32.8), (34.2, 31.3), (32.3, 31.3),
    (29.9, 31.2), (25.2, 31.6), (20.1, 32.2), (19.0, 30.3), (15.5, 31.6), (13.0, 32.9),
    (11.1, 33.3), (10.3, 36.9), (8.6, 36.9), (3.0, 36.8), (-1.0, 35.5), (-5.3, 35.9),
])  # fmt: skip


def south_africa() -> Polygon:
    """Natural Earth's South Africa in lon/lat: a region with a hole (Lesotho)."""
    data = json.loads((DATA / "naturalearth_south_africa.geojson").read_text())
    return shape(data["features"][0]["geometry"])


def gauss_bonnet_area(lonlat: np.ndarray) -> float:
    """Area of the unit sphere's simple geodesic polygon ``lonlat`` (counter-clockwise
    seen from outside): ``2π − Σ`` its turning angles (Gauss–Bonnet; Girard for a triangle)."""
    v = lonlat_to_unit(lonlat)
    m = len(v)
    turning = 0.0
    for k in range(m):
        p, q, r = v[k - 1], v[k], v[(k + 1) % m]
        t_in = -(p - (p @ q) * q)  # direction of travel arriving at q (from p)
        t_out = r - (r @ q) * q  # leaving q towards r
        t_in, t_out = t_in / np.linalg.norm(t_in), t_out / np.linalg.norm(t_out)
        turning += math.atan2(float(np.cross(t_in, t_out) @ q), float(t_in @ t_out))
    return 2 * math.pi - turning


def ccw(lonlat: np.ndarray) -> np.ndarray:
    """The ring counter-clockwise in lon/lat (so seen from outside, away from the poles)."""
    return lonlat if Polygon(lonlat).exterior.is_ccw else lonlat[::-1]


def perimeter(lonlat: np.ndarray) -> float:
    v = lonlat_to_unit(lonlat)
    return float(sum(math.acos(np.clip(v[k] @ v[(k + 1) % len(v)], -1, 1)) for k in range(len(v))))


class Gnomonic:
    """The gnomonic projection about unit ``c``: ``x ↦ (x·e1, x·e2) / x·c``."""

    def __init__(self, c: np.ndarray) -> None:
        helper = np.eye(3)[int(np.argmin(np.abs(c)))]
        self.c = c
        self.e1 = np.cross(c, helper) / np.linalg.norm(np.cross(c, helper))
        self.e2 = np.cross(c, self.e1)

    def forward(self, x: np.ndarray) -> np.ndarray:
        h = x @ self.c
        return np.column_stack((x @ self.e1 / h, x @ self.e2 / h))

    def half_plane(self, n: np.ndarray, far: float) -> Polygon:
        """The image of the hemisphere ``n·x ≤ 0`` (within ``far`` of the origin)."""
        # n·(u e1 + v e2 + c) ≤ 0: a u + b v ≤ -d.
        a, b, d = n @ self.e1, n @ self.e2, n @ self.c
        g = np.hypot(a, b)
        normal, offset = np.array([a, b]) / g, -d / g
        foot = normal * offset
        along = np.array([-normal[1], normal[0]])
        corners = [foot + far * along, foot - far * along]
        corners += [corners[1] - 2 * far * normal, corners[0] - 2 * far * normal]
        return Polygon(corners)


#: 24-point Gauss–Legendre nodes and weights on [0, 1].
_X, _W = np.polynomial.legendre.leggauss(24)
_X, _W = 0.5 * (_X + 1), 0.5 * _W


def quadrature(piece: Polygon, g: Gnomonic) -> tuple[float, np.ndarray]:
    """Area and ``∫x dA`` of the spherical image of a planar (gnomonic) polygon: signed
    fans of its rings from their first vertex, each triangle by the collapsed-square
    Gauss rule of 24 × 24 points on ``dA = (1 + u² + v²)^(-3/2) du dv``."""
    area, first = 0.0, np.zeros(3)
    parts = getattr(piece, "geoms", [piece])
    for part in parts:
        for k, ring in enumerate([part.exterior, *part.interiors]):
            pts = np.asarray(ring.coords)[:-1]
            if ring.is_ccw != (k == 0):  # the outline counter-clockwise, holes clockwise
                pts = pts[::-1]
            p0 = pts[0]
            for k in range(1, len(pts) - 1):
                e1, e2 = pts[k] - p0, pts[k + 1] - p0
                det = e1[0] * e2[1] - e1[1] * e2[0]
                s, t = np.meshgrid(_X, _X, indexing="ij")
                w = np.outer(_W, _W) * (1 - s)  # Duffy's collapse of the square
                uv = p0 + s[..., None] * e1 + (t * (1 - s))[..., None] * e2
                r2 = 1 + uv[..., 0] ** 2 + uv[..., 1] ** 2
                jac = r2**-1.5 * w * det
                x = (uv[..., 0, None] * g.e1 + uv[..., 1, None] * g.e2 + g.c) / np.sqrt(r2)[
                    ..., None
                ]
                area += float(jac.sum())
                first += (jac[..., None] * x).sum(axis=(0, 1))
    return area, first


def reference_cells(domain: hcvt.Domain, sites: np.ndarray) -> tuple[list, Gnomonic]:
    """Each cell in the gnomonic projection about the region's centre, by shapely: the
    region cut by the half-planes of every bisector; and the projection."""
    core = domain._core
    g = Gnomonic(np.asarray(core.centre))
    rings = [g.forward(np.asarray(r)) for r in core.rings]
    region = Polygon(rings[0], rings[1:])
    far = 10 * float(np.max(np.abs(rings[0])))
    unit = sites / np.linalg.norm(sites, axis=1)[:, None]
    out = []
    for i, z in enumerate(unit):
        cell = region
        for j in range(len(unit)):
            if j != i:
                cell = cell.intersection(g.half_plane(unit[j] - z, far))
        assert cell.area > 0, i
        out.append(cell)
    return out, g


def shared_arc(a: Polygon, b: Polygon, g: Gnomonic) -> float:
    """The length on the unit sphere of the boundary two plane cells share: ``a``'s within
    1e-12 of ``b`` (their edges agree to round-off, not bitwise)."""
    shared = a.boundary.intersection(b.buffer(1e-12))
    total = 0.0
    for line in getattr(shared, "geoms", [shared]):
        if line.geom_type != "LineString":  # a point where cells touch
            continue
        p = np.asarray(line.coords)
        x = p[:, :1] * g.e1 + p[:, 1:2] * g.e2 + g.c
        x /= np.linalg.norm(x, axis=1)[:, None]
        for u, v in zip(x[:-1], x[1:], strict=True):
            total += math.atan2(np.linalg.norm(np.cross(u, v)), float(u @ v))
    return total


def test_the_area_is_gauss_bonnets_and_the_perimeter_the_arcs() -> None:
    sea = hcvt.Domain.sphere(1.0, region=MEDITERRANEAN)
    want = gauss_bonnet_area(ccw(MEDITERRANEAN))
    assert abs(sea.volume - want) < 1e-12 * want  # Gauss–Bonnet cancels 2π − Σ
    assert abs(sea._core.perimeter - perimeter(MEDITERRANEAN)) < 1e-13
    # Either orientation, any radius; a shapely Polygon with a hole (Lesotho).
    earth = hcvt.Domain.sphere(6371.0, region=MEDITERRANEAN[::-1])
    assert abs(earth.volume - want * 6371.0**2) < 1e-12 * earth.volume
    sa = south_africa()
    outer, hole = np.asarray(sa.exterior.coords)[:-1], np.asarray(sa.interiors[0].coords)[:-1]
    land = hcvt.Domain.sphere(1.0, region=sa)
    want = gauss_bonnet_area(ccw(outer)) - gauss_bonnet_area(ccw(hole))
    assert abs(land.volume - want) < 1e-12 * want
    assert land.is_sphere_region and not hcvt.Domain.sphere().is_sphere_region
    again = pickle.loads(pickle.dumps(land))
    assert again.volume == land.volume


@pytest.mark.parametrize("which", ["mediterranean", "south_africa"])
def test_cells_tile_the_region_and_match_a_quadrature(which: str) -> None:
    region = MEDITERRANEAN if which == "mediterranean" else south_africa()
    domain = hcvt.Domain.sphere(1.0, region=region)
    sites = hcvt.initialise(domain, 150, seed=3)
    assert len(sites) == 150 and domain.contains(sites).all()
    diagram = hcvt.voronoi(domain, sites)
    assert abs(diagram.volume.sum() - domain.volume) < 1e-12 * domain.volume
    # Every cell on the region's boundary reports its length of it: they sum to the perimeter.
    length = domain._core.perimeter
    assert abs(diagram.boundary_measure.sum() - length) < 1e-12 * length
    assert (diagram.boundary_measure > 0).sum() < 150
    cells, g = reference_cells(domain, sites)
    for i, cell in enumerate(cells):
        area, first = quadrature(cell, g)
        assert abs(diagram.volume[i] - area) < 1e-10 * area, i
        want = first / np.linalg.norm(first)
        assert np.linalg.norm(diagram.centroid[i] - want) < 1e-10 * math.sqrt(area), i
    # Neighbours are the pairs whose reference cells share an arc, of the same length
    # (not pairs whose bisector meets only outside the region: across a peninsula).
    arcs = dict(zip(map(tuple, diagram.neighbors.tolist()), diagram.face_measures, strict=True))
    for (i, j), arc in arcs.items():
        assert abs(shared_arc(cells[i], cells[j], g) - arc) < 1e-10, (i, j)
    touching = {
        (i, j)
        for i in range(150)
        for j in range(i + 1, 150)
        if cells[i].distance(cells[j]) < 1e-12 and shared_arc(cells[i], cells[j], g) > 1e-10
    }
    assert touching == set(arcs)


def test_a_cvt_converges_inside_the_region() -> None:
    earth = 6371.0
    domain = hcvt.Domain.sphere(earth, region=MEDITERRANEAN)
    sites = hcvt.initialise(domain, 300, seed=1)
    result = hcvt.cvt(domain, sites, max_iter=3000)
    assert result.converged, result.stop_reason
    assert result.history["rms_gap"][-1] < 1e-7
    assert result.history["energy"][-1] < result.history["energy"][0]
    assert domain.contains(result.sites).all()
    r = np.linalg.norm(result.sites, axis=1)
    assert np.max(np.abs(r - earth)) < 1e-12 * earth
    # Lloyd lowers the energy from the same start and keeps the sites inside.
    lloyd = hcvt.cvt(domain, sites, method="lloyd", max_iter=30)
    assert lloyd.history["energy"][-1] < lloyd.history["energy"][0]
    assert domain.contains(lloyd.sites).all()
    with pytest.raises(ValueError, match="Newton"):
        hcvt.cvt(domain, sites, method="newton", max_iter=3)


def test_the_diagram_does_not_depend_on_the_thread_count() -> None:
    domain = hcvt.Domain.sphere(1.0, region=south_africa())
    sites = hcvt.initialise(domain, 2000, seed=5)
    before = hcvt.get_num_threads()
    try:
        out = []
        for n in (1, 3):
            hcvt.set_num_threads(n)
            d = hcvt.voronoi(domain, sites)
            out.append(
                (
                    d.volume.tobytes(),
                    d.centroid.tobytes(),
                    d.face_measures.tobytes(),
                    d.boundary_measure.tobytes(),
                    d.neighbors.tobytes(),
                )
            )
    finally:
        hcvt.set_num_threads(before)
    assert out[0] == out[1]


def test_sites_outside_and_unsupported_jobs_are_refused() -> None:
    domain = hcvt.Domain.sphere(1.0, region=MEDITERRANEAN)
    sites = hcvt.initialise(domain, 20, seed=2)
    outside = sites.copy()
    outside[4] = lonlat_to_unit(np.array([[0.0, 50.0]]))[0]  # Paris
    with pytest.raises(InvalidSitesError, match="4"):
        hcvt.voronoi(domain, outside)
    with pytest.raises(NotImplementedError, match="density"):
        hcvt.cvt(domain, sites, density=lambda p: np.ones(len(p)))
    with pytest.raises(NotImplementedError):
        hcvt.voronoi(domain, sites).spherical_mesh()
    big = box(-5, 30, 35, 45)
    assert hcvt.Domain.sphere(1.0, region=big).volume > domain.volume


def test_the_command_line_runs_a_region(tmp_path: Path) -> None:
    from click.testing import CliRunner

    from hcvt.cli import main

    summary, out = tmp_path / "summary.json", tmp_path / "sites.npy"
    args = ["run", "sphere", "--region", str(DATA / "naturalearth_south_africa.geojson")]
    args += ["-n", "200", "--radius", "6371", "--out", str(out), "--summary", str(summary)]
    result = CliRunner().invoke(main, args)
    assert result.exit_code == 0, result.output
    info = json.loads(summary.read_text())
    assert info["rms_gap"] < 1e-7 and info["region"].endswith(".geojson")
    domain = hcvt.Domain.sphere(6371.0, region=south_africa())
    assert domain.contains(np.load(out)).all()


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (
            {
                "type": "MultiPolygon",
                "coordinates": [
                    [[[10, 0], [20, 0], [20, 10], [10, 0]]],
                    [[[30, 0], [40, 0], [40, 10], [30, 0]]],
                ],
            },
            "2 polygons; a region of the sphere is one",
        ),
        (
            {
                "type": "Polygon",
                "coordinates": [[[1e5, 0], [2e5, 0], [2e5, 1e5], [1e5, 0]]],
                "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::2263"}},
            },
            "coordinates in urn:ogc:def:crs:EPSG::2263; a region is lon/lat degrees",
        ),
    ],
    ids=["multipolygon", "projected crs"],
)
def test_the_command_line_refuses_a_region_file_it_cannot_read_as_one_lonlat_polygon(
    tmp_path: Path, content: dict, message: str
) -> None:
    from click.testing import CliRunner

    from hcvt.cli import main

    path = tmp_path / "region.geojson"
    path.write_text(json.dumps(content))
    result = CliRunner().invoke(main, ["run", "sphere", "--region", str(path), "-n", "50"])
    assert result.exit_code == 2 and message in result.output, result.output


def test_the_command_line_reads_a_region_as_load_domain_reads_polygons(tmp_path: Path) -> None:
    from hcvt.cli import _read_region

    feature = {"type": "Feature", "properties": {}, "geometry": mapping(south_africa())}
    path = tmp_path / "region.geojson"
    path.write_text(json.dumps({"type": "FeatureCollection", "features": [feature]}))
    assert _read_region(str(path)).equals(south_africa())
