"""Back end and initialisation on synthetic stereo measurements of a generated drive: the
estimate, scored with the project's own ATE, must follow the exact ground truth."""

from __future__ import annotations

import numpy as np
import pytest

from ibiscape_eval.core.errors import FormatError
from ibiscape_eval.metrics import ate
from ibiscape_eval.vio.backend import StereoObservations
from ibiscape_eval.vio.estimator import Estimator
from ibiscape_eval.vio.params import VioParams
from ibiscape_eval.vio.synthetic import random_landmarks, synthetic_observations


def _run(seq, rig, *, start_s=0.0, params=None, blackout_s=None, seed=1):
    gt = seq.groundtruth
    stamps = gt.stamps_ns[::10]  # 20 Hz camera
    stamps = stamps[stamps >= gt.stamps_ns[0] + int(start_s * 1e9)]
    lm = random_landmarks(gt, seed=seed)
    black = None
    if blackout_s is not None:
        black = tuple(int(gt.stamps_ns[0] + s * 1e9) for s in blackout_s)
    obs = synthetic_observations(gt, rig, stamps, lm, pixel_sigma_px=0.3, seed=seed + 1,
                                 blackout=black)
    est = Estimator(rig.rectified(), seq.imu, seq.noise, params or VioParams(), seq.T_body_imu)
    for o in obs:
        est.process(o)
    est.finish()
    return est, est.trajectory(), gt


def test_standstill_start_follows_ground_truth(svi_seq, small_rig):
    est, traj, gt = _run(svi_seq, small_rig)
    assert est.init_method == "standstill"
    assert est.failures == []
    assert len(traj) == len(gt.stamps_ns[::10])  # a pose at every camera frame
    res = ate(traj, gt, align="yaw")
    length = gt.path_length_m()[-1]
    assert length > 25.0
    assert res.translation_m.rmse < 0.01 * length
    assert res.rotation_deg.rmse < 1.0


def test_moving_start_initialises_from_stereo_odometry(svi_seq, small_rig):
    # at 6 s the car drives at ~7 m/s on a flat road (planar motion)
    est, traj, gt = _run(svi_seq, small_rig, start_s=6.0)
    assert est.init_method == "moving"
    res = ate(traj, gt, align="yaw")
    length = gt.path_length_m()[-1] - gt.path_length_m()[np.searchsorted(gt.stamps_ns, traj.stamps_ns[0])]
    assert res.translation_m.rmse < 0.02 * length
    v = np.linalg.norm(np.diff(traj.pos_m, axis=0), axis=1) / 0.05
    assert 4.0 < v[0] < 12.0  # metric speed from the first frame on


def test_short_blackout_is_bridged_by_the_imu_and_reported(svi_seq, small_rig):
    est, traj, gt = _run(svi_seq, small_rig, blackout_s=(7.0, 8.5))
    spans = [f for f in est.failures if f.kind == "tracking"]
    assert len(spans) == 1
    t0 = gt.stamps_ns[0]
    assert spans[0].start_ns <= t0 + int(7.4e9) and spans[0].end_ns >= t0 + int(8.5e9)
    assert len(traj) == len(gt.stamps_ns[::10])  # IMU-only poses are still written
    length = gt.path_length_m()[-1]
    assert ate(traj, gt, align="yaw").translation_m.rmse < 0.02 * length


def test_long_blackout_is_reported_lost_then_reinitialised(svi_seq, small_rig):
    params = VioParams(max_imu_only_s=1.0)
    est, traj, gt = _run(svi_seq, small_rig, params=params, blackout_s=(5.0, 8.0))
    kinds = [f.kind for f in est.failures]
    assert "tracking" in kinds and "lost" in kinds
    lost = next(f for f in est.failures if f.kind == "lost")
    inside = (traj.stamps_ns > lost.start_ns) & (traj.stamps_ns < lost.end_ns)
    assert not inside.any()  # nothing written while lost
    after = traj.stamps_ns > lost.end_ns
    assert after.sum() > 50  # tracking re-initialised and the estimate resumed
    res = ate(traj.take(np.flatnonzero(after)), gt, align="yaw")
    assert res.translation_m.rmse < 2.0


