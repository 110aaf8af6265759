"""How many CPUs this process may run on (for the few kernels that split work across threads)."""

from __future__ import annotations

import os

__all__ = ["usable_cpus"]


def usable_cpus() -> int:
    """CPUs in this process's affinity mask (what a container or ``taskset`` allows), >= 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover (not Linux)
        return os.cpu_count() or 1
