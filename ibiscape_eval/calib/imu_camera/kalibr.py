"""Kalibr's ``camchain-imucam.yaml`` document and the comparison with a sequence's truth."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from .result import ImuCameraResult
from .spline import log_so3

__all__ = ["camchain_imucam_document", "errors_against_truth"]


def camchain_imucam_document(result: ImuCameraResult, *,
                             rostopics: Mapping[str, str] | None = None) -> dict[str, Any]:
    """``cam0``, ``cam1``, ... with intrinsics, distortion, ``T_cam_imu``, ``timeshift_cam_imu`` and,
    from the second camera on, ``T_cn_cnm1`` (camera n-1 to camera n), in the result's camera order."""
    doc: dict[str, Any] = {}
    prev = None
    for k, cal in enumerate(result.cameras):
        entry = cal.camera.to_kalibr()
        entry["T_cam_imu"] = [[float(v) for v in row] for row in cal.T_cam_imu]
        entry["timeshift_cam_imu"] = float(cal.timeshift_cam_imu_s)
        if prev is not None:
            T = cal.T_cam_imu @ np.linalg.inv(prev)
            entry["T_cn_cnm1"] = [[float(v) for v in row] for row in T]
        entry["rostopic"] = (rostopics or {}).get(cal.name, f"/{cal.name}/image_raw")
        prev = cal.T_cam_imu
        doc[f"cam{k}"] = entry
    return doc


def errors_against_truth(result: ImuCameraResult, truth: Mapping[str, Mapping[str, Any]]
                         ) -> dict[str, dict[str, float]]:
    """Per camera: rotation error [deg], translation error [m] and time-offset error [s] against
    ``truth[name] = {"T_cam_imu": 4x4, "timeshift_cam_imu": s}`` (``sequence.yaml``'s cameras)."""
    out: dict[str, dict[str, float]] = {}
    for cal in result.cameras:
        t = truth.get(cal.name)
        if t is None or "T_cam_imu" not in t:
            continue
        T = np.asarray(t["T_cam_imu"], dtype=np.float64)
        rot = float(np.degrees(np.linalg.norm(log_so3(T[:3, :3].T @ cal.T_cam_imu[:3, :3]))))
        out[cal.name] = {
            "rotation_error_deg": rot,
            "translation_error_m": float(np.linalg.norm(cal.T_cam_imu[:3, 3] - T[:3, 3])),
            "timeshift_error_s": float(cal.timeshift_cam_imu_s - float(t.get("timeshift_cam_imu", 0.0))),
        }
    return out
