"""The package as a user's process sees it: what `import hcvt` loads and leaves alone."""

from __future__ import annotations

import subprocess
import sys

import pytest

HEAVY = ("matplotlib", "trimesh", "dask", "distributed", "rich", "geopandas", "pyproj", "pandas")


def run(code: str) -> str:
    """Run ``code`` in a fresh interpreter (sys.modules as a user's), return its stdout."""
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    return done.stdout.strip()


def test_import_hcvt_loads_no_heavy_dependency() -> None:
    code = f"import sys, hcvt; print([m for m in {HEAVY!r} if m in sys.modules])"
    assert run(code) == "[]"


def test_heavy_dependencies_load_when_used() -> None:
    code = (
        "import sys, hcvt; hcvt.plot; print('matplotlib' in sys.modules, 'trimesh' in sys.modules)"
    )
    assert run(code) == "True False"


@pytest.mark.parametrize("backend", ["svg", "pdf"])
def test_import_leaves_the_matplotlib_backend_alone(backend: str) -> None:
    # issue 16: hcvt.plot switched to Agg, which broke inline figures in Jupyter.
    code = (
        f"import matplotlib; matplotlib.use({backend!r}); import hcvt, hcvt.plot; "
        "import matplotlib.pyplot as plt; print(matplotlib.get_backend())"
    )
    assert run(code) == backend
