"""Domains and diagrams travel between processes (dask, multiprocessing) and come back equal.

The diagram computed in a worker process from an unpickled domain must be bitwise equal to
the one computed here: the domain is pickled as its boundary, and the core rebuilds the
same index from it.
"""

from __future__ import annotations

import multiprocessing
import pickle

import numpy as np
import pytest

import hcvt
from helpers import DATA, random_inside

FIELDS = ("volume", "centroid", "second_moment", "G", "gradient", "boundary_measure")


def domains() -> list[hcvt.Domain]:
    square_with_hole = hcvt.Domain.from_polygon(
        [(0, 0), (4, 0), (4, 4), (0, 4)], holes=[[(1, 1), (1, 2), (2, 2), (2, 1)]]
    )
    bunny = hcvt.load_domain(DATA / "3d" / "bunny.off")
    repaired = hcvt.load_domain(DATA / "3d" / "bad" / "blobby-shuffled.off", repair=True)
    return [square_with_hole, bunny, repaired]


@pytest.fixture(scope="module")
def cases() -> list[tuple[hcvt.Domain, np.ndarray, hcvt.Diagram]]:
    out = []
    for k, domain in enumerate(domains()):
        sites = random_inside(domain, 300, seed=k)
        out.append((domain, sites, hcvt.voronoi(domain, sites)))
    return out


def assert_same(a: hcvt.Diagram, b: hcvt.Diagram) -> None:
    for name in FIELDS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    np.testing.assert_array_equal(a.neighbors, b.neighbors)
    np.testing.assert_array_equal(a.face_measures, b.face_measures)
    assert a.energy == b.energy


def test_domain_round_trips_through_pickle(cases) -> None:  # noqa: ANN001
    for domain, sites, diagram in cases:
        copy = pickle.loads(pickle.dumps(domain))
        assert type(copy) is hcvt.Domain and copy.dim == domain.dim
        assert copy.volume == domain.volume
        np.testing.assert_array_equal(copy.vertices, domain.vertices)
        assert str(copy.repair_report) == str(domain.repair_report)
        if domain.dim == 2:
            assert copy.geometry.equals_exact(domain.geometry, 0)
        else:
            np.testing.assert_array_equal(copy.faces, domain.faces)
        assert_same(hcvt.voronoi(copy, sites), diagram)


def test_multiprocessing_pool_gives_identical_diagrams(cases) -> None:  # noqa: ANN001
    # spawn: a fresh interpreter (fork would copy the rayon pool's threads in mid-flight).
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        results = pool.starmap(hcvt.voronoi, [(d, s) for d, s, _ in cases])
    for (_, _, diagram), result in zip(cases, results, strict=True):
        assert_same(result, diagram)


@pytest.mark.slow
def test_dask_local_cluster_gives_identical_diagrams(cases) -> None:  # noqa: ANN001
    distributed = pytest.importorskip("dask.distributed")
    with (
        distributed.LocalCluster(
            n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        worker_pids = client.run(lambda: __import__("os").getpid())
        assert multiprocessing.current_process().pid not in worker_pids.values()
        futures = [client.submit(hcvt.voronoi, d, s, pure=False) for d, s, _ in cases]
        results = client.gather(futures)
    for (_, _, diagram), result in zip(cases, results, strict=True):
        assert_same(result, diagram)
