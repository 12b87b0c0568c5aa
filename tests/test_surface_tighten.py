"""The Hausdorff step of remeshing (issue 33): ``hcvt.remesh(tighten=True)``.

Checked another way: on the kitten, the Hausdorff distance measured by
:func:`hcvt.surface_quality` (to 0.1%, not sampled) before and after the moves, the least
angle and Q before and after, the vertices on the input (the core's nearest points), no triangle
turned over.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

import hcvt
from hcvt.geometry.surface_points import closest_points
from hcvt.surface.quality import triangle_angles, triangle_quality
from hcvt.surface.remesh import TIGHTEN_MIN_ANGLE
from hcvt.surface.tighten import tighten
from helpers import DATA

DATA_3D = DATA / "3d"
needs_data = pytest.mark.skipif(not DATA_3D.is_dir(), reason="../shared/data/3d not found")


@cache
def kitten_remeshed() -> tuple[hcvt.Domain, hcvt.RemeshResult]:
    domain = hcvt.load_domain(DATA_3D / "kitten.obj", surface=True)
    return domain, hcvt.remesh(domain, 1000, seed=0, tighten=False, density=None)


@needs_data
def test_tighten_lowers_the_hausdorff_distance_of_the_kitten() -> None:
    domain, out = kitten_remeshed()
    reference = (domain.vertices, domain.faces)
    before = hcvt.surface_quality(out.vertices, out.faces, reference)
    moved = tighten(out.vertices, out.faces, domain, min_angle=30.0)
    after = hcvt.surface_quality(moved.vertices, out.faces, reference)
    assert moved.moves > 0 and moved.after < moved.before
    # Measured so (the spread start's mesh, certified distances): 1.091% -> 0.653% with 30°
    # (61 moves; 0.662% in 54 before tighten's changes of 2026-12-05, branch rtight). Moving
    # single vertices toward the sampled worst places only, and stopping where none could
    # move, left 0.731% (33 moves; seeds 1, 2: 0.747%, 0.835% against 0.720%, 0.707%): the
    # neighbours that follow a vertex, the mesh's vertices moved into the hollows its
    # triangles span and the finer search near the worst distance (tighten's module docs) take
    # it below 0.68%.
    assert after.hausdorff < 0.68
    assert after.angle_min >= 30.0 - 1e-9
    assert after.q_min >= before.q_min - 1e-12
    # The vertices stay on the input, the triangles face the same way.
    on, _ = closest_points(domain.vertices, domain.faces, moved.vertices)
    assert np.abs(on - moved.vertices).max() < 1e-12
    f = out.faces
    n0 = np.cross(
        out.vertices[f[:, 1]] - out.vertices[f[:, 0]],
        out.vertices[f[:, 2]] - out.vertices[f[:, 0]],
    )
    n1 = np.cross(
        moved.vertices[f[:, 1]] - moved.vertices[f[:, 0]],
        moved.vertices[f[:, 2]] - moved.vertices[f[:, 0]],
    )
    assert np.all(np.einsum("ij,ij->i", n0, n1) > 0)


@needs_data
def test_remesh_tightens_by_default_and_keeps_its_quality() -> None:
    domain, plain = kitten_remeshed()
    out = hcvt.remesh(domain, 1000, seed=0, density=None)
    np.testing.assert_array_equal(out.faces, plain.faces)  # the connectivity is the CVT's
    assert out.moves > 0 and out.defects == []
    assert out.quality.hausdorff < plain.quality.hausdorff
    # The default floor: 30°, or the CVT mesh's own least angle where that is lower.
    floor = min(TIGHTEN_MIN_ANGLE, plain.quality.angle_min)
    assert triangle_angles(out.vertices, out.faces).min() >= floor - 1e-9
    q = triangle_quality(out.vertices, out.faces).min()
    assert q >= triangle_quality(plain.vertices, plain.faces).min() - 1e-12
