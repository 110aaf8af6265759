"""Trajectory text I/O at 1M poses: ibiscape-eval vs evo (parse), plus write time and peak memory.

Run: ``.venv/bin/python benchmarks/bench_trajectory_io.py [N]`` (default 1_000_000 poses).
Each measurement runs in a fresh process so that peak RSS (ru_maxrss) belongs to it alone.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = r"""
import resource, sys, time, warnings
import numpy as np
what, path = sys.argv[1], sys.argv[2]
if what == "ours_read":
    from ibiscape_eval.io import read_trajectory
    small = path + ".small.txt"
    with open(path, "rb") as f, open(small, "wb") as g:
        g.write(b"".join(f.readline() for _ in range(10)))
    read_trajectory(small, "tum")  # warm-up: numba cache load
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t = time.perf_counter(); tr = read_trajectory(path, "tum"); dt = time.perf_counter() - t
elif what == "evo_read":
    from evo.tools import file_interface
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t = time.perf_counter(); tr = file_interface.read_tum_trajectory_file(path)
    dt = time.perf_counter() - t
elif what == "ours_write":
    from ibiscape_eval.io import read_trajectory, write_trajectory
    tr = read_trajectory(path, "tum")
    write_trajectory(path + ".w.txt", tr.take(np.arange(10)), "tum")  # warm-up
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t = time.perf_counter(); write_trajectory(path + ".w.txt", tr, "tum")
    dt = time.perf_counter() - t
elif what == "evo_write":
    from evo.tools import file_interface
    tr = file_interface.read_tum_trajectory_file(path)
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t = time.perf_counter(); file_interface.write_tum_trajectory_file(path + ".e.txt", tr)
    dt = time.perf_counter() - t
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(f"{dt:.4f} {peak / 1024:.0f} {(peak - base) / 1024:.0f}")
"""


def run(what: str, path: Path) -> tuple[float, float, float]:
    out = subprocess.run([sys.executable, "-c", CHILD, what, str(path)], check=True,
                         capture_output=True, text=True).stdout.split()
    return float(out[0]), float(out[1]), float(out[2])


def main() -> None:
    import numpy as np

    n = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "traj.txt"
        t = 1_305_031_098.0 + np.arange(n) * 0.01 + rng.uniform(0, 1e-3, n)
        q = rng.normal(size=(n, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        data = np.column_stack((t, rng.normal(size=(n, 3)) * 10, q))
        np.savetxt(path, data, fmt=["%.6f"] + ["%.7f"] * 7)
        print(f"{n} poses, {path.stat().st_size / 1e6:.0f} MB TUM file")
        print(f"{'step':<10} {'ibiscape-eval s':>16} {'evo s':>8} {'RATIO evo/ours':>15} "
              f"{'our peak MB':>12} {'our delta MB':>13}")
        for step in ("read", "write"):
            ours = run(f"ours_{step}", path)
            evo = run(f"evo_{step}", path)
            print(f"{step:<10} {ours[0]:>16.3f} {evo[0]:>8.3f} {evo[0] / ours[0]:>15.1f} "
                  f"{ours[1]:>12.0f} {ours[2]:>13.0f}")


if __name__ == "__main__":
    main()
