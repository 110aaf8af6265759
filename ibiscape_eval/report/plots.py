"""Figures for trajectory metrics and IMU noise.

Every ``plot_*`` function draws on its own :class:`matplotlib.figure.Figure` (never pyplot's global
state, never ``matplotlib.use``: a notebook's backend and open figures are left alone), writes one
PNG/PDF/SVG atomically and returns nothing; matplotlib is imported inside.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from ibiscape_eval.io.figure import save_figure as write_figure

if TYPE_CHECKING:
    from ibiscape_eval.core.trajectory import Trajectory

__all__ = [
    "PANELS",
    "PLOT_PLANES",
    "allan_figure",
    "compare_figure",
    "default_plot_plane",
    "drift_figure",
    "metric_figure",
    "plain_axes",
    "plot_allan",
    "plot_drift",
    "plot_trajectory_errors",
    "save_figure",
    "trajectory_errors_figure",
]


PLOT_PLANES = ("xy", "xz", "yz")
PANELS = ("trajectory", "time", "distance", "histogram")
_AXIS = {"x": 0, "y": 1, "z": 2}


def _figure(**kw: Any) -> Any:
    """A figure that belongs to no pyplot window (garbage-collected like any object)."""
    from matplotlib.figure import Figure

    return Figure(**kw)


def plain_axes(fig: Any) -> None:
    """No offset notation on any linear axis of ``fig`` (matplotlib would draw a constant
    0.3096 deg as "6.5-9.0" with a ``1e-8+3.096e-1`` note): plain numbers everywhere."""
    from matplotlib.ticker import ScalarFormatter

    for ax in fig.axes:
        for axis, scale in ((ax.xaxis, ax.get_xscale()), (ax.yaxis, ax.get_yscale())):
            if scale == "linear" and isinstance(axis.get_major_formatter(), ScalarFormatter):
                fmt = ScalarFormatter(useOffset=False)
                fmt.set_scientific(False)
                axis.set_major_formatter(fmt)


def save_figure(fig: Any, path: str | os.PathLike[str]) -> None:
    """Write ``fig`` (PNG/PDF/SVG by extension) through the atomic writer, offsets removed."""
    plain_axes(fig)
    write_figure(fig, path)


def default_plot_plane(fmt: str | None) -> str:
    """The plot plane a trajectory format is best seen in: ``"xz"`` for KITTI (its camera frame has
    y pointing down, so the ground is the x-z plane), ``"xy"`` for every other format (z up)."""
    return "xz" if fmt == "kitti" else "xy"


def _plane_axes(plane: str) -> tuple[int, int]:
    if plane not in PLOT_PLANES:
        raise ValueError(f"unknown plot plane {plane!r}; choose one of {', '.join(PLOT_PLANES)}")
    return _AXIS[plane[0]], _AXIS[plane[1]]


def _stat_lines(ax: Any, err: npt.NDArray[np.float64], unit: str) -> None:
    """evo's statistics over time: rmse, mean, median as lines and mean +- std as a band."""
    if not len(err):
        return
    rmse = float(np.sqrt(np.mean(err**2)))
    mean, med, std = float(np.mean(err)), float(np.median(err)), float(np.std(err))
    u = f" {unit}" if unit else ""
    ax.axhline(rmse, color="tab:blue", lw=1.2, label=f"rmse {rmse:.4g}{u}")
    ax.axhline(mean, color="tab:green", lw=1.2, label=f"mean {mean:.4g}{u}")
    ax.axhline(med, color="tab:orange", lw=1.2, label=f"median {med:.4g}{u}")
    ax.axhspan(mean - std, mean + std, color="tab:olive", alpha=0.2, label=f"std {std:.4g}{u}")


