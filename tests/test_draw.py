"""Jupyter display (issue 31): one-line reprs, pictures and HTML summaries, no pyplot."""

from __future__ import annotations

import io

import numpy as np
import pytest

import hcvt
from hcvt import draw
from test_package import run

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def unit_square() -> hcvt.Domain:
    return hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)])


@pytest.fixture(scope="module")
def result() -> hcvt.CVTResult:
    square = unit_square()
    return hcvt.cvt(square, hcvt.initialise(square, 150, seed=0))


def pixels(data: bytes) -> np.ndarray:
    import matplotlib.image

    return matplotlib.image.imread(io.BytesIO(data), format="png")


def test_reprs_are_one_line(result) -> None:
    for obj, start in [
        (result, "<hcvt.CVTResult n=150 d=2 converged (gap rule"),
        (result.diagram, "<hcvt.Diagram n=150 d=2 mean G="),
    ]:
        text = repr(obj)
        assert text.startswith(start), text
        assert "\n" not in text and len(text) < 200, text
        assert f"mean G={result.mean_G:.6f}" in text
    square = unit_square()
    levels = hcvt.hierarchical_cvt(square, 100, seed=0)
    assert repr(levels).startswith("<hcvt.HierarchicalResult n=100 d=2 levels ")
    assert "\n" not in repr(levels)


def test_png_shows_the_cells(result) -> None:
    data = result._repr_png_()
    assert data is not None and data.startswith(PNG_SIGNATURE)
    image = pixels(data)
    assert image.shape[0] > 200 and image.shape[1] > 200
    rgb = image[..., :3].reshape(-1, 3)
    # Many colours (cells by G, edges, colour bar), not a blank canvas.
    assert len(np.unique(np.round(rgb * 255).astype(int), axis=0)) > 50
    assert (rgb.min(axis=1) < 0.5).mean() > 0.1  # a good share of it is ink
    assert np.array_equal(result.diagram._repr_png_(), data)


def test_3d_png_is_a_cut_view() -> None:
    v = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    f = [(0, 2, 1), (0, 3, 2), (4, 5, 6), (4, 6, 7), (0, 1, 5), (0, 5, 4),
         (1, 2, 6), (1, 6, 5), (2, 3, 7), (2, 7, 6), (3, 0, 4), (3, 4, 7)]  # fmt: skip
    cube = hcvt.Domain.from_mesh(v, f)
    data = hcvt.voronoi(cube, hcvt.initialise(cube, 60, seed=0))._repr_png_()
    assert data is not None
    rgb = pixels(data)[..., :3].reshape(-1, 3)
    assert len(np.unique(np.round(rgb * 255).astype(int), axis=0)) > 50


def test_a_spherical_diagram_shows_its_cells_whole() -> None:
    # The sphere's cells() are polygons (k, 3), not (vertices, faces) pairs: drawn fanned
    # (raised "too many values to unpack" before).
    sphere = hcvt.Domain.sphere()
    diagram = hcvt.voronoi(sphere, hcvt.initialise(sphere, 200, method="fibonacci"))
    data = diagram._repr_png_()
    assert data is not None
    rgb = pixels(data)[..., :3].reshape(-1, 3)
    assert len(np.unique(np.round(rgb * 255).astype(int), axis=0)) > 50
    assert "<img" in diagram._repr_html_()


def test_html_has_summary_and_picture(result) -> None:
    text = result._repr_html_()
    assert "&lt;hcvt.CVTResult n=150" in text  # the repr, escaped
    assert "<th style='text-align:left'>RMS gap</th>" in text
    assert "mean G" in text and f"{result.mean_G:.6f}" in text
    assert "<img src='data:image/png;base64," in text


def test_large_diagrams_show_their_summary_only(result, monkeypatch) -> None:
    monkeypatch.setitem(draw.INLINE_LIMIT, 2, 100)
    assert result.diagram._repr_png_() is None
    text = result.diagram._repr_html_()
    assert "<img" not in text and "more than 100 cells: not drawn inline" in text


def test_ipython_shows_png_and_html(result) -> None:
    formatters = pytest.importorskip("IPython.core.formatters")
    shown, _ = formatters.format_display_data(result)
    assert {"text/plain", "image/png", "text/html"} <= set(shown)
    assert shown["text/plain"] == repr(result)


def test_pictures_leave_pyplot_and_the_backend_alone() -> None:
    # A notebook's inline backend must not be switched, nor a figure left open in pyplot.
    code = (
        "import sys, matplotlib; matplotlib.use('svg'); import hcvt; "
        "d = hcvt.Domain.from_polygon([(0, 0), (1, 0), (1, 1), (0, 1)]); "
        "v = hcvt.voronoi(d, hcvt.initialise(d, 30, seed=0)); "
        "loaded = 'matplotlib.pyplot' in sys.modules; "
        "png = v._repr_png_(); html = v._repr_html_(); "
        "print(loaded, 'matplotlib.pyplot' in sys.modules, matplotlib.get_backend(), len(png) > 0)"
    )
    assert run(code) == "False False svg True"
