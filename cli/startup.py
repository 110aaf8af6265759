"""Process-wide start-up tweaks of the command line, in one documented place.

The library never changes process-wide state; a command (its own process) may.  The trajectory
commands read their inputs inside :func:`numba_startup`:

- numba's import and the start of its runtime (on the first parse) create some 10^5 long-lived
  Python objects.  The cyclic garbage collector is paused meanwhile and those objects are frozen
  afterwards (``gc.freeze``), which spares several full collections over them.
- reading loads scipy's OpenBLAS, whose idle worker threads would spin for a while on the cores
  the parallel tokenizer is using; these commands only do 3x3 linear algebra, so that BLAS is
  loaded single-threaded (``OPENBLAS_NUM_THREADS=1`` is read at load time only, then removed).

Measured on ``ibiscape-eval ate`` over 1M TUM poses (2 shared cores, 12 alternating runs each):
best 2.37 s with these tweaks, 2.79 s without (-15 %); medians 2.83 s and 3.98 s.

``vio`` runs OpenCV on one thread (``ibiscape_eval.core.cpus.opencv_threads``, ``--cv-threads``): its per-frame
calls are small (KLT of ~200 corners, corner detection on a 512 px image), and OpenCV's thread
pool spent more CPU time handing them out than it saved.  Measured on the rendered 60 s drives at
512 px (quiet machine, ``benchmarks/bench_vio.py``): front end 5.7 / 6.4 / 9.5 ms per frame with
OpenCV's default threads, 4.2 / 5.4 / 7.4 ms with one; x real time by CPU time 3.93 / 3.29 / 2.83
-> 4.51 / 3.61 / 3.43, the wall time no slower (the same estimates, bit for bit).
"""

from __future__ import annotations

import contextlib
import gc
import os
from collections.abc import Iterator

__all__ = ["numba_startup"]


@contextlib.contextmanager
def numba_startup() -> Iterator[None]:
    """Run the block with the collector paused and single-threaded BLAS loading (see above)."""
    collecting = gc.isenabled()
    blas_threads = os.environ.get("OPENBLAS_NUM_THREADS")
    gc.disable()
    if blas_threads is None:
        os.environ["OPENBLAS_NUM_THREADS"] = "1"
    try:
        yield
    finally:
        if blas_threads is None:
            del os.environ["OPENBLAS_NUM_THREADS"]
        gc.freeze()
        if collecting:
            gc.enable()
