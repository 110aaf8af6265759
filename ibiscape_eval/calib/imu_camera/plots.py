"""Figures of a camera-IMU calibration, drawn on ``matplotlib.figure.Figure`` objects."""

from __future__ import annotations

from typing import Any

import numpy as np

from .result import ImuCameraResult

__all__ = ["figures"]


def figures(result: ImuCameraResult) -> list[tuple[str, Any]]:
    """``[(file name, Figure)]``: reprojection residuals, IMU residuals over time, excitation."""
    from matplotlib.figure import Figure

    out: list[tuple[str, Any]] = []
    res = result.residuals
    if res is None:
        return out
    fig = Figure(figsize=(6.0, 6.0))
    ax = fig.add_subplot()
    for name, (_, e) in res.reproj.items():
        ax.scatter(e[:, 0], e[:, 1], s=2, alpha=0.4, label=name)
    ax.set_xlabel("u residual [px]")
    ax.set_ylabel("v residual [px]")
    ax.set_aspect("equal")
    ax.legend()
    out.append(("reprojection.png", fig))
    fig = Figure(figsize=(9.0, 6.0))
    a1, a2 = fig.subplots(2, 1, sharex=True)
    for k, axn in enumerate("xyz"):
        a1.plot(res.imu_t_s, res.gyro_rad_s[:, k], lw=0.5, label=axn)
        a2.plot(res.imu_t_s, res.accel_m_s2[:, k], lw=0.5, label=axn)
    a1.set_ylabel("gyro residual [rad/s]")
    a2.set_ylabel("accel residual [m/s^2]")
    a2.set_xlabel("time [s]")
    a1.legend()
    out.append(("imu_residuals.png", fig))
    fig = Figure(figsize=(6.0, 4.0))
    ax = fig.add_subplot()
    x = np.arange(3)
    ax.bar(x - 0.2, result.excitation.gyro_std_rad_s, 0.4, label="angular rate std [rad/s]")
    ax.bar(x + 0.2, result.excitation.accel_std_m_s2 / 10.0, 0.4, label="specific force std / 10 [m/s^2]")
    ax.axhline(result.excitation.min_rate_std_rad_s, color="k", ls="--", lw=0.8)
    ax.set_xticks(x, ["IMU x", "IMU y", "IMU z"])
    ax.legend()
    out.append(("excitation.png", fig))
    return out
