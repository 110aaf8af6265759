"""Figures for trajectory metrics and IMU noise.

Every ``plot_*`` function draws on its own :class:`matplotlib.figure.Figure` (never pyplot's global
state, never ``matplotlib.use``: a notebook's backend and open figures are left alone), writes one
PNG/PDF/SVG atomically and returns nothing; matplotlib is imported inside.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.io.atomic import atomic_output_path

if TYPE_CHECKING:
    from ibiscape_eval.core.trajectory import Trajectory

__all__ = ["plot_allan", "plot_drift", "plot_trajectory_errors"]


def _figure(**kw: Any) -> Any:
    """A figure that belongs to no pyplot window (garbage-collected like any object)."""
    from matplotlib.figure import Figure

    return Figure(**kw)


def _save(fig: Any, path: str | os.PathLike[str]) -> None:
    with atomic_output_path(path) as tmp:
        fig.savefig(tmp, dpi=120, bbox_inches="tight")


def plot_trajectory_errors(
    path: str | os.PathLike[str],
    *,
    est_aligned: Trajectory,
    ref: Trajectory,
    stamps_ns: npt.NDArray[np.int64],
    errors_m: npt.NDArray[np.float64],
    errors_deg: npt.NDArray[np.float64],
    title: str,
    gps_xyz_m: npt.NDArray[np.float64] | None = None,
    distance_m: npt.NDArray[np.float64] | None = None,
) -> None:
    """Top view of the aligned estimate over the reference (and GPS), errors over time and
    distance travelled, and error histograms.

    Parameters
    ----------
    est_aligned, ref
        Matched trajectories in the reference's world frame.
    stamps_ns, errors_m, errors_deg : ndarray, shape (M,)
        Per-pose (ATE) or per-pair (RPE) errors and their times.
    gps_xyz_m : ndarray, shape (K, 3), optional
        GNSS fixes already expressed in the reference frame.
    distance_m : ndarray, shape (M,), optional
        Distance travelled along the reference at each error sample (second x axis).
    """
    fig = _figure(figsize=(12, 9))
    axes = fig.subplots(2, 2)
    ax = axes[0, 0]
    ax.plot(ref.pos_m[:, 0], ref.pos_m[:, 1], "k-", lw=1.2, label=f"reference ({ref.name})")
    ax.plot(
        est_aligned.pos_m[:, 0],
        est_aligned.pos_m[:, 1],
        "-",
        color="tab:blue",
        lw=1.0,
        label=f"estimate ({est_aligned.name}), aligned",
    )
    if gps_xyz_m is not None and len(gps_xyz_m):
        ax.plot(gps_xyz_m[:, 0], gps_xyz_m[:, 1], ".", color="tab:green", ms=3, label="GNSS")
    ax.plot(ref.pos_m[0, 0], ref.pos_m[0, 1], "ko", ms=5)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("top view")
    ax.legend(loc="best", fontsize=8)
    ax.grid(alpha=0.3)

    t_s = (stamps_ns - ref.stamps_ns[0]) / 1e9
    ax = axes[0, 1]
    ax.plot(t_s, errors_m, color="tab:red", lw=0.8)
    ax.set_xlabel("time since start [s]")
    ax.set_ylabel("translation error [m]")
    ax.grid(alpha=0.3)
    ax2 = ax.twinx()
    ax2.plot(t_s, errors_deg, color="tab:purple", lw=0.6, alpha=0.7)
    ax2.set_ylabel("rotation error [deg]", color="tab:purple")
    ax.set_title("error over time")

    ax = axes[1, 0]
    if distance_m is not None:
        ax.plot(distance_m, errors_m, color="tab:red", lw=0.8)
        ax.set_xlabel("distance travelled [m]")
        ax.set_title("error over distance")
    else:
        ax.plot(t_s, errors_deg, color="tab:purple", lw=0.8)
        ax.set_xlabel("time since start [s]")
        ax.set_title("rotation error")
    ax.set_ylabel("translation error [m]" if distance_m is not None else "rotation error [deg]")
    ax.grid(alpha=0.3)

    ax = axes[1, 1]
    bins = max(10, min(100, int(np.sqrt(max(len(errors_m), 1)))))
    ax.hist(errors_m, bins=bins, color="tab:red", alpha=0.8)
    ax.set_xlabel("translation error [m]")
    ax.set_ylabel("count")
    ax.set_title("histogram")
    rmse = float(np.sqrt(np.mean(errors_m**2))) if len(errors_m) else float("nan")
    ax.axvline(rmse, color="k", ls="--", lw=1, label=f"rmse {rmse:.4f} m")
    ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    _save(fig, path)


def plot_drift(path: str | os.PathLike[str], doc: dict[str, Any], *, title: str) -> None:
    """Bar charts of KITTI drift per segment length: translation [%] and rotation [deg/m]."""
    lengths = np.asarray(doc["lengths_m"], dtype=float)
    fig = _figure(figsize=(11, 4))
    axes = fig.subplots(1, 2)
    labels = [f"{v:.0f}" for v in lengths]
    axes[0].bar(labels, np.asarray(doc["translation_pct"], dtype=float), color="tab:red")
    means = (doc["mean_translation_pct"], doc["mean_rotation_deg_per_m"])
    for ax, mean in zip(axes, means, strict=True):
        if mean is not None and np.isfinite(mean):  # no segment fits: nothing to average
            ax.axhline(mean, color="k", ls="--", lw=1, label="average")
    axes[0].set_ylabel("translation error [%]")
    axes[1].bar(labels, np.asarray(doc["rotation_deg_per_m"], dtype=float), color="tab:purple")
    axes[1].set_ylabel("rotation error [deg/m]")
    for ax in axes:
        ax.set_xlabel("segment length [m]")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=8)
        ax.grid(alpha=0.3, axis="y")
    fig.suptitle(title)
    fig.tight_layout()
    _save(fig, path)


def plot_allan(path: str | os.PathLike[str], res: Any, model: Any, *, title: str) -> None:
    """Log-log Allan deviation of the gyro and accelerometer axes with one-sigma bands, the fitted
    slope -1/2 (N) and +1/2 (K) lines and their read-off points (N at 1 s, K at 3 s, and the bias
    instability B at the curve minimum, drawn as 0.664 B).

    ``res`` is an :class:`~ibiscape_eval.imu.AllanResult`, ``model`` its
    :class:`~ibiscape_eval.imu.NoiseModel`.
    """
    import math

    from ibiscape_eval.imu import BIAS_INSTABILITY_FACTOR

    fig = _figure(figsize=(12, 5), constrained_layout=True)
    axs = fig.subplots(1, 2)
    t = res.taus_s
    for g, (ax, unit) in enumerate(zip(axs, ("rad/s", "m/s^2"), strict=True)):
        for j in range(3 * g, min(3 * g + 3, len(res.names))):
            a = model.axes[j]
            (line,) = ax.loglog(t, res.adev[:, j], lw=1.5, label=a.name)
            c = line.get_color()
            ax.fill_between(t, res.adev_lo[:, j], res.adev_hi[:, j], color=c, alpha=0.15, lw=0)
            if math.isfinite(a.noise_density):
                ax.loglog(t, a.noise_density / np.sqrt(t), "--", color=c, lw=0.8)
                ax.plot([1.0], [a.noise_density], "o", color=c, ms=6)
            if math.isfinite(a.random_walk):
                ax.loglog(t, a.random_walk * np.sqrt(t / 3.0), ":", color=c, lw=1.0)
                ax.plot([3.0], [a.random_walk], "s", color=c, ms=6)
            if math.isfinite(a.bias_instability):
                ax.plot(
                    [a.bias_tau_s],
                    [a.bias_instability * BIAS_INSTABILITY_FACTOR],
                    "^",
                    color=c,
                    ms=7,
                )
        # y range: the curves with their bands and every read-off point, so none is clipped
        marks = [
            v
            for a in model.axes[3 * g : 3 * g + 3]
            for v in (a.noise_density, a.random_walk)
            if math.isfinite(v) and v > 0
        ]
        lo = min([float(np.nanmin(res.adev_lo[:, 3 * g : 3 * g + 3])), *marks])
        hi = max([float(np.nanmax(res.adev_hi[:, 3 * g : 3 * g + 3])), *marks])
        ax.set_ylim(lo / 2, hi * 2)
        ax.set_xlabel("tau [s]")
        ax.set_ylabel(f"Allan deviation [{unit}]")
        ax.set_title(("gyroscope", "accelerometer")[g])
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(
            title="-- N line (o at 1 s), : K line (s at 3 s), ^ 0.664 B",
            fontsize=8,
            title_fontsize=8,
        )
    fig.suptitle(f"Overlapping Allan deviation: {title}")
    _save(fig, path)
