"""Bidirectional log-intensity reconstruction: the closed form, and its point: on a board moving
at constant speed the forward estimate's smeared past pulls the corners backwards along the
motion, the average of the forward and backward estimates does not."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from _calib_render import board_pose, render_float, sim_target
from _calib_scenes import CAM_RADTAN
from hypothesis import given, settings
from hypothesis import strategies as st

from ibiscape_eval.calib.detect import detect_corners
from ibiscape_eval.calib.events import EventFrameSource
from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.events import Events


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31), st.floats(0.5, 5.0), st.integers(0, 39), st.lists(st.integers(0, 60), min_size=40,
                                                                                  max_size=40))
def test_bidirectional_estimate_is_the_closed_form(seed, tau_s, i, sizes):
    """Within MEMORY_TAU time constants (the 2 s recording), the estimate at the end of window i is
    half the decayed sum of the earlier events minus half that of the later ones, in any order."""
    rng = np.random.default_rng(seed)
    w, h, C = 6, 5, (0.3, 0.2)
    win = np.array([(10**9 + k * 50_000_000, 10**9 + (k + 1) * 50_000_000) for k in range(40)])
    events = []
    for (a, b), n in zip(win, sizes, strict=True):
        events.append(Events(np.sort(rng.integers(a, b, n)).astype(np.int64), rng.integers(0, w, n).astype(np.uint16),
                             rng.integers(0, h, n).astype(np.uint16), rng.random(n) < 0.5))
    src = EventFrameSource(lambda k: events[k], win, (w, h), "log-intensity", tau_s=tau_s, contrast=C,
                           bidirectional=True)
    for k in (39 - i, i):  # out of order: a second backward block and a forward restart
        got = src.log_estimate(k)
        t = int(win[k, 1])
        allev = Events.concatenate(events)
        c = np.where(allev.p, C[0], -C[1]) * np.exp(-np.abs(t - allev.t_ns) / 1e9 / tau_s)
        c = np.where(allev.t_ns < t, 0.5 * c, -0.5 * c)
        want = np.bincount(allev.y.astype(np.int64) * w + allev.x, weights=c, minlength=w * h).reshape(h, w)
        np.testing.assert_allclose(got, want, atol=2e-5 * max(1.0, float(np.abs(want).max())))
    fwd = EventFrameSource(lambda k: events[k], win, (w, h), "log-intensity", tau_s=tau_s, contrast=C,
                           bidirectional=False)
    before = Events.concatenate(events)
    t = int(win[i, 1])
    c = np.where(before.p, C[0], -C[1]) * np.exp(-(t - before.t_ns) / 1e9 / tau_s) * (before.t_ns < t)
    want = np.bincount(before.y.astype(np.int64) * w + before.x, weights=c, minlength=w * h).reshape(h, w)
    np.testing.assert_allclose(fwd.log_estimate(i), want, atol=1e-9)
    assert src.describe()["bidirectional"] is True and fwd.describe()["bidirectional"] is False
    with pytest.raises(IbiscapeError, match="log-intensity"):
        EventFrameSource(lambda k: events[k], win, (w, h), "accumulate").log_estimate(0)


@functools.lru_cache(maxsize=1)
def _sliding_board_events():
    """A board sliding at constant speed, about 2 px per 5 ms render (24 px squares), for 69
    windows, through the CARLA/ESIM event model (persistent per-pixel references)."""
    cam = CAM_RADTAN
    C, eps = 0.2, 0.001
    poses = [board_pose("checkerboard", distance_m=7.0, tilt_deg=(10, -15), roll_deg=5,
                        offset_m=(-1.6 + 0.045 * k, 0.01 * k)) for k in range(70)]
    imgs = [render_float(cam, T, "checkerboard", ss=2) for T in poses]
    t = 1_000_000_000 + 5_000_000 * np.arange(len(imgs))
    ref = np.log(eps + imgs[0] / 255.0)
    windows, events = [], []
    for k in range(1, len(imgs)):
        L = np.log(eps + imgs[k] / 255.0)
        n = np.trunc((L - ref) / C).astype(np.int64).ravel()
        idx = np.nonzero(n)[0]
        rep = np.repeat(idx, np.abs(n[idx]))
        tt = np.sort(np.linspace(t[k - 1], t[k] - 1, len(rep)).astype(np.int64))
        y, x = np.divmod(rep, cam.width_px)
        events.append(Events(tt, x.astype(np.uint16), y.astype(np.uint16), n[rep] > 0))
        ref = ref + C * np.trunc((L - ref) / C)
        windows.append((int(t[k - 1]), int(t[k])))
    return cam, poses[1:], np.array(windows), events, (C, C)


def test_bidirectional_removes_the_lag_of_the_forward_estimate():
    """With a memory of 8 renders (vs 12 renders per square), the forward estimate is the board
    minus a copy of it lagging by about one square: no board is found.  The average with the
    backward estimate subtracts a smear centred on the board: found, centred within 0.1 px."""
    cam, poses, win, events, C = _sliding_board_events()
    target = sim_target("checkerboard")
    obj = target.object_points()
    i = 34  # mid-motion
    T = poses[i]
    truth = cam.project(obj @ T[:3, :3].T + T[:3, 3])
    size = (cam.width_px, cam.height_px)
    found = {}
    for bidir in (False, True):
        src = EventFrameSource(lambda k: events[k], win, size, "log-intensity", tau_s=0.04, contrast=C,
                               bidirectional=bidir)
        # as the calibration pipeline detects event frames (events.py): no fast classic search first
        found[bidir] = detect_corners(src(i), target, event_frame=True, fast=False)
    assert found[False] is None
    det = found[True]
    assert det is not None and len(det) == target.n_corners
    j = np.argmin(np.linalg.norm(det.corners_px[:, None] - truth[None], axis=-1), axis=1)
    e = det.corners_px - truth[j]
    assert np.linalg.norm(e.mean(axis=0)) < 0.1
    assert np.sqrt(np.mean(np.sum(e**2, axis=1))) < 0.45


def test_noisy_boards_are_screened_out():
    """With ``max_board_noise_px`` a frame whose corners stray from their neighbours' homography is
    blanked and counted; a clean one passes unchanged."""
    from ibiscape_eval.calib.events import board_noise_px

    target = sim_target("checkerboard")
    xy = target.object_points()[:, :2]
    H = np.array([[300.0, 20.0, 100.0], [-10.0, 310.0, 80.0], [0.01, 0.02, 1.0]])
    p = np.c_[xy, np.ones(len(xy))] @ H.T
    uv = p[:, :2] / p[:, 2:]
    assert board_noise_px(uv, xy) < 1e-3
    rng = np.random.default_rng(0)
    noisy = board_noise_px(uv + rng.normal(0, 0.5, uv.shape), xy)
    assert 0.4 < noisy < 1.2
    assert board_noise_px(uv[:5], xy[:5]) == float("inf")
    cam, _, win, events, C = _sliding_board_events()
    size = (cam.width_px, cam.height_px)
    keep = EventFrameSource(lambda k: events[k], win, size, "log-intensity", tau_s=0.04, contrast=C,
                            target=target, max_board_noise_px=2.0)
    plain = EventFrameSource(lambda k: events[k], win, size, "log-intensity", tau_s=0.04, contrast=C)
    np.testing.assert_array_equal(keep(34), plain(34))
    strict = EventFrameSource(lambda k: events[k], win, size, "log-intensity", tau_s=0.04, contrast=C,
                              target=target, max_board_noise_px=0.01)
    assert detect_corners(strict(34), target) is None and strict.frames_rejected == 1
    assert strict.describe()["max_board_noise_px"] == 0.01
    with pytest.raises(IbiscapeError, match="max_board_noise_px"):
        EventFrameSource(lambda k: events[k], win, size, "log-intensity", max_board_noise_px=0.0)
