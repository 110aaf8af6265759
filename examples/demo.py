"""``make demo``: the whole product on embedded data, no downloads.

Each step runs the real command line (``ibiscape-eval ...``) exactly as a user would type it, prints
the command and its output, and writes figures and files into ``--out`` (default ``demo-output``).

Steps:
  1. trajectory metrics on the real trajectories in ``examples/data`` (TUM RGB-D fr1/xyz, EuRoC V1_02,
     an ORB-SLAM monocular run that needs Sim(3)): ATE with every alignment, RPE, KITTI-style drift;
  2. IMU noise from the Allan deviation of a generated still-IMU record with known densities;
  3. DVS hot-pixel detection and filtering on a generated event stream with planted hot pixels.
"""

from __future__ import annotations

import argparse
import shlex
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

HERE = Path(__file__).resolve().parent
DATA = HERE / "data"
EXE = str(Path(sys.executable).parent / "ibiscape-eval")


def banner(text: str) -> None:
    print(f"\n{'=' * 100}\n{text}\n{'=' * 100}", flush=True)


def sh(*args: str | Path) -> None:
    """Run one ibiscape-eval command, echoing it; stop the demo if it fails."""
    argv = [EXE, *map(str, args)]
    print(f"\n$ ibiscape-eval {shlex.join(argv[1:])}", flush=True)
    t0 = time.perf_counter()
    proc = subprocess.run(argv, check=False)
    print(f"  [{time.perf_counter() - t0:.2f} s, exit {proc.returncode}]", flush=True)
    if proc.returncode != 0:
        raise SystemExit(f"demo step failed: {shlex.join(argv)}")


def trajectories(out: Path) -> None:
    banner("1. Trajectory metrics on real data (TUM RGB-D fr1/xyz, EuRoC V1_02, ORB-SLAM mono)")
    gt = DATA / "freiburg1_xyz-groundtruth.txt"
    sh(
        "ate",
        DATA / "freiburg1_xyz-rgbdslam.txt",
        gt,
        "--align",
        "se3",
        "--plot",
        out / "ate_fr1_rgbdslam.png",
        "--save-csv",
        out / "ate_fr1_rgbdslam.csv",
    )
    # A monocular run has an arbitrary scale: only Sim(3) alignment makes its ATE meaningful.
    sh(
        "ate",
        DATA / "freiburg1_xyz-ORB_kf_mono.txt",
        gt,
        "--align",
        "sim3",
        "--plot",
        out / "ate_fr1_orb_mono_sim3.png",
        "--save-aligned",
        out / "orb_mono_aligned.txt",
    )
    # VIO: gravity is observable, so align position + yaw only (4-DoF); estimate the time offset.
    sh(
        "ate",
        DATA / "V102.txt",
        DATA / "V102_groundtruth.csv",
        "--align",
        "yaw",
        "--estimate-offset",
        "--plot",
        out / "ate_v102_yaw.png",
    )
    sh(
        "rpe",
        DATA / "V102.txt",
        DATA / "V102_groundtruth.csv",
        "--delta",
        "1",
        "--delta-unit",
        "metres",
        "--pairs",
        "all",
        "--plot",
        out / "rpe_v102_1m.png",
    )
    sh("rpe", DATA / "freiburg1_xyz-rgbdslam.txt", gt, "--delta", "1", "--delta-unit", "seconds")
    sh(
        "drift",
        DATA / "V102.txt",
        DATA / "V102_groundtruth.csv",
        "--lengths-pct",
        "10,20,30,40,50",
        "--align",
        "yaw",
        "--plot",
        out / "drift_v102.png",
    )
    sh("ate", DATA / "V102.txt", DATA / "V102_groundtruth.csv", "--align", "sim3", "--json")


STEPS: list[tuple[str, Callable[[Path], None]]] = [
    ("trajectories", trajectories),
]


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--out", type=Path, default=Path("demo-output"))
    ap.add_argument("--only", choices=[name for name, _ in STEPS], default=None)
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    for name, step in STEPS:
        if args.only in (None, name):
            step(args.out)
    banner(f"demo finished in {time.perf_counter() - t0:.1f} s; figures and files in {args.out}/")
    for p in sorted(args.out.rglob("*")):
        if p.is_file():
            print(f"  {p}")


if __name__ == "__main__":
    main()
