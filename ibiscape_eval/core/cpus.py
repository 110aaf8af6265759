"""How many CPUs this process may run on (for the few kernels that split work across threads)."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

__all__ = ["opencv_threads", "usable_cpus"]


def usable_cpus() -> int:
    """CPUs in this process's affinity mask (what a container or ``taskset`` allows), >= 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover (not Linux)
        return os.cpu_count() or 1


@contextlib.contextmanager
def opencv_threads(n: int) -> Iterator[None]:
    """Run the block with ``cv2.setNumThreads(n)`` (``n <= 0``: leave OpenCV's setting), restored
    afterwards.  OpenCV's thread count is process-wide: the library calls this only where it owns
    the process's work (a batch job); the CLI's ``vio`` runs under it (``--cv-threads``)."""
    if n <= 0:
        yield
        return
    import cv2

    before = cv2.getNumThreads()
    cv2.setNumThreads(n)
    try:
        yield
    finally:
        cv2.setNumThreads(before)
