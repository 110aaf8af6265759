"""A small analytic target renderer for calibration tests (and synthetic DVS events).

Every pixel is rendered by unprojecting s x s sample points through the (distorted) camera model,
intersecting the rays with the board plane, sampling the printed face of the simulator's target
(``sim/targets.py``, bilinear on a high-resolution texture) and averaging the samples; mild noise
is added.  Known answers: the camera, the board poses and the stereo extrinsics are set here.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.kalibr import CalibrationTarget, target_from_kalibr
from ibiscape_eval.sim.targets import make_target

PX_PER_M = 500.0
BACKGROUND = 150.0


@lru_cache(maxsize=4)
def _board(kind: str):
    t = make_target(kind, T_world_target=np.eye(4), tag_size_m=0.4)  # the scenes were laid out for 0.4 m tags
    return t, t.texture(PX_PER_M).astype(np.float32)


def sim_target(kind: str) -> CalibrationTarget:
    """The simulator's target as a calibration target (Kalibr keys)."""
    return target_from_kalibr(_board(kind)[0].kalibr)


@lru_cache(maxsize=8)
def _rays(cam: CameraModel, ss: int) -> np.ndarray:
    return cam.pixel_rays(ss).reshape(-1, 3)


def render(cam: CameraModel, T_cam_target: np.ndarray, kind: str, *, ss: int = 2,
           noise: float = 1.0, rng: np.random.Generator | None = None,
           contrast: float = 1.0) -> np.ndarray:
    """Render the board seen by ``cam`` at ``T_cam_target``; uint8 (h, w)."""
    return np.clip(np.rint(render_float(cam, T_cam_target, kind, ss=ss, contrast=contrast)
                           + (0 if rng is None else rng.normal(0, noise, (cam.height_px, cam.width_px)))),
                   0, 255).astype(np.uint8)


def render_float(cam: CameraModel, T_cam_target: np.ndarray, kind: str, *, ss: int = 3,
                 contrast: float = 1.0) -> np.ndarray:
    """Float grey image (h, w) in [0, 255] before noise and quantisation."""
    if contrast == 0.0:  # the face washed out to the background: the same float32 image, no rays cast
        return np.full((cam.height_px, cam.width_px), BACKGROUND, np.float32)
    board, tex = _board(kind)
    d = _rays(cam, ss)
    T_tc = np.linalg.inv(T_cam_target)
    R, o = T_tc[:3, :3], T_tc[:3, 3]
    dt = d @ R.T
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = -o[2] / dt[:, 2]
    xy = o[:2] + lam[:, None] * dt[:, :2]
    hit = np.isfinite(lam) & (lam > 0)
    xy[~hit] = -1e3
    uv = board.texture_px_from_target(xy, PX_PER_M).astype(np.float32)
    h, w = cam.height_px * ss, cam.width_px * ss
    mapx = uv[:, 0].reshape(h, w)
    mapy = uv[:, 1].reshape(h, w)
    val = cv2.remap(tex, mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                    borderValue=BACKGROUND)
    val = BACKGROUND + contrast * (val - BACKGROUND)
    return val.reshape(cam.height_px, ss, cam.width_px, ss).mean(axis=(1, 3))


def board_pose(kind: str, *, distance_m: float, tilt_deg: tuple[float, float], roll_deg: float,
               offset_m: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """``T_cam_target`` with the pattern centre at ``(offset, distance)`` and its face toward the
    camera, tilted about the board's x and y axes and rolled about its normal."""
    board, _ = _board(kind)
    centre = board.corners_target_m.mean(axis=0)
    # checkerboard: x right, y down, z away from the observer; AprilGrid: y up, z toward
    base = np.eye(3) if kind == "checkerboard" else np.diag([1.0, -1.0, -1.0])
    tilt = Rotation.from_euler("xyz", [tilt_deg[0], tilt_deg[1], roll_deg], degrees=True).as_matrix()
    R = tilt @ base
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.array([offset_m[0], offset_m[1], distance_m]) - R @ centre
    return T


def random_poses(kind: str, n: int, rng: np.random.Generator, *, distance_m: tuple[float, float],
                 spread: float = 0.35, tilt_max_deg: float = 35.0) -> list[np.ndarray]:
    """``n`` varied board poses (distance range, lateral spread as a fraction of the distance)."""
    out = []
    for _ in range(n):
        z = rng.uniform(*distance_m)
        out.append(board_pose(kind, distance_m=z,
                              tilt_deg=(rng.uniform(-tilt_max_deg, tilt_max_deg),
                                        rng.uniform(-tilt_max_deg, tilt_max_deg)),
                              roll_deg=rng.uniform(-180, 180),
                              offset_m=(rng.uniform(-spread, spread) * z,
                                        rng.uniform(-spread, spread) * z)))
    return out


def stereo_extrinsics(baseline_m: float, yaw_deg: float = 1.0) -> np.ndarray:
    """``T_c1_c0`` of a right camera ``baseline_m`` to the right, slightly rotated."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("yxz", [yaw_deg, 0.3, -0.2], degrees=True).as_matrix()
    T[:3, 3] = -T[:3, :3] @ np.array([baseline_m, 0.01, -0.005])
    return T


def dvs_events(img0: np.ndarray, img1: np.ndarray, t0_ns: int, t1_ns: int, *,
               threshold: float = 0.2, log_eps: float = 0.001):
    """Events between two grey renders with the CARLA/ESIM model (log-intensity crossings,
    timestamps interpolated linearly in the window), sorted by time."""
    from ibiscape_eval.core.events import Events

    L0 = np.log(log_eps + np.clip(img0, 0, 255).astype(np.float64) / 255.0)
    L1 = np.log(log_eps + np.clip(img1, 0, 255).astype(np.float64) / 255.0)
    dL = L1 - L0
    n = np.floor(np.abs(dL) / threshold).astype(np.int64)
    ys, xs = np.nonzero(n)
    counts = n[ys, xs]
    rep = np.repeat(np.arange(len(xs)), counts)
    starts = np.cumsum(counts) - counts
    k = np.arange(int(counts.sum())) - np.repeat(starts, counts) + 1
    frac = k * threshold / np.abs(dL[ys, xs])[rep]
    t = (t0_ns + frac * (t1_ns - t0_ns)).astype(np.int64)
    order = np.argsort(t, kind="stable")
    return Events(t[order], xs[rep][order].astype(np.uint16), ys[rep][order].astype(np.uint16),
                  (dL[ys, xs] > 0)[rep][order])
