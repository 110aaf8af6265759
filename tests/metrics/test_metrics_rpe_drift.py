"""RPE in every delta unit and pair mode, and KITTI drift, on trajectories with analytic errors."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from metrics_gen import smooth_trajectory

from ibiscape_eval.core import DegenerateInputError, IbiscapeError, IbiscapeWarning, Trajectory
from ibiscape_eval.core.rotations import quat_from_yaw
from ibiscape_eval.metrics import drift, rpe, select_pairs

STEP_NS = 125_000_000  # 0.125 s, exact in binary


def _line(n: int, step_m: float) -> Trajectory:
    """Straight motion along x, identity orientation."""
    x = np.arange(n) * step_m
    return Trajectory(np.arange(n, dtype=np.int64) * STEP_NS,
                      np.stack([x, 0 * x, 0 * x], 1), np.tile([0, 0, 0, 1.0], (n, 1)))


def _spin(n: int, step_deg: float) -> Trajectory:
    """Rotation in place about z."""
    return Trajectory(np.arange(n, dtype=np.int64) * STEP_NS, np.zeros((n, 3)),
                      quat_from_yaw(np.radians(step_deg) * np.arange(n)))


# Translation drift: the estimate travels 1.01 m per step where the reference travels 1 m.
# A pair k steps apart has error 0.01 k m whatever its start.
@pytest.mark.parametrize(
    ("delta", "unit", "k"),
    [(5, "frames", 5), (0.5, "seconds", 4), (5.0, "metres", 5)],
)
@pytest.mark.parametrize("pairs", ["consecutive", "all"])
def test_rpe_translation_drift(delta: float, unit: str, k: int, pairs: str) -> None:
    n = 41
    ref, est = _line(n, 1.0), _line(n, 1.01)
    res = rpe(est, ref, delta=delta, delta_unit=unit, pairs=pairs)
    np.testing.assert_array_equal(res.second_index - res.first_index, k)
    np.testing.assert_allclose(res.errors_m, 0.01 * k, rtol=1e-9)
    assert res.rotation_deg.max == 0.0
    if pairs == "consecutive":
        np.testing.assert_array_equal(res.first_index, np.arange(0, n - k, k))
    else:
        np.testing.assert_array_equal(res.first_index, np.arange(n - k))
    assert res.n_pairs == len(res.errors_m)
    assert res.delta_unit == unit and res.pairs == pairs


# Rotation drift: 2.2 deg per step estimated where the reference turns 2 deg.
@pytest.mark.parametrize(("delta", "unit", "k"), [(3, "frames", 3), (10.5, "degrees", 5)])
@pytest.mark.parametrize("pairs", ["consecutive", "all"])
def test_rpe_rotation_drift(delta: float, unit: str, k: int, pairs: str) -> None:
    n = 31
    ref, est = _spin(n, 2.0), _spin(n, 2.2)
    res = rpe(est, ref, delta=delta, delta_unit=unit, pairs=pairs)
    np.testing.assert_array_equal(res.second_index - res.first_index, k)
    np.testing.assert_allclose(res.errors_deg, 0.2 * k, rtol=1e-9)
    assert res.translation_m.max == 0.0
    expected_first = np.arange(0, n - k, k) if pairs == "consecutive" else np.arange(n - k)
    np.testing.assert_array_equal(res.first_index, expected_first)


def test_all_pairs_keeps_closest_within_tolerance() -> None:
    # Steps of 1 m: delta 2.5 m is 0.5 m from both neighbours (> 10 %): no pair at all.
    ref = _line(20, 1.0)
    with pytest.raises(DegenerateInputError, match="no pose pair"):
        rpe(ref, ref, delta=2.5, delta_unit="metres", pairs="all")
    i, j = select_pairs(ref, delta=2.5, delta_unit="metres", pairs="all", rel_tol=0.2)
    np.testing.assert_array_equal(j - i, 2)  # tie between 2 and 3 steps: the first wins
    # consecutive takes the first pose at or beyond delta
    i, j = select_pairs(ref, delta=2.5, delta_unit="metres")
    np.testing.assert_array_equal(j - i, 3)


def test_all_pairs_agrees_with_quadratic_search() -> None:
    traj = smooth_trajectory(400, seed=5)
    cum = traj.path_length_m()
    delta = 1.5
    i, j = select_pairs(traj, delta=delta, delta_unit="metres", pairs="all")
    expected = {}
    for a in range(len(cum) - 1):
        d = np.abs(cum[a + 1:] - cum[a] - delta)
        b = int(np.argmin(d))
        if d[b] <= 0.1 * delta:
            expected[a] = a + 1 + b
    assert dict(zip(i.tolist(), j.tolist(), strict=True)) == expected


def test_rpe_result_frame_and_json() -> None:
    ref = smooth_trajectory(100)
    res = rpe(ref, ref, delta=2)
    df = res.to_frame()
    assert list(df.columns) == ["ref_stamp_ns", "ref_t_s", "first_index", "second_index", "error_m",
                                "error_deg"]
    assert len(df) == res.n_pairs == 49
    doc = json.loads(json.dumps(res.to_dict()))
    for key in ("n_matched", "n_dropped_est", "n_dropped_ref", "alignment", "scale",
                "transform", "t_offset_s", "n_pairs", "delta", "delta_unit", "pairs"):
        assert key in doc
    assert set(doc["translation_m"]) == {"rmse", "mean", "median", "std", "min", "max", "sse"}
    assert doc["alignment"] == "none" and doc["delta_unit"] == "frames"


def test_rpe_bad_options() -> None:
    ref = _line(10, 1.0)
    with pytest.raises(IbiscapeError, match="unknown delta unit 'furlongs'"):
        rpe(ref, ref, delta_unit="furlongs")
    with pytest.raises(IbiscapeError, match="whole number"):
        rpe(ref, ref, delta=1.5)
    with pytest.raises(IbiscapeError, match="positive"):
        rpe(ref, ref, delta=-1)
    with pytest.raises(IbiscapeError, match="unknown pair mode"):
        rpe(ref, ref, pairs="some")
    with pytest.raises(DegenerateInputError, match=r"delta = 100 metres .*\(9\.000 m of path\)"):
        rpe(ref, ref, delta=100, delta_unit="metres")


# --- drift ---------------------------------------------------------------------------------


def test_drift_straight_line_with_scale_error() -> None:
    ref, est = _line(1001, 1.0), _line(1001, 1.02)  # 1000 m, 2 % too long
    res = drift(est, ref, lengths_m=(100, 400, 800, 2000))
    np.testing.assert_allclose(res.translation_pct[:3], 2.0, rtol=1e-9)
    np.testing.assert_allclose(res.rotation_deg_per_m[:3], 0.0, atol=1e-12)
    # starts every 10 frames from 0 while start + L <= 1000
    np.testing.assert_array_equal(res.n_segments, [91, 61, 21, 0])
    assert math.isnan(res.translation_pct[3]) and math.isnan(res.rotation_deg_per_m[3])
    assert res.mean_translation_pct == pytest.approx(2.0, rel=1e-9)  # NaN length skipped
    doc = json.loads(json.dumps(res.to_dict()))
    assert doc["translation_pct"][3] is None and doc["n_segments"] == [91, 61, 21, 0]
    assert doc["lengths_m"] == [100.0, 400.0, 800.0, 2000.0]
    assert list(res.to_frame().columns) == ["length_m", "reached", "n_segments",
                                            "translation_pct", "rotation_deg_per_m"]


def test_drift_circle_with_scale_and_heading_drift() -> None:
    # A polygonal circle of N steps of chord c; the estimate is 3 % larger and turns 0.01 deg
    # per step more.  A segment of k steps has translation error 0.03 * chord_k only when the
    # heading drift is zero, so check the two effects separately.
    n_per_turn, radius = 360, 100.0
    a = 2 * np.pi / n_per_turn
    idx = np.arange(2 * n_per_turn + 1)
    pos = radius * np.stack([np.cos(idx * a), np.sin(idx * a), 0 * idx], 1)
    q = quat_from_yaw(idx * a + np.pi / 2)
    stamps = idx.astype(np.int64) * STEP_NS
    ref = Trajectory(stamps, pos, q)
    est = Trajectory(stamps, 1.03 * pos, q)
    chord = 2 * radius * math.sin(a / 2)
    lengths = (100.0, 300.0)
    res = drift(est, ref, lengths_m=lengths)
    for L, pct in zip(lengths, res.translation_pct, strict=True):
        k = math.ceil(L / chord - 1e-9)
        chord_k = 2 * radius * math.sin(k * a / 2)
        assert pct == pytest.approx(3.0 * chord_k / L, rel=1e-9)
    turning = Trajectory(stamps, pos, quat_from_yaw(idx * (a + np.radians(0.01)) + np.pi / 2))
    res = drift(turning, ref, lengths_m=lengths)
    for L, rot in zip(lengths, res.rotation_deg_per_m, strict=True):
        k = math.ceil(L / chord - 1e-9)
        assert rot == pytest.approx(0.01 * k / L, rel=1e-6)


def test_drift_lengths_pct_and_averages_like_kitti() -> None:
    ref, est = _line(501, 1.0), _line(501, 1.01)  # 500 m
    res = drift(est, ref, lengths_pct=(10, 50), step_frames=5)
    np.testing.assert_allclose(res.lengths_m, [50.0, 250.0])
    np.testing.assert_array_equal(res.n_segments, [91, 51])
    # the average runs over all segments, not over lengths
    assert res.mean_translation_pct == pytest.approx(1.0, rel=1e-9)
    assert len(res.segment_first_index) == 142


def test_drift_no_segment_warns_and_bad_lengths() -> None:
    ref = _line(11, 1.0)
    with pytest.warns(IbiscapeWarning, match="no drift segment fits"):
        res = drift(ref, ref)
    assert math.isnan(res.mean_translation_pct) and res.n_segments.sum() == 0
    with pytest.raises(IbiscapeError, match="lengths_m"):
        drift(ref, ref, lengths_m=(-1.0,))
    with pytest.raises(IbiscapeError, match="lengths_pct"):
        drift(ref, ref, lengths_pct=(150,))
    with pytest.raises(IbiscapeError, match="step_frames"):
        drift(ref, ref, step_frames=0)
