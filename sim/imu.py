"""IMU model: exact specific force and angular rate of a mounted IMU, plus seeded noise.

For an IMU at ``r`` (body frame) with axes ``R_body_imu``, a body at ``p, R`` (world) with body
angular rate ``w`` and its derivative ``dw`` (both body frame)::

    a_imu = a + R (dw x r + w x (w x r))         (second derivative of p + R r)
    f     = R_body_imu^T R^T (a_imu - g)          (specific force, g = (0, 0, -9.81))
    gyro  = R_body_imu^T w

Noise (continuous-time model, Kalibr's convention, :func:`ibiscape_eval.sim.noise.imu_noise_chunks`):
white noise of density N (per-sample sigma ``N sqrt(rate)``), a bias random walk of density K (per
step ``K sqrt(dt)``) and a constant turn-on bias drawn once per axis.  The CARLA-compatible model
takes per-sample sigmas (white only) and CARLA's constant gyro bias instead.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ibiscape_eval.core.rotations import matrix_from_quat

from .noise import imu_noise_chunks
from .types import GRAVITY_M_S2, MotionState

if TYPE_CHECKING:
    import pandas as pd

    from .config import ImuNoise

__all__ = ["ImuMeasurements", "NoiseParameters", "ideal_imu", "noise_parameters", "simulate_imu",
           "sub_seed"]

FloatArray = npt.NDArray[np.float64]


def sub_seed(seed: int, *tags: int | str) -> int:
    """A 63-bit seed derived from ``seed`` and tags (one independent stream per sensor/purpose)."""
    words = [seed] + [t if isinstance(t, int) else int.from_bytes(t.encode()[:8], "little")
                      for t in tags]
    return int(np.random.SeedSequence(words).generate_state(2, np.uint64)[0] >> np.uint64(1))


@dataclass(frozen=True, eq=False)
class ImuMeasurements:
    """IMU samples in the IMU frame.

    Attributes
    ----------
    stamps_ns : ndarray, shape (N,), int64
    gyro_rad_s : ndarray, shape (N, 3)
        Angular rate, rad/s.
    accel_m_s2 : ndarray, shape (N, 3)
        Specific force, m/s^2 (reads +9.81 on z when level and still).
    name : str
    """

    stamps_ns: npt.NDArray[np.int64]
    gyro_rad_s: FloatArray
    accel_m_s2: FloatArray
    name: str = "imu0"

    def __len__(self) -> int:
        return int(self.stamps_ns.shape[0])

    def to_frame(self) -> pd.DataFrame:
        """Columns ``stamp_ns, wx_rad_s .. wz_rad_s, ax_m_s2 .. az_m_s2``."""
        import pandas as pd

        d: dict[str, np.ndarray] = {"stamp_ns": self.stamps_ns}
        for k, ax in enumerate("xyz"):
            d[f"w{ax}_rad_s"] = self.gyro_rad_s[:, k]
        for k, ax in enumerate("xyz"):
            d[f"a{ax}_m_s2"] = self.accel_m_s2[:, k]
        return pd.DataFrame(d)


@dataclass(frozen=True)
class NoiseParameters:
    """Noise of one IMU at its rate, in both conventions (6 axes: gyro x y z, accel x y z).

    ``noise_density`` [u/sqrt(Hz)], ``random_walk`` [u*sqrt(Hz)], ``sigma_per_sample`` [u]
    (``noise_density * sqrt(rate)``), ``walk_sigma_per_step`` [u] (``random_walk / sqrt(rate)``),
    ``turn_on_bias_sigma`` [u]."""

    rate_hz: float
    noise_density: tuple[float, ...]
    random_walk: tuple[float, ...]
    sigma_per_sample: tuple[float, ...]
    walk_sigma_per_step: tuple[float, ...]
    turn_on_bias_sigma: tuple[float, ...]
    constant_bias: tuple[float, ...]


def noise_parameters(noise: ImuNoise, rate_hz: float, *, ideal: bool = False) -> NoiseParameters:
    """The per-axis parameters :func:`simulate_imu` uses (all zero when ``ideal``)."""
    if ideal:
        z = (0.0,) * 6
        return NoiseParameters(rate_hz, z, z, z, z, z, z)
    sq = math.sqrt(rate_hz)
    if noise.model == "carla":
        sig = (noise.carla_gyro_sigma_rad_s,) * 3 + (noise.carla_accel_sigma_m_s2,) * 3
        nd = tuple(s / sq for s in sig)
        z = (0.0,) * 6
        return NoiseParameters(rate_hz, nd, z, sig, z, z, (noise.carla_gyro_bias_rad_s,) * 3 + (0.0,) * 3)
    nd = (noise.gyro_noise_density_rad_s_sqrt_hz,) * 3 + (noise.accel_noise_density_m_s2_sqrt_hz,) * 3
    rw = (noise.gyro_random_walk_rad_s2_sqrt_hz,) * 3 + (noise.accel_random_walk_m_s3_sqrt_hz,) * 3
    tb = (noise.gyro_turn_on_bias_sigma_rad_s,) * 3 + (noise.accel_turn_on_bias_sigma_m_s2,) * 3
    return NoiseParameters(rate_hz, nd, rw, tuple(v * sq for v in nd), tuple(v / sq for v in rw), tb,
                           (0.0,) * 6)


def turn_on_bias(params: NoiseParameters, seed: int) -> FloatArray:
    """Constant bias per axis, shape (6,): ``constant_bias + N(0, turn_on_bias_sigma)``."""
    rng = np.random.default_rng(sub_seed(seed, "turn-on"))
    return np.asarray(params.constant_bias) + rng.standard_normal(6) * np.asarray(params.turn_on_bias_sigma)


def ideal_imu(state: MotionState, T_body_imu: npt.ArrayLike, name: str = "imu0") -> ImuMeasurements:
    """Noise-free IMU readings of an IMU mounted at ``T_body_imu`` on the moving body.

    Parameters
    ----------
    state : MotionState
        Exact body kinematics at the IMU stamps (N samples).
    T_body_imu : array_like, shape (4, 4)
        Pose of the IMU frame in the body frame (lever arm ``r = T[:3, 3]``).

    Returns
    -------
    ImuMeasurements
        Gyro rad/s and specific force m/s^2 in the IMU frame (see the module docstring).
    """
    T = np.asarray(T_body_imu, dtype=np.float64)
    R_bi, r = T[:3, :3], T[:3, 3]
    R = matrix_from_quat(state.quat_xyzw)  # (N, 3, 3) world <- body
    w, dw = state.angvel_body_rad_s, state.angacc_body_rad_s2
    acc = state.acc_m_s2
    if np.any(r != 0.0):
        lever_b = np.cross(dw, r) + np.cross(w, np.cross(w, r))  # body frame
        acc = acc + np.einsum("nij,nj->ni", R, lever_b)
    f_body = np.einsum("nji,nj->ni", R, acc - GRAVITY_M_S2)  # R^T (a - g)
    gyro = w @ R_bi  # rows: R_bi^T w
    return ImuMeasurements(np.asarray(state.stamps_ns, dtype=np.int64), gyro, f_body @ R_bi, name)


def simulate_imu(state: MotionState, T_body_imu: npt.ArrayLike, noise: ImuNoise, *, rate_hz: float,
                 seed: int, ideal: bool = False, name: str = "imu0") -> ImuMeasurements:
    """:func:`ideal_imu` plus noise (white, bias random walk, turn-on bias, or CARLA's sigmas).

    ``seed`` should already be specific to this IMU (see :func:`sub_seed`); ``rate_hz`` is the
    rate of ``state``'s stamps.  ``ideal`` returns the noise-free readings.
    """
    m = ideal_imu(state, T_body_imu, name)
    if ideal:
        return m
    p = noise_parameters(noise, rate_hz)
    b0 = turn_on_bias(p, seed)
    n = len(m)
    eps = np.concatenate(list(imu_noise_chunks(
        n, rate_hz, noise_density=p.noise_density, random_walk=p.random_walk, bias0=b0,
        seed=sub_seed(seed, "noise"), chunk=max(n, 1))) or [np.zeros((0, 6))], axis=0)
    return ImuMeasurements(m.stamps_ns, m.gyro_rad_s + eps[:, :3], m.accel_m_s2 + eps[:, 3:], name)