def trajectory_errors_figure(
    *,
    est_aligned: Trajectory,
    ref: Trajectory,
    stamps_ns: npt.NDArray[np.int64],
    errors_m: npt.NDArray[np.float64],
    errors_deg: npt.NDArray[np.float64],
    title: str = "",
    gps_xyz_m: npt.NDArray[np.float64] | None = None,
    distance_m: npt.NDArray[np.float64] | None = None,
    plane: str = "xy",
    panels: Sequence[str] | None = None,
    aligned: str = "",
    error_label: str = "translation error",
    error_unit: str = "m",
    errors: npt.NDArray[np.float64] | None = None,
    est_label: str = "estimate",
    ref_label: str = "reference",
    color_index: npt.NDArray[np.intp] | None = None,
    pose_index: npt.NDArray[np.int64] | None = None,
) -> Any:
    """The figure of :func:`plot_trajectory_errors` (a new :class:`~matplotlib.figure.Figure`).

    Panels (``panels`` chooses and orders them; default all four, or three without
    ``distance_m``): ``trajectory``: the reference in grey and the estimate coloured by its
    error (a line collection with a colour bar), in ``plane``; ``time``: the error over time
    with the rmse / mean / median lines and the mean +- std band (evo's view); ``distance``:
    the error over the distance travelled; ``histogram``.  ``aligned`` names the alignment
    applied to the estimate (empty or ``"none"``: the legend says "not aligned").
    ``errors`` replaces the translation errors (another pose relation, ``error_label`` /
    ``error_unit``); ``color_index`` gives the estimate row each error belongs to (RPE: the
    pair's first pose), by default row ``i`` for error ``i``.  ``pose_index`` (one per error)
    replaces the time axis by a "pose index" axis: for synthetic stamps (KITTI without times,
    pairing by index), which are not times.
    """
    err = np.asarray(errors_m if errors is None else errors, dtype=np.float64)
    panels = _chosen_panels(panels, distance_m is not None)
    n = len(panels)
    cols = 1 if n == 1 else 2
    rows = (n + cols - 1) // cols
    fig = _figure(figsize=(6.5 * cols, 5.0 * rows), constrained_layout=True)
    axs = np.atleast_1d(fig.subplots(rows, cols)).ravel()
    for extra in axs[n:]:
        extra.remove()
    label = f"{error_label} [{error_unit}]" if error_unit else error_label
    for ax, panel in zip(axs, panels, strict=False):
        if panel == "trajectory":
            state = "not aligned" if aligned in ("", "none") else f"aligned ({aligned})"
            _trajectory_panel(fig, ax, est_aligned, ref, err, plane=plane, label=label,
                              est_label=f"{est_label}, {state} (colour: error)",
                              ref_label=ref_label, gps_xyz_m=gps_xyz_m, color_index=color_index)
        elif panel == "time":
            x = ((np.asarray(stamps_ns) - ref.stamps_ns[0]) / 1e9 if pose_index is None
                 else np.asarray(pose_index))
            ax.plot(x, err, color="0.2", lw=0.8, label=error_label)
            _stat_lines(ax, err, error_unit)
            ax.set_xlabel("time since start [s]" if pose_index is None
                          else "pose index (no timestamps)")
            ax.set_ylabel(label)
            ax.legend(loc="upper right", fontsize=8)
        elif panel == "distance":
            ax.plot(distance_m, err, color="0.2", lw=0.8)
            ax.set_xlabel("distance travelled [m]")
            ax.set_ylabel(label)
        else:
            _histogram_panel(ax, err, error_label, error_unit)
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    plain_axes(fig)
    return fig


def _chosen_panels(panels: Sequence[str] | None, with_distance: bool) -> list[str]:
    """The panels asked for (default all, ``distance`` only with distances), checked."""
    if panels is None:
        return [p for p in PANELS if p != "distance" or with_distance]
    for p in panels:
        if p not in PANELS:
            raise ValueError(f"unknown panel {p!r}; choose from {', '.join(PANELS)}")
    return [p for p in panels if p != "distance" or with_distance]


