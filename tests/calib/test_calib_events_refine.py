"""Checkerboard corners refined from the events (X-junction line fits): known answers on an
analytic moving checkerboard fed through the simulator's DVS pixel model."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from ibiscape_eval.calib.detect import Detection
from ibiscape_eval.calib.events import EventFrameSource, refine_xcorners
from ibiscape_eval.core.events import Events
from ibiscape_eval.core.kalibr import CalibrationTarget
from ibiscape_eval.sim.dvs import DvsConfig, DvsSimulator

N = 48           # patch size [px]
SQUARE = 12.0    # square size [px]
BLACK, WHITE = 10.0, 200.0


def _image(corner: np.ndarray, angle: float, blur: float, swap: bool) -> np.ndarray:
    """Box-filtered (8x8 samples per pixel) checkerboard with an inner corner at ``corner``."""
    o = (np.arange(8) + 0.5) / 8 - 0.5
    ys, xs = np.mgrid[0:N, 0:N].astype(float)
    X = xs[..., None, None] + o[None, None, None, :] - corner[0]
    Y = ys[..., None, None] + o[None, None, :, None] - corner[1]
    u = X * np.cos(angle) + Y * np.sin(angle)
    v = -X * np.sin(angle) + Y * np.cos(angle)
    white = (np.floor(u / SQUARE) + np.floor(v / SQUARE)) % 2
    if swap:
        white = 1 - white
    img = BLACK + (WHITE - BLACK) * white.mean(axis=(2, 3))
    return gaussian_filter(img, blur) if blur else img


def _events(c0: np.ndarray, vel: np.ndarray, angle: float, *, blur: float = 0.7, swap: bool = False,
            span_s: float = 0.1, rate_hz: float = 4000.0) -> Events:
    """DVS events of the patch moving at ``vel`` [px/s] over ``t in [-span, span]`` (corner at c0
    at t = 0), the pixels' references randomised by a lead-in."""
    sim = DvsSimulator((N, N), DvsConfig(), np.random.default_rng(0))
    ts = np.arange(-span_s - 0.05, span_s + 1e-9, 1.0 / rate_hz)
    sim.reset(round(ts[0] * 1e9), _image(c0 + vel * ts[0], angle, blur, swap))
    # the steady state of a pixel that saw squares pass: its reference is the level of its last
    # event, up to one contrast step beyond the current log intensity (above it on dark squares,
    # which it reached falling; below it on bright ones)
    mid = 0.5 * (sim.ref.min() + sim.ref.max())
    step = np.random.default_rng(1).uniform(0.0, DvsConfig().positive_threshold, sim.ref.size)
    sim.ref += np.where(sim.ref < mid, step, -step)
    parts = [sim.step(round(t * 1e9), _image(c0 + vel * t, angle, blur, swap))[0] for t in ts[1:]]
    return Events.concatenate(parts)


@pytest.mark.parametrize(("vdeg", "angle_deg", "swap"), [(0, 20, False), (130, 20, True), (250, -35, False)])
def test_refined_corner_matches_the_truth(vdeg: float, angle_deg: float, swap: bool) -> None:
    c0 = np.array([23.3, 24.1])
    a = np.radians(angle_deg)
    vel = 30.0 * np.array([np.cos(np.radians(vdeg)), np.sin(np.radians(vdeg))])
    ev = _events(c0, vel, a, swap=swap)
    dirs = np.array([[[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]]])
    start = c0 + np.array([0.6, -0.5])  # a frame's corner, 0.8 px off
    got = refine_xcorners(ev, 0, start[None], vel[None], dirs, [SQUARE])[0]
    assert np.all(np.isfinite(got))
    assert np.hypot(*(got - c0)) < 0.08


def test_dropping_run_ends_removes_the_hysteresis_lag() -> None:
    c0 = np.array([23.3, 24.1])
    a = np.radians(20)
    dirs = np.array([[[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]]])
    lag = {True: [], False: []}
    for vdeg in (0, 90, 180, 270):
        u = np.array([np.cos(np.radians(vdeg)), np.sin(np.radians(vdeg))])
        # 2 kHz renders (0.015 px apart): measured the same lags as at 4 kHz to 0.001 px (mean with
        # the run ends dropped 0.0065 against 0.0067 px, kept -0.2005 both) in half the time
        ev = _events(c0, 30.0 * u, a, span_s=0.15, rate_hz=2000.0)
        for drop in (True, False):
            got = refine_xcorners(ev, 0, (c0 + 0.5)[None], (30.0 * u)[None], dirs, [SQUARE], drop_run_ends=drop)[0]
            lag[drop].append(float((got - c0) @ u))
    assert np.mean(lag[False]) < -0.1   # behind the motion
    assert abs(np.mean(lag[True])) < 0.03


