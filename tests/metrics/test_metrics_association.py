"""Association by time (one-to-one, offsets, interpolation) and by index; bad inputs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from metrics_gen import continuous_pose, smooth_trajectory

from ibiscape_eval.core import DegenerateInputError, IbiscapeError, Trajectory, ns_from_s
from ibiscape_eval.core.rotations import quat_from_rotvec
from ibiscape_eval.metrics import associate, associate_by_index, ate


def _traj(stamps_ns: np.ndarray, name: str = "") -> Trajectory:
    n = len(stamps_ns)
    pos = np.stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)], 1)
    return Trajectory(np.asarray(stamps_ns, dtype=np.int64), pos,
                      np.tile([0, 0, 0, 1.0], (n, 1)), name)


def test_nearest_within_max_diff_and_counts() -> None:
    ms = 1_000_000
    ref = _traj(np.arange(0, 100) * 10 * ms, "ref")  # 100 Hz
    est = _traj(np.array([3, 21, 45, 50, 77, 1500, 2000]) * ms, "est")
    m = associate(est, ref, max_diff_s=0.004)
    np.testing.assert_array_equal(m.est.stamps_ns // ms, [3, 21, 50, 77])
    np.testing.assert_array_equal(m.ref.stamps_ns // ms, [0, 20, 50, 80])
    assert (m.n_dropped_est, m.n_dropped_ref, m.n_matched) == (3, 96, 4)
    assert not m.interpolated and not m.by_index and m.t_offset_s == 0.0


def test_one_to_one_keeps_the_closest_partner() -> None:
    ms = 1_000_000
    ref = _traj(np.array([0, 100, 200, 300]) * ms)
    # The estimate is denser: 95 and 104 both want ref 100; 104 is closer.  198/202 tie for 200:
    # the earlier one wins (evo breaks ties the same way).
    est = _traj(np.array([1, 95, 104, 198, 202, 299, 400]) * ms)
    m = associate(est, ref, max_diff_s=0.01)
    np.testing.assert_array_equal(m.ref.stamps_ns // ms, [0, 100, 200, 300])
    np.testing.assert_array_equal(m.est.stamps_ns // ms, [1, 104, 198, 299])
    assert len(np.unique(m.est.stamps_ns)) == m.n_matched
    assert m.n_dropped_est == 3 and m.n_dropped_ref == 0


def test_offset_is_added_to_estimate_stamps() -> None:
    ref = smooth_trajectory(100, rate_hz=20.0)
    shift = ns_from_s(2.5)
    est = Trajectory(ref.stamps_ns - shift, ref.pos_m, ref.quat_xyzw)
    with pytest.raises(IbiscapeError, match="do not overlap"):
        associate(est.take(np.arange(40)), ref.take(np.arange(60, 100)))
    m = associate(est, ref, offset_s=2.5)
    assert m.n_matched == 100 and m.t_offset_s == 2.5
    np.testing.assert_array_equal(m.est.stamps_ns, ref.stamps_ns)  # on the reference clock
    assert ate(est, ref, offset_s=2.5).translation_m.max < 1e-9


def test_no_overlap_names_both_ranges() -> None:
    ref = _traj(ns_from_s(np.arange(10) + 1000.0), "gt.txt")
    est = _traj(ns_from_s(np.arange(10) + 2000.0), "est.txt")
    with pytest.raises(IbiscapeError, match=r"'est.txt' spans \[2000\.0+, 2009\.0+\] s.*"
                       r"'gt.txt' spans \[1000\.0+, 1009\.0+\] s.*do not overlap"):
        associate(est, ref)


def test_fewer_than_three_matches_suggests_options() -> None:
    ref = _traj(ns_from_s(np.arange(10) * 0.1))
    est = _traj(ns_from_s(np.array([0.0, 0.305, 0.555, 0.9])))
    with pytest.raises(DegenerateInputError,
                       match=r"only 2 pose\(s\) matched.*max_diff_s.*offset_s.*"
                             r"estimate_offset=True") as ei:
        associate(est, ref, max_diff_s=0.001)
    assert [r.option for r in ei.value.hint] == ["max_diff_s", "offset_s", "estimate_offset"]
    assert associate(est, ref, max_diff_s=0.01).n_matched == 3  # 0.555 is 45 ms off


def test_index_pairing() -> None:
    a = smooth_trajectory(30)
    b = Trajectory(np.arange(30, dtype=np.int64), a.pos_m, a.quat_xyzw)  # stamps unrelated
    m = associate_by_index(a, b)
    assert m.by_index and m.n_matched == 30
    assert ate(a, b, match="index", align="none").translation_m.max == 0.0
    with pytest.raises(DegenerateInputError, match=r"has 30 poses and reference .* has 29"):
        associate_by_index(a, b.take(np.arange(29)))
    with pytest.raises(DegenerateInputError, match="equally long"):
        ate(a, b.take(np.arange(29)), match="index")
    with pytest.raises(IbiscapeError, match="unknown match mode"):
        ate(a, b, match="nearest")


def test_interpolation_is_exact_on_piecewise_linear_motion() -> None:
    # Dense reference at 100 Hz whose poses are (lerp, slerp) of 1 Hz keyframes: between two
    # keyframes positions move linearly and the rotation turns at a constant rate about a
    # fixed axis, so interpolating it anywhere reproduces the underlying motion exactly.
    keys_s = np.arange(0.0, 11.0)
    rng = np.random.default_rng(2)
    key_pos = rng.normal(size=(11, 3))
    key_rv = rng.normal(scale=0.3, size=(11, 3))

    def motion(t_ns: np.ndarray) -> Trajectory:
        from ibiscape_eval.core.rotations import quat_slerp

        t_s = t_ns / 1e9
        k = np.clip(np.floor(t_s).astype(int), 0, 9)
        a = t_s - keys_s[k]
        pos = key_pos[k] + a[:, None] * (key_pos[k + 1] - key_pos[k])
        q = quat_slerp(quat_from_rotvec(key_rv[k]), quat_from_rotvec(key_rv[k + 1]), a)
        return Trajectory(t_ns, pos, q)

    ref = motion(ns_from_s(np.arange(0, 1001) / 100.0))
    est_t = np.sort(rng.uniform(0.5, 9.5, 40))
    est_t = est_t[np.diff(est_t, prepend=0) > 1e-3]
    est = motion(ns_from_s(est_t))
    m = associate(est, ref, max_diff_s=0.01, interpolate=True)
    assert m.interpolated and m.n_matched == len(est)
    np.testing.assert_array_equal(m.ref.stamps_ns, m.est.stamps_ns)
    np.testing.assert_allclose(m.ref.pos_m, est.pos_m, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.abs(np.sum(m.ref.quat_xyzw * est.quat_xyzw, 1)), 1.0,
                               rtol=0, atol=1e-12)
    res = ate(est, ref, align="none", interpolate=True)
    assert res.translation_m.max < 1e-12 and res.rotation_deg.max < 1e-5
    # Without interpolation the nearest pose is up to 5 ms away: a visible error.
    assert ate(est, ref, align="none").translation_m.max > 1e-3


def test_interpolation_stays_inside_the_overlap() -> None:
    t = np.arange(0, 200) / 100.0
    pos, q = continuous_pose(t)
    ref = Trajectory(ns_from_s(t + 1.0), pos, q)  # spans [1, 2.99] s
    te = np.arange(0, 40) / 10.0  # spans [0, 3.9] s
    pe, qe = continuous_pose(te)
    est = Trajectory(ns_from_s(te), pe, qe)
    m = associate(est, ref, interpolate=True)
    assert m.est.stamps_ns[0] >= ref.stamps_ns[0] and m.est.stamps_ns[-1] <= ref.stamps_ns[-1]
    assert m.n_matched == 20  # 1.0 .. 2.9 s
    assert m.n_dropped_est == 20


def test_inputs_are_not_mutated() -> None:
    ref = smooth_trajectory(50)
    before = ref.pos_m.copy(), ref.stamps_ns.copy()
    ate(ref, ref, offset_s=0.001, align="sim3", interpolate=True)
    np.testing.assert_array_equal(ref.pos_m, before[0])
    np.testing.assert_array_equal(ref.stamps_ns, before[1])


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.integers(0, 10_000), min_size=3, max_size=60, unique=True),
    st.lists(st.integers(0, 10_000), min_size=3, max_size=60, unique=True),
    st.integers(0, 400),
)
def test_property_matches_evo_and_is_one_to_one(a: list[int], b: list[int], tol: int) -> None:
    from evo.core.sync import matching_time_indices

    ref_ns = np.sort(np.array(a, dtype=np.int64)) * 1_000_000  # ms -> ns
    est_ns = np.sort(np.array(b, dtype=np.int64)) * 1_000_000
    ref, est = _traj(ref_ns), _traj(est_ns)
    # est carries its index in x, ref too: recover which rows were paired.
    try:
        m = associate(est, ref, max_diff_s=tol / 1000)
    except IbiscapeError:
        return
    ie, ir = m.est.pos_m[:, 0].astype(int), m.ref.pos_m[:, 0].astype(int)
    assert len(set(ie)) == len(ie) and len(set(ir)) == len(ir)  # one to one
    assert np.all(np.abs(est_ns[ie] - ref_ns[ir]) <= tol * 1_000_000)
    # Same as evo (in integer milliseconds, exact in float) wherever evo is one to one.
    short_is_est = len(est_ns) <= len(ref_ns)
    s, l_ = (est_ns, ref_ns) if short_is_est else (ref_ns, est_ns)
    i_s, i_l = matching_time_indices(s / 1e6, l_ / 1e6, max_diff=float(tol))
    if len(set(i_l)) == len(i_l):
        evo_pairs = set(zip(i_s, i_l, strict=True)) if short_is_est else set(zip(i_l, i_s, strict=True))
        assert set(zip(ie.tolist(), ir.tolist(), strict=True)) == evo_pairs