def _trajectory_panel(fig: Any, ax: Any, est_aligned: Trajectory, ref: Trajectory,
                      err: npt.NDArray[np.float64], *, plane: str, label: str, est_label: str,
                      ref_label: str, gps_xyz_m: npt.NDArray[np.float64] | None,
                      color_index: npt.NDArray[np.intp] | None) -> None:
    """The reference in grey and the estimate coloured by its error, with a colour bar."""
    from matplotlib.collections import LineCollection

    a, b = _plane_axes(plane)
    ax.plot(ref.pos_m[:, a], ref.pos_m[:, b], "--", color="0.45", lw=1.0, label=ref_label)
    idx = np.arange(len(err)) if color_index is None else np.asarray(color_index)
    pts = est_aligned.pos_m[:, [a, b]]
    # colour each estimate segment by the error at its start pose
    seg_err = np.full(len(pts), np.nan)
    seg_err[idx] = err
    seg_err = _fill_forward(seg_err)
    segs = np.stack([pts[:-1], pts[1:]], axis=1)
    lc = LineCollection(list(segs), cmap="jet", linewidths=1.8)
    lc.set_array(seg_err[:-1])
    if np.isfinite(seg_err).any():
        lc.set_clim(float(np.nanmin(seg_err)), float(np.nanmax(seg_err)))
    ax.add_collection(lc)
    ax.plot([], [], "-", color=lc.cmap(0.75), lw=1.8, label=est_label)
    if gps_xyz_m is not None and len(gps_xyz_m):
        ax.plot(gps_xyz_m[:, a], gps_xyz_m[:, b], ".", color="tab:green", ms=3, label="GNSS")
    ax.plot(ref.pos_m[0, a], ref.pos_m[0, b], "ko", ms=5, label="start")
    ax.autoscale_view()
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"{plane[0]} [m]")
    ax.set_ylabel(f"{plane[1]} [m]")
    fig.colorbar(lc, ax=ax, label=label)
    ax.legend(loc="best", fontsize=8)


def _histogram_panel(ax: Any, err: npt.NDArray[np.float64], error_label: str,
                     error_unit: str) -> None:
    bins = max(10, min(100, int(np.sqrt(max(len(err), 1)))))
    ax.hist(err, bins=bins, color="tab:red", alpha=0.8, label=error_label)
    ax.set_xlabel(f"{error_label} [{error_unit}]" if error_unit else error_label)
    ax.set_ylabel("count")
    if len(err):
        rmse = float(np.sqrt(np.mean(err**2)))
        ax.axvline(rmse, color="k", ls="--", lw=1, label=f"rmse {rmse:.4g} {error_unit}")
    ax.legend(fontsize=8)


