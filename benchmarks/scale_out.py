"""Scale-out: one partitioned diagram / CVT on a LocalCluster with a memory limit per worker.

Cases (each on a fresh LocalCluster of ``--workers`` worker processes, one dask thread
each, ``--memory-limit`` each, so that a worker is restarted by its nanny if it exceeds it):

1. a diagram of ``--n2d`` random sites in the unit square (2D);
2. a diagram of ``--n3d`` random sites in the ball of volume 1.42 (3D);
3. ``--iters`` L-BFGS iterations from ``--nlbfgs`` random sites in the unit square;
4. ``ratio``: throughput of the partitioned 2D diagram of ``--nratio`` sites (``--workers``
   worker processes, one dask thread and one core thread each) against one process with
   ``--workers`` core threads, taking turns ``--repeats`` times in the same run, with the
   partitioned run's wall time split into the client's split, scatter, each round of
   halo growth (the workers' task time by kind, from dask's task stream) and the sums,
   and a gather to the client timed beside it. The load average (``uptime``) is printed
   at the start and the end: other processes on the machine share the cores.

For each: wall time, cells per second (cells of all diagrams over the wall time), the
rounds of halo growth (cells computed and halo sites per round), the halo sites moved
between workers (what travels, with 8 bytes per coordinate and per row number), and the
peak resident memory (VmHWM) of every worker and of the client. Beside them, in the same
run, the single-process diagram of ``--single`` sites (2D and 3D) in a child process: time,
cells/s and peak memory, whose per-site memory times the large n is what one process would
need (printed as "one process would need").

    OPENBLAS_NUM_THREADS=1 python benchmarks/scale_out.py [--quick]
        [--n2d 20000000] [--n3d 2000000] [--nlbfgs 10000000] [--iters 10]
        [--workers 2] [--memory-limit 6GB] [--per-part 1000000] [--single 1000000]
    OPENBLAS_NUM_THREADS=1 python benchmarks/scale_out.py --cases ratio --nratio 4000000
        [--repeats 2]
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import collections
import resource
import statistics
import subprocess
import sys
import time

import numpy as np

from hcvt.distributed.driver import partitioned_cvt, partitioned_voronoi
from hcvt.geometry import shapes

CHILD = """
import sys, time, numpy as np, hcvt
from hcvt.geometry import shapes
def hwm():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
dim, n = int(sys.argv[1]), int(sys.argv[2])
sys.path.insert(0, sys.argv[3])
if len(sys.argv) > 4:
    hcvt.set_num_threads(int(sys.argv[4]))
