"""Initialisation of the first state: gravity direction, velocity and gyro bias.

Two ways, tried in this order:

1. **Standstill** (a car waiting at the start): when the first ``still_window_s`` of IMU data are
   quiet, gravity in the body frame is the mean specific force, the velocity is zero and the
   gyro bias is the mean angular rate.
2. **Moving**: stereo odometry over the first frames (landmarks triangulated in frame 0, PnP with
   RANSAC in frame ``k``) gives metric poses ``T_b0_bk``; with the IMU preintegrated from frame 0
   (``Delta p_0k``, ``Delta v_0k``) the body-0 velocity ``v_0`` and gravity ``g`` solve the linear
   least-squares problem ``p_k = v_0 t_k + g t_k^2 / 2 + Delta p_0k`` (Qin & Shen, "Robust
   initialization of monocular visual-inertial estimation", IROS 2017, with the scale known from
   stereo).  Planar car motion does not make this singular: the accelerometer sees gravity
   whatever the path, and stereo gives the metric positions.

Both return the body's attitude with zero yaw (yaw is unobservable; ATE aligns it).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from .backend import GRAVITY_M_S2, StereoObservations, integrate_imu
from .params import VioParams
from .rig import RectifiedStereo

__all__ = ["InitialState", "gravity_alignment", "initialise_moving", "initialise_standstill"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class InitialState:
    """The state the smoother is anchored at (``index`` of the frame it belongs to).

    ``frame_poses`` holds ``T_world_body`` of the frames before it (moving initialisation only).
    """

    index: int
    stamp_ns: int
    T_world_body: FloatArray
    vel_m_s: FloatArray
    bias_gyro_rad_s: FloatArray
    method: str
    frame_poses: dict[int, FloatArray]


def gravity_alignment(up_body: npt.ArrayLike) -> FloatArray:
    """``R_world_body`` with zero yaw whose body vector ``up_body`` points along world +z."""
    from scipy.spatial.transform import Rotation

    u = np.asarray(up_body, dtype=np.float64)
    u = u / np.linalg.norm(u)
    R, _ = Rotation.align_vectors(np.array([[0.0, 0.0, 1.0]]), u[None, :])
    ypr = R.as_euler("ZYX")
    return np.asarray(Rotation.from_euler("ZYX", [0.0, ypr[1], ypr[2]]).as_matrix())


def initialise_standstill(stamps_ns: npt.NDArray[np.int64], gyro_rad_s: FloatArray,
                          accel_m_s2: FloatArray, t0_ns: int, params: VioParams,
                          R_body_imu: FloatArray | None = None) -> InitialState | None:
    """The standstill start at ``t0_ns``, or None when the IMU is not quiet then."""
    t1 = t0_ns + int(params.still_window_s * 1e9)
    sel = (stamps_ns >= t0_ns - int(0.05e9)) & (stamps_ns <= t1)
    if sel.sum() < 10:
        return None
    g, a = gyro_rad_s[sel], accel_m_s2[sel]
    if R_body_imu is not None:
        g, a = g @ R_body_imu.T, a @ R_body_imu.T
    f = a.mean(axis=0)
    quiet = (np.linalg.norm(g.mean(axis=0)) < params.still_gyro_rad_s
             and float(a.std(axis=0).max()) < params.still_accel_std_m_s2
             and abs(np.linalg.norm(f) - GRAVITY_M_S2) < 0.5)
    if not quiet:
        return None
    T = np.eye(4)
    T[:3, :3] = gravity_alignment(f)
    bg = g.mean(axis=0) if R_body_imu is None else g.mean(axis=0) @ R_body_imu
    return InitialState(0, int(t0_ns), T, np.zeros(3), bg, "standstill", {})


def stereo_odometry(frames: Sequence[StereoObservations], rect: RectifiedStereo,
                    min_points: int) -> list[FloatArray] | None:
    """``T_b0_bk`` of every frame from PnP against frame 0's stereo landmarks, or None."""
    import cv2

    f0 = frames[0]
    ok0 = (f0.uL - f0.uR) > 0.5
    pts0 = rect.triangulate(f0.uL[ok0], f0.uR[ok0], f0.v[ok0])
    ids0 = f0.ids[ok0]
    keep = pts0[:, 2] < 80.0 * rect.baseline_m / 0.4
    pts0, ids0 = pts0[keep], ids0[keep]
    T_br = rect.T_body_rect
    T_rb = np.linalg.inv(T_br)
    out = [np.eye(4)]
    K = rect.K
    thr = 2.0 * rect.width_px / 512.0
    for fr in frames[1:]:
        common, i0, i1 = np.intersect1d(ids0, fr.ids, return_indices=True)
        if len(common) < min_points:
            return None
        obj = pts0[i0].astype(np.float64)
        img = np.stack([fr.uL[i1], fr.v[i1]], axis=1).astype(np.float64)
        ok, rvec, tvec, inl = cv2.solvePnPRansac(obj, img, K, None, reprojectionError=thr,
                                                 iterationsCount=100, confidence=0.999,
                                                 flags=cv2.SOLVEPNP_ITERATIVE)
        if not ok or inl is None or len(inl) < min_points:
            return None
        T_rk_r0 = np.eye(4)
        T_rk_r0[:3, :3] = cv2.Rodrigues(rvec)[0]
        T_rk_r0[:3, 3] = tvec.ravel()
        out.append(T_br @ np.linalg.inv(T_rk_r0) @ T_rb)
    return out


