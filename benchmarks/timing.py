"""Timing shared by the benchmark scripts (run them from the repository root).

Wall-clock medians, a fresh child process for one measurement whose peak memory must
be its own (``run_child``), and the same cores for hcvt and its peers (``use_cores``).
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import time
from collections.abc import Callable

#: Python source defining ``status(key)``: the value of a line of ``/proc/self/status``
#: (``"VmHWM:"``, the peak resident memory; ``"VmRSS:"``, the present one) in MiB.
#: ``run_child`` defines it in every child.
PROC_STATUS = """
def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) / 1024
"""


def median_seconds(fn: Callable[..., object], repeats: int, *args: object) -> float:
    """Median wall time of ``repeats`` calls ``fn(*args)``, seconds."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn(*args)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def run_child(code: str, *args: object, env: dict[str, str] | None = None) -> list[str]:
    """Run ``code`` in a fresh Python process and return what it prints, split into words.

    ``args`` are its ``sys.argv[1:]`` (as strings) and ``env`` its environment (this
    process's by default); ``code`` may call ``status`` (``PROC_STATUS``). A fresh process
    measures its own peak memory (VmHWM), not the peak of the process that runs it.
    """
    out = subprocess.run(
        [sys.executable, "-c", PROC_STATUS + code, *map(str, args)],
        check=True,
        capture_output=True,
        text=True,
        env=env,
    )
    return out.stdout.split()


def use_cores(cores: int | None) -> str:
    """Give this process, hcvt and every peer in it alike, ``cores`` CPUs; describe what it got.

    ``None`` leaves the machine as it is: hcvt's default threads (one per available core)
    and each peer its own (pysdot's thread pool, pyacvd's OpenMP kd-tree: neither is
    single-threaded). A number pins every thread of the process to that many CPUs
    (``sched_setaffinity``) and sets ``OMP_NUM_THREADS``, re-executing the script once so
    that an OpenMP runtime loaded at start-up (``LD_PRELOAD``) reads it; the caller then
    gives hcvt the same number (``hcvt.set_num_threads``). Call it first in ``main``.
    """
    available = sorted(os.sched_getaffinity(0))
    if cores is None:
        return f"all {len(available)} cores: hcvt's default threads, each peer its own"
    if not 1 <= cores <= len(available):
        raise SystemExit(f"--cores must be 1..{len(available)}, got {cores}")
    chosen = set(available[:cores])
    for task in os.listdir("/proc/self/task"):
        os.sched_setaffinity(int(task), chosen)
    if os.environ.get("OMP_NUM_THREADS") != str(cores):
        os.environ["OMP_NUM_THREADS"] = str(cores)
        os.execv(sys.executable, sys.orig_argv)  # with the interpreter's own flags (-W ...)
    return f"{cores} core(s) for every code (CPU affinity; hcvt and OpenMP {cores} thread(s))"


def cpu_seconds() -> float:
    """User + system CPU seconds of this process so far (every thread's)."""
    times = os.times()
    return times.user + times.system
