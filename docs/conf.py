"""Sphinx configuration of hcvt's documentation (issue 31).

Built by ``tests/test_docs.py`` (``sphinx-build -W``): every warning fails the tests.
The API reference is generated from the docstrings (numpydoc) of every name in
``hcvt.__all__``; the gallery runs the ``examples/plot_*.py`` scripts (sphinx-gallery);
Markdown pages (``results.md``, ``architecture.md``) go through myst-parser.
"""

from __future__ import annotations

import os
from pathlib import Path

import hcvt

os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
HERE = Path(__file__).resolve().parent

project = "hcvt"
author = "the hcvt developers"
copyright = "2026, the hcvt developers"  # noqa: A001 (Sphinx's name)
release = version = hcvt.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
templates_path = ["_templates"]
# results/ holds the raw outputs results.md links to (tables, logs), not pages.
exclude_patterns = ["_build", "results/*.md", "**.ipynb_checkpoints"]
html_theme = "alabaster"
html_theme_options = {
    "description": "exact clipped Voronoi diagrams and CVTs",
    "fixed_sidebar": True,
}
html_static_path: list[str] = []

autosummary_generate = True
autodoc_default_options = {"members": True, "member-order": "bysource"}
autodoc_typehints = "none"  # the numpydoc Parameters sections say the types, with shapes
numpydoc_show_class_members = False  # members documented by autodoc, once
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

myst_heading_anchors = 3

sphinx_gallery_conf = {
    "examples_dirs": str(HERE.parent / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",  # run these; examples/density.py is a long job
    "ignore_pattern": r"(^|[/\\])(?!plot_)[^/\\]+\.py$",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "reset_modules": ("matplotlib",),
    "image_scrapers": ("matplotlib",),
    "min_reported_time": 1,
}
