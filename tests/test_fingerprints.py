"""Behaviour fingerprints: the sha256 of every array the public API returns on fixed inputs.

Recorded once at 34a1fc5, before the package was restructured (issue 29), so that moving
code can be shown to change no bit. A deliberate change of results re-records them and
says so in its commit: ``HCVT_RECORD_FINGERPRINTS=1 pytest tests/test_fingerprints.py``
rewrites ``tests/data/fingerprints.json`` (only the cases that ran).

What is hashed: every ndarray reachable from a result (dataclass and NamedTuple fields,
dict values, properties listed per case), with its dtype and shape; floats by ``repr``;
written files byte for byte. Floats in seconds, paths and wall-clock history are left out.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import hcvt
from hcvt.export import merged_boundary, mesh_quality
from helpers import DATA

RECORD = os.environ.get("HCVT_RECORD_FINGERPRINTS") == "1"
STORE = Path(__file__).parent / "data" / "fingerprints.json"
_recorded: dict[str, str] = {}

# History columns that are clocks, not results.
_CLOCKS = {"seconds", "time", "wall", "elapsed"}


def _digest(value: Any, h: Any) -> None:
    """Feed ``value`` into the hash ``h``: arrays with dtype and shape, containers in order."""
    if isinstance(value, np.ndarray):
        array = np.ascontiguousarray(value)
        h.update(f"{array.dtype.str}{array.shape}".encode())
        h.update(array.tobytes())
    elif isinstance(value, dict):
        for key in sorted(value, key=str):
            if str(key) in _CLOCKS:
                continue
            h.update(repr(key).encode())
            _digest(value[key], h)
    elif isinstance(value, tuple | list):
        h.update(f"{type(value).__name__}{len(value)}".encode())
        for item in value:
            _digest(item, h)
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for f in dataclasses.fields(value):
            if f.name not in _CLOCKS:
                h.update(f.name.encode())
                _digest(getattr(value, f.name), h)
    elif isinstance(value, float | int | bool | str | np.generic) or value is None:
        h.update(repr(value).encode())
    else:
        raise TypeError(f"no fingerprint for {type(value).__name__}")


def fingerprint(value: Any) -> str:
    h = hashlib.sha256()
    _digest(value, h)
    return h.hexdigest()


def check(name: str, value: Any) -> None:
    """Compare ``value``'s fingerprint with the recorded one (or record it)."""
    got = fingerprint(value)
    if RECORD:
        _recorded[name] = got
        return
    expected = json.loads(STORE.read_text())
    assert name in expected, f"no fingerprint recorded for {name}"
    assert got == expected[name], f"{name}: results changed"


@pytest.fixture(scope="module", autouse=True)
def _store():
    yield
    if RECORD and _recorded:
        old = json.loads(STORE.read_text()) if STORE.exists() else {}
        STORE.parent.mkdir(exist_ok=True)
        STORE.write_text(json.dumps({**old, **_recorded}, indent=1, sort_keys=True) + "\n")


def _diagram_arrays(d: hcvt.Diagram) -> dict[str, Any]:
    return {
        "volume": d.volume,
        "centroid": d.centroid,
        "second_moment": d.second_moment,
        "G": d.G,
        "energy": d.energy,
        "neighbors": d.neighbors,
        "face_measures": d.face_measures,
    }


def _mesh_arrays(mesh: Any) -> dict[str, Any]:
    """The mesh's fields, less those it does not have (None: the periodic pairing, later)."""
    fields = {f.name: getattr(mesh, f.name) for f in dataclasses.fields(mesh)}
    return {name: value for name, value in fields.items() if value is not None}


def _history(result: Any) -> dict[str, Any]:
    return {k: v for k, v in result.history.items() if k not in _CLOCKS}


@pytest.fixture(scope="module")
def star():
    domain = hcvt.load_domain(DATA / "2d" / "star5.geojson")
    return domain, hcvt.initialise(domain, 300, method="random", seed=1)


