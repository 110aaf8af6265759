"""Tracking lost for longer than ``max_imu_only_s`` and back (issue #24): the estimate resumes as
a new segment (the lost span closed and reported), a stop without vision is held by the IMU's
zero-velocity update instead of being lost, and stereo odometry restarts on tracks shorter than
its window (event frames: a corner lives a few frames).  Synthetic stereo measurements of the
generated 14 s drive (still start, drive, a stop from ~9.5 s to ~12.7 s, drive)."""

from __future__ import annotations

import numpy as np
import pytest

from ibiscape_eval.metrics import ate
from ibiscape_eval.vio.backend import StereoObservations
from ibiscape_eval.vio.estimator import Estimator
from ibiscape_eval.vio.initialise import stereo_odometry
from ibiscape_eval.vio.params import VioParams
from ibiscape_eval.vio.synthetic import random_landmarks, synthetic_observations


def _short_tracks(obs: list[StereoObservations], life: int) -> list[StereoObservations]:
    """Every track renamed every ``life`` frames, staggered by landmark (a corner of an event
    frame lives a few frames): consecutive frames share ``(life - 1) / life`` of their tracks,
    frames ``life`` apart none."""
    out = []
    for i, o in enumerate(obs):
        gen = (i + o.ids % life) // life
        out.append(StereoObservations(o.stamp_ns, o.ids * 10_000 + gen, o.uL, o.uR, o.v))
    return out


def _run(seq, rig, blackout_s, *, params, life=None, imu=None):
    gt = seq.groundtruth
    stamps = gt.stamps_ns[::10]  # 20 Hz camera
    black = tuple(int(gt.stamps_ns[0] + s * 1e9) for s in blackout_s)
    obs = synthetic_observations(gt, rig, stamps, random_landmarks(gt, seed=1), pixel_sigma_px=0.3,
                                 seed=2, blackout=black)
    if life is not None:
        obs = _short_tracks(obs, life)
    est = Estimator(rig.rectified(), seq.imu if imu is None else imu, seq.noise, params,
                    seq.T_body_imu)
    for o in obs:
        est.process(o)
    est.finish()
    return est, est.trajectory(), gt, obs


def test_a_stop_without_vision_is_held_by_the_imu_not_lost(svi_seq, small_rig):
    # no vision from 9 s to 13 s: the car brakes, stands still 3.2 s and drives off; the
    # IMU-only limit (1.5 s) is shorter than the blackout, the moving part of it is not
    params = VioParams(max_imu_only_s=1.5)
    est, traj, gt, _ = _run(svi_seq, small_rig, (9.0, 13.0), params=params)
    kinds = [f.kind for f in est.failures]
    assert "lost" not in kinds, est.failures
    still = [f for f in est.failures if f.kind == "standstill"]
    assert still and sum(f.duration_s for f in still) > 2.0  # reported, most of the 3.2 s stop
    t0 = gt.stamps_ns[0]
    assert all(t0 + int(9.0e9) <= f.start_ns and f.end_ns <= t0 + int(13.1e9) for f in still)
    assert len(traj) == len(gt.stamps_ns[::10])  # a pose at every frame
    stop = (traj.stamps_ns > t0 + int(10.0e9)) & (traj.stamps_ns < t0 + int(12.5e9))
    assert np.ptp(traj.pos_m[stop], axis=0).max() < 0.05  # held still, not drifting
    length = gt.path_length_m()[-1]
    assert ate(traj, gt, align="yaw").translation_m.rmse < 0.02 * length


def test_lost_then_resumes_on_short_tracks(svi_seq, small_rig):
    # tracks live 6 frames (0.3 s): no track spans the 10-frame moving initialisation, which the
    # chained stereo odometry bridges; vision is back at 5.5 s while the car drives at ~6 m/s
    params = VioParams(max_imu_only_s=1.0)
    est, traj, gt, _ = _run(svi_seq, small_rig, (3.0, 5.5), params=params, life=6)
    lost = [f for f in est.failures if f.kind == "lost"]
    assert len(lost) == 1
    t0 = gt.stamps_ns[0]
    assert lost[0].start_ns < t0 + int(4.5e9)
    assert lost[0].end_ns < t0 + int(6.5e9)  # the lost span is closed: the estimate resumed
    inside = (traj.stamps_ns > lost[0].start_ns) & (traj.stamps_ns < lost[0].end_ns)
    assert not inside.any()  # nothing written while lost
    after = traj.stamps_ns >= lost[0].end_ns
    assert after.sum() > 120  # the rest of the drive (>= 6 s of 20 Hz frames)
    # the new segment follows the truth on its own (aligned separately: its start is the last
    # held position, as after every lost span)
    seg = traj.take(np.flatnonzero(after))
    assert ate(seg, gt, align="yaw").translation_m.rmse < 1.0  # ~20 m driven on 0.3 s tracks


