"""Figures for the hot-pixel report: per-pixel count histograms before and after removal (log
scale, like the IBISCape paper's figure ``fig:histo_hot_pixel``) and a heat map of the sensor."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .hotpix import HotPixelResult

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["hot_pixel_figure"]


def hot_pixel_figure(result: HotPixelResult, *, title: str = "") -> Figure:
    """Histograms of events per pixel before / after removing ``result.pixels`` (log-spaced
    bins on log axes, silent pixels counted in the legend) and a log-scale heat map of the
    sensor in which pixels without events have their own colour (shown on the colour bar) and
    the hot pixels are circled, on a new :class:`~matplotlib.figure.Figure` (pyplot's state and
    the backend are left alone)."""
    import matplotlib as mpl
    from matplotlib.colors import LogNorm
    from matplotlib.figure import Figure

    before = result.count_map
    after = before.copy()
    if len(result.pixels):
        after[result.pixels[:, 1], result.pixels[:, 0]] = 0
    fig = Figure(figsize=(13, 4.5), constrained_layout=True)
    ax_h, ax_m = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.1, 1]})
    fired_b = before[before > 0]
    fired_a = after[after > 0]
    top = max(int(fired_b.max()) if fired_b.size else 1, 1)
    zero_b, zero_a = int(before.size - fired_b.size), int(after.size - fired_a.size)
    bins = np.geomspace(1, top + 1, 60) if top > 1 else np.array([0.5, 1.5])
    ax_h.hist(fired_b, bins=bins, color="tab:red", alpha=0.55,
              label=f"before ({result.n_events:,} events; {zero_b:,} pixels silent)")
    ax_h.hist(fired_a, bins=bins, color="tab:blue", alpha=0.7,
              label=f"after ({result.n_events - result.n_discarded:,} events; "
              f"{zero_a:,} pixels silent)")
    ax_h.set_xscale("log")
    ax_h.set_yscale("log")
    ax_h.set_xlabel("events per pixel")
    ax_h.set_ylabel("pixels")
    ax_h.set_title(f"{len(result.pixels)} hot pixels, "
                   f"{100 * result.fraction_discarded:.2f} % of events discarded")
    if np.isfinite(result.threshold):
        ax_h.axvline(result.threshold, color="k", ls="--", lw=1,
                     label=f"mean + {result.n_sigma:g} std = {result.threshold:.0f}")
    ax_h.legend(loc="upper right", fontsize=8)
    # zero counts fall below the log norm's vmin: drawn in the colour map's "under" colour
    cmap = mpl.colormaps["inferno"].with_extremes(under="#2b6cb0")
    shown: Any = np.where(before > 0, before, 0.5).astype(np.float64)
    im = ax_m.imshow(shown, cmap=cmap, interpolation="nearest",
                     norm=LogNorm(vmin=1, vmax=max(top, 2)))
    if len(result.pixels):
        ax_m.scatter(result.pixels[:, 0], result.pixels[:, 1], s=40, facecolors="none",
                     edgecolors="cyan", linewidths=1.0, label="hot pixels")
        ax_m.legend(loc="lower right", fontsize=8)
    ax_m.set_title("events per pixel (blue: none)")
    ax_m.set_xlabel("x [px]")
    ax_m.set_ylabel("y [px]")
    fig.colorbar(im, ax=ax_m, label="events (triangle: 0)", extend="min")
    if title:
        fig.suptitle(title)
    return fig
