"""The esvi rig's calibration drive (stereo RGB board frames, stereo DVS events of the board
images) written by the simulator, shared by ``test_imu_camera_dvs.py`` and
``benchmarks/bench_imu_camera.py --esvi``."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ibiscape_eval.sim import preset
from ibiscape_eval.sim.calib_scene import write_board_frames
from ibiscape_eval.sim.generator import generate

SHIFT_S = 0.0083  # one clock offset for the synchronised rig


def board_gray(cfg: Any, cam: Any, *, supersample: int = 2, background: float = 110.0):
    """``gray(t_cam_ns)`` -> the linear grey image (float32, 0..255) of the board alone seen by
    ``cam`` at ``t_cam + timeshift_cam_imu`` (the exact homography of the camera pose)."""
    import cv2

    from ibiscape_eval.core.rotations import matrix_from_quat
    from ibiscape_eval.sim.generator import plan
    from ibiscape_eval.sim.render.rays import camera_model
    from ibiscape_eval.sim.rig import T_body_camera

    world, motion, _ = plan(cfg)
    tgt = world.target_named(cfg.target)
    ppm = 200.0
    tex = tgt.texture(ppm).astype(np.float32)
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    uv = tgt.texture_px_from_target(xy, ppm)
    A = np.linalg.solve(np.c_[uv, np.ones(3)], np.c_[xy, np.ones(3)]).T
    ss = int(supersample)
    S = np.array([[ss, 0.0, 0.5 * (ss - 1)], [0.0, ss, 0.5 * (ss - 1)], [0.0, 0.0, 1.0]])
    K = camera_model(cam).K
    T_bc = T_body_camera(cam)
    shift = round(cam.timeshift_cam_imu_s * 1e9)

    def gray(t_ns: int) -> np.ndarray:
        s = motion.sample(np.array([int(t_ns) + shift], np.int64))
        T_wb = np.eye(4)
        T_wb[:3, :3] = matrix_from_quat(s.quat_xyzw)[0]
        T_wb[:3, 3] = s.pos_m[0]
        T_ct = np.linalg.inv(T_wb @ T_bc) @ tgt.T_world_target
        big = np.full((ss * cam.height_px, ss * cam.width_px), background, np.float32)
        depth = tgt.corners_target_m @ T_ct[2, :3] + T_ct[2, 3]
        if depth.min() > 1.0:
            H = S @ K @ np.c_[T_ct[:3, :2], T_ct[:3, 3]] @ A
            cv2.warpPerspective(tex, H, big.shape[::-1], dst=big, flags=cv2.INTER_LINEAR,
                                borderMode=cv2.BORDER_TRANSPARENT)
        return cv2.resize(big, (cam.width_px, cam.height_px), interpolation=cv2.INTER_AREA)

    return gray


def write_esvi_calibration(out: Path, *, duration_s: float, rgb_px: int, dvs_px: int,
                           rgb_rate_hz: float = 10.0, seed: int = 2, shift_s: float = SHIFT_S) -> Any:
    """A calibration drive of the esvi rig with stereo RGB (board frames) and stereo DVS (events of
    the board images); returns the config."""
    from ibiscape_eval.sim.dvs import write_dvs_camera
    from ibiscape_eval.sim.render.sequence import camera_stamps

    base = preset("esvi", "calibration", "clear", duration_s=duration_s, seed=seed)
    rgb = tuple(replace(c, width_px=rgb_px, height_px=rgb_px, rate_hz=rgb_rate_hz,
                        timeshift_cam_imu_s=shift_s) for c in preset("svi", "calibration").cameras)
    dvs = tuple(replace(c, width_px=dvs_px, height_px=dvs_px, timeshift_cam_imu_s=shift_s)
                for c in base.cameras)
    cfg = replace(base, cameras=rgb + dvs)
    generate(cfg, out, render=False)
    write_board_frames(replace(cfg, cameras=rgb), out)
    for i, cam in enumerate(dvs):
        write_dvs_camera(board_gray(cfg, cam), cam, camera_stamps(cfg, cam), out / cam.name,
                         rng=np.random.default_rng(100 + i))
    return cfg