def test_stereo_odometry_chains_tracks_shorter_than_the_window(svi_seq, small_rig):
    gt = svi_seq.groundtruth
    stamps = gt.stamps_ns[::10][100:110]  # 5.0 s - 5.45 s, ~6 m/s
    obs = synthetic_observations(gt, small_rig, stamps, random_landmarks(gt, seed=1),
                                 pixel_sigma_px=0.3, seed=2)
    short = _short_tracks(obs, 4)
    assert not np.intersect1d(short[0].ids, short[-1].ids).size  # no track spans the window
    poses = stereo_odometry(short, small_rig.rectified(), 12)
    assert poses is not None
    d_est = np.linalg.norm(poses[-1][:3, 3])
    i0, i1 = np.searchsorted(gt.stamps_ns, stamps[[0, -1]])
    d_true = np.linalg.norm(gt.pos_m[i1] - gt.pos_m[i0])
    assert abs(d_est - d_true) < 0.05 * d_true  # metric distance, within 5 %


def test_lost_then_restarts_at_the_stop_without_vision(svi_seq, small_rig):
    # no vision from 5 s to 13 s: lost while driving (~6 s), the car stops at ~9.5 s; the quiet
    # IMU (and its prediction through the lost span: speed near zero) restarts the estimate there
    params = VioParams(max_imu_only_s=1.0)
    est, traj, gt, _ = _run(svi_seq, small_rig, (5.0, 13.0), params=params)
    t0 = gt.stamps_ns[0]
    lost = [f for f in est.failures if f.kind == "lost"]
    assert len(lost) == 1
    assert t0 + int(9.5e9) < lost[0].end_ns < t0 + int(10.5e9)  # restarted in the stop
    assert any(f.kind == "standstill" for f in est.failures)   # then held still
    stop = (traj.stamps_ns > lost[0].end_ns) & (traj.stamps_ns < t0 + int(12.5e9))
    assert stop.sum() > 30
    assert np.ptp(traj.pos_m[stop], axis=0).max() < 0.05
    assert (traj.stamps_ns > t0 + int(13.5e9)).sum() > 5  # and drove on


@pytest.mark.parametrize("hold_after_m_s", [None, 0.0])
def test_a_pull_away_without_vision_is_not_held(svi_seq, small_rig, monkeypatch, hold_after_m_s):
    # no vision from 0.6 s to 3 s, while the car pulls away from its start: a quiet IMU at low speed
    # is not a stop when the estimate has never moved (the hold needs a stop after motion); with
    # the guard off (0 m/s, the earlier behaviour) the pull-away is held and reported as a stop
    from ibiscape_eval.vio import estimator

    if hold_after_m_s is not None:
        monkeypatch.setattr(estimator, "HOLD_AFTER_SPEED_M_S", hold_after_m_s)
    est, *_ = _run(svi_seq, small_rig, (0.6, 3.0), params=VioParams(max_imu_only_s=5.0))
    still = [f for f in est.failures if f.kind == "standstill"]
    assert bool(still) == (hold_after_m_s is not None), est.failures


def test_a_pull_away_after_a_held_stop_restarts_the_imu_only_bound(svi_seq, small_rig):
    # no vision from 8 s to 13.9 s: 1.5 s braking, the 3.2 s stop, 1.2 s pulling away; the moving
    # IMU-only time (2.7 s) exceeds the bound (2 s), but the hold measured the velocity (zero), so
    # the bound counts from the pull-away and vision is back before it runs out (the 60 s ESVI
    # dynamic drive was lost for its last 20-24 s: 3.3 s into the stop plus 3.2 s out of it)
    est, traj, gt, _ = _run(svi_seq, small_rig, (8.0, 13.9), params=VioParams(max_imu_only_s=2.0))
    kinds = [f.kind for f in est.failures]
    assert "lost" not in kinds, est.failures
    assert "standstill" in kinds
    assert len(traj) == len(gt.stamps_ns[::10])  # a pose at every frame
    imu_only = [f for f in est.failures if f.kind == "tracking"]
    assert max(f.duration_s for f in imu_only) > 5.0  # the failure span itself is reported whole
    assert ate(traj, gt, align="yaw").translation_m.rmse < 0.02 * gt.path_length_m()[-1]


