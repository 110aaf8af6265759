"""Log-intensity reconstruction (leaky integration across windows) and the event-window reader."""

from __future__ import annotations

import numpy as np
import pytest
from _calib_render import render_float, sim_target
from _calib_scenes import CAM_RADTAN
from hypothesis import given, settings
from hypothesis import strategies as st

from ibiscape_eval.calib.detect import detect_corners
from ibiscape_eval.calib.events import EventFrameSource, read_event_window
from ibiscape_eval.core.errors import IbiscapeError
from ibiscape_eval.core.events import Events
from ibiscape_eval.events.intensity import estimate_contrast_ratio, leaky_integrate


def _random_events(rng, n, w, h, t0, t1):
    t = np.sort(rng.integers(t0, t1, n))
    return Events(t, rng.integers(0, w, n).astype(np.uint16), rng.integers(0, h, n).astype(np.uint16),
                  rng.random(n) < 0.5)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31), st.integers(1, 200), st.floats(0.01, 5.0))
def test_leaky_integrate_is_the_closed_form_and_splits(seed, n, tau_s):
    rng = np.random.default_rng(seed)
    w, h, t0, t1 = 7, 5, 1_000, 50_000_000
    ev = _random_events(rng, n, w, h, t0, t1)
    got = leaky_integrate(np.zeros(w * h), t0, ev, t1, width_px=w, tau_s=tau_s, contrast=(0.3, 0.2))
    want = np.zeros(w * h)
    for t, x, y, p in zip(ev.t_ns, ev.x, ev.y, ev.p, strict=True):
        want[int(y) * w + int(x)] += (0.3 if p else -0.2) * np.exp(-(t1 - int(t)) / 1e9 / tau_s)
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-12)
    # two windows in a row equal one
    tm = int(rng.integers(t0, t1))
    k = int(np.searchsorted(ev.t_ns, tm))
    a = Events(ev.t_ns[:k], ev.x[:k], ev.y[:k], ev.p[:k])
    b = Events(ev.t_ns[k:], ev.x[k:], ev.y[k:], ev.p[k:])
    s = leaky_integrate(np.zeros(w * h), t0, a, tm, width_px=w, tau_s=tau_s, contrast=(0.3, 0.2))
    s = leaky_integrate(s, tm, b, t1, width_px=w, tau_s=tau_s, contrast=(0.3, 0.2))
    np.testing.assert_allclose(s, got, rtol=1e-9, atol=1e-12)


def test_leaky_integrate_bad_inputs():
    ev = Events(np.array([5], np.int64), np.array([9], np.uint16), np.array([0], np.uint16), np.array([True]))
    with pytest.raises(IbiscapeError, match="outside the 4x2 sensor"):
        leaky_integrate(np.zeros(8), 0, ev, 10, width_px=4, tau_s=1.0)
    with pytest.raises(IbiscapeError, match="tau_s"):
        leaky_integrate(np.zeros(8), 0, ev, 10, width_px=4, tau_s=0.0)
    with pytest.raises(IbiscapeError, match="before"):
        leaky_integrate(np.zeros(8), 20, ev, 10, width_px=4, tau_s=1.0)
    assert estimate_contrast_ratio(300, 100) == 3.0 and estimate_contrast_ratio(0, 5) == 1.0


