"""Export a generated sequence for ORB-SLAM3, BASALT, VINS-Fusion, OpenVINS and Kalibr
(notebook-style; about a minute at the small default resolution).

Generates two short rendered sequences (stereo RGB + IMU calibration run; RGB-D run), exports
them as an EuRoC/ASL folder, a ROS 1 bag (Kalibr: ``kalibr_calibrate_cameras --bag ... --topics
/cam0/image_raw /cam1/image_raw``) and a TUM RGB-D folder, and reads every export back with the
project's readers to show that nothing changed on the way.

Run: ``.venv/bin/python examples/export_sequence.py [--out DIR] [--resolution 128]``.
From the shell::

    ibiscape-eval sim --setup svi --kind calibration --export euroc --out SVI_1_calib
    ibiscape-eval sim --setup svi --kind calibration --export rosbag --out SVI_1_calib
    ibiscape-eval sim --setup rgbd --export tum-rgbd --out RGBD_1_town
"""

# %%
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from ibiscape_eval.io import read_ibiscape_groundtruth, read_trajectory
from ibiscape_eval.io.asl import read_asl_image_list, read_asl_sensor_yaml, read_imu_samples
from ibiscape_eval.io.rosbag_export import read_bag_images, read_bag_imu
from ibiscape_eval.io.tum_rgbd import read_tum_list
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.config import with_resolution
from ibiscape_eval.sim.export import export_sequence

ap = argparse.ArgumentParser(description=__doc__)
ap.add_argument("--out", type=Path, default=Path(tempfile.mkdtemp(prefix="export_demo_")))
ap.add_argument("--resolution", type=int, default=128, help="camera width = height [px]")
ap.add_argument("--duration", type=float, default=2.0, help="seconds per sequence")
args, _ = ap.parse_known_args()
out: Path = args.out
out.mkdir(parents=True, exist_ok=True)

# %% 1. A short stereo RGB + IMU calibration sequence, rendered
cfg = with_resolution(preset("svi", "calibration", "clear", duration_s=args.duration, seed=1),
                      args.resolution, args.resolution)
svi = out / "SVI_1_calib"
print(generate(cfg, svi, render=True))

# %% 2. EuRoC/ASL: mav0/cam0, cam1 (grey PNG), imu0, state_groundtruth_estimate0, sensor.yaml
euroc = export_sequence(svi, "euroc", out / "SVI_1_calib_euroc")
print(euroc)
mav = out / "SVI_1_calib_euroc" / "mav0"
st, names = read_asl_image_list(mav / "cam0" / "data.csv")
print(f"cam0: {st.size} images, first {names[0]}; T_BS =\n"
      f"{read_asl_sensor_yaml(mav / 'cam0' / 'sensor.yaml')['T_BS'].round(3)}")
t_imu, gyro, acc = read_imu_samples(mav / "imu0" / "data.csv")
t_src, gyro_src, _ = read_imu_samples(svi / "other_sensors" / "imu.csv", frame="ibiscape")
print(f"imu0: {t_imu.size} samples, equal to the sequence's (converted from CARLA's frame): "
      f"{np.array_equal(t_imu, t_src) and np.allclose(gyro, gyro_src, rtol=1e-13, atol=0)}")
gt = read_trajectory(mav / "state_groundtruth_estimate0" / "data.csv", fmt="euroc")
src = read_ibiscape_groundtruth(svi / "vehicle_gt" / "groundtruth_sync.csv").trajectory
print(f"ground truth: {len(gt)} poses, max position difference "
      f"{np.abs(gt.pos_m - src.pos_m).max():.1e} m")

# %% 3. ROS 1 bag for Kalibr: /cam0/image_raw, /cam1/image_raw (rgb8) and /imu0 (sensor_msgs/Imu)
bag = export_sequence(svi, "rosbag", out / "SVI_1_calib.bag")
print(bag)
t_img, imgs = read_bag_images(out / "SVI_1_calib.bag", "/cam0/image_raw")
t_b, g_b, _ = read_bag_imu(out / "SVI_1_calib.bag", "/imu0")
print(f"bag: {len(imgs)} images {imgs[0].shape}, {t_b.size} IMU messages; IMU identical: "
      f"{np.array_equal(g_b, gyro_src)}")

# %% 4. TUM RGB-D from an RGB-D sequence: rgb/, depth/ (16-bit mm), association.txt
cfg = with_resolution(preset("rgbd", "slam", "clear", duration_s=args.duration, seed=1),
                      args.resolution, args.resolution)
rgbd = out / "RGBD_1_town"
generate(cfg, rgbd, render=True)
tum = export_sequence(rgbd, "tum-rgbd", out / "RGBD_1_town_tum")
print(tum)
t_rgb, files = read_tum_list(out / "RGBD_1_town_tum" / "rgb.txt")
pairs = (out / "RGBD_1_town_tum" / "association.txt").read_text().splitlines()
print(f"rgb.txt: {t_rgb.size} images ({files[0]}), {len(pairs)} RGB-D pairs; "
      f"groundtruth.txt is the RGB camera's pose (TUM convention)")

# %% 5. An SVI sequence has no depth camera: its TUM RGB-D export is refused with a one-line reason
try:
    export_sequence(svi, "tum-rgbd", out / "nope")
except Exception as e:  # IbiscapeError
    print("refused:", e)
print(f"outputs in {out}")
