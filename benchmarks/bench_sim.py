"""Synthetic generator: a 60 s SVI sequence without rendering, and the still-IMU streaming rate.

    .venv/bin/python benchmarks/bench_sim.py            # 60 s SVI + still IMU 1 h (csv, npy)
    .venv/bin/python benchmarks/bench_sim.py --hours 6  # a longer still recording

Each run is ``ibiscape-eval sim`` in a fresh process (wall time and peak RSS from ``wait4``),
writing into a temporary folder that is deleted afterwards.  The peer is CARLA's acquisition,
which runs at best in real time (the paper's scripts tick the simulator once per 5 ms IMU step),
so the RATIO column is simulated seconds per wall-clock second (higher is better, 1 = CARLA at
real time).  Bounded memory: the still-IMU peak RSS is printed for two durations; it must not grow.
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _runner import run

CLI = str(Path(sys.executable).with_name("ibiscape-eval"))


def _sim(args: list[str], tmp: Path, name: str) -> tuple[float, float]:
    out = tmp / name
    r = run([CLI, "sim", *args, "--out", str(out)])
    if not r.ok:
        raise SystemExit(f"ibiscape-eval sim {' '.join(args)} failed")
    shutil.rmtree(out, ignore_errors=True)
    return r.wall_s, r.peak_mb


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hours", type=float, default=1.0, help="still-IMU duration of the long run")
    a = ap.parse_args()
    rows: list[tuple[str, float, float, str]] = []
    with tempfile.TemporaryDirectory(prefix="bench_sim_") as d:
        tmp = Path(d)
        for setup, kind in (("svi", "slam"), ("svi", "calibration"), ("full", "slam")):
            wall, mb = _sim(["--setup", setup, "--kind", kind, "--duration-s", "60"], tmp, setup + kind)
            rows.append((f"{setup} {kind} 60 s (no render)", wall, mb, f"{60 / wall:.1f}x real time"))
        for fmt in ("csv", "npy"):
            for hours in (a.hours / 6, a.hours):
                cfg = tmp / f"{fmt}.yaml"
                cfg.write_text(f"setup: imu\nstill_format: {fmt}\n")
                dur = hours * 3600
                wall, mb = _sim(["--config", str(cfg), "--duration-s", str(dur)], tmp, f"{fmt}{hours}")
                n = int(dur * 200) + 1
                rows.append((f"still IMU {hours:g} h {fmt} ({n / 1e6:.2f} M samples)", wall, mb,
                             f"{n / wall / 1e6:.2f} M samples/s = {dur / wall:.0f}x real time"))
    print(f"{'case':<42} {'wall [s]':>9} {'peak [MB]':>10}  RATIO vs CARLA (real time)")
    for name, wall, mb, ratio in rows:
        print(f"{name:<42} {wall:>9.2f} {mb:>10.0f}  {ratio}")
    print("168 h at 200 Hz = 121 M samples: extrapolate from the still-IMU rate above.")


if __name__ == "__main__":
    main()
