"""Do the camera-IMU calibration's standard deviations cover the truth as often as they say?

Seeded short calibration drives of the simulator (corners projected, no rendering); every
rotation (about the IMU axes), translation and time-offset error of both cameras divided by its
reported std, pooled over parameters and seeds, must fall below 1 in 60-75 % (normal: 68.3 %)
and below 2 in 90-98 % (95.4 %) of the cases.  ``benchmarks/bench_coverage.py --imu`` runs the
same with more and longer drives, ``--seq`` on rendered drives.
"""

from __future__ import annotations

import warnings
from dataclasses import replace
from functools import lru_cache

import numpy as np

from ibiscape_eval.calib.imu_camera import ImuCameraOptions, calibrate_imu_camera
from ibiscape_eval.calib.imu_camera.synthetic import CalibrationScene, calibration_scene
from ibiscape_eval.core.so3 import log_so3
from ibiscape_eval.sim import preset
from ibiscape_eval.sim.calib_scene import simulate_calibration
from ibiscape_eval.sim.config import MotionSpec

SEEDS = range(1, 9)
SHIFTS = {"rgbL": 0.0123, "rgbR": -0.0171}


@lru_cache(maxsize=8)
def _scene(seed: int, walk: float = 1.0) -> CalibrationScene:
    cfg = preset("svi", "calibration", "clear", duration_s=8.0, seed=seed, motion=MotionSpec(bumps=True))
    n = cfg.imu_noise
    cfg = replace(cfg, imu_noise=replace(
        n, gyro_random_walk_rad_s2_sqrt_hz=walk * n.gyro_random_walk_rad_s2_sqrt_hz,
        accel_random_walk_m_s3_sqrt_hz=walk * n.accel_random_walk_m_s3_sqrt_hz))
    cfg = replace(cfg, cameras=tuple(replace(c, width_px=320, height_px=320, rate_hz=10.0)
                                     for c in cfg.cameras))
    return calibration_scene(simulate_calibration(cfg, timeshifts_s=SHIFTS), noise_px=0.2,
                             min_spacing_px=4.0)


def _z(res, sc: CalibrationScene) -> tuple[np.ndarray, np.ndarray]:
    """|error| / reported std and / the plain ``(J^T J)^-1`` std, per camera (7 each)."""
    after, before = [], []
    for cal in res.cameras:
        T = sc.T_cam_imu[cal.name]
        e = np.r_[log_so3(T[:3, :3].T @ cal.T_cam_imu[:3, :3]), cal.T_cam_imu[:3, 3] - T[:3, 3],
                  cal.timeshift_cam_imu_s - sc.timeshift_cam_imu_s[cal.name]]
        sd = np.r_[np.radians(cal.rotation_std_deg), cal.translation_std_m, cal.timeshift_std_s]
        after.append(np.abs(e / sd))
        before.append(np.abs(e / np.asarray(res.uncertainty["std_plain"][cal.name])))
    return np.concatenate(after), np.concatenate(before)


def _coverage(z: np.ndarray) -> tuple[float, float]:
    return float(np.mean(z < 1)), float(np.mean(z < 2))


def _in_band(z: np.ndarray) -> bool:
    one, two = _coverage(z)
    return 0.60 <= one <= 0.75 and 0.90 <= two <= 0.98


def test_misweighted_noise_is_measured():
    """``imu.yaml`` densities 4x the truth (Kalibr's advice for real IMUs) and ``sigma_px`` 2x the
    corner noise: the plain std scales with the assumed noise (1-sigma covers nearly everything);
    the residuals' measured variance per group brings the coverage back."""
    za, zb = [], []
    for seed in SEEDS:
        sc = _scene(seed)
        noise = replace(sc.noise,
                        gyro_noise_density_rad_s_sqrt_hz=4 * sc.noise.gyro_noise_density_rad_s_sqrt_hz,
                        accel_noise_density_m_s2_sqrt_hz=4 * sc.noise.accel_noise_density_m_s2_sqrt_hz)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = calibrate_imu_camera(sc.observations, sc.imu, noise, sc.corners_target_m, ImuCameraOptions(sigma_px=0.4))
        scale = res.uncertainty["residual_scale"]
        assert 1 / 16 / 1.3 < scale["gyro"] < 1.3 / 16 and 1 / 16 / 1.3 < scale["accel"] < 1.3 / 16
        a, b = _z(res, sc)
        za.append(a)
        zb.append(b)
    z, z_plain = np.concatenate(za), np.concatenate(zb)
    assert _in_band(z), _coverage(z)
    assert _coverage(z_plain)[0] > 0.85  # the old std: far wider than the errors


def test_bias_random_walk_between_knots_is_covered():
    """A consumer-grade IMU (bias random walk 10x the default: 0.03 m/s^3/sqrt(Hz)), its densities
    in ``imu.yaml``: the bias wanders between the knots, which the linear interpolation cannot
    follow; the plain std ignores that (1-sigma covered 15 % on 12 s drives), the bridge term
    covers it."""
    za, zb = [], []
    for seed in SEEDS:
        sc = _scene(seed, 10.0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = calibrate_imu_camera(sc.observations, sc.imu, sc.noise, sc.corners_target_m, ImuCameraOptions(sigma_px=0.2))
        a, b = _z(res, sc)
        za.append(a)
        zb.append(b)
    z, z_plain = np.concatenate(za), np.concatenate(zb)
    assert _in_band(z), (_coverage(z), _coverage(z_plain))
    assert _coverage(z_plain)[1] < 0.80, _coverage(z_plain)


def test_intrinsics_error_is_propagated():
    """Intrinsics off by a draw from the covariance their camera calibration reports and held
    in the solve: their error moves the extrinsics by several plain stds; with
    ``intrinsics_covariance`` the reported std covers it.  (``calib SEQ --imu`` without ``--cams``
    refines the focal lengths and principal point and holds the distortion; on these small
    drives the distortion alone moves little, see ``bench_coverage.py --intrinsics-error``.)"""
    sd = np.array([0.5, 0.5, 0.5, 0.5, 4e-3, 4e-3, 4e-4, 4e-4])
    C = np.diag(sd**2)
    C[4, 5] = C[5, 4] = -0.5 * sd[4] * sd[5]
    za, zb = [], []
    for seed in SEEDS:
        sc = _scene(seed)
        rng = np.random.default_rng(100 + seed)
        obs = []
        for o in sc.observations:
            assert o.camera is not None
            d = np.linalg.cholesky(C) @ rng.normal(size=8)
            cam = replace(o.camera, fx=o.camera.fx + d[0], fy=o.camera.fy + d[1], cx=o.camera.cx + d[2],
                          cy=o.camera.cy + d[3], coeffs=tuple(float(v) for v in d[4:]))
            obs.append(replace(o, camera=cam))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = calibrate_imu_camera(obs, sc.imu, sc.noise, sc.corners_target_m,
                                       ImuCameraOptions(sigma_px=0.2, refine_intrinsics=False),
                                       intrinsics_covariance={o.name: C for o in obs})
        a, b = _z(res, sc)
        za.append(a)
        zb.append(b)
    z, z_plain = np.concatenate(za), np.concatenate(zb)
    assert _in_band(z), (_coverage(z), _coverage(z_plain))
    assert _coverage(z_plain)[1] < 0.80, _coverage(z_plain)  # without it: a confident wrong number
