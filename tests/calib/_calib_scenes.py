"""Rendered calibration scenes with known answers (shared by the calib tests)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from _calib_render import random_poses, render, sim_target, stereo_extrinsics

from ibiscape_eval.calib.calibrate import Observations
from ibiscape_eval.calib.detect import detect_corners
from ibiscape_eval.core.camera import CameraModel

CAM_RADTAN = CameraModel(480, 360, 330.0, 331.5, 241.3, 178.2, "radtan", (-0.21, 0.06, 0.0012, -0.0008))
CAM_RADTAN_R = CameraModel(480, 360, 328.2, 329.0, 236.6, 182.4, "radtan", (-0.19, 0.05, -0.0006, 0.0009))
CAM_EQUI = CameraModel(480, 360, 250.0, 250.5, 238.9, 181.1, "equidistant", (0.02, -0.01, 0.004, -0.001))
BASELINE_M = 0.2


@lru_cache(maxsize=8)
def stereo_scene(kind: str, n_views: int = 12, seed: int = 1, equi: bool = False):
    """Images and detections of a stereo pair (left, right) viewing the board."""
    rng = np.random.default_rng(seed)
    left = CAM_EQUI if equi else CAM_RADTAN
    right = CAM_EQUI if equi else CAM_RADTAN_R
    T10 = stereo_extrinsics(BASELINE_M)
    target = sim_target(kind)
    dist = (3.0, 6.0)
    poses = random_poses(kind, n_views, rng, distance_m=dist, spread=0.1 if kind == "checkerboard" else 0.2)
    imgs_l = [render(left, T, kind, rng=rng) for T in poses]
    imgs_r = [render(right, T10 @ T, kind, rng=rng) for T in poses]
    det_l = [detect_corners(im, target) for im in imgs_l]
    det_r = [detect_corners(im, target) for im in imgs_r]
    obs = (Observations("cam0", (left.width_px, left.height_px), det_l),
           Observations("cam1", (right.width_px, right.height_px), det_r))
    return target, (left, right), T10, poses, (imgs_l, imgs_r), obs


@lru_cache(maxsize=2)
def dvs_scene(kind: str = "checkerboard", n_views: int = 10, seed: int = 4):
    """A blinking target seen by an event camera: per view, the events of the board appearing
    (uniform grey -> printed board) within a 20 ms window."""
    from _calib_render import dvs_events, render_float

    rng = np.random.default_rng(seed)
    cam = CAM_RADTAN
    poses = random_poses(kind, n_views, rng, distance_m=(3.0, 5.5), spread=0.1)
    windows, events = [], []
    for v, T in enumerate(poses):
        t0 = 1_000_000_000 + v * 50_000_000
        on = render_float(cam, T, kind)
        off = render_float(cam, T, kind, contrast=0.0)
        ev = dvs_events(off + rng.normal(0, 0.3, off.shape), on + rng.normal(0, 0.3, on.shape),
                        t0, t0 + 20_000_000)
        windows.append((t0, t0 + 20_000_000))
        events.append(ev)
    return sim_target(kind), cam, poses, windows, events
