"""The depth unit's check against the IMU (issue #24): the factor it measures on the right depth
and on depth misread by 5x, 0.2x and 1000x, per sequence, and what the check costs against the
whole RGB-D VIO run (CPU time of this process).

    ibiscape-eval sim --setup rgbd --weather clear --duration-s 60 --resolution 346x260 --out RGBD60_clear
    .venv/bin/python benchmarks/bench_depth_scale.py --sequences RGBD60_clear [--no-vio]

The misread depth is the right one times the factor (``measure_depth_scale(scale=...)``), so no
file is rewritten; the CLI's refusal of rewritten files is tested in
``tests/vio/test_vio_depth_unit.py``.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sequences", nargs="+", type=Path, required=True, help="RGB-D sequence folders")
    ap.add_argument("--scales", nargs="*", type=float, default=[1.0, 5.0, 0.2, 1000.0])
    ap.add_argument("--no-vio", action="store_true", help="skip the VIO run (the check's share of it)")
    a = ap.parse_args()

    from ibiscape_eval.io.open_sequence import open_sequence
    from ibiscape_eval.vio.inputs import stereo_inputs
    from ibiscape_eval.vio.pipeline import run_vio
    from ibiscape_eval.vio.scale_check import measure_depth_scale

    print(f"load average {os.getloadavg()[0]:.1f}")
    print(f"{'sequence':24s} {'weather':9s} {'depth x':>8s} {'status':>12s} {'factor':>9s} "
          f"{'sigma ln':>8s} {'window s':>11s} {'CPU s':>6s}")
    for folder in a.sequences:
        seq = stereo_inputs(open_sequence(folder), setup="rgbd")
        check_cpu = 0.0
        for scale in a.scales:
            c0 = time.process_time()
            r = measure_depth_scale(seq, scale=scale)
            cpu = time.process_time() - c0
            check_cpu = cpu if scale == 1.0 else check_cpu
            print(f"{folder.name:24s} {seq.weather or '?':9s} {scale:8g} {r.status:>12s} "
                  f"{r.factor:9.4g} {r.sigma_log:8.3f} {r.start_s:5.2f}-{r.end_s:5.2f} {cpu:6.2f}")
        if not a.no_vio:
            c0 = time.process_time()
            res = run_vio(seq)  # includes the check
            vio_cpu = time.process_time() - c0
            print(f"{folder.name:24s} VIO run {vio_cpu:.1f} s CPU for {res.stats.frames} frames, "
                  f"the check {check_cpu:.2f} s of it ({100 * check_cpu / vio_cpu:.1f} %)")


if __name__ == "__main__":
    main()
