"""The options of the camera-IMU solve (:func:`~.calibrate.calibrate_imu_camera`) and of the whole
job on a sequence (:func:`~.sequence.calibrate_sequence`), each one frozen value."""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ibiscape_eval.core.errors import IbiscapeError

__all__ = ["ImuCameraOptions", "SequenceOptions"]


@dataclass(frozen=True)
class ImuCameraOptions:
    """How :func:`~.calibrate.calibrate_imu_camera` weighs, models and solves.

    Attributes
    ----------
    sigma_px : float
        Corner noise [px].
    knot_rate_hz : float
        Knots of the trajectory spline per second.
    bias_knot_s : float
        Spacing of the bias knots [s] (random walk between them).
    max_shift_s : float
        Search range of the coarse time offset, ``+-`` seconds.
    gap_s : float
        Stretches without the target longer than this are cut out of the spline.
    min_corners : int
        Frames with fewer corners are ignored.
    min_rate_std_rad_s : float
        An IMU axis whose angular-rate std is below this counts as not excited.
    gravity_m_s2 : float
    force : bool
        Estimate even when fewer than two rotation axes are excited (the translation is then not
        observable); the result carries warnings naming the weak directions.
    refine_intrinsics : bool
        Also estimate each camera's focal lengths and principal point (distortion held), from
        the given intrinsics: for intrinsics from a camera calibration of weakly tilted views.
    max_iterations : int
        Levenberg-Marquardt iterations of each solve.
    rate_tolerance : float
        Relative disagreement allowed between ``imu.yaml``'s update rate and the data's.
    keep_residuals : bool
        Keep the residual series (for the figures) in the result.
    reweight_cameras : bool
        When a camera's reprojection RMS is more than 1.5 times the best camera's, weigh every
        camera by its RMS relative to the best one and solve again (a warning names the noisy
        cameras).
    estimate_corner_noise : bool
        Solve once with ``sigma_px``, then weigh every camera by its own reprojection RMS (at
        least 0.02 px) and solve again.
    """

    sigma_px: float = 0.3
    knot_rate_hz: float = 50.0
    bias_knot_s: float = 10.0
    max_shift_s: float = 0.1
    gap_s: float = 1.0
    min_corners: int = 6
    min_rate_std_rad_s: float = 0.02
    gravity_m_s2: float = 9.81
    force: bool = False
    refine_intrinsics: bool = False
    max_iterations: int = 40
    rate_tolerance: float = 0.05
    keep_residuals: bool = True
    reweight_cameras: bool = True
    estimate_corner_noise: bool = False

    def check(self) -> None:
        """Raise :class:`IbiscapeError` on a non-positive noise, knot rate or bias spacing."""
        if not (self.sigma_px > 0 and self.knot_rate_hz > 0 and self.bias_knot_s > 0
                and self.max_shift_s >= 0):
            raise IbiscapeError("sigma_px, knot_rate_hz and bias_knot_s must be > 0, max_shift_s >= 0")


@dataclass(frozen=True)
class SequenceOptions:
    """What :func:`~.sequence.calibrate_sequence` (``calib SEQ --imu``) uses and how.

    Attributes
    ----------
    camchain : path, optional
        Kalibr ``camchain.yaml`` with the intrinsics (default: calibrate the cameras on the same
        frames first).
    cameras : sequence of str, optional
        Cameras to use, in order (default: every camera of the sequence).
    force : bool
        Estimate even without the rotational excitation the translation needs (marked).
    imu_data : path, optional
        IMU csv (``#timestamp [ns], w_xyz, a_xyz``; IBISCape's frame inside an IBISCape folder)
        instead of the sequence's ``other_sensors`` file.
    target : CalibrationTarget, optional
        Default: ``sequence.yaml``'s target.
    frame_step : int
        Use every n-th frame of each camera (1: all).
    sigma_px : float
        The nominal corner noise [px] of the first solve.
    refine_intrinsics : bool, optional
        Also estimate focal lengths and principal points (default: when they come from the camera
        calibration of the same frames, not with ``camchain``).
    estimate_corner_noise : bool
        Solve with ``sigma_px``, then weigh each camera by its own reprojection RMS and solve again
        (default: a detector's corners are usually several times better than the nominal 0.3 px,
        and the under-weighted cameras let the accelerometer noise bend the lever arms: on the
        60 s drive at -20 ms, translation 8.3 -> 2.6 mm, rotation 0.020 -> 0.014 deg).
    workers : int, optional
        Detection processes (default: the usable CPUs).
    """

    camchain: str | os.PathLike[str] | None = None
    cameras: Sequence[str] | None = None
    force: bool = False
    imu_data: str | os.PathLike[str] | None = None
    target: Any = None
    frame_step: int = 1
    sigma_px: float = 0.3
    refine_intrinsics: bool | None = None
    estimate_corner_noise: bool = True
    workers: int | None = None

    def __post_init__(self) -> None:
        fs = self.frame_step
        if isinstance(fs, bool) or not isinstance(fs, int) or fs < 1:
            raise IbiscapeError(f"frame_step must be an integer >= 1, got {fs!r}")

    def solve_options(self) -> ImuCameraOptions:
        """The solve's options: intrinsics from a calibration on the drive's own (weakly tilted)
        views are refined with the extrinsics; those of ``camchain`` are taken as they are
        (Kalibr's way)."""
        refine = self.camchain is None if self.refine_intrinsics is None else bool(self.refine_intrinsics)
        return ImuCameraOptions(sigma_px=self.sigma_px, force=self.force, refine_intrinsics=refine,
                                estimate_corner_noise=self.estimate_corner_noise)
