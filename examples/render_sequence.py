"""Render synthetic sequences, read the images back, and check the camera model with OpenCV.

    .venv/bin/python examples/render_sequence.py [OUT_DIR]

Notebook-style: each block can be pasted into a cell.  Small images (256 px) keep it to a minute.
"""

# %% Imports and output folder
import sys
import tempfile
from pathlib import Path

import cv2
import numpy as np

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.io.images import read_depth_mm, read_frame_timestamps, read_labels, read_png
from ibiscape_eval.io.sequence import read_sequence_yaml
from ibiscape_eval.sim import generate, preset
from ibiscape_eval.sim.config import with_resolution
from ibiscape_eval.sim.render import Renderer, RenderOptions
from ibiscape_eval.sim.render.labels import CARLA_TAGS
from ibiscape_eval.sim.render.preview import contact_sheet
from ibiscape_eval.sim.world import build_world

root = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="render_example_"))

# %% An RGB-D sequence in dynamic weather (fog, rain, wet road), every camera at 256 x 192 px
cfg = with_resolution(preset("rgbd", "slam", "dynamic", duration_s=2.0, seed=2), 256, 192)
s = generate(cfg, root / "RGBD_dynamic", overwrite=True, render=True)
seq = Path(s.path)
doc = read_sequence_yaml(seq / "sequence.yaml")
print("camera rgb (true model):", {k: doc["cameras"]["rgb"][k] for k in
                                   ("intrinsics", "distortion_model", "distortion_coeffs", "resolution")})

# %% Read a frame back: RGB, depth in metres, semantic tags
stamps, names = read_frame_timestamps(seq / "rgb" / "timestamps.csv")
rgb = read_png(seq / "rgb" / "frames" / names[10])
depth = read_depth_mm(seq / "depth" / "mm" / names[10])
tags = read_labels(seq / "semantic" / "labels" / names[10]) if (seq / "semantic").exists() else None
print(f"frame {stamps[10]} ns: rgb {rgb.shape}, depth {np.nanmin(depth):.2f}..{np.nanmax(depth):.2f} m "
      f"({np.isnan(depth).mean():.0%} sky or beyond 65 m)")
if tags is not None:
    print("tags:", {CARLA_TAGS[int(t)]: int(n) for t, n in zip(*np.unique(tags, return_counts=True), strict=True)})
print("association.txt:", (seq / "association.txt").read_text().splitlines()[0])
print("contact sheet:", contact_sheet(seq, root / "rgbd_dynamic_sheet.png"), "->", root / "rgbd_dynamic_sheet.png")

# %% A camera with lens distortion looks at the checkerboard from ten poses; OpenCV calibrates it
world = build_world(kind="calibration", seed=1, bumps=False)
board = world.target_named("checkerboard")
renderer = Renderer(world, options=RenderOptions())
truth = CameraModel(320, 240, 190.0, 188.0, 163.2, 117.6, "radtan", (-0.15, 0.04, 0.001, -0.0008))


def pose(dist_m: float, yaw_deg: float, pitch_deg: float, roll_deg: float) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    z = -board.observer_normal_world
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z], 1) @ Rotation.from_euler(
        "yxz", [yaw_deg, pitch_deg, roll_deg], degrees=True).as_matrix()
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, board.centre_world_m - R[:, 2] * dist_m
    return T


obj, img = [], []
for k, view in enumerate([(4.5, 0, 0, 10), (5, 25, -8, -5), (5, -25, 10, 15), (4.8, 15, 15, -20),
                          (5.2, -18, -14, 25), (5.5, 30, 5, 0), (5.5, -30, -5, -30), (4.6, 5, -18, 40)]):
    gray = cv2.cvtColor(renderer.render_pose(truth, pose(*view), noise_key=k).rgb, cv2.COLOR_RGB2GRAY)
    ok, corners = cv2.findChessboardCorners(gray, (7, 7))
    if ok:
        corners = cv2.cornerSubPix(gray, corners, (7, 7), (-1, -1), (3, 100, 1e-4))
        obj.append(board.corners_target_m.astype(np.float32))
        img.append(corners.reshape(-1, 2))
        if k == 0:
            cv2.imwrite(str(root / "board_view.png"), gray)
rms, K, dist, _, _ = cv2.calibrateCamera(obj, img, (320, 240), None, None, flags=cv2.CALIB_FIX_K3)
print(f"calibrateCamera on {len(obj)} rendered views: rms {rms:.3f} px")
print("  fx fy cx cy  true", truth.intrinsics, " estimated", np.round([K[0, 0], K[1, 1], K[0, 2], K[1, 2]], 3))
print("  k1 k2 p1 p2  true", list(truth.coeffs), " estimated", np.round(dist.ravel()[:4], 4))
print(f"outputs in {root}")
