"""Top view of a VIO estimate, with the ground truth and the failure spans (matplotlib
``Figure`` objects, no pyplot state).

The ground truth is drawn over the estimate's time span only, with :data:`GT_MARGIN_S` on either
side (:func:`ground_truth_in_span`): a 5 s estimate on a 145 s recording stays visible.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ibiscape_eval.core.trajectory import Trajectory

# the project's atomic writer (renamed ibiscape_eval.io.atomic by a pending refactor): the one
# place this package imports it
from .estimator import FailureSpan

__all__ = ["GT_MARGIN_S", "ground_truth_in_span", "top_view_figure"]

#: ground truth kept before the first and after the last estimated pose, seconds
GT_MARGIN_S = 1.0


def ground_truth_in_span(ref: Trajectory, est: Trajectory, margin_s: float = GT_MARGIN_S) -> Trajectory:
    """The poses of ``ref`` from ``margin_s`` before the first to ``margin_s`` after the last pose
    of ``est`` (all of ``ref`` when ``est`` is empty)."""
    if len(est) == 0 or len(ref) == 0:
        return ref
    m = round(margin_s * 1e9)
    t0, t1 = int(est.stamps_ns[0]) - m, int(est.stamps_ns[-1]) + m
    keep = np.flatnonzero((ref.stamps_ns >= t0) & (ref.stamps_ns <= t1))
    return ref.take(keep)


def top_view_figure(est: Trajectory, ref: Trajectory | None = None,
                    failures: Sequence[FailureSpan] = (), *, title: str = "",
                    margin_s: float = GT_MARGIN_S) -> Any:
    """x-y plot of ``est`` (already aligned to ``ref`` if given), ``ref`` over the estimate's time
    span +- ``margin_s`` (:func:`ground_truth_in_span`), and the estimated frames inside failure
    spans in red."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 6))
    ax = fig.add_subplot(1, 1, 1)
    if ref is not None:
        ref = ground_truth_in_span(ref, est, margin_s)
        ax.plot(ref.pos_m[:, 0], ref.pos_m[:, 1], color="0.5", lw=2.5,
                label=f"ground truth (estimate's span +- {margin_s:g} s)")
    ax.plot(est.pos_m[:, 0], est.pos_m[:, 1], color="C0", lw=1.2, label="VIO estimate")
    bad = np.zeros(len(est), dtype=bool)
    for f in failures:
        bad |= (est.stamps_ns >= f.start_ns) & (est.stamps_ns <= f.end_ns)
    if bad.any():
        ax.plot(est.pos_m[bad, 0], est.pos_m[bad, 1], ".", color="C3", ms=3,
                label="IMU only (tracking failure)")
    if len(est):
        ax.plot(est.pos_m[0, 0], est.pos_m[0, 1], "o", color="C2", label="start")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    return fig
