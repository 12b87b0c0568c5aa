"""The split's kernel in the core (hcvt.mesh.cut) against the whole-mesh check.

The search trusts the core's figures for a cut's parts; the final check is
``split.failing_faces`` on the whole mesh (numpy, ``hcvt.mesh.quality``). On real
boundary cells of the bunny and of the cheese (which has holes), each cut applied must give
a mesh whose parts fail exactly the faces, and have exactly the centres and volumes, the core
predicted. (The kernel replaced a Python version of itself; it matched it bit for bit on
these cells, planes and search steps before that version was removed.)
"""

from __future__ import annotations

import numpy as np
import pytest

import hcvt
from hcvt import _core
from hcvt.errors import InvalidMeshError
from hcvt.mesh.cut import cut_by_planes
from hcvt.mesh.split import Editor, _Journal, _newell, failing_faces
from helpers import DATA, random_inside

#: Failing cells tried per domain.
CELLS = 12


@pytest.mark.parametrize("name", ["bunny.off", "cheese.off"])
def test_the_cores_cut_is_what_the_mesh_then_measures(name: str) -> None:
    domain = hcvt.load_domain(DATA / "3d" / name)
    mesh = hcvt.voronoi(domain, random_inside(domain, 300, seed=5)).mesh()
    editor = Editor(mesh)
    bad = failing_faces(mesh)
    cells = np.unique(mesh.owner[bad]).tolist()
    checked = 0
    for c in cells[:: max(1, len(cells) // CELLS)]:
        faces = sorted(editor.cell_faces[c])
        loops = [editor.outward(c, k) for k in faces]
        if any(len(set(loop)) < len(loop) for loop in loops):
            continue  # a keyhole face: the search leaves it alone
        now = editor.measure_cell(c)
        assert now is not None and now[0] > 0
        normals = [_newell(editor.coords(loop)) for loop in loops]
        planes = [p for k in now[2] for p in editor.candidates(c, faces, loops, normals, k)]
        cuts = cut_by_planes(editor, c, faces, loops, planes)
        assert 0 < len(cuts) <= len(planes)
        for cut in (
            min(cuts, key=lambda x: (x.worst, x.oblique)),
            max(cuts, key=lambda x: x.worst),
        ):
            editor.journal = _Journal(len(editor.extra), len(editor.faces), len(editor.site), 0)
            parts = editor.apply(c, faces, cut)
            result, site = editor.mesh()
            core_centroid = np.array([editor.centroid[p] for p in parts])
            editor.undo()
            result.check()
            assert (site[parts] == c).all()
            volume, centroid = result.cell_geometry
            # The parts make up the cell, and their centres are the core's.
            assert volume[parts].sum() == pytest.approx(mesh.cell_geometry.volume[c], rel=1e-12)
            np.testing.assert_allclose(centroid[parts], core_centroid, rtol=0, atol=1e-12)
            # The faces of the parts that fail, as the whole mesh sees them.
            of_parts = np.isin(result.owner, parts) | np.isin(result.neighbour, parts)
            assert int((failing_faces(result) & of_parts).sum()) == cut.failing
            checked += 1
    print(f"\n{name}: {checked} cuts applied and measured")
    assert checked >= CELLS


def test_bad_input_is_an_invalid_mesh_error() -> None:
    points = np.eye(3)
    offsets = np.array([0, 3], dtype=np.int64)
    no_plane = np.zeros((0, 3))
    with pytest.raises(InvalidMeshError, match="face 0: vertex 5"):
        _core.cut_cell_3d(
            points,
            offsets,
            np.array([0, 1, 5]),
            np.array([-1]),
            no_plane,
            no_plane,
            no_plane,
        )
    with pytest.raises(InvalidMeshError, match="face 0: ghost 0, but 0 ghost centroids"):
        _core.cut_cell_3d(
            points, offsets, np.array([0, 1, 2]), np.array([0]), no_plane, no_plane, no_plane
        )
    with pytest.raises(InvalidMeshError, match="face 0: 2 vertices"):
        _core.measure_region_3d(
            points,
            np.array([0, 2], dtype=np.int64),
            np.array([0, 1]),
            np.array([0]),
            np.array([-1]),
            1,
            no_plane,
        )
