"""Grey PNG decoding for the VIO: ``ibiscape_eval.io.images.decode_png_grey`` (libdeflate inflate +
numba unfilter/grey) against OpenCV's ``cv2.imdecode(..., IMREAD_GRAYSCALE)`` (libpng + zlib), on
the same bytes in memory, checking that both give the same pixels.

    .venv/bin/python benchmarks/bench_png.py                        # renders 1 s at 512 and 1024 px
    .venv/bin/python benchmarks/bench_png.py --frames SVI_clear_512/rgbL/frames ...

CPU milliseconds per image (process CPU time, one OpenCV thread), the ratio OpenCV / ours (> 1:
ours faster), and the peak RSS of the process.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

CLI = str(Path(sys.executable).with_name("ibiscape-eval"))
REAL = Path(__file__).resolve().parents[1] / "tests" / "data" / "real"


def _render(out: Path, resolution: int) -> Path:
    cmd = [CLI, "sim", "--setup", "svi", "--kind", "slam", "--weather", "clear", "--seed", "1",
           "--duration-s", "1", "--resolution", str(resolution), "--out", str(out)]
    if subprocess.run(cmd, check=False, stdout=subprocess.DEVNULL).returncode != 0:
        raise SystemExit(f"rendering failed: {' '.join(cmd)} (give --frames)")
    return out / "rgbL" / "frames"


def _row(name: str, files: list[Path], repeat: int) -> None:
    import cv2

    from ibiscape_eval.io.images import decode_png_grey

    datas = [f.read_bytes() for f in files]
    decode_png_grey(datas[0])  # numba: compiled (or loaded from its cache) once, not timed
    same = fast_n = 0
    for d in datas:
        ours = decode_png_grey(d)
        ref = cv2.imdecode(np.frombuffer(d, np.uint8), cv2.IMREAD_GRAYSCALE)
        fast_n += ours is not None
        same += ours is None or bool(np.array_equal(ours, ref))
    t = {}
    for label, fn in (("opencv", lambda d: cv2.imdecode(np.frombuffer(d, np.uint8),
                                                         cv2.IMREAD_GRAYSCALE)),
                      ("ours", decode_png_grey)):
        c0 = time.process_time()
        for _ in range(repeat):
            for d in datas:
                fn(d)
        t[label] = 1e3 * (time.process_time() - c0) / (repeat * len(datas))
    h, w = cv2.imdecode(np.frombuffer(datas[0], np.uint8), cv2.IMREAD_GRAYSCALE).shape
    print(f"{name:<28}{w:>5}x{h:<5}{len(datas):>7}{fast_n:>6}{t['opencv']:>9.2f}{t['ours']:>8.2f}"
          f"{t['opencv'] / t['ours']:>8.2f}x   {same}/{len(datas)}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", nargs="*", type=Path, help="folders of PNG frames")
    ap.add_argument("--max", type=int, default=40, help="images per folder")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    import cv2

    cv2.setNumThreads(1)
    print(f"{'frames':<28}{'size':>11}{'images':>7}{'ours':>6}{'opencv':>9}{'ours':>8}{'ratio':>9}"
          "   identical")
    print(f"{'':<28}{'':>11}{'':>7}{'':>6}{'[ms]':>9}{'[ms]':>8}")
    with tempfile.TemporaryDirectory(prefix="bench_png_") as d:
        folders = a.frames or [_render(Path(d) / f"svi_{r}", r) for r in (512, 1024)]
        for folder in folders:
            files = sorted(folder.glob("*.png"))[:a.max]
            if files:
                _row(folder.parent.parent.name + "/" + folder.parent.name, files, a.repeat)
        real = sorted(REAL.glob("**/*.png"))
        if real:
            _row("tests/data/real (EuRoC)", real, 10 * a.repeat)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"(CPU time per image; ours: images the fast path decoded, the rest went to OpenCV; "
          f"peak RSS {peak:.0f} MB; load average {os.getloadavg()[0]:.1f})")


if __name__ == "__main__":
    main()