from scale_out import sites
domain = shapes.unit_square() if dim == 2 else shapes.ball()
sites = sites(dim, n)
before = hwm()
t = time.perf_counter()
d = hcvt.voronoi(domain, sites)
seconds = time.perf_counter() - t
print(seconds, before, hwm())
"""


def sites(dim: int, n: int, seed: int = 0) -> np.ndarray:
    """``n`` uniform random sites in the unit square (2D) or the ball of volume 1.42 (3D)."""
    rng = np.random.default_rng(seed)
    if dim == 2:
        return rng.random((n, 2))
    # The ball is a triangle mesh: keep the points its exact winding number puts inside.
    ball = shapes.ball()
    radius = (3 * shapes.BALL_VOLUME / (4 * np.pi)) ** (1 / 3)
    out = np.empty((0, 3))
    while len(out) < n:
        batch = rng.uniform(-radius, radius, (2 * (n - len(out)) + 16, 3))
        batch = batch[(batch**2).sum(axis=1) < radius**2]
        out = np.concatenate([out, batch[ball.contains(batch)]])
    return out[:n]


def single_process(dim: int, n: int, threads: int | None = None) -> tuple[float, float]:
    """Seconds and peak MB (VmHWM growth) of one in-process diagram, in a child process.

    ``threads``: the core's thread count there (default: the core's default).
    """
    here = os.path.dirname(os.path.abspath(__file__))
    command = [sys.executable, "-c", CHILD, str(dim), str(n), here]
    if threads is not None:
        command.append(str(threads))
    child = subprocess.run(command, capture_output=True, text=True)
    if child.returncode:
        raise RuntimeError(f"single-process diagram failed:\n{child.stderr}")
    out = child.stdout.split()
    seconds, before, after = (float(x) for x in out)
    return seconds, after - before


def cluster(workers: int, memory_limit: str):
    from dask.distributed import Client, LocalCluster

    c = LocalCluster(
        n_workers=workers,
        threads_per_worker=1,
        processes=True,
        memory_limit=memory_limit,
        dashboard_address=None,
    )
    return c, Client(c)


def report_memory(memory: dict[str, float]) -> str:
    workers = [v for k, v in memory.items() if k != "client"]
    return (
        f"peak RSS MB: workers {', '.join(f'{w:.0f}' for w in workers)}; "
        f"client {memory['client']:.0f}"
    )


def diagram_case(dim: int, n: int, args: argparse.Namespace) -> None:
    domain = shapes.unit_square() if dim == 2 else shapes.ball()
    points = sites(dim, n)
    cl, client = cluster(args.workers, args.memory_limit)
    try:
        t = time.perf_counter()
        per_part = args.per_part_3d if dim == 3 and args.per_part_3d else args.per_part
        parted = partitioned_voronoi(domain, points, client, sites_per_partition=per_part)
        seconds = time.perf_counter() - t
        halo = sum(parted.rounds.halo)
        print(
            f"{dim}D diagram, n = {n:,}: {parted.parts} parts, {seconds:.1f} s, "
            f"{n / seconds:,.0f} cells/s, energy {parted.energy:.10g}, mean G {parted.mean_G:.6f}"
        )
        print(
            f"  rounds: cells {parted.rounds.cells}, halo sites {parted.rounds.halo} "
            f"({halo / n:.3f} per site; {halo * (dim + 1) * 8 / 2**20:.0f} MiB moved)"
        )
        print("  " + report_memory(parted.peak_memory_mb()))
    finally:
        client.close()
        cl.close()


def lbfgs_case(n: int, iters: int, args: argparse.Namespace) -> None:
    domain = shapes.unit_square()
    points = sites(2, n)
    cl, client = cluster(args.workers, args.memory_limit)
    try:
        t = time.perf_counter()
        res = partitioned_cvt(
            domain,
            points,
            "lbfgs",
            client,
            tol=0,
            max_iter=iters,
            sites_per_partition=args.per_part,
            checkpoint=False,
        )
        seconds = time.perf_counter() - t
        h = res.history
        diagrams = int(h["evaluations"][-1])
        print(
            f"2D L-BFGS, n = {n:,}: {iters} iterations, {diagrams} diagrams, {seconds:.1f} s "
            f"({seconds / diagrams:.1f} s per diagram, {n * diagrams / seconds:,.0f} cells/s); "
            f"energy {h['energy'][0]:.8g} -> {h['energy'][-1]:.8g}, RMS gap "
            f"{h['rms_gap'][0]:.3g} -> {h['rms_gap'][-1]:.3g}; sites migrated "
            f"{int(h['migrated'].sum()):,}"
        )
        print("  " + report_memory(res.diagram.peak_memory_mb()))
    finally:
        client.close()
        cl.close()


def uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def children_cpu() -> float:
    """CPU seconds (user + system) of the finished child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def workers_cpu(client) -> float:
    """CPU seconds of every worker process so far (all its threads), summed."""
    return sum(client.run(time.process_time).values())


def _core_threads(n: int) -> int:
    import hcvt

    hcvt.set_num_threads(n)
    return hcvt.get_num_threads()


def task_seconds(stream: list[dict]) -> dict[str, float]:
    """Seconds of worker time by task kind (``part_cells``, ...) and action (transfer, ...)."""
    from dask.utils import key_split

    out: dict[str, float] = collections.defaultdict(float)
    for task in stream:
        name = key_split(task["key"])
        for span in task["startstops"]:
            label = name if span["action"] == "compute" else span["action"]
            out[label] += span["stop"] - span["start"]
    return dict(out)


def partitioned_turn(client, domain, points, per_part: int) -> tuple[float, float]:
    """One partitioned diagram: print where its wall time went; (seconds, gather seconds)."""
    from dask.distributed import get_task_stream

    cpu = workers_cpu(client), time.process_time()
    with get_task_stream(client) as stream:
        t = time.perf_counter()
        parted = partitioned_voronoi(domain, points, client, sites_per_partition=per_part)
        seconds = time.perf_counter() - t
    cpu = workers_cpu(client) - cpu[0], time.process_time() - cpu[1]
    t = time.perf_counter()
    gathered = parted.gather()
    gather_seconds = time.perf_counter() - t
    nbytes = sum(
        getattr(gathered, k).nbytes
        for k in ("volume", "centroid", "second_moment", "G", "neighbor_sites")
    )
    del gathered
    split = parted.timings
    r = parted.rounds
    rounds = ", ".join(
        f"{s:.2f} s ({c:,} cells, {h:,} halo sites)"
        for s, c, h in zip(r.seconds, r.cells, r.halo, strict=True)
    )
    work = task_seconds(stream.data)
    busy = sum(v for k, v in work.items())
    print(
        f"  partitioned: {seconds:.2f} s, {len(points) / seconds:,.0f} cells/s, {parted.parts} "
        f"parts; client: split {split['split']:.2f} s, scatter {split['scatter']:.2f} s, "
        f"rounds {rounds}, sums {split['sums']:.2f} s"
    )
    print(f"    CPU seconds: workers {cpu[0]:.2f}, client {cpu[1]:.2f}")
    print(
        "    worker task seconds: "
        + ", ".join(f"{k} {v:.2f}" for k, v in sorted(work.items(), key=lambda kv: -kv[1]))
        + f"; idle {max(len(client.scheduler_info()['workers']) * seconds - busy, 0):.2f}"
    )
    print(
        f"    gather to the client (not in the time above): {gather_seconds:.2f} s, "
        f"{nbytes / 2**20:.0f} MiB of main arrays"
    )
    return seconds, gather_seconds


