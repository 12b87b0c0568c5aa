"""One diagram and one CVT partitioned over dask.distributed workers (hcvt.distributed).

Clusters are LocalClusters of worker *processes* (``processes=True``, one thread each), so
parts, halos and the domain really travel pickled between processes. One cluster per
worker count, started once for the module.
"""

from __future__ import annotations

import os
import signal
import threading

import numpy as np
import pytest
import shapely.affinity

import hcvt
from hcvt import _core
from hcvt.distributed import partition as pt
from hcvt.distributed import partitioned_cvt, partitioned_voronoi
from hcvt.geometry import shapes

distributed = pytest.importorskip("dask.distributed")

DATA = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "data")
if not os.path.isdir(DATA):
    DATA = "/work/shared/data"

PER_CELL = (
    "volume",
    "centroid",
    "second_moment",
    "G",
    "energy_terms",
    "gradient",
    "boundary_measure",
    "neighbor_offsets",
    "neighbor_sites",
    "neighbor_measures",
)


@pytest.fixture(scope="module", params=[1, 2, 3], ids=lambda w: f"{w}workers")
def client(request):
    cluster = distributed.LocalCluster(
        n_workers=request.param,
        threads_per_worker=1,
        processes=True,
        dashboard_address=None,
    )
    with distributed.Client(cluster) as c:
        yield c
    cluster.close()


@pytest.fixture(scope="module")
def holes():
    """A polygon with a hole from ../shared/data, and 3,000 random sites."""
    domain = hcvt.load_domain(os.path.join(DATA, "2d", "triangle_square_circle_hole.geojson"))
    return domain, hcvt.initialise(domain, n=3000, method="random", seed=3)


@pytest.fixture(scope="module")
def bunny():
    """The Stanford bunny from ../shared/data, and 1,500 random sites."""
    domain = hcvt.load_domain(os.path.join(DATA, "3d", "bunny.off"))
    return domain, hcvt.initialise(domain, n=1500, method="random", seed=5)


def assert_bitwise(got: hcvt.Diagram, expected: hcvt.Diagram) -> None:
    for key in PER_CELL:
        a, b = getattr(got, key), getattr(expected, key)
        assert a.shape == b.shape and a.dtype == b.dtype, key
        # Bits, not values: NaN G of empty cells and -0.0 included.
        assert np.array_equal(a.view(np.uint8), b.view(np.uint8)), key
    assert np.array_equal(got.neighbors, expected.neighbors)
    assert got.energy == pytest.approx(expected.energy, rel=1e-13, abs=0)


@pytest.mark.parametrize("per_part", [400, 1000, 100_000])
def test_partitioned_diagram_is_bitwise_the_single_process_one(client, holes, bunny, per_part):
    for domain, sites in (holes, bunny):
        expected = hcvt.voronoi(domain, sites)
        parted = partitioned_voronoi(domain, sites, client, sites_per_partition=per_part)
        assert parted.parts >= len(sites) / per_part
        got = parted.gather()
        assert_bitwise(got, expected)
        assert parted.energy == got.energy
        assert parted.rounds.cells[0] == len(sites)
        if parted.parts > 1:
            # The first halo certifies most cells at once; only the rest go again.
            assert sum(parted.rounds.cells[1:]) < 0.3 * len(sites)


def test_voronoi_with_a_client_returns_a_diagram(client, holes):
    domain, sites = holes
    got = hcvt.voronoi(domain, sites, client=client, sites_per_partition=800)
    assert isinstance(got, hcvt.Diagram)
    assert_bitwise(got, hcvt.voronoi(domain, sites))


def test_halo_too_thin_for_some_cells_is_grown_for_them_only(holes):
    """A part computed among a halo of 1 spacing: the cells it cannot certify are the
    ones whose reach it misses, and every certified cell is already exact."""
    domain, sites = holes
    expected = hcvt.voronoi(domain, sites)
    split = pt.kd_split(sites, 1000)
    parts = pt.make_parts(sites, split)
    h = (domain.volume / len(sites)) ** 0.5
    part = parts[1]
    lo, hi = part.box()
    slices = [pt.halo_slice(q, lo - h, hi + h) for q in parts if q.index != part.index]
    cells = pt.part_cells(domain, part, h, len(sites), None, False, *slices)
    certified = cells.certified
    assert 0 < certified.sum() < len(certified)  # some certified, some not
    rows = part.rows[certified]
    assert np.array_equal(cells.arrays["volume"][certified], expected.volume[rows])
    # The uncovered ones, computed again among balls past their reach, now agree.
    centres, radii = cells.balls()
    more = [pt.ball_slice(q, centres, radii) for q in parts if q.index != part.index]
    again = pt.part_cells(domain, part, radii, len(sites), cells, False, *more)
    assert again.certified.all()
    assert np.array_equal(
        again.arrays["volume"].view(np.uint8), expected.volume[part.rows].view(np.uint8)
    )
    assert np.array_equal(again.arrays["neighbor_offsets"], _local_offsets(expected, part.rows))


