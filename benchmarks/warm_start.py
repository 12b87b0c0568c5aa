"""Cold against warm-started diagrams at a late CVT iterate (issue 32).

Every CVT now starts each diagram from the previous one's near-site lists
(``crates/hcvt-core/src/diagram/warm.rs``); the cells are the cold ones bit for bit. For
each case this script writes the domain's boundary as text, runs the Rust example
``warm_start`` (an L-BFGS CVT of ``--iterations`` steps from random sites, then Lloyd
steps from that late iterate, each diagram computed cold and warm in turn) and prints the
median per-diagram times, their ratio, and whether the two chains of diagrams agreed bit
for bit. Timings are of the shared machine, under load from other jobs.

    python benchmarks/warm_start.py [--cases square:20000 ball:20000 ...] [--threads 2]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import tempfile
from pathlib import Path

import numpy as np

import hcvt
from hcvt.geometry import shapes

ROOT = Path(__file__).resolve().parent.parent
DATA = ROOT.parent / "shared" / "data"
DOMAINS = {
    "square": lambda: shapes.square(),
    "star": lambda: shapes.star(),
    "ball": lambda: hcvt.load_domain(DATA / "3d" / "sphere.ply"),
    "bunny": lambda: hcvt.load_domain(DATA / "3d" / "bunny.off"),
}
DEFAULT_CASES = ["square:20000", "star:20000", "ball:20000", "bunny:20000"]


def write_boundary(name: str, prefix: Path) -> int:
    """Write domain ``name``'s boundary as ``prefix_v.txt`` and ``prefix_f.txt``.

    Returns the domain's dimension.
    """
    domain = DOMAINS[name]()
    vertices = np.asarray(domain.vertices)
    if domain.dim == 2:
        # The 2D shapes here are one ring, its vertices in order.
        m = len(vertices)
        faces = np.stack([np.arange(m), (np.arange(m) + 1) % m], axis=1)
    else:
        faces = np.asarray(domain.faces)
    np.savetxt(f"{prefix}_v.txt", vertices, fmt="%.17g")
    np.savetxt(f"{prefix}_f.txt", faces, fmt="%d")
    return int(domain.dim)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="+", default=DEFAULT_CASES, help="NAME:SITES")
    parser.add_argument("--iterations", type=int, default=100, help="L-BFGS steps first")
    parser.add_argument("--steps", type=int, default=6, help="Lloyd steps timed")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=2)
    args = parser.parse_args()
    subprocess.run(
        ["cargo", "build", "--release", "-q", "-p", "hcvt-core", "--example", "warm_start"],
        cwd=ROOT,
        check=True,
    )
    binary = ROOT / "target" / "release" / "examples" / "warm_start"
    env = dict(os.environ, RAYON_NUM_THREADS=str(args.threads))
    print(f"warm-started diagrams, {args.threads} threads (timings under load)")
    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        for case in args.cases:
            name, sites = case.split(":")
            prefix = Path(tmp) / name
            dim = write_boundary(name, prefix)
            run = subprocess.run(
                [binary, str(dim), str(prefix), sites]
                + [str(args.iterations), str(args.steps), str(args.repeats)],
                env=env,
                capture_output=True,
                text=True,
            )
            print(f"{name} {sites}:")
            for line in (run.stdout + run.stderr).strip().splitlines():
                print(f"  {line}")
            failed |= run.returncode != 0
    if failed:
        raise SystemExit("warm and cold diagrams differ (or a case failed)")


if __name__ == "__main__":
    main()
