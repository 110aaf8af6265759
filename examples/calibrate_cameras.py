"""Calibrate a stereo camera pair from checkerboard / AprilGrid images and judge it against truth.

    .venv/bin/python examples/calibrate_cameras.py --out calib-example

1. Render a stereo calibration sequence with known cameras (IBISCape layout: ``rgbL/``, ``rgbR/``
   with ``timestamps.csv`` and ``frames/<ns>.png``, plus a ``sequence.yaml`` holding the truth).
   Until ``ibiscape-eval sim --kind calibration`` renders its own images, the views come from the
   test suite's analytic renderer (rays of the distorted camera intersected with the simulator's
   printed board, supersampled).
2. Calibrate with the library: detect corners, calibrate the chain, compare with the truth.
3. The same in one command: ``ibiscape-eval calib <seq> --yaml camchain.yaml --plot plots/``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "calib"))  # the analytic renderer (see the docstring)

from ibiscape_eval.core.camera import CameraModel

LEFT = CameraModel(640, 480, 420.0, 420.0, 319.5, 239.5, "radtan", (-0.12, 0.03, 0.0005, -0.0004))
RIGHT = CameraModel(640, 480, 421.0, 420.5, 322.0, 237.0, "radtan", (-0.11, 0.025, -0.0003, 0.0002))


def render_sequence(out: Path, kind: str = "checkerboard", n_views: int = 16, seed: int = 0) -> Path:
    """Write a stereo calibration sequence of ``n_views`` board poses; returns ``out``."""
    import yaml
    from _calib_render import random_poses, render, sim_target, stereo_extrinsics
    from _calib_seqs import sequence_yaml, write_camera_folder

    rng = np.random.default_rng(seed)
    T_right_left = stereo_extrinsics(0.4, yaw_deg=0.5)  # the paper's RGB baseline
    poses = random_poses(kind, n_views, rng, distance_m=(4.0, 7.5), spread=0.12, tilt_max_deg=30)
    stamps = [1_000_000_000 + i * 50_000_000 for i in range(n_views)]
    write_camera_folder(out / "rgbL", [render(LEFT, T, kind, rng=rng) for T in poses], stamps)
    write_camera_folder(out / "rgbR", [render(RIGHT, T_right_left @ T, kind, rng=rng) for T in poses],
                        stamps)
    doc = sequence_yaml({"rgbL": LEFT, "rgbR": RIGHT},
                        {"rgbL": np.eye(4), "rgbR": np.linalg.inv(T_right_left)},
                        sim_target(kind).to_kalibr())
    (out / "sequence.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("calib-example"))
    ap.add_argument("--target", choices=["checkerboard", "aprilgrid"], default="aprilgrid")
    a = ap.parse_args()

    # 1. a sequence with known truth
    seq = render_sequence(a.out / f"stereo_{a.target}", a.target)
    print(f"rendered {seq}")

    # 2. the library, step by step
    import cv2
    import yaml

    from ibiscape_eval.calib import (
        Observations,
        calibrate,
        compare_with_truth,
        detect_corners,
        format_report,
        target_from_kalibr,
        truth_from_sequence,
    )

    doc = yaml.safe_load((seq / "sequence.yaml").read_text())
    target = target_from_kalibr(doc["target"])
    obs = []
    for cam in ("rgbL", "rgbR"):
        frames = sorted((seq / cam / "frames").glob("*.png"))
        dets = [detect_corners(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), target) for f in frames]
        print(f"{cam}: target found in {sum(d is not None for d in dets)} of {len(frames)} frames")
        obs.append(Observations(cam, (640, 480), dets))
    result = calibrate(target, obs, model="pinhole-radtan")
    truth = compare_with_truth(result, truth_from_sequence(doc))
    print("\n".join(format_report(result, truth)))

    # 3. the same in one command (plus camchain.yaml and plots):
    print(f"\nibiscape-eval calib {seq} --yaml {a.out}/camchain.yaml --plot {a.out}/plots")


if __name__ == "__main__":
    main()
