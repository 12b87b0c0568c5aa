"""Cells as VTU pieces per part (``PartitionedDiagram.write_cells``) against one process.

For each case, in the same run: the single-process ``Diagram.mesh()`` and ``write_vtu`` of
all cells (the gathered way), and on a LocalCluster of ``--workers`` worker processes (one
dask thread each) the partitioned diagram's ``write_cells`` (pieces by the workers, the
index by the client). Prints the medians of ``--repeats`` runs, their ratio, the halo
sites of each round of the pieces and the peak RSS (VmHWM) of the workers and the client.

    OPENBLAS_NUM_THREADS=1 python benchmarks/pieces.py [--n2d 100000] [--n3d 20000]
        [--per-part 25000] [--workers 2] [--repeats 3]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import hcvt
from hcvt.distributed.driver import partitioned_voronoi
from hcvt.geometry import shapes
from hcvt.io.vtu import write_vtu

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
if not DATA.is_dir():
    DATA = Path("/work/shared/data")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--n2d", type=int, default=100_000)
    parser.add_argument("--n3d", type=int, default=20_000)
    parser.add_argument("--per-part", type=int, default=25_000)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    from dask.distributed import Client, LocalCluster

    cases = [
        ("unit square", shapes.unit_square(), args.n2d),
        (
            "polygon with a hole",
            hcvt.load_domain(DATA / "2d" / "triangle_square_circle_hole.geojson"),
            args.n2d,
        ),
        ("bunny", hcvt.load_domain(DATA / "3d" / "bunny.off"), args.n3d),
    ]
    cluster = LocalCluster(
        n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=None
    )
    with Client(cluster) as client, tempfile.TemporaryDirectory() as tmp:
        for name, domain, n in cases:
            sites = hcvt.initialise(domain, n=n, method="random", seed=1)
            one, parted_times = [], []
            parted = partitioned_voronoi(domain, sites, client, sites_per_partition=args.per_part)
            for _ in range(args.repeats):
                diagram = hcvt.voronoi(domain, sites)
                t = time.perf_counter()
                write_vtu(
                    diagram.mesh(),
                    Path(tmp) / "all.vtu",
                    cell_data={"volume": diagram.volume, "G": diagram.G},
                )
                one.append(time.perf_counter() - t)
                t = time.perf_counter()
                parted.write_cells(Path(tmp) / "cells.pvtu")
                parted_times.append(time.perf_counter() - t)
            a, b = statistics.median(one), statistics.median(parted_times)
            print(
                f"{name}, {n} sites, {parted.parts} parts of <= {args.per_part}: "
                f"one process mesh + write_vtu {a:.2f} s; write_cells on {args.workers} "
                f"workers {b:.2f} s (ratio {b / a:.2f}); halo sites per round "
                f"{parted.piece_rounds}; peak RSS MB "
                + ", ".join(f"{v:.0f}" for v in parted.peak_memory_mb().values())
            )
    cluster.close()


if __name__ == "__main__":
    main()
