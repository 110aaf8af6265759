"""Peak memory of reading a large IMU ``.npy`` chunk by chunk: ``readinto`` into one reused buffer
(what :class:`ibiscape_eval.io.imu.npy.NpyRows` does) against slicing ``np.load(mmap_mode="r")``.

Each reader runs in a fresh process (peak RSS from GNU time).  Pages of a memory map that have been
read count toward the process' resident memory until the kernel needs them back, so the map's peak
grows with the file (the 168-hour, 200 Hz record of ``bench_allan.py`` is ~5.8 GB), while
``readinto`` stays at one chunk.  Measured here (2 cores, 24 GB), 1.06 GB file: readinto 170 MB,
memory map 1065 MB.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np
from _runner import run

READER = """
import sys, numpy as np
path, mode = sys.argv[1], sys.argv[2]
total = 0.0
if mode == "readinto":
    from ibiscape_eval.io.imu.npy import NpyRows
    for b in NpyRows(path, first=1).iter_rows(1 << 20):
        total += float(np.asarray(b, dtype=np.float64).sum())
else:
    mm = np.load(path, mmap_mode="r")
    for i in range(0, mm.shape[0], 1 << 20):
        total += float(np.asarray(mm[i : i + (1 << 20), 1:7], dtype=np.float64).sum())
print(total)
"""

if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rows", type=int, default=19_000_000, help="rows of 7 float64 (19M: 1.06 GB)")
    a = ap.parse_args()
    from ibiscape_eval.io.imu import write_imu_npy

    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "imu.npy"
        chunk = 1 << 20
        write_imu_npy(path, (np.column_stack([np.arange(i, min(i + chunk, a.rows)) * 5e6,
                                              rng.normal(size=(min(chunk, a.rows - i), 6))])
                             for i in range(0, a.rows, chunk)))
        size_mb = path.stat().st_size / 1e6
        print(f"{'reader':<22}{'wall s':>8}{'peak RSS MB':>13}   file {size_mb:.0f} MB")
        sums = []
        for mode in ("readinto", "mmap"):
            r = run([sys.executable, "-c", READER, str(path), mode])
            sums.append(r.stdout.strip())
            print(f"{mode:<22}{r.wall_s:>8.2f}{r.peak_mb:>13.0f}")
        print(f"same sums: {sums[0] == sums[1] or abs(float(sums[0]) - float(sums[1])) < 1e-6}")
