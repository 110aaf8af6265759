"""The chunked IMU noise generator has the densities it is asked for."""

from __future__ import annotations

import numpy as np
import pytest

from ibiscape_eval.sim.noise import imu_noise, imu_noise_chunks


def test_white_sigma_and_walk_steps() -> None:
    rate = 100.0
    y = imu_noise(200_000, rate, noise_density=[0.01, 0.0], random_walk=[0.0, 0.02],
                  bias0=[1.0, -2.0], seed=3, chunk=30_000)
    assert y.shape == (200_000, 2)
    assert y[:, 0].std() == pytest.approx(0.01 * np.sqrt(rate), rel=0.01)
    assert y[:, 0].mean() == pytest.approx(1.0, abs=0.001)
    steps = np.diff(y[:, 1])  # continuous across chunk borders
    assert steps.std() == pytest.approx(0.02 * np.sqrt(1 / rate), rel=0.01)
    assert y[0, 1] == -2.0


def test_seeded_and_bounded_chunks() -> None:
    a = list(imu_noise_chunks(1000, 10.0, noise_density=1.0, random_walk=1.0, seed=5, chunk=300))
    b = list(imu_noise_chunks(1000, 10.0, noise_density=1.0, random_walk=1.0, seed=5, chunk=300))
    assert [c.shape[0] for c in a] == [300, 300, 300, 100]
    np.testing.assert_array_equal(np.concatenate(a), np.concatenate(b))
    c = imu_noise(1000, 10.0, noise_density=1.0, random_walk=1.0, seed=6, chunk=300)
    assert not np.array_equal(np.concatenate(a), c)


def test_bad_arguments() -> None:
    with pytest.raises(ValueError, match="rate_hz"):
        next(imu_noise_chunks(10, 0.0, noise_density=1.0, random_walk=1.0))
