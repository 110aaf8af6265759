"""Camera calibration from planar targets (checkerboards, Kalibr AprilGrids): mono, stereo and
camera chains, RGB and event cameras, with a ground-truth report.

::

    from ibiscape_eval.calib import target_from_kalibr, detect_corners, calibrate, Observations
    target = target_from_kalibr({"target_type": "aprilgrid", "tagRows": 6, "tagCols": 6,
                                 "tagSize": 0.088, "tagSpacing": 0.3})
    dets = [detect_corners(img, target) for img in images]
    result = calibrate(target, [Observations("cam0", (w, h), dets)], model="pinhole-radtan")

Heavy modules (cv2, scipy, matplotlib) load on first use.
"""

from __future__ import annotations

from ibiscape_eval.core.kalibr import CalibrationTarget, target_from_kalibr

from .calibrate import (
    MODELS,
    CalibrationResult,
    CameraCalibration,
    Observations,
    calibrate,
    evaluate,
)
from .detect import Detection, detect_corners, detect_many
from .pipeline import CameraFrames, DetectionSummary, calibrate_frames, check_frames, detect_frames
from .report import TruthComparison, compare_with_truth, format_report, truth_from_sequence

__all__ = [
    "MODELS",
    "CalibrationResult",
    "CalibrationTarget",
    "CameraCalibration",
    "CameraFrames",
    "Detection",
    "DetectionSummary",
    "Observations",
    "TruthComparison",
    "calibrate",
    "calibrate_frames",
    "check_frames",
    "compare_with_truth",
    "detect_corners",
    "detect_frames",
    "detect_many",
    "evaluate",
    "format_report",
    "target_from_kalibr",
    "truth_from_sequence",
]
