"""Test helpers: paths to the real data of ../shared/data and seeded random sites."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np

import hcvt

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
if not DATA.exists():  # CI clones next to shared/
    DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data"

POLYGON_FILES = sorted((DATA / "2d").glob("*.geojson"))
BAD_POLYGON_FILES = sorted((DATA / "2d" / "bad").glob("*.geojson"))


def random_inside(domain: hcvt.Domain, n: int, seed: int = 0) -> np.ndarray:
    """n uniform random points strictly inside ``domain`` (rejection in the box)."""
    rng = np.random.default_rng(seed)
    lo, hi = domain.bounds
    found: list[np.ndarray] = []
    count = 0
    while count < n:
        p = rng.uniform(lo, hi, size=(max(2 * n, 1000), domain.dim))
        p = p[domain.contains(p)]
        found.append(p)
        count += len(p)
    return np.concatenate(found)[:n]


def check_mesh_output(case: Path) -> str:
    """What OpenFOAM's checkMesh prints for ``case`` (``WM_PROJECT_DIR`` set if missing)."""
    env = {**os.environ}
    env.setdefault("WM_PROJECT_DIR", "/usr/share/openfoam")
    return subprocess.run(
        ["checkMesh", "-case", str(case)], capture_output=True, text=True, env=env, check=True
    ).stdout
