"""Camera-IMU calibration without ROS: planted extrinsics and clock offsets are recovered.

Run:  .venv/bin/python examples/calibrate_imu_camera.py   (a few minutes; writes imucam_example/)

1. The simulator drives its calibration shuttle in front of the checkerboard (forward and in
   reverse, over bubbles and waves that excite roll and pitch) and simulates IMU0; each camera's
   clock runs late or early by a planted offset (``cameras.<name>.timeshift_cam_imu_s``, Kalibr's
   ``t_imu = t_cam + shift``), recorded as the truth in ``sequence.yaml``.  The camera frames here
   are the board drawn by its exact homography (``sim.calib_scene.write_board_frames``, fast);
   ``ibiscape-eval sim --kind calibration`` renders the whole scene instead.
2. ``calibrate_sequence`` (= ``ibiscape-eval calib SEQ --imu imu.yaml``) detects the board,
   takes the intrinsics from ``camchain.yaml`` and estimates ``T_cam_imu`` and the offsets.
3. The same drive on a flat road: roll and pitch are not excited, the lever arm is not observable;
   the calibration refuses, and with ``force=True`` names the weak directions.
"""

# %% a short calibration drive with planted clock offsets
from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

from ibiscape_eval.calib.imu_camera import SequenceOptions, calibrate_sequence, camchain_imucam
from ibiscape_eval.core.errors import CalibrationError
from ibiscape_eval.sim import preset
from ibiscape_eval.sim.calib_scene import write_board_frames
from ibiscape_eval.sim.config import with_resolution
from ibiscape_eval.sim.generator import generate

SHIFTS = {"rgbL": 0.0123, "rgbR": -0.0171}


def make_sequence(out: str | Path, *, duration_s: float = 12.0, size: int = 384, bumps: bool = True,
                  rate_hz: float = 10.0, seed: int = 1) -> Path:
    """A calibration drive with board frames, its ``imu.yaml`` and the cameras' ``camchain.yaml``."""
    out = Path(out)
    cfg = with_resolution(preset("svi", "calibration", "clear", duration_s=duration_s, seed=seed), size, size)
    cfg = replace(cfg, cameras=tuple(replace(c, rate_hz=rate_hz, timeshift_cam_imu_s=SHIFTS[c.name])
                                     for c in cfg.cameras),
                  motion=replace(cfg.motion, bumps=bumps))
    generate(cfg, out, render=False)
    write_board_frames(cfg, out)
    doc = yaml.safe_load((out / "sequence.yaml").read_text())
    imu = doc["imus"]["imu0"]
    (out / "imu.yaml").write_text(yaml.safe_dump({k: imu[k] for k in (
        "accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
        "gyroscope_random_walk", "update_rate", "rostopic")}))
    keep = ("camera_model", "intrinsics", "distortion_model", "distortion_coeffs", "resolution", "rostopic")
    chain = {f"cam{i}": {k: doc["cameras"][n][k] for k in keep} for i, n in enumerate(SHIFTS)}
    chain["cam1"]["T_cn_cnm1"] = doc["cameras"]["rgbR"]["T_cn_cnm1"]
    (out / "camchain.yaml").write_text(yaml.safe_dump(chain))
    return out


if __name__ == "__main__":
    root = Path("imucam_example")
    seq = root / "SVI_calib_imu"
    # < 1: shorter drives (the tests run 0.1; 12 s is about the shortest that calibrates), 5
    # frames a second at 320 px
    scale = float(os.environ.get("IBISCAPE_EXAMPLE_SCALE", "1"))
    size: dict = {} if scale >= 1 else {"size": 320, "rate_hz": 5.0}
    duration_s = max(12.0, 24.0 * scale)
    if not seq.exists():
        make_sequence(seq, duration_s=duration_s, **size)

    # %% calibrate both cameras in one problem
    res = calibrate_sequence(seq, seq / "imu.yaml", SequenceOptions(camchain=seq / "camchain.yaml"))
    print(res)
    for cal in res.result.cameras:
        e = res.errors_vs_truth[cal.name]
        print(f"{cal.name}: rotation error {e['rotation_error_deg']:.4f} deg (std "
              f"{np.linalg.norm(cal.rotation_std_deg):.4f}), translation error "
              f"{e['translation_error_m'] * 1e3:.1f} mm (std {np.linalg.norm(cal.translation_std_m) * 1e3:.1f}), "
              f"time offset {cal.timeshift_cam_imu_s * 1e3:+.3f} ms (truth {SHIFTS[cal.name] * 1e3:+.3f}, "
              f"error {e['timeshift_error_s'] * 1e3:+.4f} ms)")
    print("excitation (angular-rate std, rad/s):", np.round(res.result.excitation.gyro_std_rad_s, 3))
    print("time:", {k: round(v, 1) for k, v in res.timing_s.items()})

    # %% Kalibr's camchain-imucam.yaml and the figures
    from ibiscape_eval.calib.imu_camera.plots import figures
    from ibiscape_eval.io.figure import save_figures
    from ibiscape_eval.io.kalibr import write_camchain

    write_camchain(root / "camchain-imucam.yaml", camchain_imucam(res.result))
    print("wrote", [str(p) for p in save_figures(root, figures(res.result))])
    print((root / "camchain-imucam.yaml").read_text()[:400])

    # %% the same drive on a flat road: refused with the measured numbers, then forced and marked
    flat = root / "SVI_calib_flat"
    if not flat.exists():
        make_sequence(flat, duration_s=duration_s, bumps=False, **size)
    try:
        calibrate_sequence(flat, flat / "imu.yaml", SequenceOptions(camchain=flat / "camchain.yaml"))
    except CalibrationError as e:
        print("refused:", e)
    forced = calibrate_sequence(flat, flat / "imu.yaml", SequenceOptions(camchain=flat / "camchain.yaml", force=True))
    for w in forced.result.warnings:
        print("weak:", w)