def test_a_part_along_the_curve_has_its_cells_in_its_own_order(holes):
    """A part put along the Morton curve (as a diagram's parts are on their workers) gets
    its cells from the core in its own order, unmoved: each is the single-process cell of
    its row, faces (CSR) included."""
    domain, sites = holes
    expected = hcvt.voronoi(domain, sites)
    parts = pt.make_parts(sites, pt.kd_split(sites, 1000))
    part = pt.along_curve(parts[1])
    assert part.along_curve and not np.all(np.diff(part.rows) > 0)
    assert np.array_equal(np.sort(part.rows), parts[1].rows)
    h = (domain.volume / len(sites)) ** 0.5
    lo, hi = part.box()
    slices = [pt.halo_slice(q, lo - 30 * h, hi + 30 * h) for q in parts if q.index != 1]
    cells = pt.part_cells(domain, part, 30 * h, len(sites), None, False, *slices)
    assert cells.certified.all()
    for key in ("volume", "G", "centroid"):
        assert np.array_equal(cells.arrays[key], getattr(expected, key)[part.rows])
    assert np.array_equal(cells.arrays["neighbor_offsets"], _local_offsets(expected, part.rows))
    faces = np.concatenate(
        [
            expected.neighbor_sites[a:b]
            for a, b in zip(
                expected.neighbor_offsets[part.rows],
                expected.neighbor_offsets[part.rows + 1],
                strict=True,
            )
        ]
    )
    assert np.array_equal(cells.arrays["neighbor_sites"], faces)


def test_a_halo_side_beyond_every_site_needs_no_room(holes):
    """Told the box of every site, a first round certifies the cells whose reach crosses
    only sides of the halo box beyond it (where no site can be missed): fewer cells go
    again, and every certified cell is the single-process one."""
    domain, sites = holes
    expected = hcvt.voronoi(domain, sites)
    parts = pt.make_parts(sites, pt.kd_split(sites, 1000))
    h = (domain.volume / len(sites)) ** 0.5
    box = (sites.min(axis=0), sites.max(axis=0))
    fewer = 0
    for part in parts:
        lo, hi = part.box()
        slices = [pt.halo_slice(q, lo - h, hi + h) for q in parts if q.index != part.index]
        plain = pt.part_cells(domain, part, h, len(sites), None, False, *slices)
        freed = pt.part_cells(domain, part, h, len(sites), None, False, *slices, sites_box=box)
        assert np.all(freed.certified[plain.certified])  # never fewer certified
        fewer += int(freed.certified.sum() - plain.certified.sum())
        rows = part.rows[freed.certified]
        assert np.array_equal(freed.arrays["volume"][freed.certified], expected.volume[rows])
        assert np.array_equal(freed.arrays["G"][freed.certified], expected.G[rows])
    assert fewer > 0


@pytest.mark.parametrize("name", ["square", "star5.geojson"])
def test_no_cell_reaches_across_the_domain(name):
    """Every 2D cell's reach, the distance within which it read sites, stays a few
    spacings on 200,000 uniform random sites: the halo a part needs is local.

    Before cells still open into the domain were kept from localising, the largest reach
    was 559 (square) and 1,095 (star) spacings, and 208 / 228 cells reached beyond 20."""
    domain = (
        shapes.unit_square()
        if name == "square"
        else hcvt.load_domain(os.path.join(DATA, "2d", name))
    )
    n = 200_000
    sites = hcvt.initialise(domain, n, "random", seed=0)
    rows = np.arange(n, dtype=np.int64)
    out = hcvt._core.partition_cells(domain._core, sites, rows, rows.astype(np.uint32), n)
    reach = np.sqrt(out["reach2"]) / (domain.volume / n) ** 0.5
    assert reach.max() < 20  # measured 11.7 (square) and 16.5 (star)
    assert np.percentile(reach, 99.9) < 6  # measured 5.4 and 5.6


def _local_offsets(diagram: hcvt.Diagram, rows: np.ndarray) -> np.ndarray:
    counts = np.diff(diagram.neighbor_offsets)[rows]
    return np.concatenate([[0], np.cumsum(counts)])


def test_kd_split_depends_on_the_data_only_and_locates_every_site():
    rng = np.random.default_rng(0)
    sites = rng.random((5000, 2))
    split = pt.kd_split(sites, 700)
    assert split.parts == 8
    parts = pt.make_parts(sites, split)
    assert [len(p.rows) for p in parts] == [625] * 8
    for p in parts:
        assert np.all(np.diff(p.rows) > 0)
        assert np.all(split.locate(p.sites) == p.index)
    again = pt.kd_split(sites.copy(), 700)
    assert np.array_equal(again.value, split.value)
    # In one pass: the same planes and the same parts.
    once, made = pt.split_parts(sites, 700)
    assert np.array_equal(once.value, split.value) and once.parts == split.parts
    for p, q in zip(made, parts, strict=True):
        assert np.array_equal(p.rows, q.rows) and np.array_equal(p.sites, q.sites)


