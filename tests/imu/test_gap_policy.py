"""The gap policy and the per-sample sigmas are library decisions (a notebook gets the same)."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from ibiscape_eval.core import FormatError, IbiscapeWarning, ImuTiming
from ibiscape_eval.imu import allan_deviation, check_gaps, fit_noise_model


def _timing(missing: float, largest_s: float, n_gaps: int = 3) -> ImuTiming:
    return ImuTiming(has_stamps=True, median_dt_s=0.005, n_gaps=n_gaps, missing_samples=10,
                     missing_fraction=missing, largest_gap_s=largest_s, first_gap_line=42)


def test_large_gaps_refused_with_file_and_line() -> None:
    with pytest.raises(FormatError) as ei:
        check_gaps(_timing(0.01, 0.02), "imu.csv")
    assert ei.value.line == 42 and "imu.csv" in str(ei.value) and "allow_gaps=True" in str(ei.value)
    with pytest.raises(FormatError):  # one interval of more than 100 median intervals
        check_gaps(_timing(0.0001, 0.6), "imu.csv")


def test_small_gaps_pass_and_allowed_gaps_warn() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_gaps(_timing(0.001, 0.02), "imu.csv")
        check_gaps(ImuTiming(has_stamps=False, median_dt_s=0.005), "imu.npy")
    with pytest.warns(IbiscapeWarning, match="gaps are ignored"):
        check_gaps(_timing(0.5, 10.0), "imu.csv", allow_gaps=True)


def test_discrete_sigmas_follow_the_densities() -> None:
    rng = np.random.default_rng(0)
    rate = 200.0
    y = rng.normal(0.0, 0.01, size=(400_000, 6)) + np.cumsum(rng.normal(0, 1e-4, (400_000, 6)), axis=0)
    names = ("w_x", "w_y", "w_z", "a_x", "a_y", "a_z")
    model = fit_noise_model(allan_deviation(y, rate, names=names))
    k = model.kalibr(names[:3], names[3:])
    d = model.kalibr_discrete(names[:3], names[3:])
    assert d["gyroscope_noise_sigma"] == pytest.approx(k["gyroscope_noise_density"] * math.sqrt(rate))
    assert d["accelerometer_bias_step_sigma"] == pytest.approx(
        k["accelerometer_random_walk"] / math.sqrt(rate))
    # white noise of 0.01 per sample: the per-sample sigma reads it back within 10 %
    assert d["gyroscope_noise_sigma"] == pytest.approx(0.01, rel=0.1)
