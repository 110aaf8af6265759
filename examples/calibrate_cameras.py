"""Calibrate a stereo camera pair from checkerboard / AprilGrid images and judge it against truth.

    .venv/bin/python examples/calibrate_cameras.py --out calib-example

1. Render a stereo calibration sequence with known cameras (IBISCape layout: ``rgbL/``, ``rgbR/``
   with ``timestamps.csv`` and ``frames/<ns>.png``, plus a ``sequence.yaml`` holding the truth)
   with the simulator's renderer in its calibration world (:mod:`ibiscape_eval.sim.calib_views`:
   the rig held at varied, tilted poses 3-15 m in front of the board).  The simulator's own
   calibration drive (``ibiscape-eval sim --kind calibration``) approaches the board head-on as in
   the paper; those nearly fronto-parallel views leave the focal length weakly determined.
2. Calibrate with the library: detect corners, calibrate the chain, compare with the truth.
3. The whole job in one library call, the pipeline ``calib`` and the benchmark run:
   ``calibrate_cameras(open_sequence(seq))`` (any layout ``open_sequence`` reads: IBISCape,
   EuRoC/TUM-VI, ROS bags, ``images=["cam0=left/*.png", ...]``).
4. The same in one command: ``ibiscape-eval calib <seq> --yaml camchain.yaml --plot plots/``.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.sim.calib_views import render_calibration_views

LEFT = CameraModel(640, 480, 420.0, 420.0, 319.5, 239.5, "radtan", (-0.12, 0.03, 0.0005, -0.0004))
RIGHT = CameraModel(640, 480, 421.0, 420.5, 322.0, 237.0, "radtan", (-0.11, 0.025, -0.0003, 0.0002))


def rig() -> np.ndarray:
    """``T_cam0_cam1``: the right camera 0.4 m to the right (the paper's RGB baseline), turned 0.5 deg."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("yxz", [0.5, 0.3, -0.2], degrees=True).as_matrix()
    T[:3, 3] = [0.4, 0.01, -0.005]
    return T


def render_sequence(out: Path, kind: str = "checkerboard", n_views: int = 16, seed: int = 0,
                    size: float = 1.0) -> Path:
    """Write a stereo calibration sequence of ``n_views`` rig poses; returns ``out``.

    ``size`` < 1: smaller images (``size`` x 640 x 480, the same optics) seen from ``size`` times
    the distance, so the board covers as many pixels (the tests render half size)."""
    # AprilTags want ~12 px per tag: at f = 420 px the AprilGrid views stay within 12 m
    dist = (3.0, 15.0) if kind == "checkerboard" else (3.0, 12.0)
    cams = {n: c.scaled(round(c.width_px * size), round(c.height_px * size))
            for n, c in (("rgbL", LEFT), ("rgbR", RIGHT))}
    return render_calibration_views(out, cams, {"rgbR": rig()}, target=kind, n_views=n_views,
                                    seed=seed, distance_m=(dist[0] * size, dist[1] * size),
                                    overwrite=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("calib-example"))
    ap.add_argument("--target", choices=["checkerboard", "aprilgrid"], default="aprilgrid")
    a = ap.parse_args()

    # 1. a sequence with known truth
    scale = float(os.environ.get("IBISCAPE_EXAMPLE_SCALE", "1"))  # < 1: fewer views (tests: 0.1)
    size = 1.0 if scale >= 1 else 0.5  # and half-size images
    seq = render_sequence(a.out / f"stereo_{a.target}", a.target, n_views=max(6, round(16 * scale)),
                          size=size)
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
        obs.append(Observations(cam, (round(640 * size), round(480 * size)), dets))
    result = calibrate(target, obs, model="pinhole-radtan")
    truth = compare_with_truth(result, truth_from_sequence(doc))
    print("\n".join(format_report(result, truth)))

    # 3. the whole job on the opened sequence: the pipeline the calib command and the benchmark run
    from ibiscape_eval import calibrate_cameras, open_sequence

    opened = open_sequence(seq)
    print(opened)
    run = calibrate_cameras(opened, max_views=20)
    assert run.result is not None
    print(f"calibrate_cameras: rms {run.result.to_dict()['rms_px']:.3f} px, max focal error "
          f"{run.truth.to_dict()['max_focal_error_px'] if run.truth else float('nan'):.2f} px")

    # 4. the same in one command (plus camchain.yaml and plots):
    print(f"\nibiscape-eval calib {seq} --yaml {a.out}/camchain.yaml --plot {a.out}/plots")


if __name__ == "__main__":
    main()
