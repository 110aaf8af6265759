"""Kalibr's files (and OpenCV's YAML) as other projects ship them, through one reader each.

Run:  .venv/bin/python examples/kalibr_files.py   (a second; reads tests/data/real/kalibr/)

1. ``read_yaml`` reads plain YAML and OpenCV FileStorage YAML alike (``%YAML:1.0``,
   ``!!opencv-matrix`` as numpy arrays): VINS-Fusion's EuRoC settings.
2. ``read_imu_noise`` takes Kalibr's ``imu.yaml``, OpenVINS' ``%YAML:1.0`` IMU chain, an EuRoC IMU
   ``sensor.yaml`` or our ``sequence.yaml``: one ``ImuNoise`` with keyword-only fields.
3. ``read_camchain`` takes Kalibr's camchain / camchain-imucam and OpenVINS' chain (``T_imu_cam``);
   ``check_camchain_matches`` says whether it fits a sequence's cameras and resolutions.
4. ``read_target`` gives the board with its 3-D corner points (Kalibr's numbering).
"""

# %% the data
from __future__ import annotations

from pathlib import Path

import numpy as np

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.core.kalibr import check_camchain_matches
from ibiscape_eval.io.asl import read_asl_sensor_yaml
from ibiscape_eval.io.kalibr import read_camchain, read_imu_noise, read_target
from ibiscape_eval.io.yaml_file import read_yaml

REAL = Path(__file__).resolve().parents[1] / "tests" / "data" / "real" / "kalibr"

# %% 1. OpenCV FileStorage YAML (VINS-Fusion's EuRoC config)
cfg = read_yaml(REAL / "vinsfusion_euroc_stereo_imu_config.yaml")
print("VINS-Fusion body_T_cam0 (opencv-matrix, dt d):\n", cfg["body_T_cam0"].round(4))

# %% 2. IMU noise, whichever file states it
for name in ("kalibr_imu.yaml", "openvins_euroc_kalibr_imu_chain.yaml"):
    print(f"{name}: {read_imu_noise(REAL / name)}")

# %% 3. camera chains: Kalibr's and OpenVINS' (T_imu_cam, no T_cn_cnm1), against EuRoC's sensor.yaml
chain = read_camchain(REAL / "openvins_euroc_kalibr_imucam_chain.yaml")
T10 = chain.cameras[1].T_cn_cnm1
assert T10 is not None
print(f"{chain}: stereo baseline {np.linalg.norm(T10[:3, 3]):.4f} m (derived from the two T_cam_imu)")
s0 = read_asl_sensor_yaml(REAL / "euroc_cam0_sensor.yaml")
assert chain.cameras[0].T_cam_imu is not None
print("same cam0 pose as EuRoC's sensor.yaml:",
      np.allclose(np.linalg.inv(chain.cameras[0].T_cam_imu), s0["T_BS"]))
print("matches a 752x480 stereo sequence:",
      check_camchain_matches(chain, {"cam0": (752, 480), "cam1": (752, 480)}, source="chain"))
try:
    check_camchain_matches(chain, {"cam0": (640, 480), "cam1": None}, source="kalibr_imucam_chain.yaml")
except FormatError as e:
    print("refused:", e)

# %% 4. the target and its corners
target = read_target(REAL / "kalibr_april_6x6_80x80cm.yaml")
print(target, "corners:", target.object_points().shape, "last at", target.object_points()[-1].round(4))
