"""What the two-thread paths buy: the parallel TUM tokenizer and the metric kernels split in two.

Both paths are tested for identical results (tests/io/test_io_parallel_paths.py); this measures
their gain on 1M poses in the same process, best of ``--repeat`` warm runs, with the usable CPU
count forced to 1 (single-thread path) and then left as it is.  Run it on an otherwise idle machine:
with other jobs on the cores the threads have nothing to gain.

    .venv/bin/python benchmarks/bench_parallel_paths.py [--poses N] [--repeat R]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any


def best(fn: Callable[[], Any], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--poses", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()

    import numpy as np

    import ibiscape_eval.io._text as text
    import ibiscape_eval.metrics._fast as fast
    from ibiscape_eval import ate, read_trajectory
    from ibiscape_eval.core.cpus import usable_cpus

    n = args.poses
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "traj.txt"
        t = 1_305_031_098.0 + np.arange(n) * 0.01
        q = rng.normal(size=(n, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        np.savetxt(path, np.column_stack((t, rng.normal(size=(n, 3)) * 10, q)),
                   fmt=["%.6f"] + ["%.7f"] * 7)
        ref = read_trajectory(path, "tum")
        est = read_trajectory(path, "tum")
        ate(est, ref)  # compile and warm every kernel once

        def read() -> None:
            read_trajectory(path, "tum")

        def metric() -> None:
            ate(est, ref)

        rows = []
        for label, fn in (("read 1M-pose TUM", read), ("ate se3 on 1M poses", metric)):
            saved = (text.usable_cpus, fast._cpus)
            try:
                text.usable_cpus = lambda: 1  # type: ignore[assignment]
                fast._cpus = lambda: 1  # type: ignore[assignment]
                one = best(fn, args.repeat)
            finally:
                text.usable_cpus, fast._cpus = saved
            two = best(fn, args.repeat)
            rows.append((label, one, two))
    print(f"{n} poses, usable CPUs {usable_cpus()}, best of {args.repeat}")
    print(f"{'step':<24}{'1 thread [s]':>14}{'2 threads [s]':>15}{'RATIO 1/2':>11}")
    for label, one, two in rows:
        print(f"{label:<24}{one:>14.3f}{two:>15.3f}{one / two:>11.2f}")


if __name__ == "__main__":
    main()
