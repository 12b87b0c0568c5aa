"""Time this checkout against another build of hcvt, in the same run, case by case.

A refactoring must not cost speed (issue 29): each case runs in a fresh interpreter, once
with this checkout's package and once with the other build's (``--old``, a ``python/``
directory holding an ``hcvt`` package with its compiled ``_core``), alternating, and the
medians and the ratio new/old are printed. Build the old one with, for instance::

    git worktree add --detach /tmp/old 34a1fc5
    (cd /tmp/old && maturin build --release -o /tmp/old/dist)
    unzip -o -d /tmp/old/python /tmp/old/dist/*.whl 'hcvt/_core*'

    OPENBLAS_NUM_THREADS=1 python benchmarks/against_build.py --old /tmp/old/python [--quick]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
NEW = HERE.parent / "python"

# Each case prints one JSON number: the seconds of the timed call (setup excluded).
CASES = {
    "voronoi 2D, square, 200k": """
import time, numpy as np, hcvt
from hcvt.geometry import shapes
d = shapes.unit_square(); s = np.random.default_rng(0).random((200_000, 2))
hcvt.voronoi(d, s[:1000]); t = time.perf_counter(); hcvt.voronoi(d, s)
print(time.perf_counter() - t)
""",
    "voronoi 3D, bunny, 50k": """
import time, hcvt
d = hcvt.load_domain(DATA + "/3d/bunny.off"); s = hcvt.initialise(d, 50_000, seed=0)
hcvt.voronoi(d, s[:1000]); t = time.perf_counter(); hcvt.voronoi(d, s)
print(time.perf_counter() - t)
""",
    "cvt lbfgs, star, 10k, 40 iterations": """
import time, hcvt
from hcvt.geometry import shapes
d = shapes.star(); s = hcvt.initialise(d, 10_000, seed=0)
t = time.perf_counter(); hcvt.cvt(d, s, "lbfgs", max_iter=40)
print(time.perf_counter() - t)
""",
    "cvt newton, ball, 2k": """
import time, hcvt
from hcvt.geometry import shapes
d = shapes.ball(); s = hcvt.initialise(d, 2_000, seed=0)
t = time.perf_counter(); hcvt.cvt(d, s, "newton", max_iter=30)
print(time.perf_counter() - t)
""",
    "power diagram 3D, ball, 20k": """
import time, numpy as np, hcvt
from hcvt.geometry import shapes
d = shapes.ball(); s = hcvt.initialise(d, 20_000, method="random", seed=0)
w = np.random.default_rng(1).random(20_000) * 3 * (d.volume / 20_000) ** (2 / 3)
hcvt.voronoi(d, s[:1000], weights=w[:1000]); t = time.perf_counter(); hcvt.voronoi(d, s, weights=w)
print(time.perf_counter() - t)
""",
    "transport 3D, ball, 20k, equal masses": """
import time, numpy as np, hcvt
from hcvt.geometry import shapes
d = shapes.ball(); s = hcvt.initialise(d, 20_000, method="random", seed=0)
m = np.full(20_000, d.volume / 20_000)
t = time.perf_counter(); hcvt.optimal_transport(d, s, m)
print(time.perf_counter() - t)
""",
    "transport 2D, square, 10k, equal masses": """
import time, numpy as np, hcvt
from hcvt.geometry import shapes
d = shapes.unit_square(); s = np.random.default_rng(0).random((10_000, 2))
m = np.full(10_000, 1 / 10_000)
hcvt.optimal_transport(d, s[:1000], m[:1000] * 10); t = time.perf_counter()
hcvt.optimal_transport(d, s, m)
print(time.perf_counter() - t)
""",
    "mesh + quality, bunny, 10k": """
import time, hcvt
from hcvt.export import mesh_quality
d = hcvt.load_domain(DATA + "/3d/bunny.off")
v = hcvt.voronoi(d, hcvt.initialise(d, 10_000, seed=0))
t = time.perf_counter(); mesh_quality(v.mesh())
print(time.perf_counter() - t)
""",
}
# Before the layers (34a1fc5) the shapes were hcvt.shapes (an old build without hcvt/geometry).
OLD_NAMES = {"from hcvt.geometry import shapes": "from hcvt import shapes"}


def run(case: str, python_dir: Path, data: str, old: bool) -> float:
    code = CASES[case].replace("DATA", json.dumps(data))
    if old and not (python_dir / "hcvt" / "geometry").is_dir():
        for new_name, old_name in OLD_NAMES.items():
            code = code.replace(new_name, old_name)
    env = {**os.environ, "PYTHONPATH": str(python_dir), "OPENBLAS_NUM_THREADS": "1"}
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--old", type=Path, required=True, help="python/ dir of the old build")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="one run each")
    parser.add_argument("--cases", nargs="*", default=list(CASES))
    args = parser.parse_args()
    data = str(HERE.parents[1] / "shared" / "data")
    repeat = 1 if args.quick else args.repeat
    print(f"{'case':40s} {'old s':>9s} {'new s':>9s} {'new/old':>8s}")
    for case in args.cases:
        times: dict[bool, list[float]] = {True: [], False: []}
        for _ in range(repeat):
            for old in (True, False):  # alternate, so that load drifts hit both
                times[old].append(run(case, args.old if old else NEW, data, old))
        t_old, t_new = statistics.median(times[True]), statistics.median(times[False])
        print(f"{case:40s} {t_old:9.3f} {t_new:9.3f} {t_new / t_old:8.3f}")


if __name__ == "__main__":
    main()