def _fill_forward(a: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """NaNs replaced by the last finite value before them (the first ones by the first)."""
    ok = np.isfinite(a)
    if not ok.any():
        return a
    idx = np.where(ok, np.arange(len(a)), 0)
    np.maximum.accumulate(idx, out=idx)
    out = a[idx]
    first = int(np.argmax(ok))
    out[:first] = a[first]
    return out


_RELATION_LABELS = {"trans": "translation error", "rot-angle": "rotation error",
                    "rot-part": "rotation part ||R-I||", "full": "full ||E-I||",
                    "point-distance": "point distance error"}


def metric_figure(result: Any, *, unit: str = "m", **kw: Any) -> Any:
    """:func:`trajectory_errors_figure` of an :class:`~ibiscape_eval.metrics.AteResult` or
    :class:`~ibiscape_eval.metrics.RpeResult`: its errors (of its pose relation), the distance
    travelled, the pair colouring (RPE), the alignment in the legend, and a pose-index axis
    when its stamps are synthetic.  ``unit`` (``m``, ``cm``, ``mm``) scales length errors;
    ``kw`` are the remaining keyword arguments (``plane``, ``title``, ``panels``, ``gps_xyz_m``
    ...)."""
    from ibiscape_eval.metrics import LENGTH_UNITS
    from ibiscape_eval.metrics.relations import RELATION_UNITS

    ref = result.ref
    idx = getattr(result, "first_index", None)
    path_len = ref.path_length_m()
    rel = result.pose_relation
    rel_unit = RELATION_UNITS[rel]
    if unit not in LENGTH_UNITS:
        raise ValueError(f"unknown length unit {unit!r}; choose one of {', '.join(LENGTH_UNITS)}")
    f = LENGTH_UNITS[unit] if rel_unit == "m" else 1.0
    pose_index = None
    if result.stamps_synthetic:
        pi = (np.arange(len(ref)) if result.ref_pose_index is None
              else np.asarray(result.ref_pose_index))
        pose_index = pi if idx is None else pi[idx]
    return trajectory_errors_figure(
        est_aligned=result.est_aligned, ref=ref, stamps_ns=result.stamps_ns,
        errors_m=result.errors_m, errors_deg=result.errors_deg, errors=result.errors * f,
        error_label=_RELATION_LABELS[rel], error_unit=unit if rel_unit == "m" else rel_unit,
        distance_m=path_len if idx is None else path_len[idx], aligned=result.alignment.method,
        color_index=idx, pose_index=pose_index, **kw)


def plot_trajectory_errors(path: str | os.PathLike[str], **kw: Any) -> None:
    """Write :func:`trajectory_errors_figure` (same keyword arguments) to ``path``."""
    save_figure(trajectory_errors_figure(**kw), path)


def compare_figure(result: Any, *, plane: str = "xy", title: str = "") -> Any:
    """Several estimates against one reference (a
    :class:`~ibiscape_eval.metrics.CompareResult`): every aligned estimate over the reference in
    ``plane``, the ATE over time of each, and box plots of the ATE and RPE per estimate."""
    a, b = _plane_axes(plane)
    fig = _figure(figsize=(13, 9), constrained_layout=True)
    axs = fig.subplots(2, 2)
    ax = axs[0, 0]
    ref = result.entries[0].ate.ref
    ax.plot(ref.pos_m[:, a], ref.pos_m[:, b], "--", color="0.3", lw=1.2, label="reference")
    for e in result.entries:
        p = e.ate.est_aligned.pos_m
        ax.plot(p[:, a], p[:, b], lw=1.0, label=f"{e.label} ({e.ate.alignment.method})")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"{plane[0]} [m]")
    ax.set_ylabel(f"{plane[1]} [m]")
    ax.legend(fontsize=8)
    ax = axs[0, 1]
    synthetic = any(e.ate.stamps_synthetic for e in result.entries)
    t0 = min(int(e.ate.stamps_ns[0]) for e in result.entries if len(e.ate.stamps_ns))
    for e in result.entries:
        if synthetic:
            x = (np.arange(len(e.ate.errors_m)) if e.ate.ref_pose_index is None
                 else e.ate.ref_pose_index)
        else:
            x = (e.ate.stamps_ns - t0) / 1e9
        ax.plot(x, e.ate.errors_m, lw=0.8,
                label=f"{e.label}: rmse {e.ate.translation_m.rmse:.4g} m")
    ax.set_xlabel("pose index (no timestamps)" if synthetic else "time since start [s]")
    ax.set_ylabel("ATE translation error [m]")
    ax.legend(fontsize=8)
    labels = [e.label for e in result.entries]
    for ax, data, ylabel in (
        (axs[1, 0], [e.ate.errors_m for e in result.entries], "ATE translation error [m]"),
        (axs[1, 1], [e.rpe.errors_m for e in result.entries],
         f"RPE translation error [m] (delta {result.options['delta']:g} "
         f"{result.options['delta_unit']})"),
    ):
        ax.boxplot(data, widths=0.6, medianprops={"color": "tab:red"})
        ax.set_xticks(np.arange(1, len(labels) + 1), labels)
        ax.set_ylabel(ylabel)
    for ax in axs.ravel():
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    plain_axes(fig)
    return fig


