"""PyVista and trimesh at home (issue 31): Domain.from_pyvista / from_trimesh, mesh.hcvt.

The accessor test runs ``pv.read(bunny).hcvt.cvt(2000)`` in a fresh interpreter that
imports only pyvista: PyVista must find hcvt through the ``pyvista.accessors`` entry point
of ``pyproject.toml``. Where hcvt is installed (``pip install -e .``) its metadata carries
that entry point; in a checkout on ``sys.path`` without it, the test writes the same
entry point, read from ``pyproject.toml``, into a throwaway ``.dist-info`` first.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np
import pytest

import hcvt
from helpers import DATA

pv = pytest.importorskip("pyvista")
trimesh = pytest.importorskip("trimesh")

BUNNY = DATA / "3d" / "bunny.off"
PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"


def declared_entry_point() -> str:
    project = tomllib.loads(PYPROJECT.read_text())["project"]
    return project["entry-points"]["pyvista.accessors"]["hcvt"]


def test_from_pyvista_and_trimesh_take_the_file_as_indexed() -> None:
    expected = hcvt.load_domain(BUNNY)
    for domain in (
        hcvt.Domain.from_pyvista(pv.read(BUNNY)),  # an UnstructuredGrid of triangles
        hcvt.Domain.from_pyvista(pv.wrap(trimesh.load(BUNNY, process=False))),  # PolyData
        hcvt.Domain.from_trimesh(trimesh.load(BUNNY, process=False)),
    ):
        np.testing.assert_array_equal(domain.vertices, expected.vertices)
        np.testing.assert_array_equal(domain.faces, expected.faces)
        assert domain.volume == expected.volume


def test_from_pyvista_quads_and_volume_meshes() -> None:
    assert hcvt.Domain.from_pyvista(pv.Cube(x_length=2.0)).volume == pytest.approx(2.0, rel=1e-14)
    grid = pv.ImageData(dimensions=(3, 4, 5), spacing=(0.5, 1.0, 2.0))
    for mesh in (grid.cast_to_unstructured_grid(), grid.triangulate()):  # hexahedra, tetrahedra
        assert hcvt.Domain.from_pyvista(mesh).volume == pytest.approx(1.0 * 3.0 * 8.0, rel=1e-14)
    with pytest.raises(hcvt.InvalidDomainError, match="open boundary"):
        hcvt.Domain.from_pyvista(pv.Plane())
    with pytest.raises(TypeError, match="expected a pyvista dataset"):
        hcvt.Domain.from_pyvista(np.zeros((3, 3)))
    with pytest.raises(TypeError, match=r"scene.to_mesh\(\)"):
        hcvt.Domain.from_trimesh(trimesh.Scene([trimesh.creation.box()]))


def test_accessor_voronoi_in_process() -> None:
    import hcvt.accessor  # noqa: F401  (registers mesh.hcvt here, as the entry point would)

    box = pv.Cube(x_length=2.0, y_length=1.0, z_length=1.0).triangulate()
    sites = [[-0.5, 0.0, 0.0], [0.5, 0.0, 0.0]]
    diagram = box.hcvt.voronoi(sites=sites)
    np.testing.assert_allclose(diagram.volume, [1.0, 1.0], rtol=1e-14)
    assert box.hcvt.voronoi(50, seed=1).n == 50
    with pytest.raises(ValueError, match="either n"):
        box.hcvt.voronoi()


def test_entry_point_is_declared() -> None:
    assert declared_entry_point() == "hcvt.accessor"


def test_pyvista_finds_the_accessor_in_a_fresh_process(tmp_path: Path) -> None:
    env = dict(os.environ)
    if not any(ep.name == "hcvt" for ep in entry_points(group="pyvista.accessors")):
        info = tmp_path / "hcvt_accessor_entry_point-0.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(
            "Metadata-Version: 2.1\nName: hcvt-accessor-entry-point\nVersion: 0\n"
        )
        (info / "entry_points.txt").write_text(
            f"[pyvista.accessors]\nhcvt = {declared_entry_point()}\n"
        )
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(tmp_path), env.get("PYTHONPATH")]))
    # cvt(2000) to the default rule takes ~45 s on this 2-core machine; 50 L-BFGS steps
    # (~4 s) show the accessor runs the optimiser on the file's solid.
    code = f"""
import json, sys
import pyvista as pv
assert "hcvt" not in sys.modules
result = pv.read({str(BUNNY)!r}).hcvt.cvt(2000, max_iter=50)
print(json.dumps(dict(
    hcvt_loaded="hcvt.accessor" in sys.modules,
    n=len(result.sites), iterations=result.iterations, stop=result.stop_reason,
    gap=[float(result.history["rms_gap"][0]), float(result.history["rms_gap"][-1])],
    volume=float(result.diagram.volume.sum()), domain=float(result.diagram.domain.volume),
)))
"""
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=300
    )
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["hcvt_loaded"] and out["n"] == 2000
    assert out["iterations"] == 50 and out["stop"] == "max_iter"
    assert out["gap"][1] < out["gap"][0] / 20, out["gap"]
    assert out["volume"] == pytest.approx(hcvt.load_domain(BUNNY).volume, rel=1e-12)
    assert out["domain"] == pytest.approx(out["volume"], rel=1e-12)