@pytest.fixture(scope="module", params=["bunny.off", "cheese.off"])
def solid(request):
    """1k sites in the bunny and the cheese after 10 Lloyd steps (boundary pieces to fix)."""
    domain = hcvt.load_domain(DATA / "3d" / request.param)
    sites = hcvt.initialise(domain, 1000, method="random", seed=2)
    result = hcvt.cvt(domain, sites, "lloyd", max_iter=10)
    return request.param.removesuffix(".off"), domain, result


def test_voronoi_2d(star):
    domain, sites = star
    d = hcvt.voronoi(domain, sites)
    check("voronoi_2d", _diagram_arrays(d))
    check("mesh_2d", _mesh_arrays(d.mesh()))
    check("quality_2d", _recorded_quality(mesh_quality(d.mesh())))


def _recorded_quality(quality) -> dict:
    """The fields of a MeshQuality recorded (volume_ratio came later, issue 30)."""
    return {k: v for k, v in dataclasses.asdict(quality).items() if k != "volume_ratio"}


def test_solid_diagram_mesh_and_quality(solid):
    name, _, result = solid
    check(f"lloyd10_{name}_sites", result.sites)
    check(f"lloyd10_{name}_history", _history(result))
    d = result.diagram
    check(f"voronoi_{name}", _diagram_arrays(d))
    mesh = d.mesh()
    check(f"mesh_{name}", _mesh_arrays(mesh))
    check(f"quality_{name}", _recorded_quality(mesh_quality(mesh)))


def test_merged_boundary(solid):
    name, domain, result = solid
    merged, report = merged_boundary(result.diagram.mesh(), domain)
    check(f"merged_{name}", {"mesh": _mesh_arrays(merged), "report": tuple(report)})


@pytest.mark.parametrize("method", ["random", "halton", "hammersley", "lattice"])
def test_initialise(method, star):
    domain, _ = star
    ball = hcvt.load_domain(DATA / "3d" / "sphere.ply")
    check(f"initialise_{method}_2d", hcvt.initialise(domain, 200, method=method, seed=4))
    check(f"initialise_{method}_3d", hcvt.initialise(ball, 100, method=method, seed=4))


def test_hierarchical_and_regular(star):
    domain, _ = star
    h = hcvt.hierarchical_cvt(domain, 160, 2, seed=5, max_iter=30, method="lbfgs")
    check("hierarchical_2d", {"sites": h.sites, "history": _history(h)})
    r = hcvt.regular_cvt(domain, 120, seed=6, moves=4, max_iter=30)
    check("regular_2d", {"sites": r.sites, "G": r.diagram.G})


def test_written_files(star, solid, tmp_path):
    domain, sites = star
    name, _, result = solid
    files: dict[str, bytes] = {}
    for label, diagram in (("2d", hcvt.voronoi(domain, sites)), (name, result.diagram)):
        hcvt.write_mesh(diagram, tmp_path / f"cells_{label}.vtu")
        # Recorded when "exact" was the default (issue 30 made "merged" the default).
        hcvt.write_mesh(diagram, tmp_path / f"case_{label}", boundary_faces="exact")
    for path in sorted(tmp_path.rglob("*")):
        if path.is_file():
            files[str(path.relative_to(tmp_path))] = path.read_bytes()
    check(f"files_{name}", {k: np.frombuffer(v, np.uint8) for k, v in files.items()})


@pytest.mark.slow
@pytest.mark.parametrize("workers", [1, 3])
@pytest.mark.parametrize("method", ["lloyd", "lbfgs"])
def test_partitioned_cvt(workers, method):
    distributed = pytest.importorskip("distributed")
    domain = hcvt.load_domain(DATA / "2d" / "triangle_square_circle_hole.geojson")
    sites = hcvt.initialise(domain, 2000, method="random", seed=7)
    cluster = distributed.LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
    )
    with cluster, distributed.Client(cluster) as client:
        result = hcvt.cvt(domain, sites, method, client=client, max_iter=8, sites_per_partition=500)
        sites_out = result.sites
        history = _history(result)
    # One fingerprint for both worker counts: results do not depend on them.
    check(f"partitioned_{method}", {"sites": sites_out, "history": history})