def test_integration_recovers_the_log_image_of_a_moving_board():
    """A board fades in, then slides by ~2 px per render; the integrated events are L(t) - L(t0) up
    to one threshold per pixel, the board is found in the reconstruction (squares filled) at its
    current place, and not in the last window's signed accumulation (edges only)."""
    from _calib_render import board_pose

    target = sim_target("checkerboard")
    cam = CAM_RADTAN
    C, eps = 0.2, 0.001
    poses = [board_pose("checkerboard", distance_m=3.5, tilt_deg=(10, -15), roll_deg=5,
                        offset_m=(-0.3 + 0.02 * k, 0.0)) for k in range(16)]
    # the board fades in (first render: uniform grey), then slides
    imgs = [render_float(cam, poses[0], "checkerboard", contrast=0.0)]
    imgs += [render_float(cam, T, "checkerboard") for T in poses[1:]]
    t = 1_000_000_000 + 5_000_000 * np.arange(len(imgs))
    L = [np.log(eps + im / 255.0) for im in imgs]
    # per-pixel reference model: the reference moves by whole thresholds
    ref = L[0].copy()
    windows, events = [], []
    for k in range(1, len(imgs)):
        n = np.trunc((L[k] - ref) / C).astype(np.int64).ravel()
        idx = np.nonzero(n)[0]
        rep = np.repeat(idx, np.abs(n[idx]))
        tt = np.sort(np.linspace(t[k - 1], t[k] - 1, len(rep)).astype(np.int64))
        y, x = np.divmod(rep, cam.width_px)
        events.append(Events(tt, x.astype(np.uint16), y.astype(np.uint16), n[rep] > 0))
        ref = ref + C * np.trunc((L[k] - ref) / C)
        windows.append((int(t[k - 1]), int(t[k])))
    win = np.array(windows)
    src = EventFrameSource(lambda i: events[i], win, (cam.width_px, cam.height_px), "log-intensity",
                           tau_s=1e6, contrast=(C, C))
    state = np.zeros(cam.width_px * cam.height_px)
    for (a, b), ev in zip(windows, events, strict=True):
        state = leaky_integrate(state, a, ev, b, width_px=cam.width_px, tau_s=1e6, contrast=(C, C))
    err = state.reshape(L[0].shape) - (L[-1] - L[0])
    assert np.abs(err).max() <= C + 1e-6
    det = detect_corners(src(len(windows) - 1), target)
    assert det is not None and len(det) == target.n_corners
    obj = target.object_points()
    T = poses[-1]
    e = min((np.hypot(*(det.corners_px - cam.project(obj[p[det.ids]] @ T[:3, :3].T + T[:3, 3])).T)
             for p in target.symmetries()), key=lambda v: float(v.mean()))
    assert np.sqrt(np.mean(e**2)) < 0.3, e
    one = EventFrameSource(lambda i: events[i], win, (cam.width_px, cam.height_px), "accumulate-signed")
    assert detect_corners(one(len(windows) - 1), target) is None


def test_source_in_any_order_gives_the_same_frames():
    rng = np.random.default_rng(3)
    w, h = 16, 12
    win = np.array([(1_000_000_000 + k * 50_000_000, 1_000_000_000 + (k + 1) * 50_000_000) for k in range(40)])
    events = [_random_events(rng, 300, w, h, a, b) for a, b in win]
    calls = []

    def read(i):
        calls.append(i)
        return events[i]

    fwd = EventFrameSource(read, win, (w, h), "log-intensity", tau_s=0.2, cache_frames=1, bidirectional=False)
    a = [fwd(i) for i in range(40)]
    assert len(calls) == 40  # in time order every window is read once
    bwd = EventFrameSource(lambda i: events[i], win, (w, h), "log-intensity", tau_s=0.2, cache_frames=1,
                           bidirectional=False)
    b = [bwd(i) for i in reversed(range(40))][::-1]
    # a restart forgets what is older than 5 time constants: at most exp(-5) of the range
    for x, y in zip(a[25:], b[25:], strict=True):
        assert np.abs(x.astype(int) - y.astype(int)).max() <= 4
    # bidirectional: the same in any order too (backward states come in blocks of windows)
    both = [EventFrameSource(lambda i: events[i], win, (w, h), "log-intensity", tau_s=0.2, cache_frames=1)
            for _ in range(2)]
    c = [both[0].log_estimate(i) for i in range(40)]
    d = [both[1].log_estimate(i) for i in reversed(range(40))][::-1]
    for x, y in zip(c[25:], d[25:], strict=True):
        np.testing.assert_allclose(x, y, atol=0.01 * float(np.abs(x).max()) + 1e-6)
    with pytest.raises(IbiscapeError, match="40 windows"):
        fwd(40)
    with pytest.raises(IbiscapeError, match="reconstruction"):
        EventFrameSource(read, win, (w, h), "e2vid")


def test_read_event_window(tmp_path):
    p = tmp_path / "1.npz"
    np.savez(p, t=np.zeros(0, np.int64), x=np.zeros(0, np.uint16), y=np.zeros(0, np.uint16), p=np.zeros(0, bool))
    assert len(read_event_window(p)) == 0
    q = tmp_path / "2.npz"
    q.write_bytes(b"not a zip")
    with pytest.raises(IbiscapeError, match=r"2\.npz"):
        read_event_window(q)