def ratio_case(args: argparse.Namespace) -> None:
    """Partitioned against single-process cells/s, taking turns, in one run."""
    n, workers = args.nratio, args.workers
    per_part = args.per_part_ratio or -(-n // workers)
    domain = shapes.unit_square()
    points = sites(2, n)
    print(f"start: {uptime()}")
    print(
        f"2D diagram of {n:,} uniform random sites in the unit square (under load): one "
        f"process with {workers} core threads against {workers} worker processes of one dask "
        f"thread and one core thread each, parts of at most {per_part:,} sites"
    )
    cl, client = cluster(workers, args.memory_limit)
    single, parted = [], []
    try:
        client.run(_core_threads, 1)
        for turn in range(args.repeats):
            cpu = children_cpu()
            seconds, _ = single_process(2, n, threads=workers)
            single.append(seconds)
            print(
                f"turn {turn + 1}: single process: {seconds:.2f} s, {n / seconds:,.0f} cells/s; "
                f"CPU seconds {children_cpu() - cpu:.2f} (with making the sites)"
            )
            parted.append(partitioned_turn(client, domain, points, per_part)[0])
            print(f"  ratio this turn, partitioned / single cells/s: {seconds / parted[-1]:.2f}")
    finally:
        client.close()
        cl.close()
    s, p = statistics.median(single), statistics.median(parted)
    print(
        f"median of {args.repeats} turns: single process {n / s:,.0f} cells/s, partitioned "
        f"{n / p:,.0f} cells/s: ratio {s / p:.2f} (target >= 0.6), under load"
    )
    print(f"end: {uptime()}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="1/100 of the sizes")
    parser.add_argument("--n2d", type=int, default=20_000_000)
    parser.add_argument("--n3d", type=int, default=2_000_000)
    parser.add_argument("--nlbfgs", type=int, default=10_000_000)
    parser.add_argument("--iters", type=int, default=10)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--memory-limit", default="6GB")
    parser.add_argument("--per-part", type=int, default=1_000_000)
    parser.add_argument("--per-part-3d", type=int, default=None, help="default: --per-part")
    parser.add_argument("--single", type=int, default=1_000_000)
    parser.add_argument("--nratio", type=int, default=4_000_000)
    parser.add_argument("--repeats", type=int, default=2, help="turns of the ratio case")
    parser.add_argument(
        "--per-part-ratio", type=int, default=None, help="default: one part per worker"
    )
    parser.add_argument(
        "--cases",
        nargs="*",
        default=["single", "2d", "3d", "lbfgs"],
        help="any of single, 2d, 3d, lbfgs, ratio",
    )
    args = parser.parse_args()
    if args.quick:
        args.n2d, args.n3d, args.nlbfgs = args.n2d // 100, args.n3d // 100, args.nlbfgs // 100
        args.single, args.per_part = args.single // 100, args.per_part // 100
        args.nratio //= 100
    print(
        f"{args.workers} workers, memory limit {args.memory_limit} each, at most "
        f"{args.per_part:,} sites per part"
    )
    if "single" in args.cases:
        for dim, big in ((2, args.n2d), (3, args.n3d)):
            seconds, mb = single_process(dim, args.single)
            per_site = mb * 2**20 / args.single
            print(
                f"single process {dim}D diagram, n = {args.single:,}: {seconds:.1f} s, "
                f"{args.single / seconds:,.0f} cells/s, peak +{mb:.0f} MB "
                f"({per_site:.0f} B/site); one process would need "
                f"{per_site * big / 2**30:.1f} GiB for n = {big:,}"
            )
    cases = {
        "2d": lambda: diagram_case(2, args.n2d, args),
        "3d": lambda: diagram_case(3, args.n3d, args),
        "lbfgs": lambda: lbfgs_case(args.nlbfgs, args.iters, args),
        "ratio": lambda: ratio_case(args),
    }
    for name, case in cases.items():
        if name in args.cases:
            try:
                case()
            except Exception as err:  # a worker over its memory limit: say so, go on
                print(f"{name}: FAILED ({type(err).__name__}: {str(err)[:200]})")


if __name__ == "__main__":
    main()
