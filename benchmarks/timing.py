"""Timing shared by the benchmark scripts (run them from the repository root).

Wall-clock medians, and a fresh child process for one measurement whose peak memory must
be its own (``run_child``).
"""

from __future__ import annotations

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
