"""Initialisation of the first state: gravity direction, velocity and gyro bias.

Two ways, tried in this order:

1. **Standstill** (a car waiting at the start, a drone on the ground with its rotors spinning):
   when the first ``still_window_s`` of IMU data are quiet (:func:`detect_standstill`: the
   gyroscope and the accelerometer do not VARY at low frequency; their means are free, since a
   constant gyro reading is the bias), gravity in the body frame is the mean specific force, the
   velocity is zero and the gyro bias is the mean angular rate.
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

__all__ = ["InitialState", "StandstillTest", "detect_standstill", "gravity_alignment", "initialise_moving",
           "initialise_standstill", "mean_specific_force", "standstill_at"]

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


#: low-pass of the standstill test: two passes of a moving average this long (a triangular
#: kernel of twice the length; gain 0.04 at 17 Hz, the EuRoC MAV's rotor-frame vibration, -3 dB
#: at ~3 Hz), so rotor and engine vibration average out while a start or a sway remains
STILL_SMOOTH_S = 0.1
#: a mean rate above this is a rotation, not a MEMS gyro bias (the estimator's plausibility bound)
STILL_MAX_GYRO_BIAS_RAD_S = 0.2
#: tolerance of the mean specific-force norm around gravity (accelerometer bias and scale)
STILL_GRAVITY_TOL_M_S2 = 0.5


@dataclass(frozen=True)
class StandstillTest:
    """Outcome of :func:`detect_standstill`, with what was measured and the limits it was held to.

    Attributes
    ----------
    still : bool
        Every statistic below its limit.
    reason : str
        Empty when still; otherwise which statistic exceeded its limit (one line).
    n_samples : int
        IMU samples in the window.
    gyro_var_rad2_s2, gyro_var_limit_rad2_s2 : float
        Largest per-axis variance of the low-passed angular rate, and its limit (``gyro_std_rad_s``
        squared).  The mean rate (bias) does not enter.
    accel_norm_std_m_s2 : float
        Standard deviation of the low-passed specific-force norm (vertical starts, bumps, lift-off).
    accel_axis_std_m_s2 : float
        Largest per-axis standard deviation of the low-passed specific force (horizontal starts and
        tilts, which hardly change the norm: ``|f| = sqrt(g^2 + a^2)``).
    accel_std_limit_m_s2 : float
        Limit of both accelerometer statistics.
    mean_gyro_rad_s : (3,) array
        Mean angular rate over the window: the gyro bias when still.
    mean_accel_norm_m_s2 : float
        Norm of the mean specific force (must be gravity within ``STILL_GRAVITY_TOL_M_S2``).
    raw_gyro_std_rad_s, raw_accel_std_m_s2 : float
        Largest per-axis standard deviation before the low-pass: the vibration level, for the
        record (not tested).
    """

    still: bool
    reason: str
    n_samples: int
    gyro_var_rad2_s2: float
    gyro_var_limit_rad2_s2: float
    accel_norm_std_m_s2: float
    accel_axis_std_m_s2: float
    accel_std_limit_m_s2: float
    mean_gyro_rad_s: FloatArray
    mean_accel_norm_m_s2: float
    raw_gyro_std_rad_s: float
    raw_accel_std_m_s2: float

    def to_dict(self) -> dict[str, Any]:
        """Plain mapping (JSON)."""
        d = {f: getattr(self, f) for f in self.__dataclass_fields__}
        d["mean_gyro_rad_s"] = [float(x) for x in self.mean_gyro_rad_s]
        return d


def _smooth(x: FloatArray, n: int) -> FloatArray:
    """Two passes of an ``n``-sample moving average along axis 0 ('valid' part only)."""
    if n <= 1:
        return x
    for _ in range(2):
        c = np.cumsum(np.concatenate((np.zeros((1, x.shape[1])), x)), axis=0)
        x = (c[n:] - c[:-n]) / n
    return x


def detect_standstill(stamps_ns: npt.ArrayLike, gyro_rad_s: npt.ArrayLike, accel_m_s2: npt.ArrayLike,
                      t0_ns: int, t1_ns: int, *, gyro_std_rad_s: float = 0.02,
                      accel_std_m_s2: float = 0.15, smooth_s: float = STILL_SMOOTH_S) -> StandstillTest:
    """Whether the IMU stood still between ``t0_ns`` and ``t1_ns`` (inclusive).

    Bias-aware: only the VARIATION of the angular rate counts (the variance of the low-passed
    rate), never its mean, so a gyro bias of 0.1 rad/s is still.  Vibration-tolerant: the rates
    and the specific force are low-passed first (two passes of a ``smooth_s`` moving average,
    :data:`STILL_SMOOTH_S`), so rotor or engine vibration of 1 m/s^2 RMS averages out while a
    start, a sway or a lift-off (below ~3 Hz) remains.  Still means: per-axis variance of the
    low-passed rate <= ``gyro_std_rad_s`` squared, standard deviation of the low-passed
    specific-force norm AND of each of its axes <= ``accel_std_m_s2``, the mean specific force
    within ``STILL_GRAVITY_TOL_M_S2`` of gravity and the mean rate below
    ``STILL_MAX_GYRO_BIAS_RAD_S``.

    Limits of any IMU-only test, by physics: a constant rotation rate is indistinguishable from
    a bias and a constant acceleration from a tilt; the VIO therefore also requires the image to be
    still.  The low-pass needs ~0.2 s of data in the window (at least ``2 * smooth_s`` plus 10
    samples), otherwise the result is "not still" with the reason.

    Parameters
    ----------
    stamps_ns : (N,) int64
    gyro_rad_s, accel_m_s2 : (N, 3)
        In any one frame (the statistics do not depend on it).
    t0_ns, t1_ns : int
        The window.
    gyro_std_rad_s, accel_std_m_s2 : float
        Limits (``VioParams.still_gyro_rad_s``, ``still_accel_std_m_s2``).
    smooth_s : float
        Length of the moving average.
    """
    t = np.asarray(stamps_ns, dtype=np.int64)
    sel = (t >= t0_ns) & (t <= t1_ns)
    w = np.asarray(gyro_rad_s, dtype=np.float64)[sel]
    a = np.asarray(accel_m_s2, dtype=np.float64)[sel]
    n = int(sel.sum())
    ts = t[sel]
    dt = float(np.median(np.diff(ts))) * 1e-9 if n >= 2 else 0.0
    k = max(1, round(smooth_s / dt)) if dt > 0 else 1
    nan = float("nan")
    if n < 2 * k + 10 or dt <= 0:
        return StandstillTest(False, f"{n} IMU samples in the window: too few to tell (need "
                              f"{2 * k + 10})", n, nan, gyro_std_rad_s ** 2, nan, nan,
                              accel_std_m_s2, np.full(3, nan), nan, nan, nan)
    norm = np.linalg.norm(a, axis=1)[:, None]
    lw = _smooth(w, k)
    la = _smooth(np.concatenate((a, norm), axis=1), k)
    gvar = float(lw.var(axis=0).max())
    ax_std = float(la[:, :3].std(axis=0).max())
    n_std = float(la[:, 3].std())
    mw = w.mean(axis=0)
    mf = float(np.linalg.norm(a.mean(axis=0)))
    reasons = []
    if not gvar <= gyro_std_rad_s ** 2:
        reasons.append(f"gyro variance {gvar:.2g} rad^2/s^2 > {gyro_std_rad_s ** 2:.2g}")
    if not n_std <= accel_std_m_s2:
        reasons.append(f"accel norm std {n_std:.3f} m/s^2 > {accel_std_m_s2:.3f}")
    if not ax_std <= accel_std_m_s2:
        reasons.append(f"accel axis std {ax_std:.3f} m/s^2 > {accel_std_m_s2:.3f}")
    if not abs(mf - GRAVITY_M_S2) <= STILL_GRAVITY_TOL_M_S2:
        reasons.append(f"mean specific force {mf:.2f} m/s^2 is not gravity")
    if not float(np.linalg.norm(mw)) <= STILL_MAX_GYRO_BIAS_RAD_S:
        reasons.append(f"mean rate {np.linalg.norm(mw):.3f} rad/s is a rotation, not a bias")
    return StandstillTest(not reasons, "; ".join(reasons), n, gvar, gyro_std_rad_s ** 2, n_std, ax_std,
                          accel_std_m_s2, mw, mf, float(w.std(axis=0).max()),
                          float(a.std(axis=0).max()))


def initialise_standstill(stamps_ns: npt.NDArray[np.int64], gyro_rad_s: FloatArray,
                          accel_m_s2: FloatArray, t0_ns: int, params: VioParams,
                          R_body_imu: FloatArray | None = None) -> InitialState | None:
    """The standstill start at ``t0_ns``, or None when the IMU is not still then
    (:func:`standstill_at` tells why)."""
    test = standstill_at(stamps_ns, gyro_rad_s, accel_m_s2, t0_ns, params)
    if not test.still:
        return None
    t1 = t0_ns + int(params.still_window_s * 1e9)
    sel = (stamps_ns >= t0_ns - int(0.05e9)) & (stamps_ns <= t1)
    g, a = gyro_rad_s[sel], accel_m_s2[sel]
    if R_body_imu is not None:
        g, a = g @ R_body_imu.T, a @ R_body_imu.T
    f = a.mean(axis=0)
    T = np.eye(4)
    T[:3, :3] = gravity_alignment(f)
    bg = g.mean(axis=0) if R_body_imu is None else g.mean(axis=0) @ R_body_imu
    return InitialState(0, int(t0_ns), T, np.zeros(3), bg, "standstill", {})


def mean_specific_force(stamps_ns: npt.NDArray[np.int64], accel_m_s2: FloatArray, t0_ns: int, t1_ns: int,
                        R_body_imu: FloatArray | None = None,
                        bias_acc_m_s2: FloatArray | None = None) -> FloatArray:
    """Mean specific force of the IMU samples in ``[t0_ns, t1_ns]``, less ``bias_acc_m_s2``,
    turned into the body frame by ``R_body_imu`` (at a standstill: minus gravity)."""
    i0 = int(np.searchsorted(stamps_ns, t0_ns, side="left"))
    i1 = int(np.searchsorted(stamps_ns, t1_ns, side="right"))
    f = accel_m_s2[i0:i1].mean(axis=0)
    if bias_acc_m_s2 is not None:
        f = f - bias_acc_m_s2
    return np.asarray(f if R_body_imu is None else R_body_imu @ f, np.float64)


def standstill_at(stamps_ns: npt.NDArray[np.int64], gyro_rad_s: FloatArray, accel_m_s2: FloatArray,
                  t0_ns: int, params: VioParams) -> StandstillTest:
    """:func:`detect_standstill` over the VIO's window (``still_window_s`` from ``t0_ns``, and the
    0.05 s before it) with the limits of ``params``."""
    return detect_standstill(stamps_ns, gyro_rad_s, accel_m_s2, t0_ns - int(0.05e9),
                             t0_ns + int(params.still_window_s * 1e9),
                             gyro_std_rad_s=params.still_gyro_rad_s,
                             accel_std_m_s2=params.still_accel_std_m_s2)


def stereo_odometry(frames: Sequence[StereoObservations], rect: RectifiedStereo,
                    min_points: int) -> list[FloatArray] | None:
    """``T_b0_bk`` of every frame from PnP against a map of stereo landmarks, or None.

    Each frame is resected against frame 0's triangulated points when it still sees
    ``min_points`` of them (the poses then do not chain errors); otherwise against the map, frame
    0's points grown after each frame's PnP by the points that frame triangulates first (expressed
    in frame 0 through its pose), so tracks shorter than the window (event frames: a corner lives
    a few frames) still chain the poses.
    """
    import cv2

    T_br = rect.T_body_rect
    T_rb = np.linalg.inv(T_br)
    max_z = 80.0 * rect.baseline_m / 0.4
    map_ids = np.zeros(0, dtype=np.int64)
    map_pts = np.zeros((0, 3))
    T_r0_rk: FloatArray = np.eye(4)
    out = []
    K = rect.K
    thr = 2.0 * rect.width_px / 512.0
    ids0, pts0 = map_ids, map_pts
    for k, fr in enumerate(frames):
        if k > 0:
            common, i0, i1 = np.intersect1d(ids0, fr.ids, return_indices=True)
            ref = pts0
            if len(common) < min_points:
                common, i0, i1 = np.intersect1d(map_ids, fr.ids, return_indices=True)
                ref = map_pts
            if len(common) < min_points:
                return None
            obj = ref[i0].astype(np.float64)
            img = np.stack([fr.uL[i1], fr.v[i1]], axis=1).astype(np.float64)
            ok, rvec, tvec, inl = cv2.solvePnPRansac(obj, img, K, None, reprojectionError=thr,
                                                     iterationsCount=100, confidence=0.999,
                                                     flags=cv2.SOLVEPNP_ITERATIVE)
            if not ok or inl is None or len(inl) < min_points:
                return None
            T_rk_r0 = np.eye(4)
            T_rk_r0[:3, :3] = cv2.Rodrigues(rvec)[0]
            T_rk_r0[:3, 3] = tvec.ravel()
            T_r0_rk = np.asarray(np.linalg.inv(T_rk_r0), dtype=np.float64)
        out.append(T_br @ T_r0_rk @ T_rb)
        ok_d = (fr.uL - fr.uR) > 0.5  # NaN uR (left-only tracks) compares False
        new = ok_d & ~np.isin(fr.ids, map_ids)
        if new.any():
            p = rect.triangulate(fr.uL[new], fr.uR[new], fr.v[new])
            keep = p[:, 2] < max_z
            p_0 = p[keep] @ T_r0_rk[:3, :3].T + T_r0_rk[:3, 3]
            map_ids = np.concatenate((map_ids, fr.ids[new][keep]))
            map_pts = np.concatenate((map_pts, p_0))
        if k == 0:
            ids0, pts0 = map_ids, map_pts
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