def test_stamps_must_increase(svi_seq, small_rig):
    est = Estimator(small_rig.rectified(), svi_seq.imu, svi_seq.noise, VioParams())
    t = int(svi_seq.groundtruth.stamps_ns[20])
    from ibiscape_eval.vio.backend import StereoObservations

    est.process(StereoObservations.empty(t))
    with pytest.raises(FormatError, match="increase"):
        est.process(StereoObservations.empty(t))


def test_a_diverging_state_is_reported_and_reinitialised(svi_seq, small_rig, monkeypatch):
    """Corrupt the smoother's speed once: the estimator must not keep writing that estimate."""
    from ibiscape_eval.vio import backend as bk

    real = bk.Backend.add_keyframe
    calls = {"n": 0}

    def add(self, t_ns, pim, obs):
        used = real(self, t_ns, pim, obs)
        calls["n"] += 1
        if calls["n"] == 15:
            st = self.states[self.k]
            self.states[self.k] = bk.KeyframeState(st.stamp_ns, st.T_world_body, st.vel_m_s + 100.0,
                                                  st.bias_acc_m_s2, st.bias_gyro_rad_s)
        return used

    monkeypatch.setattr(bk.Backend, "add_keyframe", add)
    est, traj, gt = _run(svi_seq, small_rig)
    kinds = [f.kind for f in est.failures]
    assert "diverged" in kinds and "lost" in kinds
    v = np.linalg.norm(np.diff(traj.pos_m, axis=0), axis=1) / np.diff(traj.stamps_ns) * 1e9
    assert v.max() < 20.0  # no 100 m/s pose written
    assert len(traj) > 0.8 * len(gt.stamps_ns[::10])  # and the estimate resumed


@pytest.mark.parametrize("start_s", [0.0, 3.0])
def test_stereo_only_where_needed_gives_the_same_estimate(svi_seq, small_rig, start_s):
    """Frames for which ``needs_stereo`` says no carry left tracks only (``uR`` NaN, as
    ``StereoFrontEnd.track`` gives them): the keyframes, the initialisation (standstill and
    moving) and so the estimate are exactly those of stereo on every frame."""
    gt = svi_seq.groundtruth
    stamps = gt.stamps_ns[::10]
    stamps = stamps[stamps >= gt.stamps_ns[0] + int(start_s * 1e9)]
    obs = synthetic_observations(gt, small_rig, stamps, random_landmarks(gt, seed=4),
                                 pixel_sigma_px=0.3, seed=5)
    full, lazy = (Estimator(small_rig.rectified(), svi_seq.imu, svi_seq.noise, VioParams(),
                            svi_seq.T_body_imu) for _ in range(2))
    skipped = 0
    for o in obs:
        full.process(o)
        left_only = type(o)(o.stamp_ns, o.ids, o.uL, np.full(len(o), np.nan), o.v)
        if lazy.needs_stereo(left_only):
            lazy.process(o)
        else:
            skipped += 1
            lazy.process(left_only)
    full.finish()
    lazy.finish()
    assert skipped > len(obs) // 3
    assert lazy.n_keyframes == full.n_keyframes and lazy.init_method == full.init_method
    a, b = full.trajectory(), lazy.trajectory()
    assert np.array_equal(a.stamps_ns, b.stamps_ns)
    np.testing.assert_allclose(b.matrices(), a.matrices(), atol=1e-9)


def test_matched_keeps_the_stereo_observations():
    o = StereoObservations(5, np.array([1, 2, 3]), np.array([10.0, 20.0, 30.0]),
                           np.array([8.0, np.nan, 25.0]), np.array([1.0, 2.0, 3.0]))
    m = o.matched()
    assert m.stamp_ns == 5 and m.ids.tolist() == [1, 3] and m.uR.tolist() == [8.0, 25.0]
    full = StereoObservations(5, o.ids, o.uL, np.array([8.0, 9.0, 25.0]), o.v)
    assert full.matched() is full
