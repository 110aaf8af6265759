"""Seeded, chunked IMU noise: white noise, bias random walk and a turn-on bias.

Continuous-time parameters (Kalibr's convention):

- white noise density ``N`` (u/sqrt(Hz)): each sample gets ``N(0, (N sqrt(rate))^2)``;
- random walk ``K`` (u*sqrt(Hz)): the bias moves by ``N(0, (K sqrt(dt))^2)`` each sample;
- ``bias0``: the bias at the first sample.

Chunks are generated one after the other from one ``numpy.random.Generator``, so the sequence
depends on ``seed`` and ``chunk`` only, and 168 hours at 200 Hz are produced in bounded memory.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence

import numpy as np

__all__ = ["imu_noise", "imu_noise_chunks"]


def imu_noise_chunks(
    n_samples: int,
    rate_hz: float,
    *,
    noise_density: float | Sequence[float] | np.ndarray,
    random_walk: float | Sequence[float] | np.ndarray,
    bias0: float | Sequence[float] | np.ndarray = 0.0,
    seed: int | None = 0,
    chunk: int = 1 << 20,
    n_axes: int | None = None,
) -> Iterator[np.ndarray]:
    """Yield noise samples in chunks of shape (rows, k), float64, rows <= ``chunk``.

    Parameters
    ----------
    n_samples : int
        Total number of samples.
    rate_hz : float
        Sample rate, Hz.
    noise_density : float or array_like, shape (k,)
        White noise density per axis, u/sqrt(Hz).
    random_walk : float or array_like, shape (k,)
        Bias random walk density per axis, u*sqrt(Hz).
    bias0 : float or array_like, shape (k,)
        Turn-on bias per axis, u.
    seed : int or None
        Seed of ``numpy.random.default_rng``.
    chunk : int
        Rows per chunk.
    n_axes : int, optional
        Number of axes when every parameter is a scalar (default 1).

    Yields
    ------
    ndarray, shape (rows, k)
        ``bias0 + bias_walk + white``; the walk starts at 0 on the first sample.
    """
    if n_samples < 0 or chunk < 1:
        raise ValueError("n_samples must be >= 0 and chunk >= 1")
    if not rate_hz > 0:
        raise ValueError(f"rate_hz must be positive, got {rate_hz!r}")
    nd = np.atleast_1d(np.asarray(noise_density, dtype=np.float64))
    rw = np.atleast_1d(np.asarray(random_walk, dtype=np.float64))
    b0 = np.atleast_1d(np.asarray(bias0, dtype=np.float64))
    k = max(nd.size, rw.size, b0.size, n_axes or 1)
    nd, rw, b0 = (np.broadcast_to(v, (k,)) for v in (nd, rw, b0))
    sigma_white = nd * math.sqrt(rate_hz)
    sigma_step = rw * math.sqrt(1.0 / rate_hz)
    rng = np.random.default_rng(seed)
    walk_last = np.zeros(k)  # bias walk at the previous sample
    for start in range(0, n_samples, chunk):
        rows = min(chunk, n_samples - start)
        walk = rng.standard_normal((rows, k))
        walk *= sigma_step
        if start == 0:
            walk[0] = 0.0  # the walk starts at 0 on the first sample
        np.cumsum(walk, axis=0, out=walk)
        walk += walk_last
        walk_last = walk[-1].copy()
        out = rng.standard_normal((rows, k))
        out *= sigma_white
        out += walk
        out += b0
        yield out


def imu_noise(n_samples: int, rate_hz: float, **kwargs: object) -> np.ndarray:
    """All of :func:`imu_noise_chunks` in one array of shape (n_samples, k)."""
    parts = list(imu_noise_chunks(n_samples, rate_hz, **kwargs))  # type: ignore[arg-type]
    if not parts:
        return np.zeros((0, 1))
    return np.concatenate(parts, axis=0)