def initialise_moving(frames: Sequence[StereoObservations], first_index: int,
                      rect: RectifiedStereo, imu: tuple[npt.NDArray[np.int64], FloatArray, FloatArray],
                      imu_params: Any, params: VioParams) -> InitialState | None:
    """Stereo odometry over ``frames`` aligned with the preintegrated IMU (module docstring).

    Returns the state at the LAST frame (index ``first_index + len(frames) - 1``) and the poses of
    the earlier ones, or None when the odometry or the alignment is not trustworthy.
    """
    import gtsam

    poses = stereo_odometry(frames, rect, params.min_tracked)
    if poses is None:
        return None
    stamps, gyro, acc = imu
    t0 = frames[0].stamp_ns
    pim = gtsam.PreintegratedCombinedMeasurements(imu_params, gtsam.imuBias.ConstantBias())
    rows_a, rows_b = [], []
    t_prev = t0
    dv = np.zeros(3)
    for k in range(1, len(frames)):
        tk = frames[k].stamp_ns
        integrate_imu(pim, stamps, gyro, acc, t_prev, tk)
        t_prev = tk
        t = (tk - t0) * 1e-9
        A = np.zeros((3, 6))
        A[:, :3] = np.eye(3) * t
        A[:, 3:] = np.eye(3) * 0.5 * t * t
        rows_a.append(A)
        rows_b.append(poses[k][:3, 3] - np.asarray(pim.deltaPij()))
        dv = np.asarray(pim.deltaVij())
    if not rows_a:
        return None
    A = np.concatenate(rows_a)
    b = np.concatenate(rows_b)
    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    v0, g = x[:3], x[3:]
    if abs(np.linalg.norm(g) - GRAVITY_M_S2) > 0.1 * GRAVITY_M_S2:
        return None
    R_w_b0 = gravity_alignment(-g)
    T_w_b0 = np.eye(4)
    T_w_b0[:3, :3] = R_w_b0
    t_n = (frames[-1].stamp_ns - t0) * 1e-9
    v_n = R_w_b0 @ (v0 + g * t_n + dv)
    n = len(frames) - 1
    world = [T_w_b0 @ P for P in poses]
    return InitialState(first_index + n, frames[-1].stamp_ns, world[-1], v_n, np.zeros(3),
                        "moving", {first_index + i: world[i] for i in range(n)})
