"""ATE results (frame, JSON contract, immutability) and time-offset estimation."""

from __future__ import annotations

import json

import numpy as np
import pytest
from metrics_gen import continuous_pose, smooth_trajectory, transformed

from ibiscape_eval.core import DegenerateInputError, Trajectory, ns_from_s
from ibiscape_eval.core.rotations import quat_from_yaw
from ibiscape_eval.metrics import ErrorStats, ate, estimate_time_offset


def test_error_stats_definitions() -> None:
    e = np.array([1.0, 2.0, 2.0, 5.0])
    s = ErrorStats.from_errors(e)
    assert s.rmse == pytest.approx(np.sqrt(34 / 4))
    assert (s.mean, s.median, s.min, s.max, s.sse, s.n) == (2.5, 2.0, 1.0, 5.0, 34.0, 4)
    assert s.std == pytest.approx(np.sqrt(np.mean((e - 2.5) ** 2)))  # population std
    assert list(s.to_dict()) == ["rmse", "mean", "median", "std", "min", "max", "sse"]
    assert np.isnan(ErrorStats.from_errors([]).rmse)


def test_ate_known_offset_error_and_contract() -> None:
    ref = smooth_trajectory(120)
    est = Trajectory(ref.stamps_ns, ref.pos_m + np.array([0.0, 0.3, 0.4]), ref.quat_xyzw, "est")
    res = ate(est, ref, align="none")
    np.testing.assert_allclose(res.errors_m, 0.5, rtol=1e-12)
    assert res.translation_m.rmse == pytest.approx(0.5) and res.translation_m.std < 1e-12
    df = res.to_frame()
    assert list(df.columns) == ["ref_stamp_ns", "ref_t_s", "est_stamp_ns", "error_m", "error_deg",
                                "est_x_m", "est_y_m", "est_z_m", "ref_x_m", "ref_y_m", "ref_z_m"]
    assert len(df) == 120 and df["ref_stamp_ns"].dtype == np.int64
    doc = json.loads(json.dumps(res.to_dict()))
    assert {"n_matched", "n_dropped_est", "n_dropped_ref", "alignment", "scale", "transform",
            "t_offset_s", "translation_m", "rotation_deg"} <= set(doc)
    assert doc["n_matched"] == 120 and doc["alignment"] == "none"
    assert np.array(doc["transform"]).shape == (4, 4)
    assert set(doc["rotation_deg"]) == {"rmse", "mean", "median", "std", "min", "max", "sse"}
    # frozen results with read-only arrays
    with pytest.raises(ValueError):
        res.errors_m[0] = 0.0
    with pytest.raises(AttributeError):
        res.n_matched = 3  # type: ignore[misc]


def _sampled(t_s: np.ndarray, shift_s: float = 0.0) -> Trajectory:
    """Poses of the closed-form motion at times ``t_s``, stamped ``t_s - shift_s``."""
    pos, q = continuous_pose(t_s)
    return Trajectory(ns_from_s(t_s - shift_s), pos, q)


@pytest.mark.parametrize("shift_s", [0.137, -0.0423])
def test_offset_estimation_recovers_planted_shift(shift_s: float) -> None:
    ref = _sampled(np.arange(0, 30, 1 / 200))  # 200 Hz ground truth
    rng = np.random.default_rng(1)
    # 20 Hz estimate with jittered sampling, its clock `shift_s` behind: t_ref = t_est + shift.
    t = np.arange(1, 29, 1 / 20) + rng.uniform(-2e-3, 2e-3, 560)
    est = _sampled(t, shift_s)
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    est = transformed(est, R, np.array([5.0, 1.0, 0.0]))  # another world frame
    off = estimate_time_offset(est, ref)
    assert off == pytest.approx(shift_s, abs=1e-3)
    coarse = estimate_time_offset(est, ref, refine=False)
    assert coarse == pytest.approx(shift_s, abs=0.01)
    res = ate(est, ref, estimate_offset=True, interpolate=True)
    assert res.t_offset_s == pytest.approx(shift_s, abs=1e-3)
    assert res.translation_m.rmse < 1e-3
    naive = ate(est, ref, interpolate=True)
    assert naive.translation_m.rmse > 10 * res.translation_m.rmse


def test_offset_estimation_without_rotation_fails_clearly() -> None:
    t = np.arange(0, 10, 0.05)
    flat = Trajectory(ns_from_s(t), np.stack([t, 0 * t, 0 * t], 1), quat_from_yaw(0 * t))
    with pytest.raises(DegenerateInputError, match=r"no rotation to correlate.*offset_s"):
        estimate_time_offset(flat, flat)
    with pytest.raises(DegenerateInputError, match="at least 4"):
        estimate_time_offset(flat.take(np.arange(3)), flat)
