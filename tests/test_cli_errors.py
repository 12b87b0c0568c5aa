"""``hcvt show`` and ``hcvt run`` on bad input: one readable error, exit status 2, no traceback."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from hcvt.cli import main


def _invoke(*args: str):
    return CliRunner().invoke(main, list(args))


def _refused(result, *words: str) -> None:
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)
    for word in words:
        assert word in result.output


def test_show_draws_a_saved_result(tmp_path) -> None:
    sites = tmp_path / "sites.npy"
    np.save(sites, np.random.default_rng(0).uniform(0, 1, size=(50, 2)))
    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps({"input": "unit-square", "sites": str(sites)}))
    png = tmp_path / "cells.png"
    result = _invoke("show", str(summary), "--plot", str(png))
    assert result.exit_code == 0, result.output
    assert png.stat().st_size > 0


@pytest.mark.parametrize(
    ("content", "sites", "words"),
    [
        ("{not json", None, ["hcvt: error:"]),
        (json.dumps({"input": "unit-square"}), None, ["has no sites file"]),
        (json.dumps({"input": "unit-square", "sites": "missing.npy"}), None, ["missing.npy"]),
        (json.dumps({"input": "nowhere.geojson"}), [[0.5, 0.5]], ["no such file"]),
        (json.dumps({"input": "unit-square"}), [[0.5, 0.5], [0.5, 0.5]], ["coincide"]),
        (json.dumps({"input": "unit-square"}), [[0.5, np.nan]], ["non-finite"]),
        (json.dumps({"input": "unit-square"}), [[2.0, 0.5]], ["outside the domain"]),
        (json.dumps({"input": "unit-square"}), [[1.0, 2.0, 3.0]], ["shape"]),
    ],
)
def test_show_refuses_bad_results_in_one_message(tmp_path, content, sites, words) -> None:
    summary = tmp_path / "summary.json"
    if sites is not None:
        path = tmp_path / "sites.npy"
        np.save(path, np.asarray(sites, dtype=float))
        info = json.loads(content)
        info["sites"] = str(path)
        content = json.dumps(info)
    summary.write_text(content)
    _refused(_invoke("show", str(summary), "--plot", str(tmp_path / "x.png")), *words)


def test_run_refuses_unknown_inputs(tmp_path) -> None:
    _refused(_invoke("run", str(tmp_path / "missing.geojson"), "-n", "10"), "no such file")
    (tmp_path / "x.txt").write_text("")
    _refused(_invoke("run", str(tmp_path / "x.txt"), "-n", "10"), "unknown file type")
    (tmp_path / "y.geojson").write_text("{")
    _refused(_invoke("run", str(tmp_path / "y.geojson"), "-n", "10"), "cannot read")
