"""``ibiscape-eval benchmark``: wall time per step at the demo's scale (and larger), plus a cached
re-run.

Each scale runs the command as a fresh process on an empty folder with ``--no-cache`` (so every
job runs), then once more on the same folder with a fresh cache directory twice (the second run
finds every analysis job in the cache and every sequence already generated).  The per-step wall
times come from the report's JSON (``wall_s``).  There is no peer: no other tool runs the paper's
whole evaluation; the numbers say what a scale costs on this machine and how much of it each step
takes.  The load average is printed, since the machine may be shared.

Run: ``.venv/bin/python benchmarks/bench_benchmark.py [--scales 0.02,0.05] [--workers N]``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

EXE = str(Path(sys.executable).parent / "ibiscape-eval")
STEPS = ("suite", "camera_calibration", "imu_camera", "imu_noise", "hot_pixels", "vio", "evaluation")


def run(args: list[str]) -> tuple[float, dict]:
    t0 = time.perf_counter()
    proc = subprocess.run([EXE, *args, "--json"], capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        raise SystemExit(f"ibiscape-eval {' '.join(args)} failed:\n{proc.stderr[-2000:]}")
    return wall, json.loads(proc.stdout)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scales", default="0.02", help="comma-separated suite scales")
    ap.add_argument("--workers", type=int, default=None)
    a = ap.parse_args()
    extra = [] if a.workers is None else ["--workers", str(a.workers)]
    rows = []
    with tempfile.TemporaryDirectory(prefix="bench_benchmark_") as tmp:
        for scale in (float(s) for s in a.scales.split(",")):
            out = Path(tmp) / f"b{scale:g}"
            load0 = os.getloadavg()[0]
            wall, doc = run(["benchmark", str(out), "--scale", f"{scale:g}", "--no-cache", *extra])
            cache = Path(tmp) / f"cache{scale:g}"
            run(["benchmark", str(out), "--scale", f"{scale:g}", "--cache", str(cache), *extra])
            again, _ = run(["benchmark", str(out), "--scale", f"{scale:g}", "--cache", str(cache),
                            *extra])
            rows.append((scale, wall, again, doc, load0, os.getloadavg()[0]))
            shutil.rmtree(out, ignore_errors=True)
    head = f"{'scale':>6} {'total [s]':>10} " + " ".join(f"{s[:10]:>10}" for s in STEPS)
    print(head + f" {'re-run [s]':>10} {'jobs':>5} {'failed':>6} {'load':>10}")
    for scale, wall, again, doc, l0, l1 in rows:
        w = doc["wall_s"]
        print(f"{scale:>6g} {wall:>10.1f} " + " ".join(f"{w.get(s, 0.0):>10.1f}" for s in STEPS)
              + f" {again:>10.1f} {doc['summary']['n_jobs']:>5} {doc['summary']['n_failed']:>6}"
              f" {l0:>4.1f}-{l1:<4.1f}")
    print("(total: the whole command, start-up and report included; steps: wall time of each "
          "batch; re-run: the same folder and a filled cache)")


if __name__ == "__main__":
    main()
