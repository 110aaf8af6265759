"""Calibration figures: residual scatter and corner-coverage heat map per camera.

Drawn on ``matplotlib.figure.Figure`` objects (no pyplot state); the caller saves them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .calibrate import CalibrationResult

__all__ = ["calibration_figures"]


def calibration_figures(result: CalibrationResult, *, bins: int = 16) -> list[tuple[str, Any]]:
    """``(file name, Figure)`` per camera: ``<cam>_residuals.png`` and ``<cam>_coverage.png``."""
    from matplotlib.figure import Figure

    out = []
    for c in result.cameras:
        r = c.residuals_px
        fig = Figure(figsize=(5.2, 5.0))
        ax = fig.add_subplot(1, 1, 1)
        ax.scatter(r[:, 0], r[:, 1], s=3, alpha=0.4, color="tab:blue", linewidths=0)
        lim = max(float(np.percentile(np.abs(r), 99.5)) * 1.2, 0.05) if len(r) else 1.0
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.axhline(0, color="0.6", lw=0.6)
        ax.axvline(0, color="0.6", lw=0.6)
        ax.set_xlabel("residual x [px]")
        ax.set_ylabel("residual y [px]")
        ax.set_title(f"{c.name}: {c.residuals.kalibr()} px\nrms {c.residuals.rms_px:.3f} px, "
                     f"{c.residuals.n_corners} corners", fontsize=9)
        fig.tight_layout()
        out.append((f"{c.name}_residuals.png", fig))

        w, h = c.camera.width_px, c.camera.height_px
        fig = Figure(figsize=(6.0, 6.0 * h / w + 0.6))
        ax = fig.add_subplot(1, 1, 1)
        nb_y = max(2, round(bins * h / w))
        H, _, _ = np.histogram2d(c.corners_px[:, 1], c.corners_px[:, 0], bins=(nb_y, bins),
                                 range=((-0.5, h - 0.5), (-0.5, w - 0.5)))
        im = ax.imshow(H, extent=(-0.5, w - 0.5, h - 0.5, -0.5), cmap="viridis", interpolation="nearest")
        fig.colorbar(im, ax=ax, label="corners per cell", shrink=0.8)
        empty = float((H == 0).mean())
        ax.set_title(f"{c.name}: corner coverage ({100 * (1 - empty):.0f} % of cells)", fontsize=9)
        ax.set_xlabel("u [px]")
        ax.set_ylabel("v [px]")
        fig.tight_layout()
        out.append((f"{c.name}_coverage.png", fig))
    return out
