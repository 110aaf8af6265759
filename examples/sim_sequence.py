"""Generate a short calibration and a short SLAM sequence, read them back, print a summary.

    .venv/bin/python examples/sim_sequence.py [OUT_DIR]

Notebook-style: each block can be pasted into a cell.
"""

# %% Imports and output folder
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from ibiscape_eval.io import read_gnss, read_ibiscape_groundtruth
from ibiscape_eval.io.imu import read_imu
from ibiscape_eval.io.sequence import read_sequence_yaml
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.generator import roll_pitch_rad

root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="sim_example_"))
SCALE = float(os.environ.get("IBISCAPE_EXAMPLE_SCALE", "1"))  # < 1: shorter data (the tests run 0.1)

# %% A 20 s SVI calibration run toward the AprilGrid, and a 30 s SVI SLAM run in dynamic weather
calib = generate(preset("svi", "calibration", "clear", duration_s=20 * SCALE, seed=1,
                        target="aprilgrid"),
                 root / "SVI_1_calib", overwrite=True)
slam = generate(preset("svi", "slam", "dynamic", duration_s=30 * SCALE, seed=2), root / "SVI_2_town",
                overwrite=True)

# %% Read them back with the project's readers and summarise
for s in (calib, slam):
    seq = Path(s.path)
    gt = read_ibiscape_groundtruth(seq / "vehicle_gt" / "groundtruth_sync.csv")
    imu = read_imu(seq / "other_sensors" / "imu.csv")
    fixes = read_gnss(seq / "other_sensors" / "gnss.csv")
    doc = read_sequence_yaml(seq / "sequence.yaml")
    roll, pitch = roll_pitch_rad(gt.trajectory.quat_xyzw)
    length = np.linalg.norm(np.diff(gt.trajectory.pos_m, axis=0), axis=1).sum()
    print(f"{seq.name}: {length:.1f} m in {s.duration_s:.0f} s, {len(gt)} GT poses, "
          f"{imu.n_samples} IMU samples at {imu.rate_hz:.0f} Hz, {len(fixes)} GNSS fixes")
    print(f"  roll/pitch std {np.degrees(roll.std()):.2f} / {np.degrees(pitch.std()):.2f} deg, "
          f"cameras {list(doc['cameras'])}, target {(doc['target'] or {}).get('target_type')}")
    print(f"  weather averages: fog {s.weather_averages['fog_density']:.0f} %, "
          f"rain {s.weather_averages['precipitation']:.0f} %, "
          f"wind {s.weather_averages['wind_intensity']:.0f} %")
print(f"sequences in {root}")