def drift_figure(result: Any, *, title: str = "") -> Any:
    """Box plots of the per-segment drift for every segment length (as
    rpg_trajectory_evaluation): translation [%] and rotation [deg/m], the exact lengths on the
    x axis and the number of segments above each box.  ``result`` is a
    :class:`~ibiscape_eval.metrics.DriftResult`."""
    lengths = np.asarray(result.lengths_m, dtype=float)
    seg_len = np.asarray(result.segment_length_m, dtype=float)
    fig = _figure(figsize=(11, 4.5), constrained_layout=True)
    axes = fig.subplots(1, 2)
    labels = [f"{v:g}" for v in lengths]
    for ax, values, ylabel, mean in (
        (axes[0], result.segment_translation_pct, "translation error [%]",
         result.mean_translation_pct),
        (axes[1], result.segment_rotation_deg_per_m, "rotation error [deg/m]",
         result.mean_rotation_deg_per_m),
    ):
        vals = np.asarray(values, dtype=float)
        data = [vals[seg_len == v] for v in lengths]
        pos = np.arange(1, len(lengths) + 1)
        keep = [k for k, d in enumerate(data) if len(d)]
        if keep:
            ax.boxplot([data[k] for k in keep], positions=pos[keep], widths=0.6,
                       showfliers=True, medianprops={"color": "tab:red"})
        ax.set_xticks(pos, labels)
        ax.set_xlim(0.4, len(lengths) + 0.6)
        if mean is not None and np.isfinite(mean):
            ax.axhline(mean, color="k", ls="--", lw=1, label=f"average {mean:.4g}")
            ax.legend(fontsize=8)
        ax.set_xlabel("segment length [m]")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3, axis="y")
        top = ax.get_ylim()[1]
        for k, d in enumerate(data):
            ax.text(pos[k], top, f"n={len(d)}", ha="center", va="bottom", fontsize=7)
    if title:
        fig.suptitle(title)
    plain_axes(fig)
    return fig


def plot_drift(path: str | os.PathLike[str], result: Any, *, title: str = "") -> None:
    """Write :func:`drift_figure` to ``path`` (``result``: a DriftResult)."""
    save_figure(drift_figure(result, title=title), path)


def allan_figure(res: Any, model: Any, *, title: str = "") -> Any:
    """Log-log Allan deviation of the gyro and accelerometer axes with one-sigma bands, the fitted
    slope -1/2 (N) and +1/2 (K) lines and their read-off points (N at 1 s, K at 3 s, and the bias
    instability B at the curve minimum, drawn as 0.664 B); the markers are explained in the
    legend.  ``res`` is an :class:`~ibiscape_eval.imu.AllanResult`, ``model`` its
    :class:`~ibiscape_eval.imu.NoiseModel`."""
    import math

    from matplotlib.lines import Line2D

    from ibiscape_eval.imu import BIAS_INSTABILITY_FACTOR

    fig = _figure(figsize=(12, 5), constrained_layout=True)
    axs = fig.subplots(1, 2)
    t = res.taus_s
    units = (r"rad/s", r"m/s$^2$")
    for g, (ax, unit) in enumerate(zip(axs, units, strict=True)):
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
                ax.plot([a.bias_tau_s], [a.bias_instability * BIAS_INSTABILITY_FACTOR], "^",
                        color=c, ms=7)
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
        ax.set_xlabel(r"averaging time $\tau$ [s]")
        ax.set_ylabel(f"Allan deviation [{unit}]")
        ax.set_title(("gyroscope", "accelerometer")[g])
        ax.grid(True, which="both", alpha=0.3)
        handles, _ = ax.get_legend_handles_labels()
        k = "0.6"
        handles += [
            Line2D([], [], ls="", marker="None", label=""),
            Line2D([], [], color=k, ls="--", marker="o", label=r"N: slope $-1/2$, read at 1 s"),
            Line2D([], [], color=k, ls=":", marker="s", label=r"K: slope $+1/2$, read at 3 s"),
            Line2D([], [], color=k, ls="", marker="^",
                   label=f"B: minimum = {BIAS_INSTABILITY_FACTOR:.3f} B"),
            Line2D([], [], color=k, lw=6, alpha=0.3, label=r"1$\sigma$ band"),
        ]
        ax.legend(handles=handles, fontsize=8, loc="best")
    if title:
        fig.suptitle(title)
    return fig


def plot_allan(path: str | os.PathLike[str], res: Any, model: Any, *, title: str = "") -> None:
    """Write :func:`allan_figure` to ``path``."""
    save_figure(allan_figure(res, model, title=title), path)
