"""Calibration: targets, detection, camera models, camera-IMU calibration."""
