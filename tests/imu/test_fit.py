"""Noise model fit: known N and K are recovered from generated still IMU data."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.imu import BIAS_INSTABILITY_FACTOR, allan_deviation, fit_noise_model
from ibiscape_eval.sim.noise import imu_noise

NAMES = ("w_x", "w_y", "w_z", "a_x", "a_y", "a_z")
N_TRUE = np.array([1.0e-3, 2.0e-3, 5.0e-4, 2.0e-2, 3.0e-2, 5.0e-2])
K_TRUE = np.array([2.0e-4, 3.0e-4, 1.0e-4, 4.0e-3, 6.0e-3, 1.0e-2])
RATE = 20.0


@pytest.fixture(scope="module")
def model_8h():
    """8 hours at 20 Hz (576k samples x 6 axes): hours of data in a fast test."""
    y = imu_noise(int(8 * 3600 * RATE), RATE, noise_density=N_TRUE, random_walk=K_TRUE,
                  bias0=[0.01, -0.02, 0.0, 0.1, -0.2, 9.81], seed=2024)
    res = allan_deviation(y, RATE, names=NAMES)
    return res, fit_noise_model(res)


def test_white_noise_density_within_3_percent(model_8h) -> None:
    _, model = model_8h
    got = np.array([model[n].noise_density for n in NAMES])
    np.testing.assert_allclose(got, N_TRUE, rtol=0.03)


def test_random_walk_within_30_percent(model_8h) -> None:
    _, model = model_8h
    got = np.array([model[n].random_walk for n in NAMES])
    np.testing.assert_allclose(got, K_TRUE, rtol=0.30)


def test_uncertainties_ranges_and_discrete_values(model_8h) -> None:
    res, model = model_8h
    for n in NAMES:
        a = model[n]
        assert 0 < a.noise_density_unc < 0.05 * a.noise_density
        assert 0 < a.random_walk_unc < 0.6 * a.random_walk
        assert a.white_range_s is not None and a.white_range_s[0] == pytest.approx(1 / RATE)
        assert a.walk_range_s is not None and a.walk_range_s[0] > a.white_range_s[1]
        assert a.discrete_sigma == pytest.approx(a.noise_density * math.sqrt(RATE))
        assert a.discrete_walk_sigma == pytest.approx(a.random_walk / math.sqrt(RATE))
        # B: the curve minimum / 0.664 (of the curve smoothed over 3 taus), between
        # the two lines' crossing value and the curve
        j = NAMES.index(n)
        assert a.bias_instability * BIAS_INSTABILITY_FACTOR == pytest.approx(res.adev[:, j].min(),
                                                                            rel=0.02)
        assert a.bias_instability * BIAS_INSTABILITY_FACTOR >= res.adev[:, j].min()
        assert a.notes == ()
    df = model.to_frame()
    assert list(df.index) == list(NAMES)


def test_short_record_gives_nan_random_walk_with_reason() -> None:
    # 10 minutes of white noise only: no random walk visible
    y = imu_noise(12_000, RATE, noise_density=N_TRUE[:2], random_walk=0.0, seed=1)
    model = fit_noise_model(allan_deviation(y, RATE, names=["w_x", "w_y"]))
    for a in model.axes:
        assert math.isnan(a.random_walk) and math.isnan(a.random_walk_unc)
        assert any("too short to see the rate random walk" in s for s in a.notes)
        assert a.noise_density == pytest.approx(N_TRUE[model.names.index(a.name)], rel=0.05)


def test_ranges_can_be_forced(model_8h) -> None:
    res, _ = model_8h
    model = fit_noise_model(res, white_range_s=(0.05, 0.5), walk_range_s=(500.0, 3000.0))
    a = model["w_x"]
    assert a.white_range_s[0] >= 0.05 and a.white_range_s[1] <= 0.5  # type: ignore[index]
    assert a.walk_range_s[0] >= 500 and a.walk_range_s[1] <= 3000  # type: ignore[index]
    assert a.noise_density == pytest.approx(N_TRUE[0], rel=0.03)
    with pytest.raises(IbiscapeError, match="contains no tau"):
        fit_noise_model(res, walk_range_s=(1e6, 2e6))


def test_kalibr_takes_the_largest_axis_and_keeps_nan(model_8h) -> None:
    _, model = model_8h
    k = model.kalibr(gyro=NAMES[:3], accel=NAMES[3:])
    assert k["gyroscope_noise_density"] == max(model[n].noise_density for n in NAMES[:3])
    assert k["accelerometer_random_walk"] == max(model[n].random_walk for n in NAMES[3:])
    y = imu_noise(12_000, RATE, noise_density=N_TRUE, random_walk=0.0, seed=1)
    short = fit_noise_model(allan_deviation(y, RATE, names=NAMES))
    k = short.kalibr(gyro=NAMES[:3], accel=NAMES[3:])
    assert math.isnan(k["gyroscope_random_walk"]) and math.isfinite(k["gyroscope_noise_density"])
