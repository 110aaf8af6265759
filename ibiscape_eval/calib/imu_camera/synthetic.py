"""Synthetic corner observations: a target projected through an exact trajectory with a camera
clock offset (for known-answer tests, benchmarks and demos without rendering).

The camera stamps a frame ``t_cam``; the image shows the world at ``t_cam + timeshift`` on the
IMU's clock (Kalibr's ``timeshift_cam_imu``).  A corner is kept when it is in front of the camera,
inside the image, and the board is large enough in the image for a detector (``min_spacing_px``
between neighbouring corners, from the farthest corner's depth).  Checkerboards are all-or-nothing like
OpenCV's detector; AprilGrids may be partial.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.camera import CameraModel
from ibiscape_eval.core.rotations import matrix_from_quat

from .inputs import CameraObservations

__all__ = ["observe_target"]

FloatArray = npt.NDArray[np.float64]
PoseAt = Callable[[npt.NDArray[np.int64]], tuple[FloatArray, FloatArray]]


def observe_target(
    name: str,
    camera: CameraModel,
    pose_at: PoseAt,
    T_body_cam: npt.ArrayLike,
    T_world_target: npt.ArrayLike,
    corners_target_m: npt.ArrayLike,
    stamps_ns: npt.ArrayLike,
    *,
    timeshift_s: float = 0.0,
    noise_px: float = 0.2,
    seed: int = 0,
    spacing_m: float = 0.5,
    min_spacing_px: float = 6.0,
    all_or_none: bool = True,
    border_px: float = 2.0,
) -> CameraObservations:
    """Project the target's corners into one camera at its (camera-clock) frame stamps.

    Parameters
    ----------
    pose_at : callable(stamps_ns) -> (pos_m (n, 3), quat_xyzw (n, 4))
        Exact ``T_world_body`` at IMU-clock stamps (e.g. ``motion.sample``).
    T_body_cam : (4, 4)
        Camera (OpenCV frame) in the body frame.
    T_world_target : (4, 4)
    corners_target_m : (M, 3)
    stamps_ns : (F,) int64
        Frame stamps on the camera clock.
    timeshift_s : float
        ``t_imu = t_cam + timeshift_s``.
    noise_px : float
        Standard deviation of the Gaussian corner noise per axis.
    spacing_m, min_spacing_px : float
        Corner spacing on the board and the smallest spacing in the image a detector resolves.
    """
    st = np.asarray(stamps_ns, dtype=np.int64)
    t_true = st + np.int64(round(timeshift_s * 1e9))
    pos, quat = pose_at(t_true)
    R_wb = matrix_from_quat(quat)
    T_bc = np.asarray(T_body_cam, dtype=np.float64)
    T_wt = np.asarray(T_world_target, dtype=np.float64)
    X = np.asarray(corners_target_m, dtype=np.float64) @ T_wt[:3, :3].T + T_wt[:3, 3]
    R_wc = R_wb @ T_bc[:3, :3]
    p_wc = pos + R_wb @ T_bc[:3, 3]
    pc = np.einsum("nji,nmj->nmi", R_wc, X[None] - p_wc[:, None])  # (F, M, 3)
    z = pc[..., 2]
    uv = camera.project(pc)
    with np.errstate(invalid="ignore"):
        inside = ((z > 0.1) & np.all(np.isfinite(uv), axis=-1)
                  & (uv[..., 0] >= border_px) & (uv[..., 0] <= camera.width_px - 1 - border_px)
                  & (uv[..., 1] >= border_px) & (uv[..., 1] <= camera.height_px - 1 - border_px))
    big = camera.fx * spacing_m / np.where(z > 0, z, np.inf).max(axis=1) >= min_spacing_px
    keep = inside & big[:, None]
    if all_or_none:
        keep &= keep.all(axis=1, keepdims=True)
    rng = np.random.default_rng(seed)
    fi, ids = np.nonzero(keep)
    px = uv[fi, ids] + rng.normal(0.0, noise_px, (fi.size, 2))
    return CameraObservations(name, camera, st, fi.astype(np.int64), ids.astype(np.int64), px)
