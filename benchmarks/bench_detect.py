"""Target detection on a calibration drive: every frame searched on its own (what OpenCV's
functions do when called per image, the exhaustive fallback included) against the sequence mode of
``ibiscape_eval.calib.detect_corners`` (``near=`` the previous frame's detection,
``exhaustive=False``), on the same frames, one thread.

    .venv/bin/python benchmarks/bench_detect.py                      # renders a 12 s 512 px drive
    .venv/bin/python benchmarks/bench_detect.py --seq SVI_calib --frames 600

Printed per target: CPU time per frame of both, frames with the target, corners found and the
largest difference between the two modes' corners (the same sub-pixel refinement, so it should be
far below 0.01 px), and the RATIO per-image / sequence mode (higher is better for us).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]


def render(target: str, out: Path, size: int, duration_s: float) -> Path:
    seq = out / f"drive_{target}_{size}"
    if not (seq / "sequence.yaml").exists():
        subprocess.run([sys.executable, "-m", "cli.main", "sim", "--setup", "svi", "--kind", "calibration",
                        "--target", target, "--resolution", str(size), "--duration-s", str(duration_s),
                        "--seed", "3", "--out", str(seq)], check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return seq


def measure(seq: Path, frames: int) -> None:
    import cv2

    from ibiscape_eval.calib import detect_corners
    from ibiscape_eval.calib.targets import target_from_kalibr

    cv2.setNumThreads(1)
    doc = yaml.safe_load((seq / "sequence.yaml").read_text())
    target = target_from_kalibr(doc["target"])
    files = sorted((seq / "rgbL" / "frames").glob("*.png"))[:frames]
    images = [cv2.imread(str(f), cv2.IMREAD_GRAYSCALE) for f in files]
    c0 = time.process_time()
    alone = [detect_corners(im, target) for im in images]
    t_alone = time.process_time() - c0
    c0 = time.process_time()
    tracked, prev = [], None
    for im in images:
        prev = detect_corners(im, target, near=prev, exhaustive=False)
        tracked.append(prev)
    t_tracked = time.process_time() - c0
    diff = 0.0
    for a, b in zip(alone, tracked, strict=True):
        if a is not None and b is not None:
            _, ia, ib = np.intersect1d(a.ids, b.ids, return_indices=True)
            if len(ia):
                diff = max(diff, float(np.abs(a.corners_px[ia] - b.corners_px[ib]).max()))

    def found(ds: list) -> tuple[int, int]:
        return sum(d is not None for d in ds), sum(len(d) for d in ds if d is not None)

    n = max(1, len(images))
    (fa, ca), (ft, ct) = found(alone), found(tracked)
    print(f"{seq.name} ({target.target_type}, {len(images)} frames of {images[0].shape[1]} px):")
    print(f"  per image      {1e3 * t_alone / n:7.1f} ms/frame CPU  {fa:4d} frames  {ca:6d} corners")
    print(f"  sequence mode  {1e3 * t_tracked / n:7.1f} ms/frame CPU  {ft:4d} frames  {ct:6d} corners")
    print(f"  largest corner difference {diff:.1e} px; RATIO {t_alone / max(t_tracked, 1e-9):.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seq", type=Path, action="append", help="rendered calibration sequence(s)")
    ap.add_argument("--frames", type=int, default=240)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--duration-s", type=float, default=12.0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        seqs = args.seq or [render(t, Path(tmp), args.size, args.duration_s) for t in ("checkerboard", "aprilgrid")]
        for s in seqs:
            measure(s, args.frames)


if __name__ == "__main__":
    main()
