"""Overlapping Allan deviation: exactness against allantools, taus, confidence bounds, streaming."""

from __future__ import annotations

from pathlib import Path

import allantools
import numpy as np
import pytest
from allantools import ci as at_ci
from shared_data import require_shared

from ibiscape_eval.core.errors import DegenerateInputError, IbiscapeError, IbiscapeWarning
from ibiscape_eval.imu import allan_deviation, edf_white_fm


def _ref(y: np.ndarray, rate: float, taus: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    t, ad, _, n = allantools.oadev(y, rate=rate, data_type="freq", taus=taus)
    return t, ad, n


def test_equals_allantools_on_random_data() -> None:
    rng = np.random.default_rng(11)
    n = 50_000
    y = np.column_stack([
        rng.normal(size=n),  # white
        np.cumsum(rng.normal(size=n)) * 1e-2 + rng.normal(size=n),  # white + random walk
        3e4 + rng.normal(size=n) * 1e-3,  # small noise on a large offset
    ])
    res = allan_deviation(y, 100.0, points_per_decade=12)
    for j in range(3):
        t, ad, nn = _ref(y[:, j], 100.0, res.taus_s)
        np.testing.assert_array_equal(t, res.taus_s)
        np.testing.assert_array_equal(nn, res.n_terms)
        np.testing.assert_allclose(res.adev[:, j], ad, rtol=1e-9, atol=0)


def test_equals_allantools_on_real_data() -> None:
    real = require_shared("trajectories", "V102_groundtruth.csv")  # fails under CI=true if missing
    v = np.loadtxt(real, delimiter=",", skiprows=1, usecols=(8, 9, 10))  # EuRoC velocities, 200 Hz
    res = allan_deviation(v, 200.0, names=["v_x", "v_y", "v_z"])
    for j in range(3):
        _, ad, _ = _ref(v[:, j], 200.0, res.taus_s)
        np.testing.assert_allclose(res.adev[:, j], ad, rtol=1e-9, atol=0)


def test_taus_are_rounded_to_the_sample_grid_and_reported() -> None:
    y = np.random.default_rng(2).normal(size=4000)
    asked = np.array([0.013, 0.02, 0.021, 0.5, 7.77])
    res = allan_deviation(y, 100.0, taus_s=asked)
    np.testing.assert_array_equal(res.m, [1, 2, 50, 777])
    np.testing.assert_allclose(res.taus_s, [0.01, 0.02, 0.5, 7.77])
    np.testing.assert_array_equal(res.requested_taus_s, asked)
    t, ad, _ = _ref(y, 100.0, asked)
    np.testing.assert_allclose(t, res.taus_s)
    np.testing.assert_allclose(res.adev[:, 0], ad, rtol=1e-9)


def test_taus_outside_the_record_are_dropped_with_a_warning() -> None:
    y = np.random.default_rng(2).normal(size=1000)
    with pytest.warns(IbiscapeWarning, match="left out"):
        res = allan_deviation(y, 10.0, taus_s=[0.01, 1.0, 60.0])
    np.testing.assert_array_equal(res.m, [10])


def test_confidence_bounds_match_allantools_white_fm() -> None:
    y = np.random.default_rng(3).normal(size=20_000)
    res = allan_deviation(y, 50.0)
    n_phase = y.size + 1
    for i in (0, 5, len(res.m) - 1):
        edf = at_ci.edf_simple(n_phase, res.m[i], 0)
        assert res.edf[i] == pytest.approx(max(edf, 1.0), rel=1e-12)
        lo, hi = at_ci.confidence_interval(res.adev[i, 0], max(edf, 1.0))
        assert res.adev_lo[i, 0] == pytest.approx(lo, rel=1e-10)
        assert res.adev_hi[i, 0] == pytest.approx(hi, rel=1e-10)
        assert res.adev_lo[i, 0] < res.adev[i, 0] < res.adev_hi[i, 0]
    np.testing.assert_array_equal(edf_white_fm(n_phase, res.m), res.edf)


class _Chunks:
    """A ChunkedSamples that hands out odd-sized chunks."""

    def __init__(self, data: np.ndarray):
        self.data = data
        self.n_samples, self.n_columns = data.shape

    def iter_chunks(self, columns):
        i = 0
        for size in [1, 7, 1000, 333] * 1000:
            if i >= self.n_samples:
                break
            yield self.data[i : i + size, list(columns)]
            i += size


def test_streaming_and_axis_groups_match_in_memory(tmp_path: Path) -> None:
    y = np.random.default_rng(4).normal(size=(30_000, 3)) + np.array([0.0, 5.0, -9.8])
    ref = allan_deviation(y, 200.0)
    chunked = allan_deviation(_Chunks(y), 200.0, memory_budget_bytes=1)  # one axis at a time
    np.testing.assert_allclose(chunked.adev, ref.adev, rtol=1e-9)
    np.save(tmp_path / "y.npy", y)
    mm = np.load(tmp_path / "y.npy", mmap_mode="r")
    np.testing.assert_allclose(allan_deviation(mm, 200.0).adev, ref.adev, rtol=1e-9)


def test_progress_reports_every_value() -> None:
    y = np.random.default_rng(5).normal(size=(5000, 2))
    seen: list[int] = []
    allan_deviation(y, 10.0, progress=seen.append)
    assert sum(seen) == y.size


def test_result_frame_and_shape_of_1d_input() -> None:
    y = np.random.default_rng(6).normal(size=3000)
    res = allan_deviation(y, 10.0, names=["g"])
    assert res.adev.shape == (res.taus_s.size, 1)
    df = res.to_frame()
    assert list(df.columns[:4]) == ["tau_s", "m", "n_terms", "edf"]
    np.testing.assert_array_equal(df["adev_g"], res.adev[:, 0])
    assert res.duration_s == pytest.approx(300.0)


def test_input_is_not_mutated() -> None:
    y = np.random.default_rng(7).normal(size=(2000, 2))
    before = y.copy()
    allan_deviation(y, 10.0)
    np.testing.assert_array_equal(y, before)


def test_constant_axis_is_refused() -> None:
    y = np.random.default_rng(8).normal(size=(2000, 2))
    y[:, 1] = 0.0
    with pytest.raises(DegenerateInputError, match="'a_z' is constant"):
        allan_deviation(y, 10.0, names=["w_x", "a_z"])


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_samples_are_refused(bad: float) -> None:
    y = np.random.default_rng(9).normal(size=(100, 2))
    y[42, 1] = bad
    with pytest.raises(IbiscapeError, match="sample 42 of axis '1'"):
        allan_deviation(y, 10.0)


def test_too_few_samples_and_bad_rate() -> None:
    with pytest.raises(DegenerateInputError, match="at least 3"):
        allan_deviation(np.ones(2), 10.0)
    with pytest.raises(IbiscapeError, match="rate_hz"):
        allan_deviation(np.ones(10), 0.0)
