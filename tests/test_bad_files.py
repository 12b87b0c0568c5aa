"""Every broken file of ../shared/data/{2d,3d}/bad through hcvt.load_domain and ``hcvt run``.

Each file either raises the documented error naming its defect (data README), or is
accepted (two valid but degenerate polygons); with ``repair=True`` the report says what
changed, and the diagram's cells add up to the repaired domain's volume.
"""

from __future__ import annotations

import importlib.util
import json
import math

import numpy as np
import pytest
from click.testing import CliRunner

import hcvt
from hcvt.cli import main
from helpers import DATA

# file: (word the error names without repair, or None if accepted; word of the report)
EXPECTED = {
    "2d/bad/bad_bowtie.geojson": ("outer ring crosses itself at (0.5, 0.5)", "made valid"),
    "2d/bad/bad_hole_shares_outer_edge.geojson": (
        "hole 0 shares an edge from (0, 3) to (0, 1) with the outer ring",
        "made valid",
    ),
    "2d/bad/bad_spike_zero_width.geojson": ("zero-width spike", "made valid"),
    "2d/bad/bad_duplicate_consecutive_vertices.geojson": (None, "removed 3 repeated"),
    "2d/bad/bad_hole_touches_outer_at_vertex.geojson": (None, "pinched"),
    "3d/bad/blobby-shuffled.off": ("inconsistent winding", "flipped"),
    "3d/bad/bunny.ply": ("non-manifold edges", "non-manifold"),
    "3d/bad/cow.obj": ("pinched", "pinched"),
    "3d/bad/elephant-with-holes.off": ("open boundary", "filled"),
    "3d/bad/featuretype.ply": ("duplicate vertices", "merged"),
    "3d/bad/stanford-bunny.obj": ("open boundary", "filled 5 holes"),
}
FILES = sorted(p.relative_to(DATA).as_posix() for p in DATA.glob("[23]d/bad/*.*"))
needs_data = pytest.mark.skipif(not FILES, reason="../shared/data not found")
needs_cvt = pytest.mark.skipif(
    importlib.util.find_spec("hcvt.seeding.initialisation") is None,
    reason="hcvt run needs hcvt.seeding.initialisation and hcvt.optimise (not on this branch yet)",
)


@needs_data
def test_every_bad_file_has_an_expectation() -> None:
    assert sorted(EXPECTED) == FILES


@needs_data
@pytest.mark.parametrize("name", FILES)
def test_load_names_the_defect_or_accepts(name: str) -> None:
    error, _ = EXPECTED[name]
    if error is None:
        domain = hcvt.load_domain(DATA / name)
        assert domain.volume > 0 and domain.repair_report is None
        return
    with pytest.raises(hcvt.InvalidDomainError) as info:
        hcvt.load_domain(DATA / name)
    message = str(info.value)
    assert error in message
    assert "repair=True" in message


@needs_data
@pytest.mark.parametrize("name", FILES)
def test_repair_reports_the_change_and_the_diagram_adds_up(name: str) -> None:
    domain = hcvt.load_domain(DATA / name, repair=True)
    report = domain.repair_report
    assert report is not None
    assert EXPECTED[name][1] in str(report)
    rng = np.random.default_rng(7)
    lo, hi = domain.bounds
    sites = rng.uniform(lo, hi, size=(300, domain.dim))
    d = hcvt.voronoi(domain, sites, allow_outside=True)
    assert np.isfinite(d.volume).all() and np.isfinite(d.centroid).all()
    assert np.isfinite(d.G[d.volume > 0]).all()
    total = math.fsum(d.volume)
    assert abs(total - domain.volume) <= 1e-12 * domain.volume, (total, domain.volume)


@needs_data
@pytest.mark.parametrize("name", [n for n in FILES if EXPECTED[n][0] is not None])
def test_cli_run_prints_the_defect_in_one_line(name: str) -> None:
    result = CliRunner().invoke(main, ["run", str(DATA / name), "-n", "100"])
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert result.output.startswith("hcvt: error: ")
    assert EXPECTED[name][0] in result.output
    assert "--repair" in result.output


@needs_data
@needs_cvt
@pytest.mark.parametrize("name", FILES)
def test_cli_run_with_repair(name: str, tmp_path) -> None:
    # --method voronoi: repair, 100 random sites and their diagram (the CVT of the
    # repaired Stanford bunny alone takes 20 s; the optimiser has its own tests).
    summary = tmp_path / "summary.json"
    args = ["run", str(DATA / name), "-n", "100", "--repair", "--method", "voronoi"]
    result = CliRunner().invoke(main, [*args, "--summary", str(summary)])
    assert result.exit_code == 0, result.output
    assert EXPECTED[name][1] in result.output
    assert "n = 100" in result.output
    assert json.loads(summary.read_text())["n"] == 100
