"""Report figures drawn on :class:`matplotlib.figure.Figure` objects (no pyplot state).

- :func:`sequence_trajectories_figure`: top view of the ground truth, the GNSS fixes and each
  algorithm's aligned estimate on one sequence (like the IBISCape paper's trajectory figures).
- :func:`error_boxplot_figure`: box plots of the per-pose ATE and per-pair RPE errors, grouped by
  sequence, one box per algorithm.

Each algorithm is drawn from its *representative* trial (:func:`representative_runs`: the
successful trial with the median ATE), so several trials do not clutter the picture.
:func:`ibiscape_eval.io.figure.figure_png` renders one to PNG bytes for the HTML report.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

from .paper_table import METRICS
from .runs import natural_key

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = [
    "algorithm_colors",
    "error_boxplot_figure",
    "representative_runs",
    "sequence_trajectories_figure",
]

_BOX_KEYS = {"ate_m": "ate_m", "rpe_m": "rpe_m", "rpe_deg": "rpe_deg"}


def algorithm_colors(algorithms: Sequence[str]) -> dict[str, Any]:
    """One colour per algorithm, the same in every figure of a report."""
    from matplotlib import colormaps

    cmap = colormaps["tab10" if len(algorithms) <= 10 else "tab20"]
    return {a: cmap(i % cmap.N) for i, a in enumerate(algorithms)}


def representative_runs(runs: Sequence[dict[str, Any]]) -> dict[tuple[str, str], dict[str, Any]]:
    """Per (sequence, algorithm): the successful trial with the median ATE RMSE (the lower of
    the two middle ones for an even count; ties broken by trial name)."""
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in runs:
        if r.get("status") == "ok" and r.get("ate") is not None:
            groups.setdefault((r["sequence"], r["algorithm"]), []).append(r)
    out = {}
    for k, rs in groups.items():
        rs = sorted(rs, key=lambda r: (r["ate"]["translation_m"]["rmse"], natural_key(r["trial"])))
        out[k] = rs[(len(rs) - 1) // 2]
    return out


def _new_figure(w_in: float, h_in: float, *, layout: Any = "constrained") -> Figure:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w_in, h_in), layout=layout)
    FigureCanvasAgg(fig)
    return fig


def sequence_trajectories_figure(
    sequence: str,
    gt_xyz_m: npt.NDArray[np.float64],
    tracks: dict[str, npt.ArrayLike],
    *,
    gnss_xyz_m: npt.NDArray[np.float64] | None = None,
    align: str = "se3",
    colors: dict[str, Any] | None = None,
    plane: str = "xy",
) -> Figure:
    """One sequence seen in ``plane`` (default the top view, x-y).

    Parameters
    ----------
    sequence : str
        Title.
    gt_xyz_m : ndarray, shape (N, 3)
        Ground-truth positions, metres, world frame.
    tracks : dict
        Algorithm -> aligned estimate positions, shape (M, 3), same frame.
    gnss_xyz_m : ndarray, shape (K, 3), optional
        GNSS fixes in the ground truth's frame.
    align : str
        The alignment used (for the title).
    colors : dict, optional
        Algorithm -> matplotlib colour (default: :func:`algorithm_colors` of ``tracks``).
    plane : str
        ``"xy"``, ``"xz"`` or ``"yz"`` (:data:`ibiscape_eval.report.plots.PLOT_PLANES`).
    """
    from .plots import _plane_axes

    i, j = _plane_axes(plane)
    # one axes: fixed margins instead of the (slow) constrained layout solver
    fig = _new_figure(6.4, 5.2, layout=None)
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.1, top=0.93)
    ax = fig.add_subplot()
    gt = np.asarray(gt_xyz_m, dtype=np.float64)
    ax.plot(gt[:, i], gt[:, j], color="black", lw=2.0, label="ground truth", zorder=3)
    if gnss_xyz_m is not None and len(gnss_xyz_m):
        g = np.asarray(gnss_xyz_m)
        ax.scatter(g[:, i], g[:, j], s=9, color="0.45", marker="x", label="GNSS", zorder=2)
    colors = colors or algorithm_colors(list(tracks))
    for alg, xyz in tracks.items():
        p = np.asarray(xyz, dtype=np.float64).reshape(-1, 3)
        ax.plot(p[:, i], p[:, j], color=colors[alg], lw=1.2, label=alg, zorder=4)
    ax.plot(gt[:1, i], gt[:1, j], "o", color="black", ms=5, zorder=5)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel(f"{plane[0]} [m]")
    ax.set_ylabel(f"{plane[1]} [m]")
    ax.set_title(f"{sequence} (estimates aligned: {align})")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    return fig


def error_boxplot_figure(
    runs: Sequence[dict[str, Any]], *, colors: dict[str, Any] | None = None
) -> Figure:
    """Box plots of ATE [m], RPE [m] and RPE [deg] per sequence and algorithm (representative
    trials; whiskers at 1.5 IQR, no outliers drawn); ``colors`` as in
    :func:`sequence_trajectories_figure`."""
    reps = representative_runs(runs)
    seqs = sorted({s for s, _ in reps}, key=natural_key)
    algs = sorted({a for _, a in reps}, key=natural_key)
    fig = _new_figure(max(6.0, 1.0 + 0.45 * len(seqs) * max(len(algs), 1)), 7.5)
    axes = fig.subplots(len(METRICS), 1, sharex=True)
    palette = colors or algorithm_colors(algs)
    colors_ = [palette[a] for a in algs]
    width = 0.8 / max(len(algs), 1)
    for ax, (metric, label) in zip(axes, METRICS, strict=True):
        for k, (alg, color) in enumerate(zip(algs, colors_, strict=True)):
            stats, pos = [], []
            for i, s in enumerate(seqs):
                r = reps.get((s, alg))
                b = None if r is None else (r.get("box") or {}).get(_BOX_KEYS[metric])
                if b:
                    stats.append({**b, "fliers": []})
                    pos.append(i + (k - (len(algs) - 1) / 2) * width)
            if stats:
                ax.bxp(stats, positions=pos, widths=width * 0.85, showfliers=False,
                       patch_artist=True, manage_ticks=False,
                       boxprops={"facecolor": color, "alpha": 0.75},
                       medianprops={"color": "black"})
        ax.set_ylabel(label)
        ax.grid(True, axis="y", alpha=0.3)
    axes[-1].set_xticks(range(len(seqs)), seqs, rotation=30 if len(seqs) > 4 else 0)
    axes[-1].set_xlim(-0.6, len(seqs) - 0.4)
    from matplotlib.patches import Patch

    axes[0].set_title("error distributions (median-ATE trial per algorithm)")
    fig.legend([Patch(facecolor=c, alpha=0.75) for c in colors_], algs, fontsize=8,
               loc="outside lower center", ncols=min(len(algs), 6))
    return fig
