"""The still-IMU case (``setup imu``): a standing vehicle, streamed chunk by chunk.

The vehicle stands level at the world origin, so an IMU reads ``gyro = 0`` and specific force
``f = R_body_imu^T (0, 0, 9.81)`` plus noise.  Samples are produced in chunks of ``chunk`` rows from
:func:`ibiscape_eval.sim.noise.imu_noise_chunks`, so 168 hours at 200 Hz (121 million samples) are
written in bounded memory.  The output depends on the seed and ``chunk`` (the noise generator draws
per chunk).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from .imu import noise_parameters, sub_seed, turn_on_bias
from .noise import imu_noise_chunks
from .rig import T_body_imu
from .types import GRAVITY_M_S2

if TYPE_CHECKING:
    from .config import ImuNoise, ImuSpec

__all__ = ["n_samples", "still_imu_chunks", "uniform_stamps"]


def n_samples(duration_s: float, rate_hz: float) -> int:
    """Samples covering ``[0, duration_s]`` at ``rate_hz``: ``floor(duration * rate) + 1``."""
    return math.floor(duration_s * rate_hz + 1e-9) + 1


def uniform_stamps(start_ns: int, rate_hz: float, first: int, count: int) -> npt.NDArray[np.int64]:
    """Stamps ``start + round(k * 1e9 / rate)`` for ``k = first .. first + count - 1`` (int64 ns;
    exact integer arithmetic when the period is a whole number of nanoseconds)."""
    k = np.arange(first, first + count, dtype=np.int64)
    period = 1e9 / rate_hz
    if period.is_integer():
        return start_ns + k * np.int64(int(period))
    return start_ns + np.round(k * period).astype(np.int64)


def still_imu_chunks(spec: ImuSpec, noise: ImuNoise, *, duration_s: float, start_ns: int, seed: int,
                     ideal: bool = False, chunk: int = 1 << 18,
                     ) -> Iterator[tuple[npt.NDArray[np.int64], np.ndarray, np.ndarray]]:
    """Yield ``(stamps_ns (n,), gyro_rad_s (n, 3), accel_m_s2 (n, 3))`` chunks of a still IMU.

    Parameters
    ----------
    spec : ImuSpec
        Mounting (only the orientation matters when still) and rate.
    noise : ImuNoise
    duration_s : float
        Recording length, s (``n_samples(duration_s, rate)`` samples).
    start_ns : int
        First stamp, ns.
    seed : int
        Seed of this IMU's noise (see :func:`ibiscape_eval.sim.imu.sub_seed`).
    ideal : bool
        No noise.
    chunk : int
        Rows per chunk (memory ~ 100 bytes per row).
    """
    rate = spec.rate_hz
    n = n_samples(duration_s, rate)
    R_bi = T_body_imu(spec)[:3, :3]
    f = (-GRAVITY_M_S2) @ R_bi  # R_bi^T (0, 0, 9.81)
    p = noise_parameters(noise, rate, ideal=ideal)
    if ideal:
        for a in range(0, n, chunk):
            m = min(chunk, n - a)
            yield (uniform_stamps(start_ns, rate, a, m), np.zeros((m, 3)), np.tile(f, (m, 1)))
        return
    gen = imu_noise_chunks(n, rate, noise_density=p.noise_density, random_walk=p.random_walk,
                           bias0=turn_on_bias(p, seed), seed=sub_seed(seed, "noise"), chunk=chunk)
    a = 0
    for eps in gen:
        m = eps.shape[0]
        acc = eps[:, 3:]
        acc += f
        yield uniform_stamps(start_ns, rate, a, m), eps[:, :3], acc
        a += m