def test_a_stop_is_held_when_the_speed_drifted_without_vision(svi_seq, small_rig):
    # no vision from 4 s to 13 s and, from 4 s, an accelerometer error of 0.15 m/s^2 along the
    # body's x axis that the estimate cannot see (ESVI in the rain: its accelerometer bias is off):
    # after 5.5 s without vision it enters the stop at ~0.7 m/s.  The hold's speed bound grows
    # with the IMU-only time, so the stop is held; with the fixed 0.5 m/s it was not, and the
    # estimate ran out of the IMU-only bound (8 s) while standing and was lost
    stamps, gyro, acc = svi_seq.imu
    acc = acc.copy()
    acc[stamps >= stamps[0] + int(4.0e9), 0] += 0.15
    est, traj, gt, _ = _run(svi_seq, small_rig, (4.0, 13.0), params=VioParams(max_imu_only_s=8.0),
                            imu=(stamps, gyro, acc))
    kinds = [f.kind for f in est.failures]
    assert "lost" not in kinds, est.failures
    still = [f for f in est.failures if f.kind == "standstill"]
    assert still and sum(f.duration_s for f in still) > 2.0, est.failures
    assert len(traj) == len(gt.stamps_ns[::10])


def test_a_numerical_failure_of_the_hold_is_a_reset_span_not_a_traceback(svi_seq, small_rig,
                                                                           monkeypatch):
    # the smoother's zero-velocity update may hit an indeterminate system (60 s ESVI dynamic drive,
    # standing in the rain): reported as a reset from the held state, the estimate goes on
    from ibiscape_eval.vio.backend import Backend

    def broken(self, *a, **k):
        raise RuntimeError("Indeterminant linear system detected while working near variable v1")

    monkeypatch.setattr(Backend, "hold_still", broken)
    est, traj, gt, _ = _run(svi_seq, small_rig, (9.0, 13.0), params=VioParams(max_imu_only_s=1.5))
    resets = [f for f in est.failures if f.kind == "reset"]
    t0 = gt.stamps_ns[0]
    assert resets and all(t0 + int(9.0e9) < f.start_ns < t0 + int(13.1e9) for f in resets)
    assert "lost" not in [f.kind for f in est.failures], est.failures
    stop = (traj.stamps_ns > t0 + int(10.0e9)) & (traj.stamps_ns < t0 + int(12.5e9))
    assert np.ptp(traj.pos_m[stop], axis=0).max() < 0.05  # still held (restarted at rest)
    assert len(traj) == len(gt.stamps_ns[::10])


def test_a_smoother_restart_keeps_the_gyro_bias_prior_of_the_start(svi_seq, small_rig, monkeypatch):
    # a numerical failure restarts the smoother from its last state; the gyro bias keeps the
    # standstill start's prior (1e-3 rad/s) instead of 5e-3 rad/s at every restart, which let the
    # weak event tracks of the 60 s ESVI moderate drive pull it away (yaw drift 20 deg, 1.97 %)
    from ibiscape_eval.vio.backend import Backend

    starts: list[float] = []
    start, add = Backend.start, Backend.add_keyframe
    calls = {"n": 0}

    def recording_start(self, *a, **k):
        starts.append(k.get("sigma_bias_gyro_rad_s", 5e-3))
        return start(self, *a, **k)

    def failing_add(self, *a, **k):
        calls["n"] += 1
        if calls["n"] == 20:
            raise RuntimeError("Indeterminant linear system detected while working near variable x20")
        return add(self, *a, **k)

    monkeypatch.setattr(Backend, "start", recording_start)
    monkeypatch.setattr(Backend, "add_keyframe", failing_add)
    est, traj, gt, _ = _run(svi_seq, small_rig, (13.5, 13.6), params=VioParams())
    assert est.init_method == "standstill"
    assert [f.kind for f in est.failures].count("reset") == 1
    assert len(starts) == 2 and starts[1] == starts[0] <= 1e-3
    assert len(traj) == len(gt.stamps_ns[::10])  # the estimate went on