def test_sharp_edges_are_unbiased() -> None:
    c0 = np.array([24.6, 23.2])
    vel = np.array([-20.0, 25.0])
    ev = _events(c0, vel, 0.3, blur=0.0)
    dirs = np.array([[[np.cos(0.3), np.sin(0.3)], [-np.sin(0.3), np.cos(0.3)]]])
    got = refine_xcorners(ev, 0, (c0 + 0.7)[None], vel[None], dirs, [SQUARE])[0]
    assert np.hypot(*(got - c0)) < 0.08


def test_a_still_board_or_missing_velocity_gives_nan() -> None:
    c0 = np.array([23.0, 24.0])
    still = _events(c0, np.zeros(2), 0.2, rate_hz=2000.0)  # the render rate does not matter to a NaN
    dirs = np.array([[[1.0, 0.0], [0.0, 1.0]]])
    assert len(still) == 0 or np.isnan(refine_xcorners(still, 0, c0[None], [[0.1, 0.0]], dirs, [SQUARE])).all()
    moving = _events(c0, np.array([30.0, 0.0]), 0.2, rate_hz=2000.0)
    assert len(moving) > 1000  # events enough: the NaN below is the missing velocity's
    assert np.isnan(refine_xcorners(moving, 0, c0[None], [[np.nan, np.nan]], dirs, [SQUARE])).all()
    assert np.isnan(refine_xcorners(Events.empty(), 0, c0[None], [[30.0, 0.0]], dirs, [SQUARE])).all()


def test_aprilgrid_detections_pass_unchanged() -> None:
    grid = CalibrationTarget("aprilgrid", rows=2, cols=2, tag_size_m=0.1, tag_spacing=0.3)
    src = EventFrameSource(lambda i: Events.empty(), np.array([[0, 10], [10, 20]]), (64, 48), "log-intensity")
    det = Detection(np.arange(8, dtype=np.int64), np.random.default_rng(1).uniform(5, 40, (8, 2)), (64, 48))
    out, stats = src.refine_detections(grid, [0, 1], [det, None])
    assert out[0] is det and out[1] is None
    assert stats["method"] == "none"
    off = EventFrameSource(lambda i: Events.empty(), np.array([[0, 10]]), (64, 48), "log-intensity", refine=False)
    board = CalibrationTarget("checkerboard", rows=3, cols=3, spacing_x_m=0.1, spacing_y_m=0.1)
    assert off.refine_detections(board, [0], [det])[0][0] is det
    assert off.describe()["refine_corners"] == "none"


def test_a_board_without_refinable_views_keeps_its_frame_corners() -> None:
    """A still (or blinking) board gives no moving edges: the frames' corners stay, with a warning."""
    from ibiscape_eval.core.errors import IbiscapeWarning

    board = CalibrationTarget("checkerboard", rows=3, cols=3, spacing_x_m=0.1, spacing_y_m=0.1)
    windows = np.array([[i * 50_000_000, (i + 1) * 50_000_000] for i in range(12)], np.int64)
    src = EventFrameSource(lambda i: Events.empty(), windows, (64, 48), "log-intensity")
    xy = board.object_points()[:, :2] * 100 + 10
    dets = [Detection(np.arange(9, dtype=np.int64), xy + 0.1 * i, (64, 48)) for i in range(12)]
    with pytest.warns(IbiscapeWarning, match="frames' corners are used"):
        out, stats = src.refine_detections(board, list(range(12)), dets)
    assert out == dets
    assert stats["method"] == "frames" and stats["views_refinable"] == 0
    assert stats["views_not_moving"] == 0  # 0.1 px per view, steadily: it does not jump


def test_a_board_jumping_between_views_is_not_refined() -> None:
    """A board blinking at a new pose every other view (on, off at the same pose, on at the next):
    its corners jump, the velocity from the neighbours is not that of its edges.  No view is
    refined and no event is read; the frames' corners stay."""
    from ibiscape_eval.core.errors import IbiscapeWarning

    board = CalibrationTarget("checkerboard", rows=3, cols=3, spacing_x_m=0.1, spacing_y_m=0.1)
    windows = np.array([[i * 25_000_000, (i + 1) * 25_000_000] for i in range(12)], np.int64)
    reads: list[int] = []
    src = EventFrameSource(lambda i: reads.append(i) or Events.empty(), windows, (64, 48), "log-intensity")
    xy = board.object_points()[:, :2] * 100 + 10
    dets = [Detection(np.arange(9, dtype=np.int64), xy + np.array([8.0 * (i // 2), 0.0]), (64, 48)) for i in range(12)]
    with pytest.warns(IbiscapeWarning, match="frames' corners are used"):
        out, stats = src.refine_detections(board, list(range(12)), dets)
    assert out == dets and reads == []
    assert stats["method"] == "frames" and stats["views_not_moving"] == 12