def test_the_grid_finds_every_site_in_the_balls():
    """Later rounds take the sites within balls through a grid: a superset, never fewer
    than a brute-force distance test (2D and 3D, radii from 1e-6 to 0.3)."""
    rng = np.random.default_rng(5)
    for trial in range(100):
        d = 2 + trial % 2
        points = rng.random((int(rng.integers(1, 3000)), d))
        centres = rng.random((int(rng.integers(1, 30)), d))
        radii = rng.random(len(centres)) ** 3 * 0.3 + 1e-6
        got = pt.ball_slice(pt.Part(0, np.arange(len(points)), points), centres, radii)[0]
        distance = np.sqrt(((points[:, None, :] - centres[None]) ** 2).sum(axis=-1))
        inside = np.flatnonzero((distance <= radii).any(axis=1))
        assert np.isin(inside, got).all(), trial
        assert np.all(np.diff(got) > 0)
    # Balls along a part's four faces (as after a first round): their common box is the
    # whole part, the grid keeps the sites near them (about 4% here), not the 100,000.
    points = rng.random((100_000, 2))
    t = rng.random(200)
    centres = np.concatenate([np.c_[t[:50], 0 * t[:50]], np.c_[t[50:100], 1 + 0 * t[:50]]])
    centres = np.concatenate([centres, centres[:, ::-1]])
    got = pt._near_balls(points, centres, np.full(len(centres), 0.01))
    assert len(got) < 0.1 * len(points)


