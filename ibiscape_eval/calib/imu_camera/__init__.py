"""Camera-IMU calibration without ROS: ``T_cam_imu`` and ``timeshift_cam_imu`` of every camera.

Continuous-time B-spline batch estimation (Furgale et al. 2013, Kalibr's method) over target corner
observations, IMU samples and the IMU's noise densities; see :func:`calibrate_imu_camera`.
"""

from __future__ import annotations

from .calibrate import calibrate_imu_camera
from .errors import ImuCoverageError, ImuRateError, ImuStreamError
from .inputs import CameraObservations, ImuData
from .kalibr import camchain_imucam, errors_against_truth
from .options import ImuCameraOptions, SequenceOptions
from .result import CameraImuCalibration, Excitation, ImuCameraResult, ResidualSeries
from .sequence import SequenceCalibration, calibrate_sequence
from .synthetic import observe_target

__all__ = [
    "CameraImuCalibration",
    "CameraObservations",
    "Excitation",
    "ImuCameraOptions",
    "ImuCameraResult",
    "ImuCoverageError",
    "ImuData",
    "ImuRateError",
    "ImuStreamError",
    "ResidualSeries",
    "SequenceCalibration",
    "SequenceOptions",
    "calibrate_imu_camera",
    "calibrate_sequence",
    "camchain_imucam",
    "errors_against_truth",
    "observe_target",
]
