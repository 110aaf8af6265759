"""Opening a 1-hour EuRoC-layout folder: ``open_sequence`` against the issue's 2 s budget.

    .venv/bin/python benchmarks/bench_open_sequence.py

Writes a 1-hour EuRoC/ASL listing into a temporary folder (two cameras at 20 Hz: 72 000 rows
each in ``mav0/camN/data.csv``; the IMU at 200 Hz: 720 000 rows in ``mav0/imu0/data.csv``;
``sensor.yaml`` files of the real V1_01 excerpt with their ``%YAML:1.0`` header; an empty
ground-truth csv; no image files: opening must not touch them), then times, best of 3:

- ``open_sequence(folder)`` (frame lists read, IMU and images left for later),
- the peer: ``pandas.read_csv`` of the two frame lists alone (what any reader must at least do),

and prints both with their ratio, then the time to read the IMU on first use.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT / "tests" / "data" / "real" / "euroc_v1_01_kimera" / "mav0"


def write_listing(root: Path, hours: float = 1.0) -> Path:
    m = root / "mav0"
    t0 = 1_403_715_273_262_142_976
    n_cam = int(hours * 3600 * 20)
    n_imu = int(hours * 3600 * 200)
    for cam in ("cam0", "cam1"):
        (m / cam / "data").mkdir(parents=True)
        shutil.copy(REAL / cam / "sensor.yaml", m / cam / "sensor.yaml")
        st = t0 + np.arange(n_cam, dtype=np.int64) * 50_000_000
        with open(m / cam / "data.csv", "w") as f:
            f.write("#timestamp [ns],filename\n")
            f.write("\n".join(f"{t},{t}.png" for t in st.tolist()))
            f.write("\n")
    (m / "imu0").mkdir()
    shutil.copy(REAL / "imu0" / "sensor.yaml", m / "imu0" / "sensor.yaml")
    st = t0 + np.arange(n_imu, dtype=np.int64) * 5_000_000
    vals = np.random.default_rng(0).normal(size=(n_imu, 6))
    vals[:, 5] += 9.81
    with open(m / "imu0" / "data.csv", "w") as f:
        f.write("#timestamp [ns],w_x,w_y,w_z,a_x,a_y,a_z\n")
        np.savetxt(f, np.column_stack([st.astype(np.float64), vals]),
                   fmt=["%d"] + ["%.9f"] * 6, delimiter=",")
    (m / "state_groundtruth_estimate0").mkdir()
    (m / "state_groundtruth_estimate0" / "data.csv").write_bytes(b"")
    return root


def best(fn, k: int = 3) -> float:
    out = []
    for _ in range(k):
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
    return min(out)


def main() -> None:
    import pandas as pd

    from ibiscape_eval.io.open_sequence import open_sequence

    with tempfile.TemporaryDirectory(prefix="bench_open_") as d:
        root = write_listing(Path(d))
        open_sequence(root)  # imports and numba kernels once
        t_ours = best(lambda: open_sequence(root))
        t_peer = best(lambda: [pd.read_csv(root / "mav0" / c / "data.csv") for c in ("cam0", "cam1")])
        seq = open_sequence(root)
        t = time.perf_counter()
        st, _, _ = seq.imu.samples.get() if seq.imu else (np.zeros(0), None, None)
        t_imu = time.perf_counter() - t
        print(f"1-hour EuRoC listing: {len(seq.cameras[0])} frames x {len(seq.cameras)} cameras, "
              f"{st.size} IMU rows")
        print(f"open_sequence           {t_ours:7.3f} s   (budget 2 s)")
        print(f"pandas.read_csv lists   {t_peer:7.3f} s   ratio ours/pandas {t_ours / t_peer:.2f}")
        print(f"IMU on first use        {t_imu:7.3f} s")
        sys.exit(0 if t_ours < 2.0 else 1)


if __name__ == "__main__":
    main()