def test_cells_are_visited_along_a_morton_curve():
    """The keys interleave the coordinates' bits (against one bit at a time), and the
    order is a permutation whose consecutive sites are near (mean step ~ the spacing)."""
    rng = np.random.default_rng(0)
    for d in (2, 3):
        values = rng.integers(0, 1 << (63 // d), 10_000, dtype=np.uint64)
        expected = np.zeros_like(values)
        for b in range(63 // d):
            expected |= ((values >> np.uint64(b)) & np.uint64(1)) << np.uint64(d * b)
        assert np.array_equal(pt._spread_bits(values, d), expected)
    points = rng.random((40_000, 2))
    order = pt.spatial_order(points)
    assert np.array_equal(np.sort(order), np.arange(len(points)))
    step = np.sqrt((np.diff(points[order], axis=0) ** 2).sum(axis=1)).mean()
    assert step < 2.5 / np.sqrt(len(points))  # row order: ~0.52, 100 spacings


def test_lloyd_is_bitwise_the_single_process_lloyd(client, holes):
    domain, sites = holes
    sites = sites[:1000]
    expected = hcvt.cvt(domain, sites, "lloyd", tol=0, max_iter=3)
    got = hcvt.cvt(
        domain, sites, "lloyd", tol=0, max_iter=3, client=client, sites_per_partition=300
    )
    assert np.array_equal(got.sites, expected.sites)
    assert_bitwise(got.diagram, expected.diagram)
    np.testing.assert_allclose(got.history["energy"], expected.history["energy"], rtol=1e-13)


_LBFGS: dict[str, object] = {}


def test_lbfgs_is_bitwise_the_same_for_any_number_of_workers(client, holes):
    domain, sites = holes
    sites = sites[:1000]
    res = partitioned_cvt(domain, sites, "lbfgs", client, max_iter=5, sites_per_partition=250)
    energy = res.history["energy"]
    assert np.all(np.diff(energy) < 0)
    assert res.history["rms_gap"][-1] < 0.3 * res.history["rms_gap"][0]
    assert res.history["migrated"].sum() > 0  # sites crossed the planes and moved parts
    got = res.gather()
    first = _LBFGS.setdefault("run", got)
    assert np.array_equal(got.sites, first.sites)
    assert np.array_equal(got.history["energy"], first.history["energy"])
    assert_bitwise(got.diagram, hcvt.voronoi(domain, got.sites))


def test_two_loop_in_coefficients_matches_the_recursion_on_vectors():
    rng = np.random.default_rng(1)
    n, m = 40, 3
    s = rng.normal(size=(m, n))
    y = s * 2 + 0.1 * rng.normal(size=(m, n))
    g = rng.normal(size=n)
    w = rng.random(n) + 0.5
    basis = np.vstack([s, y, g])
    c, e = _core.lbfgs_coefficients(basis @ basis.T, (basis * w) @ basis.T)
    got = w * (np.vstack([y, g]).T @ c) + s.T @ e
    # The textbook two-loop recursion with H0 = γ diag(w).
    q, alphas = g.copy(), []
    rho = [1 / (s[k] @ y[k]) for k in range(m)]
    for k in reversed(range(m)):
        a = rho[k] * (s[k] @ q)
        q -= a * y[k]
        alphas.append(a)
    r = q * w / (rho[-1] * (y[-1] * w) @ y[-1])
    for k, a in zip(range(m), reversed(alphas), strict=True):
        r += (a - rho[k] * (y[k] @ r)) * s[k]
    np.testing.assert_allclose(got, r, rtol=0, atol=1e-12 * np.abs(r).max())


def test_a_worker_killed_during_a_cvt_does_not_change_the_result(holes, tmp_path):
    """Two worker losses in one L-BFGS run: first the worker holding the only copy of the
    scattered domain (dask's active memory manager drops the broadcast replicas that no
    task waits for), between two steps, recovered from the checkpoint with the domain sent
    again; then a worker during a step, its tasks in flight. The run ends with the sites
    and energies of an undisturbed run."""
    domain, sites = holes
    sites = sites[:600]
    cluster = distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    with distributed.Client(cluster) as c:
        killed: list[object] = []
        calls = []

        def kill(info):
            calls.append(info["evaluations"])
            if len(calls) == 2:
                c.amm.run_once()  # what the memory manager does every 2 s anyway
                held = [w for k, w in c.who_has().items() if k.startswith("Domain-")]
                assert len(held) == 1 and len(held[0]) == 1, held
                os.kill(c.run(os.getpid)[held[0][0]], signal.SIGKILL)
                killed.append(held[0][0])
            elif len(calls) == 3:
                c.wait_for_workers(2)
                pid = next(iter(c.run(os.getpid).values()))
                # During the next step, not between two: the step's tasks are in flight.
                timer = threading.Timer(0.3, os.kill, (pid, signal.SIGKILL))
                timer.start()
                killed.append((timer, pid))

        hit = partitioned_cvt(
            domain,
            sites,
            "lbfgs",
            c,
            max_iter=6,
            sites_per_partition=150,
            callback=kill,
            checkpoint=str(tmp_path),
        )
        timer, pid = killed[1]  # type: ignore[misc]
        timer.join()
        print(f"restarts from the checkpoint: {hit.restarts}")
        # The first loss takes the domain: a restart. The second is recovered by dask
        # recomputing the lost tasks when their inputs are tasks (parts reloaded from the
        # files are), or by a restart when it took scattered data again: 1 or 2.
        assert hit.restarts in (1, 2)
        b = hit.gather()
        c.wait_for_workers(2)
        assert pid not in c.run(os.getpid).values()  # both kills happened
        a = partitioned_cvt(domain, sites, "lbfgs", c, max_iter=6, sites_per_partition=150)
        a = a.gather()
    cluster.close()
    assert np.array_equal(a.sites, b.sites)
    assert np.array_equal(a.history["energy"], b.history["energy"])


def test_restarts_resume_after_a_loss_and_never_after_bad_input():
    """What a run does with a failed attempt (``_Restarts``, no cluster needed): after a
    loss, the domain is scattered again and the attempt resumes from the saved state, at
    most MAX_RESTARTS times in a run; bad input and a run without a checkpoint raise at
    once."""
    from hcvt.distributed.driver import MAX_RESTARTS, _Restarts

    class Cluster:
        scattered = 0

        def scatter(self):
            self.scattered += 1

    def failing(error):
        def attempt(state):
            raise error

        return attempt

    cluster = Cluster()
    restarts = _Restarts(cluster)  # type: ignore[arg-type]
    seen = []

    def flaky(state):
        seen.append(state)
        if len(seen) < 3:
            raise OSError("worker lost")
        return state * 10

    assert restarts.run(flaky, 1, lambda s: s + 1) == 30
    assert seen == [1, 2, 3] and restarts.count == 2 and cluster.scattered == 2
    with pytest.raises(OSError):
        restarts.run(failing(OSError("lost again")), 0, lambda s: s)
    assert restarts.count == MAX_RESTARTS  # the budget is the whole run's
    for error in (hcvt.InvalidSitesError("bad"), hcvt.InvalidDensityError("bad")):
        fresh = _Restarts(cluster)  # type: ignore[arg-type]
        with pytest.raises(type(error)):
            fresh.run(failing(error), 0, lambda s: s)
        assert fresh.count == 0
    no_checkpoint = _Restarts(cluster)  # type: ignore[arg-type]
    with pytest.raises(OSError):
        no_checkpoint.run(failing(OSError("lost")), 0, lambda s: None)
    assert no_checkpoint.count == 0


def test_cells_are_written_per_part_without_a_gather(client, holes, tmp_path):
    domain, sites = holes
    expected = hcvt.voronoi(domain, sites)
    parted = partitioned_voronoi(domain, sites, client, sites_per_partition=1000)
    paths = parted.write(tmp_path)
    # rows, sites, 12 per-cell arrays (mass and the core's moments too)
    assert len(paths) == parted.parts * (2 + 12)
    volume = np.full(len(sites), np.nan)
    for p in range(parted.parts):
        rows = np.load(tmp_path / f"part{p:05d}.rows.npy")
        volume[rows] = np.load(tmp_path / f"part{p:05d}.volume.npy")
    assert np.array_equal(volume, expected.volume)
    memory = parted.peak_memory_mb()
    print("peak RSS per process, MB:", memory)
    assert len(memory) == len(client.scheduler_info()["workers"]) + 1


def test_cli_run_with_a_scheduler_matches_the_single_process_run(client, tmp_path):
    """``hcvt run --scheduler ADDRESS``: the partitioned diagram's mean G and energy are
    those of one process (``--scheduler`` alone, a LocalCluster, is the same path after
    the cluster starts)."""
    import json

    from click.testing import CliRunner

    from hcvt.cli import main

    path = os.path.join(DATA, "2d", "star5.geojson")
    args = [path, "-n", "1200", "--method", "voronoi", "--seed", "2"]
    out = tmp_path / "summary.json"
    result = CliRunner().invoke(
        main,
        [
            "run",
            *args,
            "--scheduler",
            client.scheduler.address,
            "--sites-per-partition",
            "300",
            "--summary",
            str(out),
        ],
    )
    assert result.exit_code == 0, result.output
    got = json.loads(out.read_text())
    domain = hcvt.load_domain(path)
    expected = hcvt.voronoi(domain, hcvt.initialise(domain, 1200, method="random", seed=2))
    assert got["mean_G"] == pytest.approx(expected.mean_G, rel=1e-13)
    assert got["energy"] == pytest.approx(expected.energy, rel=1e-13)
    refused = CliRunner().invoke(main, ["run", *args[:3], "--method", "newton", "--scheduler"])
    assert refused.exit_code != 0 and "--scheduler runs the methods" in refused.output


def test_bad_sites_raise_the_single_process_error_naming_the_row(client, holes):
    domain, sites = holes
    bad = sites[:1000].copy()
    bad[617] = [-50.0, -50.0]  # outside the polygon
    with pytest.raises(hcvt.InvalidSitesError, match="site 617 "):
        hcvt.voronoi(domain, bad, client=client, sites_per_partition=300)
    twin = sites[:1000].copy()
    twin[812] = twin[3]
    with pytest.raises(hcvt.InvalidSitesError, match="sites 3 and 812 coincide"):
        hcvt.voronoi(domain, twin, client=client, sites_per_partition=300)


# Density (DESIGN §8) on the partitioned path: a polynomial (exact in the core) and a numpy
# callable (sampled; called once per part and round on its cells' quadrature nodes).

WEIGHTED = (*PER_CELL, "mass", "centroid", "energy_terms", "gradient")


def _wave(scale: float):
    """A numpy density ``1 + exp(sin(x / scale)) + (y / scale)^2``, made here (a closure)
    so that dask pickles it by value, as it would a user's function."""

    def rho(points: np.ndarray) -> np.ndarray:
        x = points / scale
        return 1.0 + np.exp(np.sin(3.0 * x[:, 0])) + 0.1 * x[:, 1] ** 2

    return rho


def _densities(domain: hcvt.Domain) -> dict[str, object]:
    from hcvt.density import Polynomial

    if domain.dim == 2:  # the polygon with a hole: x in [-4, 4], y in [-6, 0]
        poly = Polynomial(1.0, [0.1, -0.1], [[0.05, 0.01], [0.01, 0.03]])
        return {"polynomial": poly, "callable": _wave(1.0)}
    # the bunny: about 0.16 across, y in [0.03, 0.19]
    poly = Polynomial(1.0, [3.0, -1.0, 2.0], np.diag([100.0, 50.0, 80.0]))
    return {"polynomial": poly, "callable": _wave(0.03)}


def _skip_three(client) -> None:
    if len(client.scheduler_info()["workers"]) == 3:
        pytest.skip("density on the partitioned path: 1 and 2 workers (time budget)")


def assert_weighted_bitwise(got: hcvt.Diagram, expected: hcvt.Diagram) -> None:
    assert got.density is expected.density
    for key in WEIGHTED:
        a, b = getattr(got, key), getattr(expected, key)
        assert a.shape == b.shape and a.dtype == b.dtype, key
        assert np.array_equal(a.view(np.uint8), b.view(np.uint8)), key
    assert not np.array_equal(got.mass, got.volume)  # the density really weighs
    assert got.energy == pytest.approx(expected.energy, rel=1e-13, abs=0)


@pytest.mark.parametrize("per_part", [100, 250])
def test_weighted_partitioned_diagram_is_bitwise_the_single_process_one(
    client, holes, bunny, per_part
):
    """Mass, weighted centroid, energy terms and gradient of every cell, with a polynomial
    and with a numpy callable: bitwise those of ``hcvt.voronoi(..., density=...)``."""
    _skip_three(client)
    for domain, sites in ((holes[0], holes[1][:500]), (bunny[0], bunny[1][:300])):
        for name, rho in _densities(domain).items():
            expected = hcvt.voronoi(domain, sites, density=rho)
            parted = partitioned_voronoi(
                domain, sites, client, sites_per_partition=per_part, density=rho
            )
            assert parted.parts >= len(sites) / per_part, name
            got = parted.gather()
            assert_weighted_bitwise(got, expected)
            assert parted.energy == got.energy


def test_weighted_lloyd_is_bitwise_the_single_process_lloyd(client, holes):
    _skip_three(client)
    domain, sites = holes
    sites = sites[:400]
    for rho in _densities(domain).values():
        expected = hcvt.cvt(domain, sites, "lloyd", tol=0, max_iter=3, density=rho)
        got = hcvt.cvt(
            domain,
            sites,
            "lloyd",
            tol=0,
            max_iter=3,
            client=client,
            sites_per_partition=150,
            density=rho,
        )
        assert np.array_equal(got.sites, expected.sites)
        assert_weighted_bitwise(got.diagram, expected.diagram)
        np.testing.assert_allclose(got.history["energy"], expected.history["energy"], rtol=1e-13)
        np.testing.assert_allclose(got.history["rms_gap"], expected.history["rms_gap"], rtol=1e-12)


_WEIGHTED_LBFGS: dict[str, object] = {}


def test_weighted_lbfgs_is_bitwise_the_same_for_any_number_of_workers(client, bunny):
    """L-BFGS with ρ: the same sites and energies for 1 and 2 workers. Its first step,
    without pairs, is ``-P g`` with the preconditioner ``P = 1/(2 m_i)``: with the weighted
    mass that is the weighted Lloyd step (bitwise: ``(0.5/m)·2f = f/m``), so its energy is
    the single-process Lloyd iterate's (with the geometric volume it would not be)."""
    _skip_three(client)
    domain, sites = bunny
    sites = sites[:300]
    rho = _densities(domain)["polynomial"]
    res = partitioned_cvt(
        domain, sites, "lbfgs", client, max_iter=4, sites_per_partition=100, density=rho
    )
    assert list(res.history["step"][1:]) == ["lbfgs"] * 4
    assert np.all(np.diff(res.history["energy"]) < 0)
    lloyd = hcvt.cvt(domain, sites, "lloyd", tol=0, max_iter=1, density=rho)
    assert res.history["energy"][1] == pytest.approx(lloyd.history["energy"][1], rel=1e-13)
    got = res.gather()
    seen = _WEIGHTED_LBFGS.setdefault("run", got)
    assert np.array_equal(got.sites, seen.sites)
    assert np.array_equal(got.history["energy"], seen.history["energy"])
    assert_weighted_bitwise(got.diagram, hcvt.voronoi(domain, got.sites, density=rho))


def test_a_bad_density_on_the_workers_raises_invalid_density_error(client, holes):
    from hcvt.density import Polynomial

    _skip_three(client)
    domain, sites = holes
    sites = sites[:400]
    negative = Polynomial(1.0, [0.5, 0.0])  # below zero for x < -2
    with pytest.raises(hcvt.InvalidDensityError, match="the density is -"):
        hcvt.voronoi(domain, sites, client=client, sites_per_partition=150, density=negative)
    with pytest.raises(hcvt.InvalidDensityError, match="the density is NaN"):
        hcvt.cvt(
            domain,
            sites,
            "lbfgs",
            client=client,
            sites_per_partition=150,
            density=lambda p: np.where(p[:, 0] > 3.0, np.nan, 1.0),
        )
    with pytest.raises(hcvt.InvalidDensityError, match="quadrature_degree"):
        hcvt.voronoi(domain, sites, client=client, density=_wave(1.0), quadrature_degree=9)


def test_cli_run_with_a_density_and_a_scheduler_matches_the_single_process_run(client, tmp_path):
    """``hcvt run --density FILE.py:NAME --scheduler``: the user's function goes to the
    workers, and the Lloyd run ends at the single-process run's energy."""
    import json

    from click.testing import CliRunner

    from hcvt.cli import main

    _skip_three(client)
    density = tmp_path / "rho.py"
    density.write_text(
        "import numpy as np\n\n\n"
        "def rho(p):\n"
        "    return 1.0 + 4.0 * np.exp(-8.0 * (p ** 2).sum(axis=1))\n"
    )
    path = os.path.join(DATA, "2d", "star5.geojson")
    args = [path, "-n", "500", "--method", "lloyd", "--max-iter", "3", "--seed", "2"]
    args += ["--density", f"{density}:rho"]
    summaries = []
    for extra in ([], ["--scheduler", client.scheduler.address, "--sites-per-partition", "150"]):
        out = tmp_path / f"summary{len(summaries)}.json"
        result = CliRunner().invoke(main, ["run", *args, *extra, "--summary", str(out)])
        assert result.exit_code == 0, result.output
        summaries.append(json.loads(out.read_text()))
    single, parted = summaries
    assert "function rho" in parted["density"] and "function rho" in single["density"]
    assert parted["energy"] == pytest.approx(single["energy"], rel=1e-13, abs=0)
    assert parted["mean_G"] == pytest.approx(single["mean_G"], rel=1e-13, abs=0)


def test_lloyd_and_lbfgs_in_a_domain_far_from_the_origin(client, holes):
    # The domain's frame is not the identity there (issue 30): each part's core steps
    # (step fields, the Lloyd step, the L-BFGS direction) must take their sites and
    # vectors into the frame, as the single process does. Not bitwise: the parts map
    # their sites back to L every iteration, the single process once at the end; the
    # gap allowed is 64 units of the last place of the offset, far below a site's move.
    domain, sites = holes
    offset = np.array([1e6, -2e6])
    far = hcvt.Domain.from_polygon(shapely.affinity.translate(domain.geometry, *offset))
    assert not far.frame.is_identity
    sites = sites[:600] + offset
    ulp = np.spacing(2e6)
    for method in ("lloyd", "lbfgs"):
        expected = hcvt.cvt(far, sites, method, tol=0, max_iter=4)
        got = hcvt.cvt(
            far, sites, method, tol=0, max_iter=4, client=client, sites_per_partition=200
        )
        moved = np.abs(expected.sites - sites).max()
        assert moved > 1e4 * ulp, f"{method}: the sites hardly moved ({moved})"
        if method == "lloyd":
            assert np.abs(got.sites - expected.sites).max() <= 64 * ulp
        # L-BFGS: the partitioned line search is not the core's; it must still descend
        assert np.all(np.diff(got.history["energy"]) < 0), method


# --------------------------------------------------------------------------- the sphere


def _skip_three_kinds(client) -> None:
    if len(client.scheduler_info()["workers"]) == 3:
        pytest.skip("the sphere, power and periodic kinds: 1 and 2 workers (time budget)")


@pytest.fixture(scope="module")
def sphere():
    """The unit sphere and 1,500 random sites on it."""
    domain = hcvt.Domain.sphere(1.0)
    return domain, hcvt.initialise(domain, n=1500, method="random", seed=8)


def test_sphere_partitioned_diagram_is_bitwise_the_single_process_one(client, sphere):
    """Areas, centroids, arc lengths, neighbours and the tangent gradient of every cell."""
    _skip_three_kinds(client)
    domain, sites = sphere
    parted = partitioned_voronoi(domain, sites, client, sites_per_partition=300)
    assert parted.parts >= 5
    assert_bitwise(parted.gather(), hcvt.voronoi(domain, sites))
    assert sum(parted.rounds.cells[1:]) < 0.3 * len(sites)


def test_sphere_lloyd_is_bitwise_the_single_process_lloyd(client, sphere):
    """Each part's sites go back to the core as they came out of its retraction (not
    normalised again): the iterates are the single process's, bit for bit."""
    _skip_three_kinds(client)
    domain, sites = sphere
    expected = hcvt.cvt(domain, sites, "lloyd", tol=0, max_iter=6)
    got = hcvt.cvt(
        domain, sites, "lloyd", tol=0, max_iter=6, client=client, sites_per_partition=400
    )
    assert np.array_equal(got.sites, expected.sites)
    assert_bitwise(got.diagram, expected.diagram)
    np.testing.assert_allclose(got.history["energy"], expected.history["energy"], rtol=1e-13)
    np.testing.assert_allclose(got.history["rms_gap"], expected.history["rms_gap"], rtol=1e-12)


_SPHERE_LBFGS: dict[str, object] = {}


def test_sphere_lbfgs_is_bitwise_the_same_for_any_number_of_workers(client, sphere):
    _skip_three_kinds(client)
    domain, sites = sphere
    res = partitioned_cvt(domain, sites, "lbfgs", client, max_iter=5, sites_per_partition=400)
    assert np.all(np.diff(res.history["energy"]) < 0)
    assert "lbfgs" in list(res.history["step"])
    got = res.gather()
    # Trial sites are retracted by the core: every iterate stays on the sphere.
    np.testing.assert_allclose(np.linalg.norm(got.sites, axis=1), 1.0, rtol=0, atol=4e-16)
    seen = _SPHERE_LBFGS.setdefault("run", got)
    assert np.array_equal(got.sites, seen.sites)
    assert np.array_equal(got.history["energy"], seen.history["energy"])
    # hcvt.voronoi pushes the sites onto the sphere once more: equal to round-off.
    again = hcvt.voronoi(domain, got.sites)
    assert np.array_equal(got.diagram.neighbors, again.neighbors)
    np.testing.assert_allclose(got.diagram.volume, again.volume, rtol=1e-12)


# ---------------------------------------------------------------------- power diagrams


def test_power_partitioned_diagram_is_bitwise_the_single_process_one(client, holes):
    """Random weights leave cells empty, and one heavy site's cell reaches over several
    parts' halos: its neighbours are certified only by the bound of the largest weight
    (DESIGN §14), so they are computed again among wider balls."""
    _skip_three_kinds(client)
    rng = np.random.default_rng(4)
    box = hcvt.Domain.box([0.0, 0.0, 0.0], [1.0, 1.0, 1.0])
    for domain, sites in ((holes[0], holes[1][:600]), (box, rng.random((500, 3)))):
        h2 = (domain.volume / len(sites)) ** (2 / domain.dim)
        weights = rng.uniform(0.0, 2.0 * h2, len(sites))
        weights[7] = 40.0 * h2
        expected = hcvt.voronoi(domain, sites, weights=weights)
        assert (expected.volume == 0).sum() >= 5  # empty cells: no faces, G NaN
        assert expected.volume[7] > 15 * domain.volume / len(sites)
        parted = partitioned_voronoi(
            domain, sites, client, sites_per_partition=120, weights=weights
        )
        assert parted.parts >= 4
        got = parted.gather()
        assert_bitwise(got, expected)
        assert np.array_equal(got.weights, expected.weights)
        assert len(parted.rounds.cells) > 1  # the heavy cell's neighbours went again
    got = hcvt.voronoi(box, sites, weights=weights, client=client, sites_per_partition=200)
    assert_bitwise(got, expected)


# ----------------------------------------------------------------------- periodic boxes


def _periodic_cases():
    """Boxes periodic along all axes or some, random sites, some given a period away."""
    rng = np.random.default_rng(6)
    square = rng.random((700, 2)) * [2.0, 1.0]
    square[:6, 0] += 2.0  # outside [lo, hi) along a periodic axis: stands for its image
    cube = rng.random((450, 3))
    cube[:6, 2] -= 1.0
    return [
        (hcvt.Domain.box([0.0, 0.0], [2.0, 1.0], periodic=True), square),
        (hcvt.Domain.box([0.0, 0.0], [2.0, 1.0], periodic=(True, False)), square),
        (hcvt.Domain.box([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], periodic=(False, True, True)), cube),
    ]


def test_periodic_partitioned_diagram_is_bitwise_the_single_process_one(client):
    """Halos wrap across the periodic sides: every face, with its neighbour's image shift,
    is the single process's, bit for bit."""
    _skip_three_kinds(client)
    for domain, sites in _periodic_cases():
        expected = hcvt.voronoi(domain, sites)
        parted = partitioned_voronoi(domain, sites, client, sites_per_partition=120)
        assert parted.parts >= 4
        got = parted.gather()
        assert_bitwise(got, expected)
        assert np.array_equal(got.neighbor_images, expected.neighbor_images)
        across = np.any(expected.neighbor_images != 0, axis=1)
        assert across.sum() > 50  # many faces across a periodic side
        assert got.volume.sum() == pytest.approx(domain.volume, rel=1e-12)


def test_periodic_lloyd_is_bitwise_the_single_process_lloyd(client):
    _skip_three_kinds(client)
    for domain, sites in _periodic_cases()[1:]:
        sites = sites[:400]
        expected = hcvt.cvt(domain, sites, "lloyd", tol=0, max_iter=3)
        got = hcvt.cvt(
            domain, sites, "lloyd", tol=0, max_iter=3, client=client, sites_per_partition=100
        )
        assert np.array_equal(got.sites, expected.sites)
        assert_bitwise(got.diagram, expected.diagram)
        np.testing.assert_allclose(got.history["energy"], expected.history["energy"], rtol=1e-13)


_PERIODIC_LBFGS: dict[str, object] = {}


def test_periodic_lbfgs_is_bitwise_the_same_for_any_number_of_workers(client):
    """Sites cross the periodic sides and the planes of the split; returned wrapped."""
    _skip_three_kinds(client)
    domain, sites = _periodic_cases()[0]
    res = partitioned_cvt(domain, sites[:300], "lbfgs", client, max_iter=3, sites_per_partition=80)
    assert np.all(np.diff(res.history["energy"]) < 0)
    assert res.history["migrated"].sum() > 0
    got = res.gather()
    assert np.all((got.sites >= 0) & (got.sites < [2.0, 1.0]))
    seen = _PERIODIC_LBFGS.setdefault("run", got)
    assert np.array_equal(got.sites, seen.sites)
    assert np.array_equal(got.history["energy"], seen.history["energy"])
    assert_bitwise(got.diagram, hcvt.voronoi(domain, got.diagram.sites))
