"""The core's allocator told to return freed memory at once, before the binding loads.

The core allocates through mimalloc (``crates/hcvt-py/src/lib.rs``), which by default
returns a freed page to the system 10 ms after the free, and only when the thread that
owns it allocates again: the batches a diagram's workers drop stay resident while its
result is assembled, and one diagram's peak moved by ~20% from run to run (2D 1M:
217-221 B/site purging at once, 244-284 with the default delay; issue 32, memory per
site, docs/results/memory.txt). mimalloc reads ``MIMALLOC_PURGE_DELAY`` when the binding
is loaded: it is set to 0 for that moment unless the user set it, and the environment is
restored after (child processes see the user's).
"""

from __future__ import annotations

import os

PURGE_DELAY = "MIMALLOC_PURGE_DELAY"
_ours = PURGE_DELAY not in os.environ
if _ours:
    os.environ[PURGE_DELAY] = "0"
try:
    from hcvt import _core  # noqa: E402, F401 (loaded here, with the option set)
finally:
    if _ours:
        del os.environ[PURGE_DELAY]
