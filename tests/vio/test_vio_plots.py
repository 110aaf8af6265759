"""The VIO top view shows the estimate's time span: the ground truth is cut to it with
``GT_MARGIN_S`` on each side, so a few seconds of estimate on a long recording stay visible."""

from __future__ import annotations

import numpy as np

from ibiscape_eval.core.trajectory import Trajectory
from ibiscape_eval.vio.estimator import FailureSpan
from ibiscape_eval.vio.plots import GT_MARGIN_S, ground_truth_in_span, top_view_figure


def _circle(t0_s: float, t1_s: float, rate_hz: float, name: str) -> Trajectory:
    """A 50 m radius circle driven at 5 m/s (one lap in ~63 s)."""
    t = np.arange(t0_s, t1_s, 1.0 / rate_hz)
    a = 0.1 * t
    pos = np.column_stack([50 * np.cos(a), 50 * np.sin(a), np.zeros_like(t)])
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1))
    return Trajectory((t * 1e9).round().astype(np.int64), pos, quat, name)


def test_ground_truth_is_cut_to_the_estimate_span_with_the_margin() -> None:
    gt = _circle(0.0, 145.0, 100.0, "gt")
    est = _circle(20.0, 24.7, 20.0, "est")
    cut = ground_truth_in_span(gt, est)
    assert cut.stamps_ns[0] >= est.stamps_ns[0] - GT_MARGIN_S * 1e9
    assert cut.stamps_ns[-1] <= est.stamps_ns[-1] + GT_MARGIN_S * 1e9
    assert abs(cut.stamps_s[0] - (20.0 - GT_MARGIN_S)) < 0.011
    assert abs(cut.stamps_s[-1] - (24.65 + GT_MARGIN_S)) < 0.011
    assert len(ground_truth_in_span(gt, est, margin_s=0.0)) < len(cut)
    empty = Trajectory(np.zeros(0, dtype=np.int64), np.zeros((0, 3)), np.zeros((0, 4)), "e")
    assert len(ground_truth_in_span(gt, empty)) == len(gt)


def test_top_view_axes_frame_the_estimate_not_the_whole_recording() -> None:
    """A short estimate on a long recording: 4.7 s of estimate on a 145 s recording (the whole circle is 100 m
    across; the estimate's arc ~24 m)."""
    gt = _circle(0.0, 145.0, 100.0, "gt")
    est = _circle(20.0, 24.7, 20.0, "est")
    fig = top_view_figure(est, gt, [FailureSpan("tracking", est.stamps_ns[10], est.stamps_ns[20])])
    ax = fig.axes[0]
    fig.draw_without_rendering()  # applies the equal-aspect data limits
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    shown = _circle(20.0 - GT_MARGIN_S, 24.7 + GT_MARGIN_S, 100.0, "gt").pos_m
    # everything drawn is inside the limits, and the limits are not the whole 100 m circle
    assert x0 <= shown[:, 0].min() and x1 >= shown[:, 0].max()
    assert y0 <= shown[:, 1].min() and y1 >= shown[:, 1].max()
    assert max(x1 - x0, y1 - y0) < 50.0
    line = next(ln for ln in ax.get_lines() if ln.get_label().startswith("ground truth"))
    assert len(line.get_xdata()) < 0.1 * len(gt)
    assert f"+- {GT_MARGIN_S:g} s" in line.get_label()
    # the old behaviour (whole ground truth) spans the whole circle
    ax2 = top_view_figure(est, gt, margin_s=200.0).axes[0]
    assert max(np.ptp(ax2.get_xlim()), np.ptp(ax2.get_ylim())) > 99.0
