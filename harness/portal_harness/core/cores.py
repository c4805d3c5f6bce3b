"""The cores this process may use: for `auto` renderer threads (experiment
schema) and the number of concurrent renders (execution)."""

from __future__ import annotations

import os


def available_cores() -> int:
    """The cores this process may run on (its CPU affinity), for `auto` threads and the job count."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1
