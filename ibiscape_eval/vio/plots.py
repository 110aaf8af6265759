"""Top view of a VIO estimate, with the ground truth and the failure spans (matplotlib
``Figure`` objects, no pyplot state)."""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from ibiscape_eval.core.trajectory import Trajectory

# the project's atomic writer (renamed ibiscape_eval.io.atomic by a pending refactor): the one
# place this package imports it
from ibiscape_eval.io.atomic import atomic_output_path

from .estimator import FailureSpan

__all__ = ["save_figure", "top_view_figure"]


def top_view_figure(est: Trajectory, ref: Trajectory | None = None,
                    failures: Sequence[FailureSpan] = (), *, title: str = "") -> Any:
    """x-y plot of ``est`` (already aligned to ``ref`` if given), ``ref``, and the estimated
    frames inside failure spans in red."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 6))
    ax = fig.add_subplot(1, 1, 1)
    if ref is not None:
        ax.plot(ref.pos_m[:, 0], ref.pos_m[:, 1], color="0.5", lw=2.5, label="ground truth")
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


def save_figure(fig: Any, path: str | os.PathLike[str]) -> None:
    """Write ``fig`` (PNG/PDF/SVG by extension) atomically."""
    with atomic_output_path(path) as tmp:
        fig.savefig(tmp, dpi=120, bbox_inches="tight", format=os.path.splitext(str(path))[1][1:] or "png")
