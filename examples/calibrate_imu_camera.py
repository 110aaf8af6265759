"""Camera-IMU calibration without ROS: planted extrinsics and clock offsets are recovered.

Run:  .venv/bin/python examples/calibrate_imu_camera.py   (about a minute; writes imucam_example/)

The simulator drives the calibration route (bubbles and waves on the road excite roll and pitch),
simulates IMU0 and projects the checkerboard's corners into the stereo RGB pair with 0.2 px noise.
Each camera's clock runs late or early by a planted offset (Kalibr's ``timeshift_cam_imu``:
``t_imu = t_cam + shift``).  The calibration sees only the corners, the IMU samples and the IMU's
noise densities; we compare what it finds with the truth, then do the same on a flat road.
"""

# %% a 24 s calibration drive (one approach to the board), 768 px cameras
from dataclasses import replace
from pathlib import Path

import numpy as np

from ibiscape_eval.calib.imu_camera import (
    calibrate_imu_camera,
    camchain_imucam_document,
    errors_against_truth,
)
from ibiscape_eval.calib.imu_camera.synthetic import calibration_scene
from ibiscape_eval.core.errors import CalibrationError
from ibiscape_eval.sim import preset
from ibiscape_eval.sim.calib_scene import simulate_calibration
from ibiscape_eval.sim.config import MotionSpec


def scene(bumps: bool):
    cfg = preset("svi", "calibration", "clear", duration_s=24.0, seed=1, motion=MotionSpec(bumps=bumps))
    cfg = replace(cfg, cameras=tuple(replace(c, width_px=768, height_px=768) for c in cfg.cameras))
    sim = simulate_calibration(cfg, timeshifts_s={"rgbL": 0.0123, "rgbR": -0.0171})
    return calibration_scene(sim, noise_px=0.2, min_spacing_px=4.0)


sc = scene(bumps=True)
for o in sc.observations:
    print(o)

# %% calibrate both cameras in one problem
res = calibrate_imu_camera(sc.observations, sc.imu, sc.noise, sc.corners_target_m, sigma_px=0.2)
print(res)
truth = {k: {"T_cam_imu": sc.T_cam_imu[k], "timeshift_cam_imu": sc.timeshift_cam_imu_s[k]}
         for k in sc.T_cam_imu}
for name, e in errors_against_truth(res, truth).items():
    cal = res.camera(name)
    print(f"{name}: rotation error {e['rotation_error_deg']:.4f} deg (std "
          f"{np.linalg.norm(cal.rotation_std_deg):.4f}), translation error "
          f"{e['translation_error_m'] * 1e3:.1f} mm (std {np.linalg.norm(cal.translation_std_m) * 1e3:.1f}), "
          f"time offset error {e['timeshift_error_s'] * 1e3:+.4f} ms (std {cal.timeshift_std_s * 1e3:.4f})")
print("excitation (angular-rate std, rad/s):", np.round(res.excitation.gyro_std_rad_s, 3))

# %% Kalibr's camchain-imucam.yaml and the figures
from ibiscape_eval.calib.imu_camera.plots import figures
from ibiscape_eval.io.kalibr_imucam import write_camchain_imucam, write_figures

out = Path("imucam_example")
out.mkdir(exist_ok=True)
write_camchain_imucam(out / "camchain-imucam.yaml", camchain_imucam_document(res))
print("wrote", [str(p) for p in write_figures(out, figures(res))])
print((out / "camchain-imucam.yaml").read_text()[:400])

# %% the same drive on a flat road: roll and pitch are not excited, the lever arm is not observable
flat = scene(bumps=False)
try:
    calibrate_imu_camera(flat.observations, flat.imu, flat.noise, flat.corners_target_m, sigma_px=0.2)
except CalibrationError as e:
    print("refused:", e)
